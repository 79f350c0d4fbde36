#pragma once
// Reverse-mode (vector-Jacobian) kernels of the step, written against the forward kernels in
// kernels.cpp (DESIGN.md section 4). Each takes the adjoint of a kernel's outputs and adds the
// adjoints of its inputs; each is checked against central finite differences in
// tests/test_gradients.cpp. Composing them into the backward pass of a whole window is the
// learning issue's next step.
#include <vector>

#include "engine/kernels.hpp"

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

// d phi / d d and d phi / d c of contact_potential.
void contact_potential_grad(double d, double theta1, double c, double eps, double& dphi_dd, double& dphi_dc);

}  // namespace crowdmpm
