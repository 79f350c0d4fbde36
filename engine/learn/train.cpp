#include "engine/learn/train.hpp"

#include "engine/learn/losses.hpp"
#include "engine/learn/optim.hpp"

#include <algorithm>
#include <unordered_map>
#include <filesystem>
#include <cmath>
#include <limits>
#include <optional>

namespace crowdmpm {

std::vector<std::string> learnable_params(const Model& m) {
  std::vector<std::string> names;
  for (const auto& info : param_table())
    if (info.learnable_in(m)) names.push_back(info.name);
  return names;
}

Fitted Fitted::of(const Model& m, const std::vector<ScenarioDef>& scenarios) {
  Fitted f{m, {}};
  for (const auto& s : scenarios) f.terms.push_back(s.terms);
  return f;
}

namespace {
// Smallest value a log-coordinate parameter is clamped to.
double log_floor(const ParamInfo& p) { return std::max(p.lo, 1e-6); }
}  // namespace

ParamMap::ParamMap(const Fitted& f, std::vector<std::string> scalars, bool network, bool learn_scalars)
    : scalars_(std::move(scalars)) {
  const Model& m = f.model;
  if (m.material == MaterialKind::Elastic) throw Error("the elastic material is not learned");
  if (!learn_scalars && !scalars_.empty()) throw Error("parameters listed although no scalar parameter is to be learned");
  if (scalars_.empty() && learn_scalars) scalars_ = learnable_params(m);
  for (size_t i = 0; i < scalars_.size(); ++i) {
    const std::string& s = scalars_[i];
    const ParamInfo& info = param_info(s);  // throws for unknown names
    if (const std::string why = info.not_learnable_in(m); !why.empty()) {
      std::string known;
      for (const auto& n : learnable_params(m)) known += (known.empty() ? "" : ", ") + n;
      throw Error("parameter '" + s + "' cannot be learned: " + why + " (learnable: " + known + ")");
    }
    for (size_t j = 0; j < i; ++j)
      if (scalars_[j] == s) throw Error("parameter '" + s + "' is listed twice");
    info_.push_back(&info);
    log_.push_back(info.field != &MaterialParams::tension_scale);
    if (s == "E") e_index_ = static_cast<int>(i);
    if (s == "gamma") gamma_index_ = static_cast<int>(i);
  }
  if (e_index_ < 0 || gamma_index_ < 0) e_index_ = gamma_index_ = -1;
  if (network && m.has_traction()) network_size_ = m.traction.parameter_count();
  for (size_t d = 0; d < f.terms.size(); ++d)
    for (size_t t = 0; t < f.terms[d].size(); ++t)
      for (size_t k = 0; k < f.terms[d][t].learn.size(); ++k)
        if (f.terms[d][t].learn[k]) {
          if (!m.is_continuum())
            throw Error(f.terms[d][t].path + ".learn: force terms are learned with the crowd and fluid materials (their adjoint), not " +
                        material_name(m.material));
          terms_.push_back(TermSlot{d, t, k});
        }
}

std::vector<double> ParamMap::get(const Fitted& f) const {
  std::vector<double> u;
  for (size_t i = 0; i < scalars_.size(); ++i) {
    double p = f.model.params.*info_[i]->field;
    u.push_back(log_[i] ? std::log(std::max(p, log_floor(*info_[i]))) : p);
  }
  // E and gamma together: the first coordinate is log(E gamma), the stiffness at J = 1.
  if (e_index_ >= 0) u[static_cast<size_t>(e_index_)] += u[static_cast<size_t>(gamma_index_)];
  if (network_size_) {
    std::vector<double> th = f.model.traction.parameters();
    u.insert(u.end(), th.begin(), th.end());
  }
  for (const TermSlot& s : terms_) u.push_back(f.terms[s.dataset][s.term].params[s.param]);
  return u;
}

void ParamMap::set(Fitted& f, const std::vector<double>& u_in) const {
  if (u_in.size() != size()) throw Error("ParamMap::set: expected " + std::to_string(size()) + " values");
  Model& m = f.model;
  std::vector<double> u = u_in;
  auto bounded = [&](size_t i, double p) {
    const ParamInfo& info = *info_[i];
    double lo = log_[i] ? log_floor(info) : info.lo;
    // The pair traction needs comfort distances above the contact epsilon.
    if (info.field == &MaterialParams::comfort_distance) lo = std::max(lo, 2 * m.params.contact_epsilon);
    return std::clamp(p, lo, info.hi);
  };
  if (e_index_ >= 0) {
    // Gamma first (clamped), then E from the stiffness E gamma, so that a gamma held at a
    // bound does not change the stiffness.
    const double gamma = bounded(static_cast<size_t>(gamma_index_), std::exp(u[static_cast<size_t>(gamma_index_)]));
    u[static_cast<size_t>(gamma_index_)] = std::log(gamma);
    u[static_cast<size_t>(e_index_)] -= std::log(gamma);
  }
  for (size_t i = 0; i < scalars_.size(); ++i) m.set(scalars_[i], bounded(i, log_[i] ? std::exp(u[i]) : u[i]));
  const size_t net0 = scalars_.size(), term0 = net0 + network_size_;
  if (network_size_)
    m.traction.set_parameters(std::vector<double>(u.begin() + static_cast<long>(net0), u.begin() + static_cast<long>(term0)));
  for (size_t j = 0; j < terms_.size(); ++j) {
    const TermSlot& s = terms_[j];
    f.terms[s.dataset][s.term].set_clamped(s.param, u[term0 + j]);
  }
}

std::vector<double> ParamMap::gradient(const Fitted& f, const ModelGradient& g, size_t dataset) const {
  std::vector<double> d;
  for (size_t i = 0; i < scalars_.size(); ++i) {
    const double gi = g.params.*info_[i]->field;
    d.push_back(log_[i] ? gi * (f.model.params.*info_[i]->field) : gi);  // dL/dlog p = p dL/dp
  }
  // With u_E = log E + log gamma and u_g = log gamma: dL/du_E = dL/dlog E and
  // dL/du_g = dL/dlog gamma - dL/dlog E.
  if (e_index_ >= 0) d[static_cast<size_t>(gamma_index_)] -= d[static_cast<size_t>(e_index_)];
  if (network_size_) d.insert(d.end(), g.network.begin(), g.network.end());
  for (const TermSlot& s : terms_)
    d.push_back(s.dataset == dataset && s.term < g.terms.size() ? g.terms[s.term][s.param] : 0.0);
  return d;
}

std::vector<std::pair<size_t, std::string>> ParamMap::term_parameter_names(const Fitted& f) const {
  std::vector<std::pair<size_t, std::string>> out;
  for (const TermSlot& s : terms_) {
    const Term& t = f.terms[s.dataset][s.term];
    out.emplace_back(s.dataset, t.path + "." + t.parameter_names()[s.param]);
  }
  return out;
}

TrainWindow window_at(const TrajectorySet& t, long start, long length, const TrainOptions& o, size_t dataset,
                      std::shared_ptr<const SpeedHistory> history) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  TrainWindow w;
  w.dataset = dataset;
  w.start = observe_at(t, start, o.velocity_window, o.speed_window, std::move(history));
  if (w.start.ids.empty()) return w;
  w.framerate = t.framerate;
  std::vector<std::pair<long, size_t>> order;  // (recorded id, index in start)
  for (size_t k = 0; k < w.start.ids.size(); ++k) order.emplace_back(w.start.ids[k], k);
  std::sort(order.begin(), order.end());
  for (long k = 1; k <= length; ++k) {
    std::vector<Vec2> row(w.start.ids.size(), Vec2(nan, nan));
    auto [b, e] = t.frame(start + k);
    for (auto p = b; p != e; ++p) {
      auto it = std::lower_bound(order.begin(), order.end(), std::make_pair(p->id, size_t{0}));
      if (it != order.end() && it->first == p->id) row[it->second] = Vec2(p->x, p->y);
    }
    w.seen.push_back(std::move(row));
  }
  return w;
}

