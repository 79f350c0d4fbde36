#pragma once
// Reverse-mode (vector-Jacobian) kernels of the step, written against the forward kernels in
// kernels.cpp (DESIGN.md section 4). Each takes the adjoint of a kernel's outputs and adds the
// adjoints of its inputs; each is checked against central finite differences in
// tests/test_gradients.cpp. Composing them into the backward pass of a whole window is the
// learning issue's next step.
#include <vector>

#include "engine/sim/kernels.hpp"

namespace crowdmpm {

// Adjoints of the pair traction's inputs.
struct TractionAdjoint {
  std::vector<Vec2> x, v, heading;  // per particle
  std::vector<double> comfort;      // per particle (c_p)
  std::vector<double> network;      // flat, TractionNet::parameters() order
  void reset(size_t particles, size_t network_parameters);
};

// Given dL/df_p for the pair force f_p of every particle (from kernel_traction, same state and
// neighbour lists), adds dL/dx, dL/dv, dL/dheading, dL/dcomfort and dL/dnetwork. Serial: the
// adjoint of a gather is a scatter onto neighbours.
void kernel_traction_adjoint(const StepInputs& in, const NeighbourGrid& nb, const World& w,
                             const std::vector<Vec2>& force_bar, TractionAdjoint& out);

// Adjoints of the grid transfer: P2G, grid update, G2P (kernels 3, 5, 6) of the crowd and fluid
// materials, from the particle state before it (x, v, C, J and the particle accelerations a and
// pair forces f) to the state after it (x', v', C', J').
struct TransferAdjoint {
  std::vector<Vec2> x, v, accel, force;
  std::vector<Mat2> C;
  std::vector<double> J;
  double E = 0, gamma = 0, tension_scale = 0, alignment_time = 0;
  void reset(size_t particles);
};

// `before` is the state the forward transfer started from (with accel and pair_force set); the
// grid is recomputed from it. x_bar ... J_bar are dL/d(state after). Where the forward clamped
// (speed above max_speed, J at its bounds) the clamped quantity passes no gradient. Serial.
// after_hook, if given, is called per particle with the forward's state after G2P (x', v') and
// may rewrite that particle's incoming x_bar, v_bar first: this is where a later per-particle
// kernel (the projection out of solids) puts its own adjoint without a second forward pass.
using AfterHook = void (*)(void* ctx, size_t p, const Vec2& x_after, const Vec2& v_after, Vec2& x_bar, Vec2& v_bar);
void kernel_transfer_adjoint(const StepInputs& in, const Grid& grid_shape, const World& before,
                             const std::vector<Vec2>& x_bar, const std::vector<Vec2>& v_bar,
                             const std::vector<Mat2>& C_bar, const std::vector<double>& J_bar, TransferAdjoint& out,
                             AfterHook after_hook = nullptr, void* hook_ctx = nullptr);

// d phi / d d and d phi / d c of contact_potential.
void contact_potential_grad(double d, double theta1, double c, double eps, double& dphi_dd, double& dphi_dc);

}  // namespace crowdmpm
