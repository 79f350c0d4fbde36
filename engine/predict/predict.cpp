#include "engine/predict/predict.hpp"

#include "engine/analysis/grid_velocity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace crowdmpm {

namespace {
// Grid velocity error between prediction and recording over frames f and f + 1 (prediction rows
// prev and cur), agents seen in both.
double grid_velocity_error(const TrajectorySet& t, long f, const std::unordered_map<long, size_t>& index,
                           const std::vector<Vec2>& prev, const std::vector<Vec2>& cur, const Grid& grid, double min_mass) {
  std::unordered_map<long, Vec2> rec0;
  auto [b0, e0] = t.frame(f);
  for (auto p = b0; p != e0; ++p) rec0[p->id] = Vec2(p->x, p->y);
  std::vector<Vec2> xr, vr, xp, vp;
  auto [b, e] = t.frame(f + 1);
  for (auto p = b; p != e; ++p) {
    auto it = index.find(p->id);
    auto r0 = rec0.find(p->id);
    if (it == index.end() || r0 == rec0.end()) continue;
    const Vec2 &a = prev[it->second], &c = cur[it->second];
    if (!a.allFinite() || !c.allFinite()) continue;
    xr.emplace_back(p->x, p->y);
    vr.push_back((xr.back() - r0->second) * t.framerate);
    xp.push_back(c);
    vp.push_back((c - a) * t.framerate);
  }
  if (xr.empty()) return std::nan("");
  return grid_velocity_rms(grid_velocity_of(xp, vp, 1, grid, min_mass), grid_velocity_of(xr, vr, 1, grid, min_mass));
}
}  // namespace

PredictionReport evaluate_predictor(const std::string& method, const TrajectorySet& t, const PredictOptions& o,
                                    const Predictor& predict, const Grid* grid, const TrajectorySet* truth) {
  const TrajectorySet& seen = truth ? *truth : t;
  PredictionReport r;
  r.method = method;
  const int seconds = std::max(1, static_cast<int>(std::floor(o.horizon + 1e-9)));
  std::vector<double> times;  // every recorded frame up to the horizon
  const long horizon_frames = std::lround(o.horizon * t.framerate);
  for (long k = 1; k <= horizon_frames; ++k) times.push_back(static_cast<double>(k) / t.framerate);
  std::vector<double> ade_sum(static_cast<size_t>(seconds), 0), fde_sum(static_cast<size_t>(seconds), 0);
  std::vector<long> ade_n(static_cast<size_t>(seconds), 0), fde_n(static_cast<size_t>(seconds), 0);
  std::vector<double> gv_sum(static_cast<size_t>(seconds), 0);
  std::vector<long> gv_n(static_cast<size_t>(seconds), 0);
  const long stride = std::max(1L, std::lround(o.stride * t.framerate));
  // For predictors whose model has a density-speed law (free speeds under the law, start_window).
  const auto history = speed_history(t, o.speed_window);
  for (long f0 = t.frame_min() + std::lround(o.observe * t.framerate); f0 + horizon_frames <= t.frame_max(); f0 += stride) {
    f0 = t.skip_gap(f0, stride);
    if (f0 + horizon_frames > t.frame_max()) break;
    if (o.max_windows > 0 && r.windows >= o.max_windows) break;
    ObservedState s = observe_at(t, f0, o.velocity_window, o.speed_window, history);
    if (s.ids.empty()) continue;
    std::vector<std::vector<Vec2>> pred = predict(s, times);
    std::unordered_map<long, size_t> index;
    for (size_t i = 0; i < s.ids.size(); ++i) index[s.ids[i]] = i;
    // Per agent, running sum of errors up to each time.
    std::vector<double> err_sum(s.ids.size(), 0);
    std::vector<long> err_n(s.ids.size(), 0);
    for (size_t k = 0; k < times.size(); ++k) {
      // Whole seconds (1..seconds) get FDE samples, ADE so far and the grid velocity error.
      const int sec = static_cast<int>(std::lround(times[k]));
      const bool whole = std::abs(times[k] - sec) < 0.5 / t.framerate && sec >= 1 && sec <= seconds;
      const size_t si = static_cast<size_t>(std::max(sec, 1) - 1);
      auto [b, e] = seen.frame(f0 + static_cast<long>(k) + 1);
      for (auto p = b; p != e; ++p) {
        auto it = index.find(p->id);
        if (it == index.end()) continue;
        const Vec2& x = pred[k][it->second];
        if (!x.allFinite()) continue;
        double err = (x - Vec2(p->x, p->y)).norm();
        err_sum[it->second] += err;
        ++err_n[it->second];
        if (whole) {
          fde_sum[si] += err;
          ++fde_n[si];
          ade_sum[si] += err_sum[it->second] / static_cast<double>(err_n[it->second]);
          ++ade_n[si];
        }
      }
      if (grid && k > 0 && whole) {
        double gv = grid_velocity_error(seen, f0 + static_cast<long>(k), index, pred[k - 1], pred[k], *grid, o.grid_min_mass);
        if (std::isfinite(gv)) {
          gv_sum[si] += gv;
          ++gv_n[si];
        }
      }
    }
    ++r.windows;
  }
  for (int sidx = 0; sidx < seconds; ++sidx) {
    HorizonError h;
    h.horizon = sidx + 1;
    h.samples = fde_n[static_cast<size_t>(sidx)];
    h.ade = ade_n[static_cast<size_t>(sidx)] ? ade_sum[static_cast<size_t>(sidx)] / static_cast<double>(ade_n[static_cast<size_t>(sidx)]) : std::nan("");
    h.fde = h.samples ? fde_sum[static_cast<size_t>(sidx)] / static_cast<double>(h.samples) : std::nan("");
    h.grid_velocity_rms = gv_n[static_cast<size_t>(sidx)] ? gv_sum[static_cast<size_t>(sidx)] / static_cast<double>(gv_n[static_cast<size_t>(sidx)]) : std::nan("");
    r.horizons.push_back(h);
  }
  return r;
}

