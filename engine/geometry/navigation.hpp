#pragma once
// Navigation field: travel distance to a target over the walkable area, by the fast marching
// method on a regular grid (first-order eikonal, |grad T| = 1), and the desired direction
// -grad T / |grad T| that agents follow around walls and obstacles.
#include <vector>

#include "engine/geometry/geometry.hpp"

namespace crowdmpm {

class NavField {
 public:
  // cell: grid spacing (metres); clearance: cells closer than this to a solid are not walkable.
  // The target is the union of the given shapes (e.g. every exit, for "nearest exit").
  NavField(const Geometry& geo, const std::vector<const Shape*>& targets, double cell, double clearance);

  // Unit desired direction at p (bilinear over walkable neighbour cells); zero if p is in a
  // region from which the target cannot be reached.
  Vec2 direction(const Vec2& p) const;
  // Travel distance (metres) to the target from p, or +inf if unreachable.
  double distance(const Vec2& p) const;
  bool reachable(const Vec2& p) const { return distance(p) < 1e299; }

  bool has_target() const { return seeded_; }
  int nx() const { return nx_; }
  int ny() const { return ny_; }
  double cell() const { return h_; }

 private:
  int index(int i, int j) const { return j * nx_ + i; }
  Vec2 lo_;
  double h_;
  int nx_, ny_;
  std::vector<double> T_;
  std::vector<Vec2> dir_;
  bool seeded_ = false;
};

}  // namespace crowdmpm
