#pragma once
// The venue: a rectangular domain (whose border is a wall), solid walls and obstacles, exits
// (regions where agents leave) and goals (named target regions).
#include <string>
#include <vector>

#include "engine/geometry/shape.hpp"

namespace crowdmpm {

struct NamedShape {
  std::string id;
  Shape shape;
};

class Geometry {
 public:
  Vec2 lo = Vec2::Zero(), hi = Vec2::Zero();  // domain bounds, metres
  std::vector<Shape> solids;                  // walls (thick polylines) and obstacles
  std::vector<NamedShape> exits;
  std::vector<NamedShape> goals;

  // Signed distance to the nearest solid, the domain border included: negative inside a solid.
  double sdf(const Vec2& p) const;
  // Central-difference gradient of sdf (length 1 off the medial axis, shorter on it, where two
  // solids are equally near).
  Vec2 sdf_gradient(const Vec2& p) const;
  // Unit outward normal of the solid nearest to p (gradient of sdf).
  Vec2 normal(const Vec2& p) const;
  // Whether p lies within the domain's bounds (border included).
  bool in_domain(const Vec2& p) const {
    return p.x() >= lo.x() && p.x() <= hi.x() && p.y() >= lo.y() && p.y() <= hi.y();
  }
  // The area (m^2) of `region` inside the domain whose points lie at least `clearance` from every
  // solid and the domain's border: sampled at 5 cm, or coarser so that at most ~4e6 samples are
  // taken. 0 when no sample is free (the region lies inside solids or outside the domain).
  double free_area(const Shape& region, double clearance) const;
  // Index of the exit containing p, or -1.
  int exit_at(const Vec2& p) const;
  const NamedShape* find_target(const std::string& id) const;  // exit or goal by id
};

}  // namespace crowdmpm
