#pragma once
// Eulerian fields for output: density (persons/m^2), velocity (m/s) and pressure on the nodes of
// the simulation grid, splatted from the particles with the same quadratic B-spline weights as P2G.
#include <vector>

#include "engine/sim/kernels.hpp"

namespace crowdmpm {

struct FieldFrame {
  Vec2 origin = Vec2::Zero();
  double dx = 0;
  int nx = 0, ny = 0;
  std::vector<double> density, pressure;  // node-major, ny rows of nx
  std::vector<Vec2> velocity;
  double at(const std::vector<double>& f, int i, int j) const { return f[static_cast<size_t>(j) * nx + i]; }
  Vec2 node_position(int i, int j) const { return origin + dx * Vec2(i, j); }
};

// Pressure at a node is the mass-weighted mean of the particles' reported pressure; nodes with
// density below min_density (persons/m^2) get pressure 0 so a lone particle does not paint a halo.
FieldFrame compute_fields(const World& w, const Grid& g, double min_density = 0.25);



}  // namespace crowdmpm