void make_windows(const std::vector<TrainDataset>& data, const TrainOptions& o, std::vector<TrainWindow>& train,
                  std::vector<TrainWindow>& validation) {
  if (!(o.validation_fraction > 0 && o.validation_fraction < 1))
    throw Error("validation fraction must be in (0, 1), got " + format_number(o.validation_fraction));
  if (!(o.window > 0 && o.stride > 0)) throw Error("window and stride must be > 0 s");
  train.clear();
  validation.clear();
  for (size_t d = 0; d < data.size(); ++d)
    for (const TrajectorySet& t : data[d].recordings) {
      const long history = std::lround(std::max(o.velocity_window, o.speed_window) * t.framerate);
      const long length = std::lround(o.window * t.framerate);
      if (length < 1)
        throw Error(t.source + ": a window of " + format_number(o.window) + " s is shorter than one frame (" +
                    format_number(1 / t.framerate) + " s)");
      const long stride = std::max(1L, std::lround(o.stride * t.framerate));
      std::vector<long> starts;
      for (long f = t.skip_gap(t.frame_min() + history, stride); f + length <= t.frame_max(); f = t.skip_gap(f + stride, stride))
        starts.push_back(f);
      const size_t n_val = static_cast<size_t>(std::ceil(o.validation_fraction * static_cast<double>(starts.size())));
      // Free speeds under a model's density-speed law read the whole recorded speed history.
      const auto speeds = speed_history_for(t, o.speed_window, o.desired_speed);
      const size_t n_train = starts.size() - std::min(starts.size(), n_val);
      const long val_start = n_train < starts.size() ? starts[n_train] : std::numeric_limits<long>::max();
      for (size_t i = 0; i < starts.size(); ++i) {
        const bool is_val = i >= n_train;
        if (!is_val && starts[i] + length > val_start) continue;
        TrainWindow w = window_at(t, starts[i], length, o, d, speeds);
        if (w.start.ids.empty()) continue;
        (is_val ? validation : train).push_back(std::move(w));
      }
    }
}

