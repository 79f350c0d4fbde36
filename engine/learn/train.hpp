#pragma once
// Learning the crowd material from tracked trajectories (DESIGN.md section 4): windows are cut
// from recordings; each starts from the observed state (positions, velocities, walking speeds),
// runs the simulator for a few seconds in the recording's venue and is scored by the trajectory
// loss (losses.hpp) against where the people were recorded; WindowGradient gives the gradient
// of that loss for every learnable parameter, and Adam with gradient-norm clipping moves them.
// The last part of every recording is held out for validation and early stopping.
#include <functional>
#include <string>
#include <vector>

#include "engine/analysis/grid_velocity.hpp"
#include "engine/learn/differentiable.hpp"
#include "engine/observe/observe.hpp"

namespace crowdmpm {

struct TrainDataset {
  ScenarioDef scenario;                    // the recordings' venue; its first group's behaviour is used
  std::vector<TrajectorySet> recordings;
};

struct TrainOptions {
  double window = 2;             // s simulated per window
  double stride = 1;             // s between window starts
  double velocity_window = 0.5;  // s, as PredictOptions
  double speed_window = 1;       // s, as PredictOptions
  DesiredSpeed desired_speed = DesiredSpeed::Observed;
  // trajectory: mean squared position error of the people seen (losses.hpp); grid_velocity: the
  // mass-weighted grid velocity against the recorded people's velocity field on the nodes they
  // cover (at least grid_min_mass persons), averaged over the window's frames.
  enum class Loss { Trajectory, GridVelocity };
  Loss loss = Loss::Trajectory;
  // Trajectory loss: plus area_weight (m^2 per (persons/m^2)^2) times the macroscopic loss in the
  // venue's measurement areas (losses.hpp area_loss_at: density and flow against the recorded
  // ones), averaged over the window's samples and areas. 0: positions only.
  double area_weight = 0;
  // Windows with observed fields (video) use the loss's empty_mass form with this many persons.
  double grid_min_mass = 0.5;
  enum class Optimizer { Adam, Lbfgs };
  // Adam on minibatches (default), or L-BFGS with a backtracking line search on the full batch
  // of training windows (for small, noise-free problems with ill-conditioned valleys).
  Optimizer optimizer = Optimizer::Adam;
  int iterations = 120;
  int batch = 4;                 // windows per Adam step
  double learning_rate = 0.03;   // in the optimiser's coordinates (log of positive parameters)
  double clip_norm = 1;          // gradient-norm clipping (0: off)
  double validation_fraction = 0.25;  // the last share of every recording's windows
  int eval_every = 5;            // iterations between validation passes
  int patience = 6;              // validation passes without improvement before stopping
  double lr_decay = 0.5;         // Adam: learning rate factor (and back to the best point) after a validation pass without improvement
  uint64_t seed = 1;             // minibatch sampling
  std::vector<std::string> params;  // scalar parameters to learn; empty: all the model kind has
  bool learn_scalars = true;     // false: no scalar parameter (only the network and force terms)
  bool learn_network = true;     // the traction network's weights and biases (crowd material)
  int threads = 1;
  // Gradient checkpoints every this many steps (WindowGradient); 0: only when a window's stored
  // states would pass max_stored_bytes, then every ceil(sqrt(steps)) steps.
  int checkpoint_every = 0;
  double max_stored_bytes = 512.0 * 1024 * 1024;
};

// What training fits: the material model, and the force terms of each dataset's venue
// (terms[d] are scenarios[d].terms; those with parameters marked "learn" are fitted too).
struct Fitted {
  Model model;
  std::vector<std::vector<Term>> terms;
  // The model with every venue's own terms.
  static Fitted of(const Model& m, const std::vector<ScenarioDef>& scenarios);
};

// The learnable parameters as one vector in the optimiser's coordinates: log p for the positive
// scalars, p for tension_scale, the raw network parameters, then the learned force-term
// parameters as they are; set() clamps to param_table() and the terms' ranges.
// When E and gamma are both learned, E's coordinate is log(E gamma): the stiffness at J = 1,
// which trajectories determine well, while gamma (the curvature of the stress law) is told
// apart only by strong compression. In (log E, log gamma) that is a long diagonal valley;
// in these coordinates it lies along gamma's axis, where Adam's per-coordinate steps follow it.
class ParamMap {
 public:
  // scalars: names from param_table() (empty: every parameter the model kind learns, unless
  // learn_scalars is false).
  ParamMap(const Fitted& f, std::vector<std::string> scalars, bool network, bool learn_scalars = true);
  std::vector<double> get(const Fitted& f) const;
  void set(Fitted& f, const std::vector<double>& u) const;
  // dL/du from one window's gradient, recorded in dataset d's venue.
  std::vector<double> gradient(const Fitted& f, const ModelGradient& g, size_t dataset) const;
  const std::vector<std::string>& scalars() const { return scalars_; }
  size_t size() const { return scalars_.size() + network_size_ + terms_.size(); }
  // "forces[i].key" names of the learned term parameters, with their dataset.
  std::vector<std::pair<size_t, std::string>> term_parameter_names(const Fitted& f) const;

