#pragma once
// Prediction from a recording: start from the observed state at t0 (positions, and velocities
// from the last observed second), roll forward a horizon, and compare with what was recorded.
// Average and final displacement errors (ADE, FDE, metres) per horizon, over windows that start
// every `stride` seconds. Agents are compared only while both the recording and the prediction
// have them (people entering the view later, or leaving it, or leaving through an exit, are masked).
#include <functional>
#include <string>
#include <vector>

#include "engine/simulation.hpp"
#include "engine/trajectory.hpp"

namespace crowdmpm {

struct PredictOptions {
  double observe = 2;       // s of recording before the first window starts (also the least history)
  double horizon = 4;       // s
  double stride = 4;        // s between window starts
  double velocity_window = 0.5;  // s: initial velocity = displacement over this much history
  int threads = 1;
  int max_windows = 0;      // 0: all windows that fit
};

struct HorizonError {
  double horizon = 0;  // s
  double ade = 0;      // mean displacement error over (agent, time <= horizon), m
  double fde = 0;      // mean displacement error at the horizon, m
  long samples = 0;    // agents compared at the horizon
};

struct PredictionReport {
  std::string method;
  long windows = 0;
  std::vector<HorizonError> horizons;  // at every whole second up to the horizon
};

// The state of one recording window, ready to roll forward.
struct ObservedState {
  long frame = 0;
  std::vector<long> ids;
  std::vector<Vec2> x, v;
};

ObservedState observe_at(const TrajectorySet& t, long frame, double velocity_window);

// Rolls one window forward with a predictor and accumulates errors. A predictor gets the
// observed state and a list of times (s after t0) and returns, per time, a position per agent
// (NaN where the agent is gone).
using Predictor = std::function<std::vector<std::vector<Vec2>>(const ObservedState&, const std::vector<double>&)>;
PredictionReport evaluate_predictor(const std::string& method, const TrajectorySet& t, const PredictOptions& o,
                                    const Predictor& predict);

// Constant velocity: x(t) = x0 + v0 t.
Predictor constant_velocity_predictor();
// The crowd material: the scenario's geometry and behaviours (its groups and sources emptied),
// the observed agents placed (moved out of solids if a recorded head leans over a barrier, body
// radius at most half the distance to the nearest observed neighbour) with the behaviour of
// the scenario's first group.
Predictor simulation_predictor(const ScenarioDef& scenario, const Model& model, int threads);

json report_to_json(const PredictionReport& r);

}  // namespace crowdmpm
