#pragma once
// Pictures and video frames: field maps with a colour bar and the venue drawn on top, and
// particles coloured by pressure. Images are 8-bit BGR (OpenCV convention), y axis up.
#include <string>
#include <vector>

#include "engine/analysis/fields.hpp"
#include "engine/geometry/geometry.hpp"
#include "engine/sim/world.hpp"

namespace cv { class Mat; }

namespace crowdmpm {

struct View {
  Vec2 lo, hi;
  double ppm;  // pixels per metre
  int width() const;
  int height() const;  // of the map area; a colour bar and a title band are added around it
  static View fit(const Geometry& geo, double pixels_per_metre);  // 0: choose from the size
};

// A scalar field on the grid nodes as a colour map in [vmin, vmax], geometry on top.
void write_field_png(const std::string& path, const Geometry& geo, const View& view, const FieldFrame& f,
                     const std::vector<double>& values, double vmin, double vmax, const std::string& title,
                     const std::string& unit);

// Paths (polylines of positions) over the venue, each set in its colour (B, G, R), with a legend.
struct PathSet {
  std::string label;
  int b, g, r;
  std::vector<std::vector<Vec2>> paths;
};
void write_paths_png(const std::string& path, const Geometry& geo, const View& view, const std::vector<PathSet>& sets,
                     const std::string& title);

class ParticleVideo {
 public:
  ParticleVideo(const std::string& path, const Geometry& geo, const View& view, double fps, double pressure_max);
  ~ParticleVideo();
  void add_frame(const World& w, double time);
  void write_snapshot(const std::string& png_path, const World& w, double time);
  bool ok() const;

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace crowdmpm
