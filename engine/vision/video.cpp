#include "engine/vision/video.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <opencv2/videoio.hpp>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/sim/stencil.hpp"

namespace crowdmpm {

namespace {

std::string pt(const Vec2& p) { return "(" + format_number(p.x()) + ", " + format_number(p.y()) + ")"; }

void check_roi(const std::vector<Vec2>& roi, int width, int height, const std::string& path) {
  if (roi.empty()) return;
  if (roi.size() < 3) throw Error(path + ": the region of interest needs at least 3 points, got " + std::to_string(roi.size()));
  double area = 0;
  for (size_t i = 0; i < roi.size(); ++i) {
    const Vec2& p = roi[i];
    if (!p.allFinite()) throw Error(path + ": region of interest point " + std::to_string(i) + " is not finite");
    if (p.x() < 0 || p.y() < 0 || p.x() > width || p.y() > height)
      throw Error(path + ": region of interest point " + std::to_string(i) + " " + pt(p) + " lies outside the " +
                  std::to_string(width) + " x " + std::to_string(height) + " frame");
    const Vec2& q = roi[(i + 1) % roi.size()];
    area += p.x() * q.y() - q.x() * p.y();
  }
  if (std::abs(area) / 2 < 1) throw Error(path + ": the region of interest encloses no area (under one pixel)");
}

// OpenCV's own log lines while it tries its backends on a file ("raised OpenCV exception", ...)
// are silenced: the caller gets one clear Error instead.
struct QuietOpenCv {
  cv::utils::logging::LogLevel before = cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  ~QuietOpenCv() { cv::utils::logging::setLogLevel(before); }
};

std::unique_ptr<cv::VideoCapture> open_capture(const std::string& path) {
  auto cap = std::make_unique<cv::VideoCapture>();
  QuietOpenCv quiet;
  try {
    cap->open(path, cv::CAP_ANY);
  } catch (const cv::Exception&) {
    throw Error(path + ": OpenCV cannot decode it as a video");
  }
  if (!cap->isOpened()) throw Error(path + ": OpenCV cannot decode it as a video (no reader accepted the file)");
  return cap;
}

bool read_frame(cv::VideoCapture& cap, cv::Mat& frame) {
  QuietOpenCv quiet;
  try {
    return cap.read(frame) && !frame.empty();
  } catch (const cv::Exception&) {
    return false;
  }
}

}  // namespace

VideoInfo probe_video(const std::string& path, const VideoOptions& o) {
  check_input_file(path, o.input);
  if (o.first < 0) throw Error(path + ": first frame must be >= 0, got " + std::to_string(o.first));
  if (o.count < 0) throw Error(path + ": frame count must be >= 0 (0: to the end), got " + std::to_string(o.count));
  if (!(o.fps >= 0 && o.fps < 1000)) throw Error(path + ": frame rate must be in (0, 1000) fps (0: the container's), got " + format_number(o.fps));
  auto cap = open_capture(path);
  cv::Mat f;
  if (!read_frame(*cap, f)) throw Error(path + ": no frame could be decoded (an empty, corrupt or unsupported video)");
  VideoInfo info;
  info.path = path;
  info.width = f.cols;
  info.height = f.rows;
  const double declared = cap->get(cv::CAP_PROP_FRAME_COUNT);
  info.frames = std::isfinite(declared) && declared > 0 && declared < 1e9 ? static_cast<long>(declared) : 0;
  info.fps = o.fps > 0 ? o.fps : cap->get(cv::CAP_PROP_FPS);
  if (!(std::isfinite(info.fps) && info.fps > 0 && info.fps < 1000))
    throw Error(path + ": the container declares no usable frame rate; give one (--fps)");
  if (info.frames > 0 && o.first >= info.frames)
    throw Error(path + ": first frame " + std::to_string(o.first) + " is beyond the video's " + std::to_string(info.frames) + " frames");
  if (info.frames > 0 && o.count > 0 && o.first + o.count > info.frames)
    throw Error(path + ": frames " + std::to_string(o.first) + " to " + std::to_string(o.first + o.count - 1) +
                " asked for, but the video has " + std::to_string(info.frames));
  check_roi(o.roi, info.width, info.height, path);
  return info;
}

struct VideoReader::Impl {
  std::unique_ptr<cv::VideoCapture> cap;
  cv::Mat frame;
};

VideoReader::VideoReader(const std::string& path, const VideoOptions& o) : impl_(new Impl), opt_(o) {
  info_ = probe_video(path, o);
  impl_->cap = open_capture(path);
  // Sequential reads to the first frame: seeking is approximate in many codecs.
  for (long k = 0; k < o.first; ++k)
    if (!read_frame(*impl_->cap, impl_->frame))
      throw Error(path + ": decoding stopped at frame " + std::to_string(k) + ", before the first frame asked for (" +
                  std::to_string(o.first) + ")");
}

VideoReader::~VideoReader() = default;

bool VideoReader::next(cv::Mat& grey) {
  const long k = frame_ < 0 ? opt_.first : frame_ + 1;
  if (opt_.count > 0 && k >= opt_.first + opt_.count) return false;
  if (!read_frame(*impl_->cap, impl_->frame)) {
    if (opt_.count > 0)
      throw Error(info_.path + ": decoding stopped at frame " + std::to_string(k) + "; frames up to " +
                  std::to_string(opt_.first + opt_.count - 1) + " were asked for (a corrupt or truncated video?)");
    // To the end: a file that stops well before the frames its container declares is damaged.
    if (info_.frames > 0 && static_cast<double>(k) < 0.95 * static_cast<double>(info_.frames))
      throw Error(info_.path + ": decoding stopped at frame " + std::to_string(k) + " of the " + std::to_string(info_.frames) +
                  " the container declares (a corrupt or truncated video?)");
    return false;
  }
  const cv::Mat& f = impl_->frame;
  if (f.cols != info_.width || f.rows != info_.height)
    throw Error(info_.path + ": frame " + std::to_string(k) + " is " + std::to_string(f.cols) + " x " + std::to_string(f.rows) +
                ", the first was " + std::to_string(info_.width) + " x " + std::to_string(info_.height));
  if (f.channels() == 3) cv::cvtColor(f, grey, cv::COLOR_BGR2GRAY);
  else if (f.channels() == 4) cv::cvtColor(f, grey, cv::COLOR_BGRA2GRAY);
  else f.copyTo(grey);
  if (grey.depth() != CV_8U) grey.convertTo(grey, CV_8U);
  frame_ = k;
  return true;
}

void FlowOptions::check() const {
  if (dis_preset < 0 || dis_preset > 2) throw Error("flow: DIS preset must be 0 (ultrafast), 1 (fast) or 2 (medium), got " + std::to_string(dis_preset));
  if (!(pyr_scale > 0 && pyr_scale < 1)) throw Error("flow: Farneback pyr_scale must be in (0, 1), got " + format_number(pyr_scale));
  if (levels < 1 || levels > 10) throw Error("flow: Farneback levels must be 1..10, got " + std::to_string(levels));
  if (winsize < 3 || winsize > 101) throw Error("flow: Farneback winsize must be 3..101 pixels, got " + std::to_string(winsize));
  if (iterations < 1 || iterations > 50) throw Error("flow: Farneback iterations must be 1..50, got " + std::to_string(iterations));
  if (poly_n != 5 && poly_n != 7) throw Error("flow: Farneback poly_n must be 5 or 7, got " + std::to_string(poly_n));
  if (!(poly_sigma > 0 && poly_sigma < 10)) throw Error("flow: Farneback poly_sigma must be in (0, 10), got " + format_number(poly_sigma));
  if (!(smoothing >= 0 && smoothing < 1)) throw Error("flow: temporal smoothing must be in [0, 1), got " + format_number(smoothing));
}

FlowOptions::Method flow_method(const std::string& name) {
  if (name == "dis") return FlowOptions::Method::Dis;
  if (name == "farneback") return FlowOptions::Method::Farneback;
  throw Error("flow method must be \"dis\" or \"farneback\", got \"" + name + "\"");
}

struct FlowEstimator::Impl {
  FlowOptions o;
  cv::Ptr<cv::DISOpticalFlow> dis;
  cv::Mat prev, smoothed;
};

FlowEstimator::FlowEstimator(const FlowOptions& o) : impl_(new Impl) {
  o.check();
  impl_->o = o;
  if (o.method == FlowOptions::Method::Dis) impl_->dis = cv::DISOpticalFlow::create(o.dis_preset);
}

FlowEstimator::~FlowEstimator() = default;

bool FlowEstimator::push(const cv::Mat& grey, cv::Mat& flow) {
  Impl& m = *impl_;
  if (m.prev.empty()) {
    grey.copyTo(m.prev);
    return false;
  }
  cv::Mat f;
  if (m.o.method == FlowOptions::Method::Dis) m.dis->calc(m.prev, grey, f);
  else
    cv::calcOpticalFlowFarneback(m.prev, grey, f, m.o.pyr_scale, m.o.levels, m.o.winsize, m.o.iterations, m.o.poly_n,
                                 m.o.poly_sigma, 0);
  if (m.o.smoothing > 0 && !m.smoothed.empty()) cv::addWeighted(f, 1 - m.o.smoothing, m.smoothed, m.o.smoothing, 0, f);
  f.copyTo(m.smoothed);
  grey.copyTo(m.prev);
  flow = f;
  return true;
}

void FieldOptions::check() const {
  if (sample_stride < 1 || sample_stride > 64) throw Error("field: sample stride must be 1..64 pixels, got " + std::to_string(sample_stride));
  if (!(min_pixels >= 0 && min_pixels < 10)) throw Error("field: min_pixels must be in [0, 10) pixels per frame, got " + format_number(min_pixels));
  if (!(min_speed >= 0 && min_speed < 10)) throw Error("field: min_speed must be in [0, 10) m/s, got " + format_number(min_speed));
  if (!(min_moving_share >= 0 && min_moving_share <= 1)) throw Error("field: min_moving_share must be in [0, 1], got " + format_number(min_moving_share));
  if (!(min_coverage > 0 && min_coverage <= 1)) throw Error("field: min_coverage must be in (0, 1], got " + format_number(min_coverage));
  if (!(glitch_ratio == 0 || (glitch_ratio > 1 && glitch_ratio < 100)))
    throw Error("field: glitch ratio must be 0 (no detection) or in (1, 100), got " + format_number(glitch_ratio));
  if (!(glitch_window > 0 && glitch_window <= 60)) throw Error("field: glitch window must be in (0, 60] s, got " + format_number(glitch_window));
  if (!(glitch_min_share >= 0 && glitch_min_share <= 1)) throw Error("field: glitch_min_share must be in [0, 1], got " + format_number(glitch_min_share));
}

std::vector<size_t> find_camera_glitches(const std::vector<GridVelocityField>& fields, const std::vector<char>& covered, double fps,
                                         const FieldOptions& o) {
  o.check();
  std::vector<size_t> out;
  if (o.glitch_ratio == 0 || fields.empty()) return out;
  if (!(fps > 0)) throw Error("camera glitches: frame rate must be > 0, got " + format_number(fps));
  const double seen = static_cast<double>(std::count(covered.begin(), covered.end(), 1));
  // RMS speed over each field's moving nodes (NaN where none moves), and their share of the view.
  std::vector<double> rms(fields.size(), std::nan("")), share(fields.size(), 0);
  for (size_t k = 0; k < fields.size(); ++k) {
    if (fields[k].velocity.size() != covered.size()) throw Error("camera glitches: field " + std::to_string(k) + " is on another grid");
    double s = 0, n = 0;
    for (size_t i = 0; i < fields[k].velocity.size(); ++i)
      if (fields[k].mask[i] > 0) {
        s += fields[k].velocity[i].squaredNorm();
        n += 1;
      }
    if (n > 0) rms[k] = std::sqrt(s / n);
    share[k] = seen > 0 ? n / seen : 0;
  }
  const long w = std::max(1L, std::lround(o.glitch_window * fps)), n = static_cast<long>(fields.size());
  // Median of the defined values in [a, b); NaN with fewer than 3.
  auto median = [&](long a, long b) {
    std::vector<double> v;
    for (long k = std::max(0L, a); k < std::min(n, b); ++k)
      if (!std::isnan(rms[static_cast<size_t>(k)])) v.push_back(rms[static_cast<size_t>(k)]);
    if (v.size() < 3) return std::nan("");
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  for (long k = 0; k < n; ++k) {
    const double r = rms[static_cast<size_t>(k)];
    if (std::isnan(r) || share[static_cast<size_t>(k)] < o.glitch_min_share) continue;
    const double before = median(k - w, k), after = median(k + 1, k + 1 + w);
    if (std::isnan(before) && std::isnan(after)) continue;
    const bool spike = (std::isnan(before) || r > o.glitch_ratio * before) && (std::isnan(after) || r > o.glitch_ratio * after);
    if (spike) out.push_back(static_cast<size_t>(k));
  }
  return out;
}

Grid grid_covering(const Calibration& cal, const std::vector<Vec2>& region_in, int width, int height, double cell) {
  if (!(cell > 0 && std::isfinite(cell))) throw Error("grid: cell size must be > 0 m, got " + format_number(cell));
  std::vector<Vec2> region = region_in;
  if (region.empty()) region = {Vec2(0, 0), Vec2(width, 0), Vec2(width, height), Vec2(0, height)};
  cal.check_region(region, "region of interest");
  Vec2 lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const Vec2& p : region) {
    const Vec2 g = cal.to_world(p);
    lo = lo.cwiseMin(g);
    hi = hi.cwiseMax(g);
  }
  const double nx = std::ceil((hi.x() - lo.x()) / cell) + 5, ny = std::ceil((hi.y() - lo.y()) / cell) + 5;
  if (!(nx * ny <= 4e6))
    throw Error("grid: the ground the video sees spans " + format_number(hi.x() - lo.x()) + " x " + format_number(hi.y() - lo.y()) +
                " m, " + format_number(nx * ny) + " nodes at a cell of " + format_number(cell) +
                " m; raise the cell size or restrict the region of interest (is the horizon in view?)");
  Grid g;
  g.dx = cell;
  g.origin = lo - Vec2(2 * cell, 2 * cell);
  g.nx = static_cast<int>(nx);
  g.ny = static_cast<int>(ny);
  return g;
}

FieldBuilder::FieldBuilder(const Grid& shape, const Calibration& cal, int width, int height, const std::vector<Vec2>& roi,
                           const FieldOptions& o)
    : cal_(cal), opt_(o), width_(width), height_(height) {
  o.check();
  shape_.origin = shape.origin;
  shape_.dx = shape.dx;
  shape_.nx = shape.nx;
  shape_.ny = shape.ny;
  cv::Mat inside(height, width, CV_8U, cv::Scalar(roi.empty() ? 255 : 0));
  if (!roi.empty()) {
    std::vector<cv::Point> poly;
    for (const Vec2& p : roi) poly.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    cv::fillPoly(inside, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  }
  coverage_.assign(shape_.nodes(), 0);
  const double s2 = static_cast<double>(o.sample_stride) * o.sample_stride, cell2 = shape_.dx * shape_.dx;
  for (int y = o.sample_stride / 2; y < height; y += o.sample_stride)
    for (int x = o.sample_stride / 2; x < width; x += o.sample_stride) {
      if (!inside.at<unsigned char>(y, x)) continue;
      const Vec2 px(x, y), g = cal.to_world(px);
      const double a = cal.pixel_area(px) * s2;
      if (!g.allFinite() || !std::isfinite(a)) continue;
      bool fits = false;
      for_stencil_on_grid(shape_.origin, shape_.dx, shape_.nx, shape_.ny, g, [&](size_t i, double w, const Vec2&) {
        coverage_[i] += w * a / cell2;
        fits = true;
      });
      if (fits) samples_.push_back(Sample{static_cast<float>(x), static_cast<float>(y), g, a});
    }
}

GridVelocityField FieldBuilder::field(const cv::Mat& flow, double fps) const {
  if (flow.type() != CV_32FC2 || flow.cols != width_ || flow.rows != height_)
    throw Error("field: flow must be " + std::to_string(width_) + " x " + std::to_string(height_) + " two-channel float");
  const size_t nodes = shape_.nodes();
  std::vector<double> all(nodes, 0), moving(nodes, 0);
  std::vector<Vec2> momentum(nodes, Vec2::Zero()), all_momentum(nodes, Vec2::Zero());
  for (const Sample& s : samples_) {
    const cv::Vec2f f = flow.at<cv::Vec2f>(static_cast<int>(s.v), static_cast<int>(s.u));
    const Vec2 to = cal_.to_world(Vec2(s.u + f[0], s.v + f[1]));
    const Vec2 vel = (to - s.ground) * fps;
    const bool moves = vel.allFinite() && vel.norm() >= opt_.min_speed && std::hypot(f[0], f[1]) >= opt_.min_pixels;
    for_stencil_on_grid(shape_.origin, shape_.dx, shape_.nx, shape_.ny, s.ground, [&](size_t i, double w, const Vec2&) {
      const double wa = w * s.area;
      all[i] += wa;
      if (vel.allFinite()) all_momentum[i] += wa * vel;
      if (moves) {
        moving[i] += wa;
        momentum[i] += wa * vel;
      }
    });
  }
  GridVelocityField out;
  out.origin = shape_.origin;
  out.dx = shape_.dx;
  out.nx = shape_.nx;
  out.ny = shape_.ny;
  out.velocity.assign(nodes, Vec2::Zero());
  out.mask.assign(nodes, 0);
  for (size_t i = 0; i < nodes; ++i)
    if (coverage_[i] >= opt_.min_coverage && moving[i] > 0 && moving[i] >= opt_.min_moving_share * all[i]) {
      // Flow noise on a still floor passes the speed threshold pixel by pixel, in random
      // directions that cancel in the mean over every sample; a crowd's motion does not.
      const Vec2 u = momentum[i] / moving[i];
      if (!((all_momentum[i] / all[i]).norm() >= opt_.min_speed)) continue;
      out.velocity[i] = u;
      out.mask[i] = 1;
    }
  return out;
}

VideoFlow extract_video_flow(const std::string& path, const VideoOptions& vo, const FlowOptions& fo, const Calibration& cal,
                             const Grid& shape, const FieldOptions& field, const FlowProgress& progress,
                             const FlowHook& hook) {
  VideoReader reader(path, vo);
  VideoFlow out;
  out.info = reader.info();
  out.first = vo.first;
  out.roi = vo.roi;
  std::vector<Vec2> region = vo.roi;
  if (region.empty()) region = {Vec2(0, 0), Vec2(out.info.width, 0), Vec2(out.info.width, out.info.height), Vec2(0, out.info.height)};
  cal.check_region(region, path + ": region of interest");
  FieldBuilder builder(shape, cal, out.info.width, out.info.height, vo.roi, field);
  FlowEstimator flow(fo);
  out.covered.resize(builder.coverage().size());
  for (size_t i = 0; i < out.covered.size(); ++i) out.covered[i] = builder.coverage()[i] >= field.min_coverage;
  const long total = vo.count > 0 ? vo.count : std::max(0L, out.info.frames - vo.first);
  cv::Mat grey, f;
  long done = 0;
  while (reader.next(grey)) {
    if (flow.push(grey, f)) {
      out.fields.push_back(builder.field(f, out.info.fps));
      if (hook) hook(out.fields.size() - 1, grey, f);
    }
    if (progress) progress(++done, total);
  }
  if (out.fields.empty()) throw Error(path + ": fewer than two frames in the range; flow needs two");
  out.glitches = find_camera_glitches(out.fields, out.covered, out.info.fps, field);
  for (size_t k : out.glitches) {
    std::fill(out.fields[k].velocity.begin(), out.fields[k].velocity.end(), Vec2::Zero());
    std::fill(out.fields[k].mask.begin(), out.fields[k].mask.end(), 0.0);
  }
  return out;
}

// --- NumPy files ------------------------------------------------------------------------------

void write_fields_npy(const std::string& path, const std::vector<GridVelocityField>& fields, double fps, long first) {
  if (fields.empty()) throw Error(path + ": no fields to write");
  const GridVelocityField& f0 = fields[0];
  for (size_t k = 0; k < fields.size(); ++k)
    if (fields[k].nx != f0.nx || fields[k].ny != f0.ny || fields[k].velocity.size() != static_cast<size_t>(f0.nx) * f0.ny)
      throw Error(path + ": field " + std::to_string(k) + " is on another grid than the first");
  std::ostringstream hs;
  hs << "{'descr': '<f4', 'fortran_order': False, 'shape': (" << fields.size() << ", " << f0.ny << ", " << f0.nx << ", 3), }";
  std::string header = hs.str();
  const size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header.push_back('\n');
  std::ofstream out(path + ".partial", std::ios::binary);
  if (!out) throw Error(path + ": cannot write file");
  const char magic[8] = {'\x93', 'N', 'U', 'M', 'P', 'Y', 1, 0};
  out.write(magic, 8);
  const uint16_t len = static_cast<uint16_t>(header.size());
  const char lenb[2] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
  out.write(lenb, 2);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  std::vector<float> row;
  for (const GridVelocityField& f : fields) {
    row.resize(f.velocity.size() * 3);
    for (size_t i = 0; i < f.velocity.size(); ++i) {
      row[3 * i] = static_cast<float>(f.velocity[i].x());
      row[3 * i + 1] = static_cast<float>(f.velocity[i].y());
      row[3 * i + 2] = static_cast<float>(f.mask[i]);
    }
    // Little-endian float32 ('<f4'): every platform we build for.
    out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size() * sizeof(float)));
  }
  out.close();
  if (!out) throw Error(path + ": write failed");
  std::rename((path + ".partial").c_str(), path.c_str());
  save_json_file(json{{"format", "crowdmpm-velocity-fields"},
                      {"version", 1},
                      {"layout", "float32 (frames, ny, nx, 3): vx, vy (m/s), mask; node (i, j) at origin + dx (i, j)"},
                      {"origin", {f0.origin.x(), f0.origin.y()}},
                      {"dx", f0.dx},
                      {"nx", f0.nx},
                      {"ny", f0.ny},
                      {"frames", fields.size()},
                      {"fps", fps},
                      {"first", first}},
                 path + ".json");
}