double window_loss(const ScenarioDef& windowed, const TrainWindow& tw, const Model& m, const TrainOptions& o,
                   ModelGradient* grad) {
  WindowSim ws = start_window(windowed, m, tw.start, WindowOptions{o.threads, o.desired_speed});
  Simulation& sim = *ws.sim;
  const size_t n = sim.world().size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (n == 0) return nan;
  // Targets in dense order (agents were added in observed order, none removed).
  TrajectoryTarget target;
  std::vector<size_t> frame_of;  // the window frame of each target step
  for (size_t k = 0; k < tw.frames(); ++k) {
    const int step = static_cast<int>(std::lround(static_cast<double>(k + 1) / tw.framerate / windowed.dt));
    if (step < 1 || (!target.steps.empty() && step <= target.steps.back())) continue;
    std::vector<Vec2> row(n, Vec2(nan, nan));
    if (tw.fields.empty())
      for (size_t i = 0; i < ws.ids.size(); ++i)
        if (ws.ids[i]) row[static_cast<size_t>(sim.world().index_of(ws.ids[i]))] = tw.seen[k][i];
    target.steps.push_back(step);
    target.targets.push_back(std::move(row));
    frame_of.push_back(k);
  }
  if (target.steps.empty() || (tw.fields.empty() && target.samples() == 0)) return nan;
  const int steps = target.steps.back();
  // Recorded positions at the window's start (dense order) and the recorded velocity at each
  // target step: the displacement since the step before (the start for the first), NaN where
  // either position is missing.
  std::vector<Vec2> start_x(n, Vec2(nan, nan));
  for (size_t i = 0; i < ws.ids.size(); ++i)
    if (ws.ids[i]) start_x[static_cast<size_t>(sim.world().index_of(ws.ids[i]))] = tw.start.x[i];
  const auto recorded_velocity = [&](size_t s) {
    std::vector<Vec2> vs(n, Vec2(nan, nan));
    const double gap = (target.steps[s] - (s > 0 ? target.steps[s - 1] : 0)) * windowed.dt;
    for (size_t p = 0; p < n; ++p) {
      const Vec2 before = s > 0 ? target.targets[s - 1][p] : start_x[p];
      if (target.targets[s][p].allFinite() && before.allFinite()) vs[p] = (target.targets[s][p] - before) / gap;
    }
    return vs;
  };
  // Per target step: the loss term at the state after it, and its gradient when asked for.
  std::function<double(size_t, const World&, std::vector<Vec2>*, std::vector<Vec2>*)> term;
  if (tw.fields.empty() && o.loss == TrainOptions::Loss::Trajectory) {
    const double weight = 1.0 / static_cast<double>(target.samples());
    // The macroscopic term: density and flow in the venue's measurement areas, averaged over the
    // window's samples and areas, times area_weight.
    std::vector<Shape> areas;
    std::vector<std::vector<Vec2>> seen_v;
    if (o.area_weight > 0)
      for (const MeasurementArea& a : windowed.areas) areas.push_back(a.shape);
    if (!areas.empty())
      for (size_t s = 0; s < target.steps.size(); ++s) seen_v.push_back(recorded_velocity(s));
    const double area_weight = areas.empty() ? 0.0 : o.area_weight / static_cast<double>(target.steps.size() * areas.size());
    term = [&, weight, areas = std::move(areas), seen_v = std::move(seen_v), area_weight](
               size_t s, const World& w, std::vector<Vec2>* dx, std::vector<Vec2>* dv) {
      double l = 0;
      trajectory_loss_at(w.x, target.targets[s], weight, l, dx);
      if (!areas.empty()) l += area_loss_at(areas, w.x, w.v, target.targets[s], seen_v[s], area_weight, dx, dv);
      return l;
    };
  } else {
    // The recorded velocity field at each target step: positions and one-frame velocities of
    // the people seen in both frames, transferred to the simulation's grid.
    // Or the observed fields themselves (video), used in place.
    std::vector<GridVelocityField> made;
    std::vector<const GridVelocityField*> fields;
    made.reserve(target.steps.size());  // pointers into it stay valid
    size_t used = 0;
    for (size_t s = 0; s < target.steps.size(); ++s) {
      if (!tw.fields.empty()) {
        fields.push_back(&tw.fields[frame_of[s]]);
        used += fields.back()->mask_sum() > 0 ? 1 : 0;
        continue;
      }
      const std::vector<Vec2> v = recorded_velocity(s);
      std::vector<Vec2> xs, vs;
      for (size_t p = 0; p < n; ++p)
        if (v[p].allFinite()) {
          xs.push_back(target.targets[s][p]);
          vs.push_back(v[p]);
        }
      made.push_back(grid_velocity_of(xs, vs, 1, sim.grid(), o.grid_min_mass));
      fields.push_back(&made.back());
      used += made.back().mask_sum() > 0 ? 1 : 0;
    }
    if (used == 0) return nan;
    const double mass = m.params.mass, weight = 1.0 / static_cast<double>(used);
    // Observed fields (video): nodes the particles left count as velocity 0, as Err_vel scores them.
    const double empty_mass = tw.fields.empty() ? 0.0 : o.grid_min_mass * mass;
    term = [&, made = std::move(made), fields = std::move(fields), mass, weight, empty_mass](
               size_t s, const World& w, std::vector<Vec2>* dx, std::vector<Vec2>* dv) {
      if (fields[s]->mask_sum() <= 0) return 0.0;
      std::vector<Vec2> gx, gv;
      if (dx) {
        gx.assign(w.size(), Vec2::Zero());
        gv.assign(w.size(), Vec2::Zero());
      }
      const double l = grid_velocity_loss(w.x, w.v, mass, sim.grid(), *fields[s], dx ? &gx : nullptr, dx ? &gv : nullptr, empty_mass);
      if (dx)
        for (size_t p = 0; p < w.size(); ++p) {
          (*dx)[p] += weight * gx[p];
          (*dv)[p] += weight * gv[p];
        }
      return weight * l;
    };
  }
  // People walking in across the view's edge (video): appended after each step, scored with the
  // others by the field loss; their entry state is data (no gradient flows to it).
  if (!tw.inflow.points.empty() && tw.fields.empty()) throw Error("an inflow needs a window of observed fields");
  InflowRun inflow(tw.inflow, o.desired_speed);
  double loss = 0;
  size_t next = 0;
  if (!grad) {
    for (int k = 1; k <= steps; ++k) {
      sim.step();
      inflow.after_step(sim);
      if (target.steps[next] == k) loss += term(next++, sim.world(), nullptr, nullptr);
    }
    return loss;
  }
  int every = o.checkpoint_every;
  if (every <= 0 && static_cast<double>(steps) * static_cast<double>(n) * static_cast<double>(WindowGradient().stored_bytes_per_agent_step()) > o.max_stored_bytes)
    every = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(steps))));
  std::function<void(Simulation&)> after_step;
  if (!tw.inflow.points.empty()) after_step = [&](Simulation& s) { inflow.after_step(s); };
  WindowGradient wg(every);
  *grad = wg.run(sim, steps, [&](int k, const World& w, std::vector<Vec2>& dx, std::vector<Vec2>& dv) {
    if (next >= target.steps.size() || target.steps[next] != k) return false;
    loss += term(next++, w, &dx, &dv);
    return true;
  }, after_step);
  return loss;
}

