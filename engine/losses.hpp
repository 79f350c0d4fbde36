#pragma once
// Losses of the learning problem (DESIGN.md section 4), each with its gradient with respect to
// the particle state, for WindowGradient:
// - trajectory loss: mean squared position error of agents against recorded positions, over the
//   samples a mask keeps (people who have left the view, or entered it after the window
//   started, are not compared);
// - grid velocity loss: the mass-weighted grid velocity of the particles (quadratic B-spline
//   P2G, the simulator's own transfer) against an observed velocity field on the same grid,
//   over the nodes a mask keeps (what the video issue learns from).
#include <vector>

#include "engine/kernels.hpp"

namespace crowdmpm {

// Recorded positions of a window's agents at some steps of the window: targets[s][p] is the
// position of agent p (dense order at the window's start) after step steps[s]; NaN = not seen.
struct TrajectoryTarget {
  std::vector<int> steps;                 // increasing, >= 1
  std::vector<std::vector<Vec2>> targets; // [sample][agent]
  long samples() const;                   // (sample, agent) pairs with a finite target
};

// The trajectory loss over a whole window is sum over samples of |x - target|^2 / samples().
// Adds one sample's share to `loss` and, when dL_dx is given, its gradient (same length as x).
void trajectory_loss_at(const std::vector<Vec2>& x, const std::vector<Vec2>& target, double weight, double& loss,
                        std::vector<Vec2>* dL_dx);

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

// L = sum_i mask_i M_i |P_i / M_i - u_i|^2 / sum_i mask_i, with u the observed field (nodes with
// M_i below 1e-9 contribute nothing). The gradient with respect to the particles' x and v is
// added to dL_dx, dL_dv when given. Throws Error if the field's grid differs from `shape`.
double grid_velocity_loss(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& shape,
                          const GridVelocityField& observed, std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv);

// Root-mean-square difference |a - b| over nodes observed in both (mask > 0 in each), m/s; NaN if none.
double grid_velocity_rms(const GridVelocityField& a, const GridVelocityField& b);

}  // namespace crowdmpm
