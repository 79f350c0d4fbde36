#pragma once
// From video to velocity fields on the simulator's grid (DESIGN.md section 3, vision):
//   frames (any container OpenCV reads, a frame range, a region of interest)
//   -> dense optical flow between consecutive frames (DIS or Farneback, optional temporal smoothing)
//   -> ground-plane rectification (Calibration: homography or scale), so flow becomes m/s
//   -> a GridVelocityField per frame: the rectified flow splatted onto the grid nodes with the
//      MPM quadratic B-spline weights (a weighted mean, each pixel weighted by the ground area it
//      covers), with a mask where there is crowd in motion.
// docs/video.md describes the options, the files written and what is lost without calibration.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/analysis/grid_velocity.hpp"
#include "engine/core/input.hpp"
#include "engine/vision/calibration.hpp"

namespace cv { class Mat; }

namespace crowdmpm {

struct VideoOptions {
  long first = 0;         // first frame (0-based)
  long count = 0;         // frames to read from `first`; 0: to the end
  double fps = 0;         // frames per second; 0: the container's (an error if it declares none)
  std::vector<Vec2> roi;  // region of interest, a polygon in pixels (x right, y down); empty: the whole frame
  InputPolicy input;      // the video file must be a regular file within the size limit
};

struct VideoInfo {
  std::string path;
  int width = 0, height = 0;
  double fps = 0;         // as used (VideoOptions::fps or the container's)
  long frames = 0;        // as the container declares (may be approximate; 0: unknown)
};

// Opens and checks a video: a regular file within the limit that OpenCV decodes, with a
// positive frame rate. Throws Error naming the file and the reason.
VideoInfo probe_video(const std::string& path, const VideoOptions& o);

// Streams grey frames of [first, first + count). Throws Error when the file stops decoding before
// the range ends (a corrupt or truncated video), or when frames change size.
class VideoReader {
 public:
  VideoReader(const std::string& path, const VideoOptions& o);
  ~VideoReader();
  const VideoInfo& info() const { return info_; }
  // The next frame (8-bit grey); false after the range.
  bool next(cv::Mat& grey);
  long frame() const { return frame_; }  // index of the frame last returned

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  VideoInfo info_;
  VideoOptions opt_;
  long frame_ = -1;
};

struct FlowOptions {
  enum class Method { Dis, Farneback };
  Method method = Method::Dis;
  // DIS (OpenCV DISOpticalFlow): preset 0 ultrafast, 1 fast, 2 medium.
  int dis_preset = 2;
  // Farneback (cv::calcOpticalFlowFarneback).
  double pyr_scale = 0.5;
  int levels = 3, winsize = 15, iterations = 3, poly_n = 5;
  double poly_sigma = 1.2;
  // Temporal smoothing of the flow: f = (1 - a) f_new + a f_previous, a in [0, 1); 0: off.
  double smoothing = 0;
  // Throws Error naming the option for a value out of range.
  void check() const;
};
FlowOptions::Method flow_method(const std::string& name);  // "dis" or "farneback"

// Optical flow between consecutive frames, in pixels per frame (CV_32FC2).
class FlowEstimator {
 public:
  explicit FlowEstimator(const FlowOptions& o);
  ~FlowEstimator();
  // The flow from the previous frame given to this one; false for the first frame.
  bool push(const cv::Mat& grey, cv::Mat& flow);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct FieldOptions {
  int sample_stride = 2;          // pixels between flow samples
  double min_speed = 0.05;        // m/s: a sample slower than this counts as still
  double min_pixels = 0.2;        // pixels per frame: so does one whose flow is shorter (the flow's noise floor)
  double min_moving_share = 0.3;  // of a node's sampled ground weight that must move for the node to count
  double min_coverage = 0.3;      // of a node's full B-spline weight (dx^2 of ground) the image must cover
  // Camera glitches (a jump, a cut, a shake): a field whose RMS speed over its moving nodes
  // exceeds glitch_ratio times the median of the fields within glitch_window seconds before it,
  // and as much after it (where at least 3 fields lie on that side), with at least
  // glitch_min_share of the nodes the image covers moving. A crowd does not double its speed for
  // one frame; a camera does, and moves the whole view (a few walkers' RMS speed is noisier
  // than that, and they cover a small share of the view). glitch_ratio 0: no detection.
  double glitch_ratio = 2;
  double glitch_window = 0.5;     // s
  double glitch_min_share = 0.25;
  void check() const;
};

// The grid of a field (origin, dx, nx, ny) covering the ground seen in `region` (pixels; the
// frame's corners if empty) with two cells of padding, as Grid::init pads a domain.
Grid grid_covering(const Calibration& cal, const std::vector<Vec2>& region, int width, int height, double cell);

// Splats rectified flow onto a grid. Velocity at a node = sum over moving samples of w a u /
// sum of w a (w: the node's B-spline weight at the sample's ground point, a: the sample's
// ground area, u: its ground velocity); mask 1 where the image covers at least min_coverage of
// the node, at least min_moving_share of that moves and the mean over all its samples is at
// least min_speed (flow noise on a still floor moves pixels in random directions that cancel
// there), 0 elsewhere.
class FieldBuilder {
 public:
  FieldBuilder(const Grid& shape, const Calibration& cal, int width, int height, const std::vector<Vec2>& roi,
               const FieldOptions& o);
  GridVelocityField field(const cv::Mat& flow, double fps) const;
  // Nodes the image covers (mask of coverage alone).
  const std::vector<double>& coverage() const { return coverage_; }

