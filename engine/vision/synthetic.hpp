#pragma once
// Synthetic crowd video with a known answer: a simulation rendered through a pinhole camera
// tilted over the ground plane (heads and shoulders as textured blobs a few pixels wide, a
// textured floor, sensor noise, lens blur and the container's lossy compression), with the
// true grid velocity of every frame saved beside it. The flow pipeline, training on flow and
// prediction from flow are tested against it (tests/test_vision.cpp, benchmarks/video/).
#include <limits>
#include <string>
#include <vector>

#include "engine/analysis/grid_velocity.hpp"
#include "engine/sim/simulation.hpp"
#include "engine/vision/calibration.hpp"

namespace crowdmpm {

struct CameraOptions {
  int width = 640, height = 480;  // pixels
  double tilt_deg = 35;           // angle of the optical axis from straight down
  double height_m = 14;           // camera height above the ground, m
  double focal_px = 0;            // 0: the largest focal length at which the domain's corners fit in the frame
  // Ground point at the image centre; NaN: the domain's centre.
  Vec2 target = Vec2(std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN());
};

// The image -> ground homography of a camera over the domain [lo, hi] (its focal length chosen
// there when not given). Throws Error for a tilt outside [0, 80) degrees or a non-positive size.
Calibration camera_calibration(const CameraOptions& c, const Vec2& lo, const Vec2& hi);

struct RenderOptions {
  CameraOptions camera;
  double fps = 10;           // video frames per simulated second
  double duration = 10;      // s rendered
  double head_radius = 0.11; // m
  double shoulder_radius = 0.22;
  double noise_sd = 3;       // grey levels of Gaussian sensor noise
  double blur_sigma = 0.7;   // pixels
  uint64_t seed = 1;         // textures and noise
  double truth_min_mass = 0.5;  // persons on a node's stencil for the true field to keep it
};

struct RenderResult {
  Calibration calibration;   // image -> ground of the camera used
  long frames = 0;
  // truth[k]: the grid velocity between frames k and k + 1 (people in both frames, displacement
  // over the frame interval), on the simulation's grid; aligned with VideoFlow::fields.
  std::vector<GridVelocityField> truth;
  double mean_density = 0;   // persons/m^2 over the truth's kept nodes (mass over B-spline area), mean of frames
};

// Steps `sim` for o.duration and writes the video (codec from the extension: .avi Motion JPEG,
// .mp4 MPEG-4 part 2). Throws Error if the video cannot be written, or if the frame interval is
// not a whole number of time steps.
RenderResult render_synthetic_video(Simulation& sim, const RenderOptions& o, const std::string& video_path);

}  // namespace crowdmpm
