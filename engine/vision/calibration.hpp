#pragma once
// Ground-plane rectification: where an image pixel lies on the floor, in metres.
//
// A calibration is either a homography H (image -> ground plane) fitted to four or more
// image <-> world point pairs, or, without calibration, a pixel-to-metre scale: world x =
// (u - u0) s, world y = (v0 - v) s (y up, origin at pixel (u0, v0), by default the image's
// bottom-left corner). A scale treats the image as a top view: on a tilted camera it is wrong by
// the perspective (far people look slower and denser than near ones), which only a homography
// removes (docs/video.md, "Without calibration").
//
// File format (docs/video.md):
//   {"format": "crowdmpm-calibration", "version": 1,
//    "image_points": [[u, v], ...], "world_points": [[x, y], ...]}      four or more pairs
//   {"format": "crowdmpm-calibration", "version": 1, "scale": s, "origin": [u0, v0]}
#include <array>
#include <string>
#include <vector>

#include "engine/core/input.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/core/vec.hpp"

namespace crowdmpm {

class Calibration {
 public:
  // A homography from point pairs (pixels, metres). Throws Error for fewer than four pairs,
  // counts that differ, non-finite points, three or more collinear points that leave it
  // undetermined, or a fit whose reprojection error is above 5% of the world points' extent.
  static Calibration from_points(const std::vector<Vec2>& image, const std::vector<Vec2>& world,
                                 const std::string& where = "calibration");
  // A top-view scale, metres per pixel, with world (0, 0) at pixel `origin`.
  static Calibration from_scale(double metres_per_pixel, const Vec2& origin, const std::string& where = "calibration");
  // From the JSON above; `image_height` places the default origin of a scale.
  static Calibration from_json(const JsonReader& r, double image_height);
  static Calibration load(const std::string& path, double image_height, const InputPolicy& policy = {});
  // A homography given directly (image -> world, row-major), checked as from_points checks a fit.
  static Calibration from_homography(const std::array<double, 9>& H, const std::string& where = "calibration");

  bool is_homography() const { return homography_; }
  double scale() const { return scale_; }  // metres per pixel of a scale calibration (0 for a homography)
  // Pixel -> ground (m). NaN where the pixel lies on or beyond the horizon (w <= 0).
  Vec2 to_world(const Vec2& pixel) const;
  // Ground (m) -> pixel (the inverse map).
  Vec2 to_image(const Vec2& world) const;
  // Ground area (m^2) that one pixel at `pixel` covers: |det d(world)/d(pixel)|.
  double pixel_area(const Vec2& pixel) const;
  // Throws Error unless every point of `region` (pixels) lies on the ground side of the horizon,
  // where the map is finite and keeps its orientation.
  void check_region(const std::vector<Vec2>& region, const std::string& what) const;
  // Mean distance (m) between the world points and the image points mapped (0 for a scale).
  double reprojection_error() const { return reprojection_; }
  const std::array<double, 9>& homography() const { return H_; }  // image -> world, row-major
  // As the file format; a homography as the pairs (to_image(w), w) of `world` (default: the
  // corners of the unit square at the origin).
  json to_json(std::vector<Vec2> world = {}) const;

 private:
  bool homography_ = false;
  double scale_ = 0;
  std::array<double, 9> H_{}, Hinv_{};
  double sign_ = 1;  // sign of w on the ground side
  double reprojection_ = 0;
  void finish(const std::string& where);
};

}  // namespace crowdmpm
