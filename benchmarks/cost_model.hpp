#pragma once
// Cost model of one step: floating-point operations and compulsory memory traffic per
// agent-step for each kernel, from the kernels' source (counted by hand, see the comments) and
// the run's neighbour statistics, compared with this machine's measured limits (a compute and a
// bandwidth probe). A transcendental call (exp, log, pow) is counted as 20 flops, roughly what
// glibc spends on one; sqrt and division count 1.
#include <string>
#include <vector>

#include "engine/sim/simulation.hpp"

namespace crowdmpm::bench {

struct MachineLimits {
  double gflops_1, gflops_n;  // double-precision flops/s with 1 and n threads (SSE2 mul+add, no FMA)
  double gbytes_1, gbytes_n;  // triad bandwidth, bytes/s, 1 and n threads
  int threads;
};
MachineLimits probe_machine(int threads);

struct KernelCost {
  std::string name;
  double flops;  // per agent-step
  double bytes;  // per agent-step (agent arrays read/written once, grid nodes once per step)
};
// Per-kernel costs for the run's state: pairs and candidates per agent, grid nodes per agent,
// traction network layer sizes.
std::vector<KernelCost> kernel_costs(const Simulation& sim, const PairStats& pairs);

}  // namespace crowdmpm::bench
