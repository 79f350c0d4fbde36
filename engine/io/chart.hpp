#pragma once
// Line and scatter charts as PNG (OpenCV): axes with ticks in data units, a legend, and shaded
// bands. Used for the validation pictures (fundamental diagram, J(b), N(t) of replays).
#include <array>
#include <string>
#include <vector>

#include "engine/core/vec.hpp"

namespace crowdmpm {

struct ChartSeries {
  enum class Style { Line, Points, LinePoints, Band };
  std::string name;              // legend entry (empty: none)
  Style style = Style::Line;
  std::array<int, 3> rgb = {0, 0, 0};
  std::vector<Vec2> points;      // (x, y); for Band the lower edge
  std::vector<Vec2> upper;       // Band only: the upper edge, at the same x as points
};

struct Chart {
  std::string title, x_label, y_label;
  std::vector<ChartSeries> series;
  // Axis ranges; when lo >= hi the range is taken from the data (with y from 0 if all y >= 0).
  double x_lo = 0, x_hi = 0, y_lo = 0, y_hi = 0;
};

// Writes c to a PNG of width x height pixels. Throws Error if the file cannot be written or no
// series has a finite point.
void write_chart_png(const std::string& path, const Chart& c, int width = 900, int height = 560);

}  // namespace crowdmpm
