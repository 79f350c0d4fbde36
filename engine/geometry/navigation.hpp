#pragma once
// Navigation field: travel distance to a target over the walkable area, by the fast marching
// method on a regular grid (first-order eikonal, |grad T| = c, c = 1 for the shortest path), and
// the desired direction -grad T / |grad T| that agents follow around walls and obstacles. A cost
// c >= 1 per cell (route choice under congestion, Hughes 2002) makes T a travel cost in
// metres of free walking and bends the routes round crowded places.
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
  // Travel distance (metres) to the target from p, or +inf if unreachable: with a congestion cost
  // set, the cost (metres of free walking) of the route the directions follow.
  double distance(const Vec2& p) const;
  // Routes under a cost per cell (nx() * ny() values, row-major from the domain's low corner,
  // each >= 1; walls ignore it), or the shortest paths again when `cost` is empty.
  void set_cost(const std::vector<double>& cost);
  // Centre of cell (i, j).
  Vec2 cell_centre(int i, int j) const { return lo_ + h_ * Vec2(i + 0.5, j + 0.5); }
  bool reachable(const Vec2& p) const { return distance(p) < 1e299; }

  bool has_target() const { return seeded_; }
  int nx() const { return nx_; }
  int ny() const { return ny_; }
  double cell() const { return h_; }

 private:
  int index(int i, int j) const { return j * nx_ + i; }
  // Fast marching from the seeds over the free cells (cost empty: 1 everywhere), then directions.
  void march(const std::vector<double>& cost);
  Vec2 lo_;
  double h_;
  int nx_, ny_;
  std::vector<char> free_;  // walkable cells
  std::vector<int> seeds_;  // target cells (T = 0)
  std::vector<double> T_;
  std::vector<Vec2> dir_;
  // Scratch of march, kept so that recomputing the routes during a run allocates nothing.
  std::vector<char> done_;
  std::vector<std::pair<double, int>> heap_;
  bool seeded_ = false;
};

}  // namespace crowdmpm