 private:
  struct Sample {
    float u, v;       // pixel
    Vec2 ground;      // m
    double area;      // m^2
  };
  Grid shape_;
  Calibration cal_;
  FieldOptions opt_;
  std::vector<Sample> samples_;
  std::vector<double> coverage_;  // per node: sum of w a / dx^2
  int width_ = 0, height_ = 0;
};

// A video's fields: fields[k] is the ground velocity between frames first + k and first + k + 1,
// taken as the field at frame first + k + 1 (time (k + 1) / fps after the first frame).
struct VideoFlow {
  VideoInfo info;
  long first = 0;
  std::vector<Vec2> roi;
  std::vector<GridVelocityField> fields;
  std::vector<char> covered;  // nodes the image covers (FieldOptions::min_coverage)
  // Fields found to be camera glitches (find_camera_glitches), ascending. Their velocity and mask
  // are cleared (no node observed): training clips and held-out predictions do not cross them.
  std::vector<size_t> glitches;
  double seconds_per_field() const { return 1 / info.fps; }
};

// The fields that are camera glitches by FieldOptions::glitch_ratio and glitch_window.
// `covered`: the nodes the image covers (VideoFlow::covered).
std::vector<size_t> find_camera_glitches(const std::vector<GridVelocityField>& fields, const std::vector<char>& covered, double fps,
                                         const FieldOptions& o);

using FlowProgress = std::function<void(long done, long total)>;
// Called with each field's index, its later frame (grey) and the flow in pixels per frame.
using FlowHook = std::function<void(size_t field, const cv::Mat& grey, const cv::Mat& flow)>;
VideoFlow extract_video_flow(const std::string& path, const VideoOptions& vo, const FlowOptions& fo,
                             const Calibration& cal, const Grid& shape, const FieldOptions& field,
                             const FlowProgress& progress = nullptr, const FlowHook& hook = nullptr);

// Fields as NumPy .npy: float32, shape (frames, ny, nx, 3) = (vx, vy, mask), node (i, j) at
// origin + dx (i, j); and the grid in a JSON sidecar (path + ".json": origin, dx, nx, ny, fps, first).
void write_fields_npy(const std::string& path, const std::vector<GridVelocityField>& fields, double fps, long first);
// Reads what write_fields_npy wrote (checks the header, shape and sidecar). fps and first may be null.
std::vector<GridVelocityField> read_fields_npy(const std::string& path, double* fps, long* first,
                                               const InputPolicy& policy = {});

}  // namespace crowdmpm
