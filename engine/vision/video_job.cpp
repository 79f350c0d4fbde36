#include "engine/vision/video_job.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "engine/core/error.hpp"
#include "engine/core/output.hpp"
#include "engine/io/render.hpp"

namespace crowdmpm {

Calibration video_calibration(const VideoSource& src, const VideoInfo& info) {
  if (!src.calibration.empty()) {
    if (src.scale > 0) throw Error("give either a calibration file or a scale (metres per pixel), not both");
    return Calibration::load(src.calibration, info.height, src.video.input);
  }
  if (src.scale > 0) return Calibration::from_scale(src.scale, Vec2(0, info.height), "--scale");
  throw Error(src.path + ": an uncalibrated video needs a calibration file (four or more image <-> ground point pairs) "
              "or a scale in metres per pixel");
}

VideoFields load_video_fields(const VideoSource& src, const ScenarioDef* scenario, const FlowProgress& progress,
                              const FlowHook& hook) {
  const VideoInfo info = probe_video(src.path, src.video);
  VideoFields out;
  out.calibration = video_calibration(src, info);
  if (scenario) {
    out.grid.init(scenario->geo, scenario->cell_size);
  } else {
    out.grid = grid_covering(out.calibration, src.video.roi, info.width, info.height, src.cell);
  }
  out.flow = extract_video_flow(src.path, src.video, src.flow, out.calibration, out.grid, src.field, progress, hook);
  return out;
}

GridVelocityField mean_field(const std::vector<GridVelocityField>& fields, double min_share) {
  if (fields.empty()) throw Error("mean_field: no fields");
  GridVelocityField m = fields[0];
  const size_t n = m.velocity.size();
  std::vector<double> count(n, 0);
  std::fill(m.velocity.begin(), m.velocity.end(), Vec2::Zero());
  for (const GridVelocityField& f : fields) {
    if (f.velocity.size() != n) throw Error("mean_field: fields on different grids");
    for (size_t i = 0; i < n; ++i)
      if (f.mask[i] > 0) {
        m.velocity[i] += f.velocity[i];
        count[i] += 1;
      }
  }
  for (size_t i = 0; i < n; ++i) {
    const bool keep = count[i] >= min_share * static_cast<double>(fields.size()) && count[i] > 0;
    m.velocity[i] = keep ? Vec2(m.velocity[i] / count[i]) : Vec2::Zero();
    m.mask[i] = keep ? 1 : 0;
  }
  return m;
}

namespace {

void write_frame_flow(const std::string& path, const cv::Mat& grey, const cv::Mat& flow, const std::vector<Vec2>& roi,
                      const std::string& text) {
  cv::Mat img;
  cv::cvtColor(grey, img, cv::COLOR_GRAY2BGR);
  const int step = std::max(8, std::min(grey.cols, grey.rows) / 40);
  // Arrows of the moving pixels (flow above the noise floor of 0.2 pixels per frame), scaled so
  // that the 90th percentile of them spans most of the spacing between arrows.
  std::vector<float> moving;
  for (int y = step / 2; y < flow.rows; y += step)
    for (int x = step / 2; x < flow.cols; x += step) {
      const cv::Vec2f f = flow.at<cv::Vec2f>(y, x);
      const float m = std::hypot(f[0], f[1]);
      if (m >= 0.2f) moving.push_back(m);
    }
  std::sort(moving.begin(), moving.end());
  const float p90 = moving.empty() ? 0 : moving[static_cast<size_t>(0.9 * static_cast<double>(moving.size() - 1))];
  const double gain = p90 > 0 ? 0.9 * step / p90 : 0;
  const float shown = 0.2f;
  for (int y = step / 2; y < flow.rows; y += step)
    for (int x = step / 2; x < flow.cols; x += step) {
      const cv::Vec2f f = flow.at<cv::Vec2f>(y, x);
      const double m = std::hypot(f[0], f[1]);
      if (!(m >= shown)) continue;
      // Hue from the direction.
      const double hue = (std::atan2(f[1], f[0]) + M_PI) / (2 * M_PI) * 180;
      cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(hue, 255, 255)), bgr;
      cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
      const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
      cv::arrowedLine(img, cv::Point(x, y), cv::Point(static_cast<int>(std::lround(x + gain * f[0])), static_cast<int>(std::lround(y + gain * f[1]))),
                      cv::Scalar(c[0], c[1], c[2]), 1, cv::LINE_AA, 0, 0.3);
    }
  if (!roi.empty()) {
    std::vector<cv::Point> poly;
    for (const Vec2& p : roi) poly.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    cv::polylines(img, poly, true, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  cv::rectangle(img, cv::Point(0, 0), cv::Point(img.cols, 22), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(img, text, cv::Point(6, 16), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  if (!cv::imwrite(path, img)) throw Error(path + ": cannot write image");
}

}  // namespace

json run_flow_job(const VideoSource& src, const ScenarioDef* scenario, const std::string& dir, const FlowProgress& progress) {
  prepare_output_folder(dir);
  const VideoInfo info = probe_video(src.path, src.video);
  const long total = src.video.count > 0 ? src.video.count : std::max(2L, info.frames - src.video.first);
  const size_t middle = static_cast<size_t>(std::max(0L, (total - 2) / 2));
  cv::Mat mid_grey, mid_flow;
  const auto t0 = std::chrono::steady_clock::now();
  VideoFields vf = load_video_fields(src, scenario, progress, [&](size_t k, const cv::Mat& g, const cv::Mat& f) {
    if (k == middle || mid_grey.empty()) {
      g.copyTo(mid_grey);
      f.copyTo(mid_flow);
    }
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& fields = vf.flow.fields;
  write_fields_npy(dir + "/fields.npy", fields, vf.flow.info.fps, src.video.first);

  Geometry geo;
  if (scenario) geo = scenario->geo;
  else {
    geo.lo = vf.grid.origin + Vec2(2 * vf.grid.dx, 2 * vf.grid.dx);
    geo.hi = vf.grid.origin + vf.grid.dx * Vec2(vf.grid.nx - 3, vf.grid.ny - 3);
  }
  const View view = View::fit(geo, 0);
  const GridVelocityField mean = mean_field(fields);
  const size_t mid = std::min(middle, fields.size() - 1);
  write_velocity_png(dir + "/field_mean.png", geo, view, mean, 0, "mean ground velocity over " + std::to_string(fields.size()) + " frames");
  write_velocity_png(dir + "/field_middle.png", geo, view, fields[mid],
                     0, "ground velocity at frame " + std::to_string(src.video.first + static_cast<long>(mid) + 1));
  write_frame_flow(dir + "/frame_flow.png", mid_grey, mid_flow, src.video.roi,
                   "optical flow (" + std::string(src.flow.method == FlowOptions::Method::Dis ? "DIS" : "Farneback") + "), frame " +
                       std::to_string(src.video.first + static_cast<long>(mid) + 1));

  // Summary: how much of the grid moved, and how fast.
  double kept = 0, speed = 0, speed_n = 0;
  for (const auto& f : fields)
    for (size_t i = 0; i < f.velocity.size(); ++i)
      if (f.mask[i] > 0) {
        kept += 1;
        speed += f.velocity[i].norm();
        speed_n += 1;
      }
  json j{{"video", src.path},
         {"width", vf.flow.info.width},
         {"height", vf.flow.info.height},
         {"fps", vf.flow.info.fps},
         {"first", src.video.first},
         {"fields", fields.size()},
         {"method", src.flow.method == FlowOptions::Method::Dis ? "dis" : "farneback"},
         {"calibration", vf.calibration.to_json()},
         {"calibrated", vf.calibration.is_homography()},
         {"grid", {{"origin", {vf.grid.origin.x(), vf.grid.origin.y()}}, {"dx", vf.grid.dx}, {"nx", vf.grid.nx}, {"ny", vf.grid.ny}}},
         {"moving_nodes_per_frame", kept / static_cast<double>(fields.size())},
         {"camera_glitches", vf.flow.glitches},
         {"mean_speed", speed_n > 0 ? speed / speed_n : 0.0},
         {"seconds", seconds},
         {"frames_per_second_processed", static_cast<double>(fields.size() + 1) / seconds}};
  save_json_file(j, dir + "/flow.json");
  return j;
}

}  // namespace crowdmpm
