#pragma once
// Observed states: where the people of a recording are at a frame, how fast they move, and a
// simulation started from that state (what training windows and predictions both start from).
#include <memory>
#include <string>
#include <vector>

#include "engine/io/trajectory.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

// The state of one recording window, ready to roll forward.
struct ObservedState {
  long frame = 0;
  std::vector<long> ids;
  std::vector<Vec2> x, v;
  std::vector<double> speed;  // m/s over the speed window (over the velocity window if the history is shorter)
};

ObservedState observe_at(const TrajectorySet& t, long frame, double velocity_window, double speed_window = 1);

// Where a window's agents get their desired speed: the scenario's group (times the model's
// v0_scale), or each person's own observed walking speed (times v0_scale).
enum class DesiredSpeed { Scenario, Observed };

struct WindowOptions {
  int threads = 1;
  DesiredSpeed desired_speed = DesiredSpeed::Observed;
};

// A scenario ready to take observed agents: its groups and sources emptied, no time limit.
// keep_exits false: exits become goals of the same shape (nobody leaves, so the set of agents
// stays fixed, as gradients need; training masks people once the recording loses them).
ScenarioDef window_scenario(const ScenarioDef& scenario, bool keep_exits);

// A simulation started from an observed state: the observed agents placed (moved out of solids
// if a recorded head leans over a barrier; body radius at most half the distance to the nearest
// observed neighbour) with the behaviour of the scenario's first group. ids[i] is the entity of
// observed agent i, 0 if it could not be placed.
struct WindowSim {
  std::unique_ptr<Simulation> sim;
  std::vector<EntityId> ids;
};
WindowSim start_window(const ScenarioDef& windowed, const Model& model, const ObservedState& s, const WindowOptions& o);

}  // namespace crowdmpm