 private:
  struct TermSlot {
    size_t dataset, term, param;
  };
  std::vector<std::string> scalars_;
  std::vector<const ParamInfo*> info_;
  std::vector<char> log_;
  int e_index_ = -1, gamma_index_ = -1;
  size_t network_size_ = 0;
  std::vector<TermSlot> terms_;
};

// The scalar parameters a model kind learns (param_table() rows learnable in it).
std::vector<std::string> learnable_params(const Model& m);

// One window: the state it starts from and where its people were seen afterwards.
struct TrainWindow {
  size_t dataset = 0;   // index of the scenario (TrainDataset) it was recorded in
  ObservedState start;  // positions, velocities, walking speeds at the window's start
  double framerate = 0; // of `seen`
  // seen[k][i]: position of start.ids[i] at frame k + 1 after the start (NaN: not in the recording).
  std::vector<std::vector<Vec2>> seen;
  // Or, for a crowd seen only as a velocity field (video): fields[k] is the observed grid
  // velocity at frame k + 1 after the start, on the venue's grid; the loss is then the grid
  // velocity loss against them whatever TrainOptions::loss says.
  std::vector<GridVelocityField> fields;
  // People walking in across the edge of the view during the window (video windows only).
  EdgeInflow inflow;
  size_t frames() const { return fields.empty() ? seen.size() : fields.size(); }
};

// The window of recording t starting at frame `start` and seen for `length` frames after it
// (start.ids empty when nobody is recorded at `start` with enough history); history: the
// recording's speed history for free speeds under a density-speed law (ObservedState::history).
TrainWindow window_at(const TrajectorySet& t, long start, long length, const TrainOptions& o, size_t dataset = 0,
                      std::shared_ptr<const SpeedHistory> history = nullptr);

// Training and validation windows of the datasets (validation: the last share of each
// recording; training windows that would overlap it in time are left out).
void make_windows(const std::vector<TrainDataset>& data, const TrainOptions& o, std::vector<TrainWindow>& train,
                  std::vector<TrainWindow>& validation);

// The loss of one window under a model (o.loss: the trajectory loss, mean squared position error
// in m^2 over every frame of the window and every person placed at its start, plus area_weight
// times the area loss in the venue's measurement areas; or the grid velocity loss, (m/s)^2 per
// person), and its gradient when `grad` is given. `windowed` is window_scenario(scenario, false).
// NaN when nobody can be compared.
double window_loss(const ScenarioDef& windowed, const TrainWindow& w, const Model& m, const TrainOptions& o,
                   ModelGradient* grad);

struct TrainProgress {
  int iteration = 0;
  double train_loss = 0;       // minibatch mean
  double grad_norm = 0;        // before clipping
  double validation_loss = 0;  // NaN when this iteration had no validation pass
  bool improved = false;
};

struct TrainResult {
  Model model;                  // the parameters with the best validation loss
  std::vector<std::vector<Term>> terms;  // each venue's force terms at that point
  double initial_validation = 0, best_validation = 0;
  int best_iteration = 0, iterations = 0;
  bool early_stopped = false;
  size_t train_windows = 0, validation_windows = 0;
  long skipped_windows = 0;     // window evaluations whose simulation failed (non-finite) and were left out
  std::vector<TrainProgress> history;
};

using TrainCallback = std::function<void(const TrainProgress&)>;

// What the training and validation losses of o are, for messages: "trajectory", "trajectory +
// 2 x area" (area_weight 2) or "grid velocity"; and their unit, "m2" or "(m/s)2".
std::string loss_name(const TrainOptions& o);
const char* loss_unit(const TrainOptions& o);

// Fits `start` on the datasets' windows. Throws Error when there are no training or no
// validation windows.
TrainResult train_model(const std::vector<TrainDataset>& data, const Model& start, const TrainOptions& o,
                        const TrainCallback& progress = nullptr);
// The same on windows made elsewhere (synthetic data, tests); scenarios[w.dataset] is each
// window's venue.
TrainResult train_on_windows(const std::vector<ScenarioDef>& scenarios, const std::vector<TrainWindow>& train,
                             const std::vector<TrainWindow>& validation, const Model& start, const TrainOptions& o,
                             const TrainCallback& progress = nullptr);

// A training job (what `crowdmpm train` and the C ABI's cmpm_TrainModel run), from JSON:
//   {"datasets": [{"scenario": PATH, "trajectories": [PATH, ...]}, ...],
//    "model": PATH (start; default: the first scenario's model),
//    "material": "crowd" | "fluid" | "social_force" (start from that kind's defaults instead),
//    "options": {"window", "stride", "iterations", "batch", "learning_rate", "clip",
//                "validation", "eval_every", "patience", "seed", "threads", "params",
//                "learn_network", "loss", "desired_speed", "area_weight"}}
// Relative paths resolve from base_dir. Errors name the JSON path (docs/learning.md).
struct TrainJob {
  std::vector<TrainDataset> data;
  std::vector<std::string> files;  // the recordings, for the learned model's description
  Model start;
  TrainOptions options;
  InputPolicy input;  // limits of the files the job reads ("input" of the request)
};
TrainJob parse_train_job(const json& request, const std::string& base_dir = "");
// The "options" object of a training request into o (defaults kept for keys not given).
void parse_train_options(const JsonReader& op, TrainOptions& o);
// The best model of a run, named "learned <kind>" and described: what it was learned from and
// its validation loss before and after.
Model describe_learned(const TrainJob& job, const TrainResult& r);
// For every dataset whose venue has learned force terms: its scenario file with "forces" set to
// the fitted terms (relative "model" and "extends" paths made absolute), written beside the
// model as <model stem>.<scenario stem>.json. Returns the files written.
std::vector<std::string> write_fitted_scenarios(const TrainJob& job, const TrainResult& r, const std::string& model_path);
// Writes a model JSON file; throws Error naming the path if it cannot.
void save_model(const Model& m, const std::string& path);

}  // namespace crowdmpm
