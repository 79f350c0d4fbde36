#pragma once
// Reverse-mode gradients of a loss over a window of steps (DESIGN.md section 4). The forward
// pass stores each step's particle state (x, v, C, J, heading) and what its drive and traction
// produced (accelerations, pair forces, headings used): 144 bytes per agent per step. The
// backward pass rebuilds each step's neighbour lists and grid and runs the kernels' adjoints in
// reverse order. Covers the crowd and fluid materials. Agents may enter during the window (a
// source, or the caller's after_step: they are appended, and their entry state is data, with no
// gradient) but not leave (an exit inside it is an error); with checkpoints the set is fixed.
#include <functional>
#include <vector>

#include "engine/learn/adjoint.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

struct ModelGradient {
  MaterialParams params = zero_params();  // dL/dp for each parameter p, read with ParamInfo::field
  std::vector<double> network;  // TractionNet::parameters() order
  std::vector<std::vector<double>> terms;  // per scenario term (ScenarioDef::terms), per parameter
  std::vector<Vec2> x0, v0;     // initial positions and velocities, per particle at the start (dense order)
};

// dL/dx and dL/dv of the state after step k (k = 1..steps), per particle (both arrive zeroed,
// sized to the agents after the step); return false when the loss has no term at this step.
using StateLossGrad = std::function<bool(int step, const World& w, std::vector<Vec2>& dL_dx, std::vector<Vec2>& dL_dv)>;

class WindowGradient {
 public:
  // Checkpointing for long windows: keep the state of every K-th step only and run each
  // segment of K steps forward again in the backward pass (one extra forward pass; memory for
  // steps / K + K states instead of steps). 0 (default): no checkpoints, every state kept.
  explicit WindowGradient(int checkpoint_every = 0) : checkpoint_every_(checkpoint_every) {}
  // Runs `steps` steps of `sim` forward (it advances and ends at the window's last state),
  // recording states, then the backward pass. after_step (optional) runs after each step, before
  // the loss sees its state; it may add agents (Simulation::add_agent) and nothing else, and
  // needs checkpoints off (its own state could not be wound back to a checkpoint).
  ModelGradient run(Simulation& sim, int steps, const StateLossGrad& loss_grad,
                    const std::function<void(Simulation&)>& after_step = nullptr);
  size_t stored_bytes_per_agent_step() const { return 6 * sizeof(Vec2) + sizeof(Mat2) + 2 * sizeof(double); }
  // Most step states held at once during the last run (checkpoints included).
  size_t peak_stored_steps() const { return peak_stored_steps_; }

 private:
  int checkpoint_every_ = 0;
  size_t peak_stored_steps_ = 0;
};

}  // namespace crowdmpm
