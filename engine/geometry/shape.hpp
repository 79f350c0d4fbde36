#pragma once
// Planar shapes used for walls, obstacles, exits, goals, spawn regions and measurement areas.
// Signed distance convention: negative inside, metres.
#include <string>
#include <vector>

#include "engine/core/json_reader.hpp"
#include "engine/core/vec.hpp"

namespace crowdmpm {

struct Shape {
  enum class Kind { Polygon, Circle, Polyline };
  Kind kind = Kind::Polygon;
  std::vector<Vec2> points;  // polygon vertices (implicitly closed) or polyline vertices
  Vec2 center = Vec2::Zero();
  double radius = 0;     // circle radius, or half the thickness of a polyline
  Vec2 lo = Vec2::Zero(), hi = Vec2::Zero();  // bounding box

  static Shape polygon(std::vector<Vec2> pts);
  static Shape rect(Vec2 lo, Vec2 hi);
  static Shape circle(Vec2 c, double r);
  static Shape polyline(std::vector<Vec2> pts, double thickness);

  double sdf(const Vec2& p) const;
  bool contains(const Vec2& p) const;  // strictly inside (bounding box, then even-odd test)
  double area() const;
};

// A region is {"rect": [xmin, ymin, xmax, ymax]} | {"polygon": [[x, y], ...]} |
// {"circle": {"center": [x, y], "radius": r}}. Validates non-degenerate, non-self-intersecting
// shapes and reports the JSON path otherwise. Extra keys allowed by the caller are passed in.
Shape parse_region(const JsonReader& r, const std::vector<std::string>& other_keys);

// A wall is a thick polyline: {"points": [[x, y], ...], "closed": b, "thickness": t} or
// {"arc": {"center": [x, y], "radius": r, "from": deg, "to": deg, "segments": n}, "thickness": t},
// both with an optional "id" (docs/scenario-format.md#geometry).
Shape parse_wall(const JsonReader& r);

double segment_distance(const Vec2& p, const Vec2& a, const Vec2& b);

}  // namespace crowdmpm
