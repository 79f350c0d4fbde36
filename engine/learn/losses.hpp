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

#include "engine/analysis/grid_velocity.hpp"
#include "engine/geometry/shape.hpp"

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

// L = sum_i mask_i M_i |P_i / M_i - u_i|^2 / sum_i mask_i, with u the observed field (nodes with
// M_i below 1e-9 contribute nothing). The gradient with respect to the particles' x and v is
// added to dL_dx, dL_dv when given. Throws Error if the field's grid differs from `shape`.
// With empty_mass > 0 it is instead L = sum_i mask_i |P_i / max(M_i, empty_mass) - u_i|^2 /
// sum_i mask_i: every observed node counts alike and one the particles left counts as velocity
// 0, as the prediction error Err_vel scores it (video learning: a model that lets the crowd
// drain out of where it is seen is penalised for it).
double grid_velocity_loss(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& shape,
                          const GridVelocityField& observed, std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv,
                          double empty_mass = 0);

// Macroscopic loss in measurement areas: the density rho = sum_p chi(x_p) / A and the flow
// q = sum_p chi(x_p) v_p / A (persons/m/s: density times velocity) of the agents in each area,
// with the soft indicator chi(x) = 1 / (1 + exp(sdf(x) / kAreaEdge)), against the same measures
// of the recorded positions seen_x and velocities seen_v:
//   L = sum over areas of (rho - rho_rec)^2 + (1 s)^2 |q - q_rec|^2   ((persons/m^2)^2).
// Agent p counts in both densities where seen_x[p] is finite, in both flows where seen_v[p] is
// too. Returns weight * L and adds weight * dL/dx, dL/dv to dL_dx, dL_dv when given. (Training
// scores every frame of a window in every area: an area's "from"/"to" times are not used.)
constexpr double kAreaEdge = 0.1;  // m: how soft an area's edge is (chi from 0.12 to 0.88 over 0.4 m)
double area_loss_at(const std::vector<Shape>& areas, const std::vector<Vec2>& x, const std::vector<Vec2>& v,
                    const std::vector<Vec2>& seen_x, const std::vector<Vec2>& seen_v, double weight,
                    std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv);

}  // namespace crowdmpm
