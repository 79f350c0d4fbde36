#include "engine/vision/synthetic.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"

namespace crowdmpm {

namespace {

// The world -> image matrix (row-major) of the camera with focal length f.
std::array<double, 9> world_to_image(const CameraOptions& c, const Vec2& target, double f) {
  const double t = c.tilt_deg * M_PI / 180, s = std::sin(t), co = std::cos(t), h = c.height_m;
  const Vec2 C(target.x(), target.y() - h * std::tan(t));
  // Camera axes: right (1, 0, 0), image down (0, -cos, -sin), forward (0, sin, -cos); a ground
  // point (X, Y, 0) has camera coordinates A (X, Y, 1).
  const double A[9] = {1, 0, -C.x(), 0, -co, co * C.y() + s * h, 0, s, -s * C.y() + co * h};
  const double K[9] = {f, 0, c.width / 2.0, 0, f, c.height / 2.0, 0, 0, 1};
  std::array<double, 9> M{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) M[static_cast<size_t>(3 * i + j)] += K[3 * i + k] * A[3 * k + j];
  return M;
}

uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
double unit(uint64_t x) { return static_cast<double>(mix(x) >> 11) * (1.0 / 9007199254740992.0); }

}  // namespace

Calibration camera_calibration(const CameraOptions& c, const Vec2& lo, const Vec2& hi) {
  if (!(c.tilt_deg >= 0 && c.tilt_deg < 80)) throw Error("camera: tilt must be in [0, 80) degrees, got " + format_number(c.tilt_deg));
  if (c.width < 16 || c.height < 16 || c.width > 8192 || c.height > 8192)
    throw Error("camera: image size must be 16..8192 pixels a side, got " + std::to_string(c.width) + " x " + std::to_string(c.height));
  if (!(c.height_m > 0)) throw Error("camera: height must be > 0 m, got " + format_number(c.height_m));
  const Vec2 target = c.target.allFinite() ? c.target : Vec2(0.5 * (lo + hi));
  double f = c.focal_px;
  if (!(f > 0)) {
    const std::array<double, 9> M = world_to_image(c, target, 1);
    f = 1e300;
    for (const Vec2& q : {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}) {
      const double x = M[0] * q.x() + M[1] * q.y() + M[2] - c.width / 2.0 * (M[6] * q.x() + M[7] * q.y() + M[8]);
      const double y = M[3] * q.x() + M[4] * q.y() + M[5] - c.height / 2.0 * (M[6] * q.x() + M[7] * q.y() + M[8]);
      const double z = M[6] * q.x() + M[7] * q.y() + M[8];
      if (!(z > 0)) throw Error("camera: the domain corner (" + format_number(q.x()) + ", " + format_number(q.y()) + ") lies behind the camera");
      if (std::abs(x) > 0) f = std::min(f, 0.95 * c.width / 2.0 / std::abs(x / z));
      if (std::abs(y) > 0) f = std::min(f, 0.95 * c.height / 2.0 / std::abs(y / z));
    }
  }
  const std::array<double, 9> M = world_to_image(c, target, f);
  cv::Matx33d inv = cv::Matx33d(M.data()).inv();
  std::array<double, 9> H;
  for (int i = 0; i < 9; ++i) H[static_cast<size_t>(i)] = inv.val[i];
  return Calibration::from_homography(H, "camera");
}

RenderResult render_synthetic_video(Simulation& sim, const RenderOptions& o, const std::string& video_path) {
  const ScenarioDef& sc = sim.scenario();
  if (!(o.fps > 0 && o.duration > 0)) throw Error("render: fps and duration must be > 0");
  const double per_frame = 1 / (o.fps * sc.dt);
  const int steps = static_cast<int>(std::lround(per_frame));
  if (steps < 1 || std::abs(per_frame - steps) > 1e-6 * per_frame)
    throw Error("render: a frame every " + format_number(1 / o.fps) + " s is not a whole number of time steps of " + format_number(sc.dt) + " s");
  RenderResult r;
  r.calibration = camera_calibration(o.camera, sc.geo.lo, sc.geo.hi);
  const int W = o.camera.width, H = o.camera.height;
  const std::string ext = video_path.size() > 4 ? video_path.substr(video_path.size() - 4) : "";
  int fourcc = 0;
  if (ext == ".avi") fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
  else if (ext == ".mp4") fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
  else throw Error(video_path + ": the synthetic video must be .avi (Motion JPEG) or .mp4 (MPEG-4)");
  cv::VideoWriter writer(video_path, fourcc, o.fps, cv::Size(W, H), true);
  if (!writer.isOpened()) throw Error(video_path + ": cannot open a video writer for it");

  // A static floor: smooth grey noise.
  cv::RNG rng(o.seed);
  cv::Mat floor(H, W, CV_32F);
  rng.fill(floor, cv::RNG::NORMAL, 0, 1);
  cv::GaussianBlur(floor, floor, cv::Size(0, 0), 2.5);
  cv::normalize(floor, floor, 95, 150, cv::NORM_MINMAX);

  std::unordered_map<EntityId, Vec2> before;
  const Grid& grid = sim.grid();
  const long frames = std::lround(o.duration * o.fps) + 1;
  double density_sum = 0;
  long density_frames = 0;
  for (long k = 0; k < frames; ++k) {
    if (k > 0)
      for (int s = 0; s < steps; ++s) sim.step();
    const World& w = sim.world();
    // Painter's order: far people (top of the image) first.
    struct Blob {
      double depth;
      cv::Point2d c;
      double head, shoulder;
      EntityId id;
    };
    std::vector<Blob> blobs;
    blobs.reserve(w.size());
    for (size_t p = 0; p < w.size(); ++p) {
      const Vec2 px = r.calibration.to_image(w.x[p]);
      const Vec2 side = r.calibration.to_image(w.x[p] + Vec2(o.head_radius, 0));
      const double scale = (side - px).norm() / o.head_radius;  // pixels per metre here
      if (!px.allFinite() || !(scale > 0)) continue;
      blobs.push_back(Blob{-px.y(), cv::Point2d(px.x(), px.y()), o.head_radius * scale, o.shoulder_radius * scale, w.id[p]});
    }
    std::sort(blobs.begin(), blobs.end(), [](const Blob& a, const Blob& b) { return a.depth > b.depth || (a.depth == b.depth && a.id < b.id); });
    cv::Mat img;
    floor.convertTo(img, CV_8U);
    const int shift = 4;  // sub-pixel drawing
    auto fixed = [&](const cv::Point2d& q) { return cv::Point(static_cast<int>(std::lround(q.x * 16)), static_cast<int>(std::lround(q.y * 16))); };
    for (const Blob& b : blobs) {
      const uint64_t h = mix(static_cast<uint64_t>(b.id) ^ mix(o.seed));
      const double clothes = 40 + 170 * unit(h), hair = 10 + 70 * unit(h + 1), angle = 2 * M_PI * unit(h + 2);
      cv::circle(img, fixed(b.c + cv::Point2d(0, 0.35 * b.shoulder)), static_cast<int>(std::lround(b.shoulder * 16)),
                 cv::Scalar(clothes), cv::FILLED, cv::LINE_AA, shift);
      cv::circle(img, fixed(b.c), static_cast<int>(std::lround(b.head * 16)), cv::Scalar(hair), cv::FILLED, cv::LINE_AA, shift);
      cv::circle(img, fixed(b.c + 0.4 * b.head * cv::Point2d(std::cos(angle), std::sin(angle))),
                 static_cast<int>(std::lround(0.35 * b.head * 16)), cv::Scalar(std::min(255.0, hair + 110)), cv::FILLED, cv::LINE_AA, shift);
    }
    if (o.blur_sigma > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), o.blur_sigma);
    if (o.noise_sd > 0) {
      cv::Mat noise(H, W, CV_32F), f;
      rng.fill(noise, cv::RNG::NORMAL, 0, o.noise_sd);
      img.convertTo(f, CV_32F);
      f += noise;
      f.convertTo(img, CV_8U);  // saturates
    }
    cv::Mat bgr;
    cv::cvtColor(img, bgr, cv::COLOR_GRAY2BGR);
    writer.write(bgr);

    // The true field between the previous frame and this one.
    std::unordered_map<EntityId, Vec2> now;
    std::vector<Vec2> xs, vs;
    for (size_t p = 0; p < w.size(); ++p) {
      now[w.id[p]] = w.x[p];
      auto it = before.find(w.id[p]);
      if (k > 0 && it != before.end()) {
        xs.push_back(w.x[p]);
        vs.push_back((w.x[p] - it->second) * o.fps);
      }
    }
    if (k > 0) {
      r.truth.push_back(grid_velocity_of(xs, vs, 1, grid, o.truth_min_mass));
      std::vector<double> M;
      std::vector<Vec2> P;
      grid_mass_momentum(xs, vs, 1, grid, M, P);
      double m = 0, n = 0;
      for (size_t i = 0; i < M.size(); ++i)
        if (r.truth.back().mask[i] > 0) {
          m += M[i];
          n += 1;
        }
      if (n > 0) {
        density_sum += m / (n * grid.dx * grid.dx);
        ++density_frames;
      }
    }
    before = std::move(now);
  }
  writer.release();
  r.frames = frames;
  r.mean_density = density_frames ? density_sum / static_cast<double>(density_frames) : 0;
  return r;
}

}  // namespace crowdmpm