Predictor constant_velocity_predictor() {
  return [](const ObservedState& s, const std::vector<double>& times) {
    std::vector<std::vector<Vec2>> out(times.size());
    for (size_t k = 0; k < times.size(); ++k)
      for (size_t i = 0; i < s.x.size(); ++i) out[k].push_back(s.x[i] + times[k] * s.v[i]);
    return out;
  };
}

Predictor simulation_predictor(const ScenarioDef& scenario, const Model& model, const WindowOptions& o) {
  ScenarioDef base = window_scenario(scenario, true);
  return [base, model, o](const ObservedState& s, const std::vector<double>& times) {
    WindowSim ws = start_window(base, model, s, o);
    Simulation& sim = *ws.sim;
    std::vector<std::vector<Vec2>> out(times.size());
    const double nan = std::numeric_limits<double>::quiet_NaN();
    double t = 0;
    for (size_t k = 0; k < times.size(); ++k) {
      long steps = std::lround((times[k] - t) / base.dt);
      sim.run_steps(steps);
      t += static_cast<double>(steps) * base.dt;
      for (EntityId id : ws.ids) {
        long i = id ? sim.world().index_of(id) : -1;
        out[k].push_back(i >= 0 ? sim.world().x[static_cast<size_t>(i)] : Vec2(nan, nan));
      }
    }
    return out;
  };
}

json report_to_json(const PredictionReport& r) {
  json h = json::array();
  for (const auto& e : r.horizons)
    h.push_back({{"horizon_s", e.horizon}, {"ade_m", std::isfinite(e.ade) ? json(e.ade) : json(nullptr)},
                 {"fde_m", std::isfinite(e.fde) ? json(e.fde) : json(nullptr)}, {"samples", e.samples},
                 {"grid_velocity_rms_m_s", std::isfinite(e.grid_velocity_rms) ? json(e.grid_velocity_rms) : json(nullptr)}});
  return {{"method", r.method}, {"windows", r.windows}, {"horizons", h}};
}

std::string model_label(const Model& m) {
  const std::string kind = material_name(m.material);
  if (m.name.empty()) return kind;
  return m.name.find(kind) == std::string::npos ? m.name + " (" + kind + ")" : m.name;
}

namespace {
constexpr double kMaxFilledRows = 1e7;  // 320 MB of TrackPoint
}  // namespace