TrainResult train_model(const std::vector<TrainDataset>& data, const Model& start, const TrainOptions& o,
                        const TrainCallback& progress) {
  std::vector<TrainWindow> train, val;
  make_windows(data, o, train, val);
  std::vector<ScenarioDef> scenarios;
  for (const auto& d : data) scenarios.push_back(d.scenario);
  return train_on_windows(scenarios, train, val, start, o, progress);
}

namespace {
// Throws Error naming the first window that cannot be trained on.
void check_windows(size_t scenarios, const std::vector<TrainWindow>& train, const std::vector<TrainWindow>& val,
                   double window_seconds) {
  if (train.empty() || val.empty())
    throw Error("training needs recordings long enough for windows of " + format_number(window_seconds) +
                " s for both training and validation (got " + std::to_string(train.size()) + " training and " +
                std::to_string(val.size()) + " validation windows)");
  for (const auto* set : {&train, &val})
    for (size_t i = 0; i < set->size(); ++i) {
      const TrainWindow& w = (*set)[i];
      const std::string where = std::string(set == &train ? "training" : "validation") + " window " + std::to_string(i);
      if (w.dataset >= scenarios)
        throw Error(where + " names scenario " + std::to_string(w.dataset) + " of " + std::to_string(scenarios));
      const size_t n = w.start.ids.size();
      if (w.start.x.size() != n || w.start.v.size() != n || (!w.start.speed.empty() && w.start.speed.size() != n))
        throw Error(where + ": start state has " + std::to_string(n) + " ids but " + std::to_string(w.start.x.size()) +
                    " positions, " + std::to_string(w.start.v.size()) + " velocities and " + std::to_string(w.start.speed.size()) + " speeds");
      if (!(w.framerate > 0) || !std::isfinite(w.framerate)) throw Error(where + ": frame rate must be > 0, got " + format_number(w.framerate));
      if (w.frames() == 0) throw Error(where + " has no recorded frames");
      for (size_t k = 0; k < w.seen.size(); ++k)
        if (w.seen[k].size() != n)
          throw Error(where + ": frame " + std::to_string(k + 1) + " has " + std::to_string(w.seen[k].size()) + " positions for " + std::to_string(n) + " people");
    }
}

// Scores candidates on the windows: validation losses, and training losses with their gradients
// in the optimiser's coordinates. Windows are independent: with several threads each runs whole
// windows on one thread (simulation and backward pass), and their results are summed in window
// order, so training gives the same model for any thread count.
class WindowScorer {
 public:
  WindowScorer(const std::vector<ScenarioDef>& scenarios, const std::vector<TrainWindow>& train,
               const std::vector<TrainWindow>& val, const ParamMap& map, const TrainOptions& o)
      : scenarios_(scenarios), train_(train), val_(val), map_(map), one_(o), pool_(std::max(1, o.threads)) {
    for (const auto& s : scenarios) {
      windowed_.push_back(window_scenario(s, false));
      bool learns = false;
      for (const Term& t : s.terms) learns = learns || t.learned_count() > 0;
      learns_terms_.push_back(learns);
    }
    one_.threads = 1;
  }

