#pragma once
// Velocity fields on the nodes of the MPM grid, transferred from particles (or tracked people)
// with the simulator's own quadratic B-spline weights: what the grid velocity loss fits, what
// prediction scores and what video yields.
#include <vector>

#include "engine/sim/kernels.hpp"

namespace crowdmpm {

// A velocity field on the nodes of an MPM grid (origin, dx, nx, ny as Grid), with a mask
// weight per node (0: not observed).
struct GridVelocityField {
  Vec2 origin = Vec2::Zero();
  double dx = 0.5;
  int nx = 0, ny = 0;
  std::vector<Vec2> velocity;
  std::vector<double> mask;
  double mask_sum() const;
};

// The particles' mass-weighted grid velocity: M_i = sum_p w_ip m, P_i = sum_p w_ip m v_p,
// velocity P_i / M_i where M_i >= min_mass (mask 1 there, 0 elsewhere). Points whose 3x3
// stencil does not fit on the grid (outside the domain) are left out, here and in the loss.
GridVelocityField grid_velocity_of(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass,
                                   const Grid& shape, double min_mass);

// M_i = sum_p w_ip mass and P_i = sum_p w_ip mass v_p over the points whose stencil fits on the grid.
void grid_mass_momentum(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& g,
                        std::vector<double>& M, std::vector<Vec2>& P);

// Root-mean-square difference |a - b| over nodes observed in both (mask > 0 in each), m/s; NaN if none.
double grid_velocity_rms(const GridVelocityField& a, const GridVelocityField& b);

}  // namespace crowdmpm
