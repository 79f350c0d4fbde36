#pragma once
// Prediction from a recording: start from the observed state at t0 (positions, and velocities
// from the last observed second), roll forward a horizon, and compare with what was recorded.
// Average and final displacement errors (ADE, FDE, metres) per horizon, over windows that start
// every `stride` seconds. Agents are compared only while both the recording and the prediction
// have them (people entering the view later, or leaving it, or leaving through an exit, are masked).
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/observe/observe.hpp"

namespace crowdmpm {

struct PredictOptions {
  double observe = 2;       // s of recording before the first window starts (also the least history)
  double horizon = 4;       // s
  double stride = 4;        // s between window starts
  double velocity_window = 0.5;  // s: initial velocity = displacement over this much history
  double speed_window = 1;  // s: observed walking speed = displacement over this much history / it
  int threads = 1;
  int max_windows = 0;      // 0: all windows that fit
  double grid_min_mass = 0.5;  // persons on a node's stencil for it to count in the grid velocity error
  InputPolicy input;        // limits of the files the job reads
};

struct HorizonError {
  double horizon = 0;  // s
  double ade = 0;      // mean displacement error over (agent, time <= horizon), m
  double fde = 0;      // mean displacement error at the horizon, m
  long samples = 0;    // agents compared at the horizon
  double grid_velocity_rms = 0;  // m/s: per window the RMS over nodes of (predicted - recorded) grid velocity at this time, averaged over windows; NaN if none
};

struct PredictionReport {
  std::string method;
  long windows = 0;
  std::vector<HorizonError> horizons;  // at every whole second up to the horizon
};

// Rolls one window forward with a predictor and accumulates errors. A predictor gets the
// observed state and a list of times (s after t0) and returns, per time, a position per agent
// (NaN where the agent is gone).
using Predictor = std::function<std::vector<std::vector<Vec2>>(const ObservedState&, const std::vector<double>&)>;
// With a grid, also the grid velocity error at every whole second: velocities by one-frame
// differences of predicted and of recorded positions (agents seen in both), each transferred to
// the grid (losses.hpp, grid_velocity_of) and compared where both have at least grid_min_mass.
// Windows start, and the observed state is read, on t's own rows; the predictions are compared
// with `truth` when given (t with the frames between its rows filled: PredictJob::filled), else
// with t.
PredictionReport evaluate_predictor(const std::string& method, const TrajectorySet& t, const PredictOptions& o,
                                    const Predictor& predict, const Grid* grid = nullptr,
                                    const TrajectorySet* truth = nullptr);

// Constant velocity: x(t) = x0 + v0 t.
Predictor constant_velocity_predictor();
// The model (any material) rolled forward from start_window.
Predictor simulation_predictor(const ScenarioDef& scenario, const Model& model, const WindowOptions& o);

json report_to_json(const PredictionReport& r);

// A model's label in tables: its name, with its kind when the name does not say it.
std::string model_label(const Model& m);

// A prediction job (what `crowdmpm predict` and the C ABI's cmpm_PredictRecording run): a
// recording in a scenario's venue, rolled forward by constant velocity, the scenario's own
// model (labelled "untrained default" when it is the built-in one) and every model given.
struct PredictJob {
  std::string scenario_path, trajectories_path;
  ScenarioDef scenario;
  TrajectorySet recording;
  std::vector<Model> models;  // the scenario's first, then the models given
  PredictOptions options;
  DesiredSpeed desired_speed = DesiredSpeed::Observed;
  // A recording with a row every few frames (ETH/UCY: every 10th) is compared at every frame,
  // whole seconds included: `filled` is the recording with the frames between a person's
  // consecutive rows that far apart filled by linear interpolation (TrajectorySet::fill_frames),
  // made when the rows are at most a second apart and it has at most 10 million rows (otherwise
  // interpolated_rows stays 0, and seconds without rows have no error). Windows still start, and
  // people are observed, on the recording's own rows only: nothing is read from after a start.
  long frame_step = 1;          // the recording's most common step between a person's rows
  TrajectorySet filled;         // empty unless interpolated_rows > 0
  size_t interpolated_rows = 0; // rows added in `filled`
};
// Loads the scenario, models and recording.
PredictJob load_predict_job(const std::string& scenario_path, const std::string& trajectories_path,
                            const std::vector<std::string>& model_paths, const PredictOptions& o, DesiredSpeed ds);
// The same, and checks that observe, horizon and stride are > 0 and observe + horizon fit the recording.
PredictJob make_predict_job(const std::string& scenario_path, const std::string& trajectories_path,
                            const std::vector<std::string>& model_paths, const PredictOptions& o, DesiredSpeed ds);
// From JSON: {"scenario": PATH, "trajectories": PATH, "models": [PATH, ...], "observe": 2,
// "horizon": 4, "stride": (horizon), "windows": 0, "threads": 1, "desired_speed": "observed",
// "input": {"max_bytes": N, "allow_outside_paths": false}}.
PredictJob parse_predict_job(const json& request);
std::vector<PredictionReport> run_prediction(const PredictJob& job);
// The reports as written to prediction.json.
json prediction_json(const PredictJob& job, const std::vector<PredictionReport>& reports);

}  // namespace crowdmpm