  // Mean validation loss; infinite when the candidate breaks a simulation (not a candidate).
  double validation_loss(const Fitted& m) {
    std::vector<double> ls(val_.size(), nan());
    std::vector<char> broke(val_.size(), 0);
    pool_.parallel_for(val_.size(), [&](size_t b, size_t e) {
      for (size_t j = b; j < e; ++j) {
        try {
          ScenarioDef scratch;
          ls[j] = window_loss(venue(m, val_[j].dataset, scratch), val_[j], m.model, one_, nullptr);
        } catch (const UnstableError&) {
          broke[j] = 1;
        } catch (const Error& err) {
          throw Error(window_name(val_[j]) + ": " + err.what());
        }
      }
    }, 1);
    double sum = 0;
    long n = 0;
    for (size_t j = 0; j < val_.size(); ++j) {
      if (broke[j]) return std::numeric_limits<double>::infinity();
      if (std::isfinite(ls[j])) {
        sum += ls[j];
        ++n;
      }
    }
    return n ? sum / static_cast<double>(n) : nan();
  }

  // Mean loss of training windows idx and, when g is given, its gradient; NaN when none could
  // be scored. Windows whose simulation broke are counted in `skipped` and left out.
  double batch_loss(const Fitted& m, const std::vector<size_t>& idx, std::vector<double>* g, long& skipped,
                    int* n_used = nullptr) {
    std::vector<WindowResult> rs(idx.size());
    pool_.parallel_for(idx.size(), [&](size_t b, size_t e) {
      for (size_t j = b; j < e; ++j) rs[j] = one_window(m, train_[idx[j]], g != nullptr);
    }, 1);
    if (g) g->assign(map_.size(), 0.0);
    double loss_sum = 0;
    int used = 0;
    for (const WindowResult& r : rs) {
      if (r.failed) {
        ++skipped;
        continue;
      }
      if (!std::isfinite(r.loss)) continue;
      if (g)
        for (size_t k = 0; k < r.grad.size(); ++k) (*g)[k] += r.grad[k];
      loss_sum += r.loss;
      ++used;
    }
    if (n_used) *n_used = used;
    if (used == 0) return nan();
    if (g)
      for (double& x : *g) x /= used;
    return loss_sum / used;
  }

 private:
  // One window's loss and, when asked, its gradient; NaN loss when nobody can be compared,
  // `failed` when its simulation became unstable.
  struct WindowResult {
    double loss = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> grad;
    bool failed = false;
  };
  static double nan() { return std::numeric_limits<double>::quiet_NaN(); }

  // A window's venue with the force terms being fitted; the windowed scenario itself (no copy)
  // when none of its terms is learned.
  const ScenarioDef& venue(const Fitted& f, size_t d, ScenarioDef& scratch) const {
    if (!learns_terms_[d]) return windowed_[d];
    scratch = windowed_[d];
    scratch.terms = f.terms[d];
    return scratch;
  }
  std::string window_name(const TrainWindow& w) const {
    return "window at frame " + std::to_string(w.start.frame) + " of dataset " + std::to_string(w.dataset) + " (" +
           scenarios_[w.dataset].source + ")";
  }

  WindowResult one_window(const Fitted& m, const TrainWindow& w, bool want_grad) const {
    WindowResult r;
    try {
      ModelGradient mg;
      ScenarioDef scratch;
      const ScenarioDef& sc = venue(m, w.dataset, scratch);
      r.loss = window_loss(sc, w, m.model, one_, want_grad && m.model.is_continuum() ? &mg : nullptr);
      if (want_grad && std::isfinite(r.loss)) {
        r.grad = m.model.is_continuum() ? map_.gradient(m, mg, w.dataset) : central_differences(m, sc, w);
        for (double x : r.grad) r.failed = r.failed || !std::isfinite(x);
      }
    } catch (const UnstableError&) {
      r.failed = true;  // these parameters break this window's simulation: left out of this step
    } catch (const Error& e) {
      throw Error(window_name(w) + ": " + e.what());
    }
    return r;
  }

  // The social force model has no adjoint here: central differences in the optimiser's
  // coordinates (a few scalars; each costs two forward runs).
  std::vector<double> central_differences(const Fitted& m, const ScenarioDef& sc, const TrainWindow& w) const {
    std::vector<double> grad;
    const std::vector<double> u0 = map_.get(m);
    const double h = 3e-3;
    for (size_t k = 0; k < u0.size(); ++k) {
      double side[2];
      for (int sgn = 0; sgn < 2; ++sgn) {
        std::vector<double> uk = u0;
        uk[k] += sgn ? -h : h;
        Fitted mk = m;
        map_.set(mk, uk);
        side[sgn] = window_loss(sc, w, mk.model, one_, nullptr);
      }
      grad.push_back((side[0] - side[1]) / (2 * h));
    }
    return grad;
  }