std::vector<GridVelocityField> read_fields_npy(const std::string& path, double* fps, long* first, const InputPolicy& policy) {
  const json side = load_json_file(path + ".json", policy);
  JsonReader r(side, path + ".json");
  if (r.string("format", std::nullopt) != "crowdmpm-velocity-fields") r.fail_at("format", "must be \"crowdmpm-velocity-fields\"");
  const Vec2 origin = r.vec2("origin", std::nullopt);
  const double dx = r.positive("dx", std::nullopt);
  const int nx = r.integer("nx", 1, 100000, std::nullopt), ny = r.integer("ny", 1, 100000, std::nullopt);
  const long frames = r.integer("frames", 1, 100000000, std::nullopt);
  if (fps) *fps = r.positive("fps", std::nullopt);
  if (first) *first = r.integer("first", 0, 1000000000, 0);
  const std::string data = read_input_file(path, policy);
  if (data.size() < 10 || std::memcmp(data.data(), "\x93NUMPY", 6) != 0) throw Error(path + ": not a NumPy .npy file");
  if (data[6] != 1) throw Error(path + ": NumPy format version " + std::to_string(static_cast<int>(data[6])) + " (this reader takes 1.0)");
  const size_t hl = static_cast<unsigned char>(data[8]) | (static_cast<size_t>(static_cast<unsigned char>(data[9])) << 8);
  if (10 + hl > data.size()) throw Error(path + ": header runs past the end of the file");
  const std::string header = data.substr(10, hl);
  std::ostringstream want;
  want << "'shape': (" << frames << ", " << ny << ", " << nx << ", 3)";
  if (header.find("'descr': '<f4'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos ||
      header.find(want.str()) == std::string::npos)
    throw Error(path + ": expected little-endian float32, C order, " + want.str() + " as its sidecar says");
  const size_t n = static_cast<size_t>(nx) * ny, bytes = static_cast<size_t>(frames) * n * 3 * sizeof(float);
  if (data.size() - 10 - hl != bytes)
    throw Error(path + ": holds " + std::to_string(data.size() - 10 - hl) + " bytes of data, the shape needs " + std::to_string(bytes));
  std::vector<GridVelocityField> out(static_cast<size_t>(frames));
  const char* p = data.data() + 10 + hl;
  for (auto& f : out) {
    f.origin = origin;
    f.dx = dx;
    f.nx = nx;
    f.ny = ny;
    f.velocity.resize(n);
    f.mask.resize(n);
    for (size_t i = 0; i < n; ++i) {
      float v[3];
      std::memcpy(v, p, sizeof v);
      p += sizeof v;
      f.velocity[i] = Vec2(v[0], v[1]);
      f.mask[i] = v[2];
      if (!f.velocity[i].allFinite() || !std::isfinite(f.mask[i]) || f.mask[i] < 0)
        throw Error(path + ": node " + std::to_string(i) + " holds a non-finite velocity or a negative mask");
    }
  }
  return out;
}

}  // namespace crowdmpm
