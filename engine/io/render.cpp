#include "engine/io/render.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"

namespace crowdmpm {

namespace {
constexpr int kTitle = 28;  // band above the map
constexpr int kBar = 90;    // colour bar to the right
constexpr int kPad = 8;
constexpr int kLeft = 44;    // left of the map: y axis labels (m)
constexpr int kBottom = 40;  // below the map: x axis labels (m) and the scale bar

cv::Point to_px(const View& v, const Vec2& p) {
  return cv::Point(kLeft + static_cast<int>(std::lround((p.x() - v.lo.x()) * v.ppm)),
                   kTitle + static_cast<int>(std::lround((v.hi.y() - p.y()) * v.ppm)));
}

cv::Vec3b colour(double t) {
  static const cv::Mat lut = [] {
    cv::Mat ramp(1, 256, CV_8UC1), out;
    for (int i = 0; i < 256; ++i) ramp.at<unsigned char>(0, i) = static_cast<unsigned char>(i);
    cv::applyColorMap(ramp, out, cv::COLORMAP_INFERNO);
    return out;
  }();
  if (!(t >= 0)) t = 0;  // NaN too
  return lut.at<cv::Vec3b>(0, static_cast<int>(std::lround(std::min(t, 1.0) * 255)));
}

cv::Mat canvas(const View& v) {
  // At least 480 px wide so that titles and legends of tall, narrow venues fit.
  return cv::Mat(v.height() + kTitle + kBottom, std::max(480, kLeft + v.width() + kPad + kBar), CV_8UC3, cv::Scalar(255, 255, 255));
}

void draw_shape(cv::Mat& img, const View& v, const Shape& s, const cv::Scalar& fill, const cv::Scalar& edge, bool filled) {
  int th = std::max(1, static_cast<int>(std::lround(2 * s.radius * v.ppm)));
  switch (s.kind) {
    case Shape::Kind::Circle: {
      int r = std::max(1, static_cast<int>(std::lround(s.radius * v.ppm)));
      if (filled) cv::circle(img, to_px(v, s.center), r, fill, cv::FILLED, cv::LINE_AA);
      cv::circle(img, to_px(v, s.center), r, edge, 1, cv::LINE_AA);
      break;
    }
    case Shape::Kind::Polyline: {
      std::vector<cv::Point> pts;
      for (const auto& q : s.points) pts.push_back(to_px(v, q));
      cv::polylines(img, pts, false, fill, th, cv::LINE_AA);
      break;
    }
    case Shape::Kind::Polygon: {
      std::vector<cv::Point> pts;
      for (const auto& q : s.points) pts.push_back(to_px(v, q));
      if (filled) cv::fillPoly(img, std::vector<std::vector<cv::Point>>{pts}, fill, cv::LINE_AA);
      cv::polylines(img, pts, true, edge, 1, cv::LINE_AA);
      break;
    }
  }
}

// A round length in metres (1, 2 or 5 times a power of ten) at least min_px pixels long.
double nice_step(const View& v, double min_px) {
  const double want = min_px / v.ppm;
  double base = std::pow(10.0, std::floor(std::log10(want)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * base >= want) return m * base;
  return 10 * base;
}

std::string metres(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", std::abs(x) < 1e-9 ? 0.0 : x);
  return buf;
}

// Axes in metres along the bottom and left of the map, and a scale bar below it on the right.
void draw_axes(cv::Mat& img, const View& v) {
  const cv::Scalar ink(0, 0, 0);
  const double step = nice_step(v, 60);
  const int bottom = kTitle + v.height(), left = kLeft;
  for (double x = std::ceil(v.lo.x() / step - 1e-9) * step; x <= v.hi.x() + 1e-9; x += step) {
    const int px = to_px(v, Vec2(x, v.lo.y())).x;
    cv::line(img, cv::Point(px, bottom), cv::Point(px, bottom + 4), ink);
    const std::string t = metres(x);
    int base = 0;
    const cv::Size sz = cv::getTextSize(t, cv::FONT_HERSHEY_SIMPLEX, 0.35, 1, &base);
    cv::putText(img, t, cv::Point(px - sz.width / 2, bottom + 15), cv::FONT_HERSHEY_SIMPLEX, 0.35, ink, 1, cv::LINE_AA);
  }
  for (double y = std::ceil(v.lo.y() / step - 1e-9) * step; y <= v.hi.y() + 1e-9; y += step) {
    const int py = to_px(v, Vec2(v.lo.x(), y)).y;
    cv::line(img, cv::Point(left - 4, py), cv::Point(left, py), ink);
    const std::string t = metres(y);
    int base = 0;
    const cv::Size sz = cv::getTextSize(t, cv::FONT_HERSHEY_SIMPLEX, 0.35, 1, &base);
    cv::putText(img, t, cv::Point(left - 6 - sz.width, py + 4), cv::FONT_HERSHEY_SIMPLEX, 0.35, ink, 1, cv::LINE_AA);
  }
  cv::putText(img, "x, y in m", cv::Point(left + v.width() + 12, bottom + 15), cv::FONT_HERSHEY_SIMPLEX, 0.35, ink, 1, cv::LINE_AA);
  // Scale bar: one step long, under the right end of the map.
  const int bar = static_cast<int>(std::lround(step * v.ppm)), x1 = left + v.width(), x0 = x1 - bar, y = bottom + 30;
  cv::line(img, cv::Point(x0, y), cv::Point(x1, y), ink, 2);
  cv::line(img, cv::Point(x0, y - 4), cv::Point(x0, y + 4), ink);
  cv::line(img, cv::Point(x1, y - 4), cv::Point(x1, y + 4), ink);
  const std::string t = metres(step) + " m";
  int base = 0;
  const cv::Size sz = cv::getTextSize(t, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &base);
  cv::putText(img, t, cv::Point(x0 - sz.width - 6, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4, ink, 1, cv::LINE_AA);
}

void draw_geometry(cv::Mat& img, const View& v, const Geometry& geo) {
  draw_axes(img, v);
  for (const auto& e : geo.exits) draw_shape(img, v, e.shape, cv::Scalar(120, 200, 120), cv::Scalar(40, 140, 40), false);
  for (const auto& g : geo.goals) draw_shape(img, v, g.shape, cv::Scalar(200, 160, 80), cv::Scalar(200, 120, 40), false);
  for (const auto& s : geo.solids) draw_shape(img, v, s, cv::Scalar(90, 90, 90), cv::Scalar(40, 40, 40), true);
  cv::rectangle(img, to_px(v, Vec2(v.lo.x(), v.hi.y())), to_px(v, Vec2(v.hi.x(), v.lo.y())), cv::Scalar(0, 0, 0), 1);
}

void draw_colour_bar(cv::Mat& img, const View& v, double vmin, double vmax, const std::string& unit) {
  int x0 = kLeft + v.width() + kPad + 10, y0 = kTitle, h = v.height(), w = 16;
  for (int y = 0; y < h; ++y) {
    cv::Vec3b c = colour(1.0 - static_cast<double>(y) / std::max(1, h - 1));
    cv::line(img, cv::Point(x0, y0 + y), cv::Point(x0 + w, y0 + y), cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(img, cv::Point(x0, y0), cv::Point(x0 + w, y0 + h), cv::Scalar(0, 0, 0));
  for (int k = 0; k <= 4; ++k) {
    double val = vmin + (vmax - vmin) * k / 4.0;
    int y = y0 + h - static_cast<int>(std::lround(h * k / 4.0));
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", val);
    cv::putText(img, buf, cv::Point(x0 + w + 4, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  // The unit under the bar, below the axes' "x, y in m": above the bar, a title wider than a
  // narrow map ran into it.
  cv::putText(img, unit, cv::Point(x0 - 6, y0 + h + 32), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

void title(cv::Mat& img, const std::string& text) {
  cv::putText(img, text, cv::Point(kPad, 19), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

void write_png(const std::string& path, const cv::Mat& img) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw Error(path + ": cannot write image (" + e.what() + ")");
  }
  if (!ok) throw Error(path + ": cannot write image");
}
}  // namespace

int View::width() const { return static_cast<int>(std::lround((hi.x() - lo.x()) * ppm)); }
int View::height() const { return static_cast<int>(std::lround((hi.y() - lo.y()) * ppm)); }

View View::fit(const Geometry& geo, double pixels_per_metre) {
  View v{geo.lo, geo.hi, pixels_per_metre};
  if (v.ppm <= 0) {
    double ext = std::max(geo.hi.x() - geo.lo.x(), geo.hi.y() - geo.lo.y());
    v.ppm = std::clamp(800.0 / ext, 1.0, 60.0);
  }
  // At most 4000 px on a side (a 7.5 GB picture helps nobody): lower the scale if asked for more.
  const double longest = std::max(geo.hi.x() - geo.lo.x(), geo.hi.y() - geo.lo.y());
  v.ppm = std::max(1e-3, std::min(v.ppm, 4000.0 / longest));
  return v;
}

void write_field_png(const std::string& path, const Geometry& geo, const View& v, const FieldFrame& f,
                     const std::vector<double>& values, double vmin, double vmax, const std::string& text,
                     const std::string& unit) {
  cv::Mat img = canvas(v);
  if (vmax <= vmin) vmax = vmin + 1;
  for (int py = 0; py < v.height(); ++py)
    for (int px = 0; px < v.width(); ++px) {
      Vec2 p(v.lo.x() + (px + 0.5) / v.ppm, v.hi.y() - (py + 0.5) / v.ppm);
      double gx = (p.x() - f.origin.x()) / f.dx, gy = (p.y() - f.origin.y()) / f.dx;
      int i = std::clamp(static_cast<int>(std::floor(gx)), 0, f.nx - 2);
      int j = std::clamp(static_cast<int>(std::floor(gy)), 0, f.ny - 2);
      double tx = gx - i, ty = gy - j;
      double val = (1 - tx) * (1 - ty) * f.at(values, i, j) + tx * (1 - ty) * f.at(values, i + 1, j) +
                   (1 - tx) * ty * f.at(values, i, j + 1) + tx * ty * f.at(values, i + 1, j + 1);
      if (geo.sdf(p) < 0) continue;
      img.at<cv::Vec3b>(kTitle + py, kLeft + px) = colour((val - vmin) / (vmax - vmin));
    }
  draw_geometry(img, v, geo);
  draw_colour_bar(img, v, vmin, vmax, unit);
  title(img, text);
  write_png(path, img);
}

void write_velocity_png(const std::string& path, const Geometry& geo, const View& v, const GridVelocityField& f,
                        double vmax, const std::string& text, double arrow_seconds,
                        const std::vector<std::pair<Vec2, double>>& circles,
                        const std::vector<std::pair<Vec2, Vec2>>& segments) {
  if (f.velocity.size() != static_cast<size_t>(f.nx) * f.ny || f.mask.size() != f.velocity.size())
    throw Error(path + ": velocity field arrays do not match its " + std::to_string(f.nx) + " x " + std::to_string(f.ny) + " grid");
  if (!(vmax > 0)) {
    std::vector<double> speeds;
    for (size_t i = 0; i < f.velocity.size(); ++i)
      if (f.mask[i] > 0 && f.velocity[i].allFinite()) speeds.push_back(f.velocity[i].norm());
    if (!speeds.empty()) {
      const size_t k = std::min(speeds.size() - 1, static_cast<size_t>(0.95 * static_cast<double>(speeds.size())));
      std::nth_element(speeds.begin(), speeds.begin() + static_cast<long>(k), speeds.end());
      vmax = speeds[k];
    }
    if (!(vmax > 0)) vmax = 1;
  }
  cv::Mat img = canvas(v);
  const double half = 0.5 * f.dx;
  for (int j = 0; j < f.ny; ++j)
    for (int i = 0; i < f.nx; ++i) {
      const size_t n = static_cast<size_t>(j) * f.nx + i;
      const Vec2 c = f.origin + f.dx * Vec2(i, j);
      if (c.x() + half < v.lo.x() || c.x() - half > v.hi.x() || c.y() + half < v.lo.y() || c.y() - half > v.hi.y()) continue;
      const bool kept = f.mask[n] > 0 && f.velocity[n].allFinite();
      const cv::Vec3b col = kept ? colour(f.velocity[n].norm() / vmax) : cv::Vec3b(225, 225, 225);
      // Clipped to the view, so that border cells do not paint over the title or the colour bar.
      const Vec2 a(std::max(c.x() - half, v.lo.x()), std::min(c.y() + half, v.hi.y()));
      const Vec2 b(std::min(c.x() + half, v.hi.x()), std::max(c.y() - half, v.lo.y()));
      cv::rectangle(img, to_px(v, a), to_px(v, b), cv::Scalar(col[0], col[1], col[2]), cv::FILLED);
    }
  for (size_t n = 0; n < f.velocity.size(); ++n) {
    if (!(f.mask[n] > 0 && f.velocity[n].allFinite())) continue;
    const Vec2 c = f.origin + f.dx * Vec2(static_cast<double>(n % f.nx), static_cast<double>(n / f.nx));
    if (c.x() < v.lo.x() || c.x() > v.hi.x() || c.y() < v.lo.y() || c.y() > v.hi.y()) continue;
    // At most one cell long, so that arrows of neighbouring nodes do not cross.
    Vec2 d = f.velocity[n] * arrow_seconds;
    if (d.norm() > f.dx) d *= f.dx / d.norm();
    cv::arrowedLine(img, to_px(v, c), to_px(v, c + d), cv::Scalar(255, 200, 0), 1, cv::LINE_AA, 0, 0.3);
  }
  draw_geometry(img, v, geo);
  for (const auto& [c, r] : circles)
    cv::circle(img, to_px(v, c), std::max(2, static_cast<int>(std::lround(r * v.ppm))), cv::Scalar(255, 0, 255), 2, cv::LINE_AA);
  for (const auto& [a, b] : segments) cv::line(img, to_px(v, a), to_px(v, b), cv::Scalar(255, 0, 255), 3, cv::LINE_AA);
  draw_colour_bar(img, v, 0, vmax, "m/s");
  title(img, text);
  write_png(path, img);
}

void write_paths_png(const std::string& path, const Geometry& geo, const View& v, const std::vector<PathSet>& sets,
                     const std::string& text) {
  // The legend sits right of the venue: as wide as its longest label.
  int label_w = 0;
  for (const auto& set : sets) {
    int base = 0;
    label_w = std::max(label_w, cv::getTextSize(set.label, cv::FONT_HERSHEY_SIMPLEX, 0.35, 1, &base).width);
  }
  cv::Mat img(v.height() + kTitle + kBottom, std::max(480, kLeft + v.width() + kPad + 4 + 18 + label_w + 6), CV_8UC3,
              cv::Scalar(255, 255, 255));
  draw_geometry(img, v, geo);
  int legend_y = kTitle + 16;
  for (const auto& set : sets) {
    cv::Scalar c(set.b, set.g, set.r);
    for (const auto& poly : set.paths) {
      std::vector<cv::Point> pts;
      for (const auto& q : poly)
        if (q.allFinite()) pts.push_back(to_px(v, q));
      if (pts.size() >= 2) cv::polylines(img, pts, false, c, 1, cv::LINE_AA);
      if (!pts.empty()) cv::circle(img, pts.back(), 2, c, cv::FILLED, cv::LINE_AA);
    }
    int x0 = kLeft + v.width() + kPad + 4;
    cv::line(img, cv::Point(x0, legend_y), cv::Point(x0 + 14, legend_y), c, 2);
    cv::putText(img, set.label, cv::Point(x0 + 18, legend_y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    legend_y += 16;
  }
  title(img, text);
  write_png(path, img);
}

struct ParticleVideo::Impl {
  cv::VideoWriter writer;
  const Geometry& geo;
  View view;
  double pmax;
  cv::Mat background;
  Impl(const Geometry& g, const View& v, double p) : geo(g), view(v), pmax(p) {}
  cv::Mat frame(const World& w, double time) {
    cv::Mat img = background.clone();
    for (size_t p = 0; p < w.size(); ++p) {
      cv::Vec3b c = colour(w.pressure[p] / pmax);
      int r = std::max(2, static_cast<int>(std::lround(w.radius[p] * view.ppm)));
      cv::circle(img, to_px(view, w.x[p]), r, cv::Scalar(c[0], c[1], c[2]), cv::FILLED, cv::LINE_AA);
    }
    char buf[96];
    std::snprintf(buf, sizeof buf, "t = %.1f s   agents: %zu   colour: pressure", time, w.size());
    title(img, buf);
    return img;
  }
};

void write_category_png(const std::string& path, const Geometry& geo, const View& v, const FieldFrame& f,
                        const std::vector<int>& category, const std::vector<Category>& legend, const std::string& text) {
  if (category.size() != static_cast<size_t>(f.nx) * static_cast<size_t>(f.ny))
    throw Error(path + ": internal error: category map size mismatch");
  cv::Mat img = canvas(v);
  for (int py = 0; py < v.height(); ++py)
    for (int px = 0; px < v.width(); ++px) {
      Vec2 p(v.lo.x() + (px + 0.5) / v.ppm, v.hi.y() - (py + 0.5) / v.ppm);
      const int i = std::clamp(static_cast<int>(std::lround((p.x() - f.origin.x()) / f.dx)), 0, f.nx - 1);
      const int j = std::clamp(static_cast<int>(std::lround((p.y() - f.origin.y()) / f.dx)), 0, f.ny - 1);
      const int c = category[static_cast<size_t>(j) * static_cast<size_t>(f.nx) + static_cast<size_t>(i)];
      if (c < 0 || c >= static_cast<int>(legend.size()) || geo.sdf(p) < 0) continue;
      const Category& k = legend[static_cast<size_t>(c)];
      img.at<cv::Vec3b>(kTitle + py, kLeft + px) = cv::Vec3b(static_cast<unsigned char>(k.b), static_cast<unsigned char>(k.g),
                                                             static_cast<unsigned char>(k.r));
    }
  draw_geometry(img, v, geo);
  const int x0 = kLeft + v.width() + kPad + 10;
  for (size_t c = 0; c < legend.size(); ++c) {
    const int y = kTitle + 4 + static_cast<int>(c) * 22;
    cv::rectangle(img, cv::Point(x0, y), cv::Point(x0 + 16, y + 16), cv::Scalar(legend[c].b, legend[c].g, legend[c].r), cv::FILLED);
    cv::rectangle(img, cv::Point(x0, y), cv::Point(x0 + 16, y + 16), cv::Scalar(0, 0, 0));
    cv::putText(img, legend[c].label, cv::Point(x0 + 22, y + 13), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  }
  title(img, text);
  write_png(path, img);
}

std::pair<long, double> video_frame_count(const std::string& path) {
  cv::VideoCapture in(path);
  if (!in.isOpened()) throw Error(path + ": cannot open video");
  return {static_cast<long>(in.get(cv::CAP_PROP_FRAME_COUNT)), in.get(cv::CAP_PROP_FPS)};
}

long transcode_to_webm(const std::string& in_path, const std::string& out_path, int stride, double scale) {
  if (stride < 1 || !(scale > 0 && scale <= 1)) throw Error(out_path + ": stride must be >= 1 and scale in (0, 1]");
  cv::VideoCapture in(in_path);
  if (!in.isOpened()) throw Error(in_path + ": cannot open video");
  double fps = in.get(cv::CAP_PROP_FPS);
  if (!(fps > 0)) fps = 10;
  cv::VideoWriter out;
  cv::Mat frame, small;
  long read = 0, written = 0;
  while (in.read(frame)) {
    if (read++ % stride) continue;
    cv::resize(frame, small, cv::Size(), scale, scale, cv::INTER_AREA);
    // Even sizes for the codec.
    small = small(cv::Rect(0, 0, small.cols - small.cols % 2, small.rows - small.rows % 2)).clone();
    if (!out.isOpened()) {
      out.open(out_path, cv::VideoWriter::fourcc('V', 'P', '8', '0'), fps / stride, small.size());
      if (!out.isOpened()) throw Error(out_path + ": cannot open a VP8/WebM video for writing (OpenCV with FFmpeg and libvpx)");
    }
    out.write(small);
    ++written;
  }
  if (written == 0) throw Error(in_path + ": no frames could be read");
  return written;
}

ParticleVideo::ParticleVideo(const std::string& path, const Geometry& geo, const View& view, double fps, double pmax)
    : impl_(new Impl(geo, view, pmax > 0 ? pmax : 1)) {
  impl_->background = canvas(view);
  // Even frame sizes for the codec.
  if (impl_->background.cols % 2) cv::copyMakeBorder(impl_->background, impl_->background, 0, 0, 0, 1, cv::BORDER_CONSTANT, cv::Scalar(255, 255, 255));
  if (impl_->background.rows % 2) cv::copyMakeBorder(impl_->background, impl_->background, 0, 1, 0, 0, cv::BORDER_CONSTANT, cv::Scalar(255, 255, 255));
  draw_geometry(impl_->background, view, geo);
  draw_colour_bar(impl_->background, view, 0, impl_->pmax, "pressure");
  if (!path.empty()) {
    impl_->writer.open(path, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, impl_->background.size());
    if (!impl_->writer.isOpened()) {
      delete impl_;
      impl_ = nullptr;
      throw Error(path + ": cannot open video for writing (OpenCV VideoWriter, mp4v)");
    }
  }
}

ParticleVideo::~ParticleVideo() { delete impl_; }
bool ParticleVideo::ok() const { return impl_ && impl_->writer.isOpened(); }

void ParticleVideo::add_frame(const World& w, double time) { impl_->writer.write(impl_->frame(w, time)); }

void ParticleVideo::write_snapshot(const std::string& png_path, const World& w, double time) {
  write_png(png_path, impl_->frame(w, time));
}

}  // namespace crowdmpm