  const std::vector<ScenarioDef>& scenarios_;
  std::vector<ScenarioDef> windowed_;
  std::vector<char> learns_terms_;  // per venue: has terms marked "learn"
  const std::vector<TrainWindow>& train_;
  const std::vector<TrainWindow>& val_;
  const ParamMap& map_;
  TrainOptions one_;  // one thread per window
  ThreadPool pool_;
};

// The optimisation state of one training run: the candidate, its coordinates, and the best
// candidate so far.
struct Search {
  Fitted model, best;
  std::vector<double> u;
};

// One Adam step on the next `batch` windows of full passes in a seeded random order.
class AdamSearch {
 public:
  AdamSearch(const TrainOptions& o, size_t parameters, size_t windows)
      : o_(o), lr_(o.learning_rate), adam_(parameters, o.learning_rate), rng_(o.seed), order_(windows), cursor_(windows) {
    adam_.set_clip_norm(o.clip_norm);
  }
  void step(Search& s, const ParamMap& map, WindowScorer& scorer, TrainProgress& pr, long& skipped) {
    std::vector<size_t> idx;
    for (int b = 0; b < o_.batch && b < static_cast<int>(order_.size()); ++b) {
      if (cursor_ == order_.size()) {
        for (size_t i = 0; i < order_.size(); ++i) order_[i] = i;
        for (size_t i = order_.size(); i > 1; --i) std::swap(order_[i - 1], order_[static_cast<size_t>(rng_.next() % i)]);
        cursor_ = 0;
      }
      idx.push_back(order_[cursor_++]);
    }
    std::vector<double> g;
    pr.train_loss = scorer.batch_loss(s.model, idx, &g, skipped);
    if (std::isfinite(pr.train_loss)) {
      pr.grad_norm = adam_.step(s.u, g);
      map.set(s.model, s.u);
      s.u = map.get(s.model);  // clamped values back into the optimiser's coordinates
    } else {
      // Every window of the batch failed with these parameters (an unstable simulation): back
      // to the best model so far, with smaller steps.
      back_to_best(s, map, o_.lr_decay < 1 ? o_.lr_decay : 0.5);
    }
  }
  // No improvement at a validation pass: back to the best point with smaller steps.
  void no_improvement(Search& s, const ParamMap& map) {
    if (o_.lr_decay < 1) back_to_best(s, map, o_.lr_decay);
  }

 private:
  void back_to_best(Search& s, const ParamMap& map, double factor) {
    lr_ *= factor;
    adam_.set_learning_rate(lr_);
    s.model = s.best;
    s.u = map.get(s.model);
  }
  const TrainOptions& o_;
  double lr_;
  Adam adam_;
  Rng rng_;
  std::vector<size_t> order_;
  size_t cursor_;
};

// L-BFGS on the full batch with a backtracking (Armijo) line search.
class LbfgsSearch {
 public:
  LbfgsSearch(Search& s, size_t windows, WindowScorer& scorer, long& skipped) : all_(windows) {
    for (size_t i = 0; i < all_.size(); ++i) all_[i] = i;
    f_ = scorer.batch_loss(s.model, all_, &g_, skipped, &used_);
  }
  // Returns true when the search has nothing left to gain (two failed line searches in a row
  // from the gradient itself).
  bool step(Search& s, const ParamMap& map, WindowScorer& scorer, TrainProgress& pr, long& skipped) {
    if (!std::isfinite(f_)) throw Error("training: no training window could be simulated with the starting model");
    std::vector<double> d = lbfgs_.direction(g_);
    double slope = 0, gnorm = 0;
    for (size_t k = 0; k < d.size(); ++k) {
      slope += d[k] * g_[k];
      gnorm += g_[k] * g_[k];
    }
    pr.grad_norm = std::sqrt(gnorm);
    if (!(slope < 0)) {  // not a descent direction: restart from the gradient
      lbfgs_.reset();
      d = lbfgs_.direction(g_);
      slope = -gnorm;
    }
    // The first step is at most 0.1 in the optimiser's coordinates (10% of a positive scalar).
    double step_len = 0;
    for (double x : d) step_len += x * x;
    double alpha = lbfgs_.empty() ? std::min(1.0, 0.1 / std::sqrt(step_len)) : 1.0;
    bool accepted = false;
    int tries = 0;
    for (; tries < 30 && !accepted; ++tries) {
      if (tries > 0) alpha *= 0.5;
      std::vector<double> u_try = s.u;
      for (size_t k = 0; k < s.u.size(); ++k) u_try[k] += alpha * d[k];
      Fitted trial = s.model;
      map.set(trial, u_try);
      u_try = map.get(trial);
      std::vector<double> g_try;
      int used_try = 0;
      const double f_try = scorer.batch_loss(trial, all_, &g_try, skipped, &used_try);
      // A trial that breaks windows the reference simulated is not comparable: rejected.
      if (std::isfinite(f_try) && used_try >= used_ && f_try <= f_ + 1e-4 * alpha * slope) {
        std::vector<double> sv(s.u.size()), y(s.u.size());
        for (size_t k = 0; k < s.u.size(); ++k) {
          sv[k] = u_try[k] - s.u[k];
          y[k] = g_try[k] - g_[k];
        }
        lbfgs_.update(sv, y);
        s.u = u_try;
        s.model = trial;
        f_ = f_try;
        g_ = g_try;
        used_ = used_try;
        accepted = true;
      }
    }
    pr.train_loss = f_;
    // A failed line search, or one that had to halve the step ten times, means the curvature
    // pairs no longer describe the loss here (it is only piecewise smooth: contacts begin and
    // end): forget them and go on from the gradient. Two failures in a row at the same point
    // from the gradient itself: nothing left to gain, stop.
    bool done = false;
    if (!accepted && lbfgs_.empty()) {
      done = ++failed_searches_ >= 2;
    } else {
      failed_searches_ = 0;
    }
    if (!accepted || tries > 10) lbfgs_.reset();
    return done;
  }

