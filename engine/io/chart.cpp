#include "engine/io/chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "engine/core/error.hpp"

namespace crowdmpm {

namespace {
// Tick spacing of 1, 2 or 5 times a power of ten giving about `target` ticks over [lo, hi].
double tick_step(double lo, double hi, int target) {
  const double raw = (hi - lo) / target, mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) return m * mag;
  return 10 * mag;
}

std::string tick_label(double v, double step) {
  char buf[32];
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof buf, "%.*f", decimals, std::abs(v) < 1e-12 * step ? 0.0 : v);
  return buf;
}
}  // namespace

void write_chart_png(const std::string& path, const Chart& c, int width, int height) {
  double xlo = 1e300, xhi = -1e300, ylo = 1e300, yhi = -1e300;
  for (const auto& s : c.series)
    for (const auto* pts : {&s.points, &s.upper})
      for (const Vec2& p : *pts)
        if (std::isfinite(p.x()) && std::isfinite(p.y())) {
          xlo = std::min(xlo, p.x()), xhi = std::max(xhi, p.x());
          ylo = std::min(ylo, p.y()), yhi = std::max(yhi, p.y());
        }
  if (!(xlo <= xhi)) throw Error(path + ": chart \"" + c.title + "\" has no finite point to draw");
  if (ylo >= 0) ylo = 0;
  if (c.x_lo < c.x_hi) xlo = c.x_lo, xhi = c.x_hi;
  if (c.y_lo < c.y_hi) ylo = c.y_lo, yhi = c.y_hi;
  if (xhi <= xlo) xhi = xlo + 1;
  if (yhi <= ylo) yhi = ylo + 1;
  // Room for markers at the edges of ranges taken from the data.
  if (!(c.x_lo < c.x_hi)) {
    const double xpad = 0.03 * (xhi - xlo);
    xlo -= xpad;
    xhi += xpad;
  }
  if (!(c.y_lo < c.y_hi)) yhi += 0.05 * (yhi - ylo);

  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 80, right = width - 30, top = 50, bottom = height - 60;
  auto X = [&](double x) { return left + (x - xlo) / (xhi - xlo) * (right - left); };
  auto Y = [&](double y) { return bottom - (y - ylo) / (yhi - ylo) * (bottom - top); };
  auto pt = [&](const Vec2& p) { return cv::Point(static_cast<int>(std::lround(X(p.x()))), static_cast<int>(std::lround(Y(p.y())))); };
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(40, 40, 40), grid(225, 225, 225);
  // Grid and ticks.
  const double xs = tick_step(xlo, xhi, 8), ys = tick_step(ylo, yhi, 6);
  // Ticks counted, not only compared: a step below the spacing of doubles would never end.
  int ticks = 0;
  for (double x = std::ceil(xlo / xs - 1e-9) * xs; x <= xhi + 1e-9 * xs && ticks < 50; x += xs, ++ticks) {
    const int px = static_cast<int>(std::lround(X(x)));
    cv::line(img, {px, top}, {px, bottom}, grid, 1);
    const std::string t = tick_label(x, xs);
    int base;
    const cv::Size sz = cv::getTextSize(t, font, 0.45, 1, &base);
    cv::putText(img, t, {px - sz.width / 2, bottom + 18}, font, 0.45, ink, 1, cv::LINE_AA);
  }
  ticks = 0;
  for (double y = std::ceil(ylo / ys - 1e-9) * ys; y <= yhi + 1e-9 * ys && ticks < 50; y += ys, ++ticks) {
    const int py = static_cast<int>(std::lround(Y(y)));
    cv::line(img, {left, py}, {right, py}, grid, 1);
    const std::string t = tick_label(y, ys);
    int base;
    const cv::Size sz = cv::getTextSize(t, font, 0.45, 1, &base);
    cv::putText(img, t, {left - 8 - sz.width, py + 5}, font, 0.45, ink, 1, cv::LINE_AA);
  }
  cv::rectangle(img, {left, top}, {right, bottom}, ink, 1);
  // Series, clipped to the plot area: bands first, then lines and points.
  cv::Mat plot = img(cv::Rect(left, top, right - left + 1, bottom - top + 1));
  const cv::Point shift(-left, -top);
  for (int pass = 0; pass < 2; ++pass)
    for (const auto& s : c.series) {
      const cv::Scalar col(s.rgb[2], s.rgb[1], s.rgb[0]);
      if ((s.style == ChartSeries::Style::Band) != (pass == 0)) continue;
      if (s.style == ChartSeries::Style::Band) {
        std::vector<cv::Point> poly;
        for (const Vec2& p : s.points) poly.push_back(pt(p) + shift);
        for (auto it = s.upper.rbegin(); it != s.upper.rend(); ++it) poly.push_back(pt(*it) + shift);
        if (poly.size() < 3) continue;
        cv::Mat layer = plot.clone();
        cv::fillPoly(layer, std::vector<std::vector<cv::Point>>{poly}, col, cv::LINE_AA);
        cv::addWeighted(layer, 0.25, plot, 0.75, 0, plot);
        continue;
      }
      if (s.style != ChartSeries::Style::Points)
        for (size_t i = 1; i < s.points.size(); ++i)
          if (std::isfinite(s.points[i - 1].y()) && std::isfinite(s.points[i].y()))
            cv::line(plot, pt(s.points[i - 1]) + shift, pt(s.points[i]) + shift, col, 2, cv::LINE_AA);
      if (s.style != ChartSeries::Style::Line)
        for (const Vec2& p : s.points)
          if (std::isfinite(p.y())) cv::circle(plot, pt(p) + shift, 4, col, cv::FILLED, cv::LINE_AA);
    }
  // Title, axis labels, legend.
  cv::putText(img, c.title, {left, 30}, font, 0.6, ink, 1, cv::LINE_AA);
  int base;
  const cv::Size xl = cv::getTextSize(c.x_label, font, 0.5, 1, &base);
  cv::putText(img, c.x_label, {(left + right) / 2 - xl.width / 2, height - 18}, font, 0.5, ink, 1, cv::LINE_AA);
  cv::Mat ylab(24, std::max(1, cv::getTextSize(c.y_label, font, 0.5, 1, &base).width + 4), CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(ylab, c.y_label, {2, 17}, font, 0.5, ink, 1, cv::LINE_AA);
  cv::Mat ylab_rot;
  cv::rotate(ylab, ylab_rot, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int ly = std::max(0, (top + bottom) / 2 - ylab_rot.rows / 2);
  if (ylab_rot.rows + ly <= height) ylab_rot.copyTo(img(cv::Rect(4, ly, ylab_rot.cols, ylab_rot.rows)));
  int row = 0;
  for (const auto& s : c.series) {
    if (s.name.empty()) continue;
    const cv::Scalar col(s.rgb[2], s.rgb[1], s.rgb[0]);
    const int y = top + 16 + 18 * row++, x = left + 12;
    if (s.style == ChartSeries::Style::Band) cv::rectangle(img, {x, y - 6}, {x + 22, y + 4}, col, cv::FILLED);
    else if (s.style == ChartSeries::Style::Points) cv::circle(img, {x + 11, y - 1}, 4, col, cv::FILLED, cv::LINE_AA);
    else cv::line(img, {x, y - 1}, {x + 22, y - 1}, col, 2, cv::LINE_AA);
    cv::putText(img, s.name, {x + 30, y + 4}, font, 0.45, ink, 1, cv::LINE_AA);
  }
  if (!cv::imwrite(path, img)) throw Error(path + ": cannot write the chart (is the folder there and writable?)");
}

}  // namespace crowdmpm