PredictJob load_predict_job(const std::string& scenario_path, const std::string& trajectories_path,
                            const std::vector<std::string>& model_paths, const PredictOptions& o, DesiredSpeed ds) {
  PredictJob job;
  job.scenario_path = scenario_path;
  job.trajectories_path = trajectories_path;
  job.scenario = ScenarioDef::load(scenario_path, o.input);
  job.models.push_back(job.scenario.model_or_default());
  job.models[0].name = !job.scenario.model ? std::string("untrained default")
                                           : "scenario's model " + job.models[0].name;
  for (const auto& p : model_paths) job.models.push_back(Model::load(p, o.input));
  job.recording = TrajectorySet::read(trajectories_path, 0, o.input);
  check_recording_scale(job.recording, job.scenario.geo, job.scenario.source);
  job.frame_step = job.recording.frame_step();
  // Filled where that stays small: a row at least every second, at most kMaxFilledRows in all.
  const double rows = static_cast<double>(job.recording.points.size()) * static_cast<double>(job.frame_step);
  if (job.frame_step > 1 && static_cast<double>(job.frame_step) <= job.recording.framerate && rows <= kMaxFilledRows) {
    job.filled = job.recording;
    job.interpolated_rows = job.filled.fill_frames(job.frame_step);
  }
  job.options = o;
  job.desired_speed = ds;
  return job;
}

PredictJob make_predict_job(const std::string& scenario_path, const std::string& trajectories_path,
                            const std::vector<std::string>& model_paths, const PredictOptions& o, DesiredSpeed ds) {
  PredictJob job = load_predict_job(scenario_path, trajectories_path, model_paths, o, ds);
  if (!(o.observe > 0 && o.horizon > 0 && o.stride > 0))
    throw Error("observe, horizon and stride must be > 0 s");
  if (o.observe + o.horizon > job.recording.duration())
    throw Error("observe + horizon (" + format_number(o.observe + o.horizon) + " s) exceed the recording " +
                trajectories_path + " (" + format_number(job.recording.duration()) + " s)");
  return job;
}

PredictJob parse_predict_job(const json& request) {
  JsonReader r(request, "");
  r.require_object();
  r.allow_only({"scenario", "trajectories", "models", "observe", "horizon", "stride", "windows", "threads", "desired_speed", "input"});
  const std::string scenario = r.string("scenario", std::nullopt);  // first: errors name the first key
  const std::string trajectories = r.string("trajectories", std::nullopt);
  PredictOptions o;
  o.observe = r.in_range("observe", 1e-3, 1e5, 2.0);
  o.horizon = r.in_range("horizon", 1e-3, 1e5, 4.0);
  o.stride = r.in_range("stride", 1e-3, 1e5, o.horizon);
  o.max_windows = r.integer("windows", 0, 1000000, 0);
  o.threads = r.integer("threads", 1, 256, 1);
  o.input = input_policy(r);
  std::vector<std::string> models;
  if (auto ms = r.get("models"))
    for (size_t i = 0; i < ms->size(); ++i) models.push_back(ms->item(i).as_string());
  const std::string speed_mode = r.one_of("desired_speed", {"observed", "scenario", "free"}, "observed");
  const DesiredSpeed ds = speed_mode == "observed" ? DesiredSpeed::Observed
                          : speed_mode == "scenario" ? DesiredSpeed::Scenario
                                                     : DesiredSpeed::Free;
  return make_predict_job(scenario, trajectories, models, o, ds);
}

std::vector<PredictionReport> run_prediction(const PredictJob& job) {
  Grid grid;
  grid.init(job.scenario.geo, job.scenario.cell_size);
  const WindowOptions wo{job.options.threads, job.desired_speed};
  const TrajectorySet* truth = job.interpolated_rows > 0 ? &job.filled : nullptr;
  std::vector<PredictionReport> reports = {
      evaluate_predictor("constant velocity", job.recording, job.options, constant_velocity_predictor(), &grid, truth)};
  for (const auto& m : job.models)
    reports.push_back(
        evaluate_predictor(model_label(m), job.recording, job.options, simulation_predictor(job.scenario, m, wo), &grid, truth));
  return reports;
}

json prediction_json(const PredictJob& job, const std::vector<PredictionReport>& reports) {
  json j = {{"scenario", job.scenario_path},
            {"trajectories", job.trajectories_path},
            {"observe_s", job.options.observe},
            {"horizon_s", job.options.horizon},
            {"stride_s", job.options.stride},
            {"desired_speed", desired_speed_name(job.desired_speed)},
            {"recording_frame_step", job.frame_step},
            {"interpolated_rows", job.interpolated_rows},
            {"units", "metres, m/s"},
            {"methods", json::array()}};
  for (const auto& r : reports) j["methods"].push_back(report_to_json(r));
  return j;
}

}  // namespace crowdmpm