 private:
  std::vector<size_t> all_;
  Lbfgs lbfgs_;
  std::vector<double> g_;
  double f_ = 0;
  int used_ = 0, failed_searches_ = 0;
};
}  // namespace

TrainResult train_on_windows(const std::vector<ScenarioDef>& scenarios, const std::vector<TrainWindow>& train,
                             const std::vector<TrainWindow>& val, const Model& start, const TrainOptions& o,
                             const TrainCallback& progress) {
  if (start.material == MaterialKind::Elastic) throw Error("training covers the crowd, fluid and social_force models, not elastic");
  check_windows(scenarios.size(), train, val, o.window);
  TrainResult res;
  res.train_windows = train.size();
  res.validation_windows = val.size();
  Search s{Fitted::of(start, scenarios), {}, {}};
  const ParamMap map(s.model, o.params, o.learn_network, o.learn_scalars);
  if (map.size() == 0) throw Error("training: nothing to learn (no scalar parameter, no network, no force term marked \"learn\")");
  s.u = map.get(s.model);
  map.set(s.model, s.u);  // clamp the start into bounds the way every later step is
  WindowScorer scorer(scenarios, train, val, map, o);

  res.initial_validation = res.best_validation = scorer.validation_loss(s.model);
  if (!std::isfinite(res.initial_validation))
    throw Error("training: the starting model cannot be scored on the validation windows (loss " +
                format_number(res.initial_validation) + "): no person could be compared, or its simulations fail");
  s.best = s.model;
  const bool adam = o.optimizer == TrainOptions::Optimizer::Adam;
  AdamSearch adam_search(o, s.u.size(), train.size());
  std::optional<LbfgsSearch> lbfgs_search;
  if (!adam) lbfgs_search.emplace(s, train.size(), scorer, res.skipped_windows);
  int since_best = 0;
  for (int it = 1; it <= o.iterations; ++it) {
    TrainProgress pr;
    pr.iteration = it;
    pr.validation_loss = std::numeric_limits<double>::quiet_NaN();
    if (adam) adam_search.step(s, map, scorer, pr, res.skipped_windows);
    else res.early_stopped = lbfgs_search->step(s, map, scorer, pr, res.skipped_windows);
    res.iterations = it;
    // Validation, keeping the best candidate; early stopping after `patience` passes without improvement.
    if (it % o.eval_every == 0 || it == o.iterations) {
      pr.validation_loss = scorer.validation_loss(s.model);
      if (pr.validation_loss < res.best_validation) {
        res.best_validation = pr.validation_loss;
        res.best_iteration = it;
        s.best = s.model;
        pr.improved = true;
        since_best = 0;
      } else if (++since_best >= o.patience) {
        res.early_stopped = true;
      } else if (adam) {
        adam_search.no_improvement(s, map);
      }
    }
    res.history.push_back(pr);
    if (progress) progress(pr);
    if (res.early_stopped) break;
  }
  res.model = s.best.model;
  res.terms = s.best.terms;
  return res;
}

std::string loss_name(const TrainOptions& o) {
  if (o.loss == TrainOptions::Loss::GridVelocity) return "grid velocity";
  return o.area_weight > 0 ? "trajectory + " + format_number(o.area_weight) + " x area" : "trajectory";
}

const char* loss_unit(const TrainOptions& o) { return o.loss == TrainOptions::Loss::GridVelocity ? "(m/s)2" : "m2"; }

void parse_train_options(const JsonReader& op, TrainOptions& o) {
  op.require_object();
  op.allow_only({"window", "stride", "iterations", "batch", "learning_rate", "clip", "validation", "eval_every",
                  "patience", "seed", "threads", "params", "learn_network", "loss", "desired_speed", "area_weight"});
  o.window = op.in_range("window", 1e-3, 1e4, o.window);
  o.stride = op.in_range("stride", 1e-3, 1e4, o.stride);
  o.area_weight = op.in_range("area_weight", 0, 1e6, o.area_weight);
  o.iterations = op.integer("iterations", 1, 1000000, o.iterations);
  o.batch = op.integer("batch", 1, 10000, o.batch);
  o.learning_rate = op.in_range("learning_rate", 1e-9, 10, o.learning_rate);
  o.clip_norm = op.in_range("clip", 0, 1e12, o.clip_norm);
  o.validation_fraction = op.in_range("validation", 0.01, 0.9, o.validation_fraction);
  o.eval_every = op.integer("eval_every", 1, 1000000, o.eval_every);
  o.patience = op.integer("patience", 1, 1000000, o.patience);
  o.seed = static_cast<uint64_t>(op.integer("seed", 0, 2000000000, static_cast<long>(o.seed)));
  o.threads = op.integer("threads", 1, 256, o.threads);
  o.learn_network = op.boolean("learn_network", o.learn_network);
  o.loss = op.one_of("loss", {"trajectory", "grid_velocity"}, "trajectory") == "trajectory" ? TrainOptions::Loss::Trajectory
                                                                                              : TrainOptions::Loss::GridVelocity;
  if (o.area_weight > 0 && o.loss != TrainOptions::Loss::Trajectory)
    throw Error(op.path() + ".area_weight: the area loss is a term of the trajectory loss; \"loss\" is \"grid_velocity\"");
  const std::string speed_mode = op.one_of("desired_speed", {"observed", "scenario", "free"}, "observed");
  o.desired_speed = speed_mode == "observed" ? DesiredSpeed::Observed : speed_mode == "scenario" ? DesiredSpeed::Scenario : DesiredSpeed::Free;
  if (auto ps = op.get("params")) {
    // [] learns no scalar parameter: only the network and the force terms marked "learn".
    for (size_t i = 0; i < ps->size(); ++i) o.params.push_back(ps->item(i).as_string());
    o.learn_scalars = !o.params.empty();
  }
}

