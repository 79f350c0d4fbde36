#pragma once
// Pictures and video frames: field maps with a colour bar and the venue drawn on top, and
// particles coloured by pressure. Images are 8-bit BGR (OpenCV convention), y axis up.
#include <string>
#include <vector>

#include "engine/analysis/fields.hpp"
#include "engine/analysis/grid_velocity.hpp"
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

// A grid velocity field (video flow, simulation, their difference): speed as a colour map over
// the nodes its mask keeps (grey elsewhere), an arrow per kept node (length: distance walked in
// `arrow_seconds`), geometry on top. vmax <= 0: the field's own 95th-percentile speed.
// circles (centre, radius in m) are outlined in magenta: regions a diagnosis found; segments
// (ends in m), likewise drawn: walls it found.
void write_velocity_png(const std::string& path, const Geometry& geo, const View& view, const GridVelocityField& f,
                        double vmax, const std::string& title, double arrow_seconds = 1,
                        const std::vector<std::pair<Vec2, double>>& circles = {},
                        const std::vector<std::pair<Vec2, Vec2>>& segments = {});

// Paths (polylines of positions) over the venue, each set in its colour (B, G, R), with a legend.
struct PathSet {
  std::string label;
  int b, g, r;
  std::vector<std::vector<Vec2>> paths;
};
void write_paths_png(const std::string& path, const Geometry& geo, const View& view, const std::vector<PathSet>& sets,
                     const std::string& title);

// A categorical map: each node's category (index into `legend`, -1 = none) as flat colour
// (nearest node), the legend as labelled swatches. Colours are {r, g, b}.
struct Category {
  std::string label;
  int r, g, b;
};
void write_category_png(const std::string& path, const Geometry& geo, const View& view, const FieldFrame& f,
                        const std::vector<int>& category, const std::vector<Category>& legend, const std::string& title);

// Re-encodes a video for web pages: VP8 in WebM (what browsers play), every `stride`-th frame,
// scaled by `scale`. Returns the frames written; throws Error naming the file on failure.
long transcode_to_webm(const std::string& in_path, const std::string& out_path, int stride, double scale);
// Frames and frame rate of a video file (OpenCV's reading), for choosing a stride.
std::pair<long, double> video_frame_count(const std::string& path);

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