TrainJob parse_train_job(const json& request, const std::string& base_dir) {
  JsonReader r(request, "");
  r.require_object();
  r.allow_only({"datasets", "model", "material", "options", "input"});
  TrainJob job;
  job.input = input_policy(r);
  JsonReader ds = r.at("datasets");
  if (ds.size() == 0) ds.fail("needs at least one {\"scenario\", \"trajectories\"} entry");
  for (size_t i = 0; i < ds.size(); ++i) {
    JsonReader d = ds.item(i);
    d.require_object();
    d.allow_only({"scenario", "trajectories"});
    TrainDataset set{ScenarioDef::load(resolve_path(base_dir, d.string("scenario", std::nullopt)), job.input), {}};
    JsonReader ts = d.at("trajectories");
    if (ts.size() == 0) ts.fail("needs at least one trajectory file");
    for (size_t k = 0; k < ts.size(); ++k) {
      const std::string f = resolve_path(base_dir, ts.item(k).as_string());
      set.recordings.push_back(TrajectorySet::read(f, 0, job.input));
      check_recording_scale(set.recordings.back(), set.scenario.geo, set.scenario.source);
      job.files.push_back(f);
    }
    job.data.push_back(std::move(set));
  }
  if (r.has("model") && r.has("material")) r.fail("give \"model\" or \"material\", not both");
  if (r.has("model")) job.start = Model::load(resolve_path(base_dir, r.string("model", std::nullopt)), job.input);
  else if (r.has("material"))
    job.start = Model::default_of(r.one_of("material", {"crowd", "fluid", "social_force"}, std::nullopt));
  else job.start = job.data[0].scenario.model_or_default();
  TrainOptions& o = job.options;
  if (auto op = r.get("options")) parse_train_options(*op, o);
  std::vector<ScenarioDef> venues;
  for (const auto& d : job.data) venues.push_back(d.scenario);
  const ParamMap check(Fitted::of(job.start, venues), o.params, o.learn_network, o.learn_scalars);  // unknown or unlearnable names fail here
  if (check.size() == 0) r.fail("nothing to learn: no scalar parameter, no network and no force term marked \"learn\"");
  return job;
}

Model describe_learned(const TrainJob& job, const TrainResult& r) {
  Model m = r.model;
  m.name = std::string("learned ") + material_name(m.material);
  std::string from;
  for (const auto& f : job.files) {
    const size_t slash = f.find_last_of('/');
    from += (from.empty() ? "" : ", ") + (slash == std::string::npos ? f : f.substr(slash + 1));
  }
  m.description = "Learned by crowdmpm train from " + from + " (" + std::to_string(r.train_windows) + " training, " +
                  std::to_string(r.validation_windows) + " validation windows of " + format_number(job.options.window) +
                  " s); validation " + loss_name(job.options) + " loss " +
                  format_number(r.initial_validation) + " " + loss_unit(job.options) + " at the start, " +
                  format_number(r.best_validation) + " at iteration " + std::to_string(r.best_iteration) + " of " +
                  std::to_string(r.iterations) + ".";
  return m;
}

std::vector<std::string> write_fitted_scenarios(const TrainJob& job, const TrainResult& r, const std::string& model_path) {
  namespace fs = std::filesystem;
  std::vector<std::string> written;
  for (size_t d = 0; d < job.data.size() && d < r.terms.size(); ++d) {
    const ScenarioDef& sc = job.data[d].scenario;
    bool learned = false;
    for (const Term& t : sc.terms) learned = learned || t.learned_count() > 0;
    if (!learned) continue;
    // Self-contained: the "extends" chain applied and the scenario's model written inline, so the
    // file loads from wherever it is written (paths inside a scenario stay in its folder).
    json j = ScenarioDef::load_json(sc.source, job.input);
    if (sc.model) j["model"] = sc.model->to_json();
    json forces = json::array();
    for (const Term& t : r.terms[d]) forces.push_back(t.to_json());
    j["forces"] = forces;
    const fs::path out = fs::path(model_path).parent_path() /
                         (fs::path(model_path).stem().string() + "." + fs::path(sc.source).stem().string() + ".json");
    save_json_file(j, out.string());
    written.push_back(out.string());
  }
  return written;
}

void save_model(const Model& m, const std::string& path) { save_json_file(m.to_json(), path); }

}  // namespace crowdmpm
