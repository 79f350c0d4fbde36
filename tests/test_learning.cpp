// Learning: the losses and their gradients, recovery of known material parameters from
// trajectories the engine generated, and learning from real recordings (held-out runs).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <functional>

#include "engine/learn/losses.hpp"
#include "engine/learn/train.hpp"
#include "engine/predict/predict.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
double rel_err(double a, double b, double floor = 1e-6) { return std::abs(a - b) / std::max({std::abs(a), std::abs(b), floor}); }

// The worst error of a loss's gradient (dx, dv) against central differences of loss(x, v) in
// every coordinate, relative to the larger of the two or `floor`.
double worst_gradient_error(const std::function<double(const std::vector<Vec2>&, const std::vector<Vec2>&)>& loss,
                            const std::vector<Vec2>& x, const std::vector<Vec2>& v, const std::vector<Vec2>& dx,
                            const std::vector<Vec2>& dv, double h, double floor = 1e-6) {
  double worst = 0;
  for (size_t p = 0; p < x.size(); ++p)
    for (int a = 0; a < 2; ++a) {
      auto xp = x, xm = x, vp = v, vm = v;
      xp[p][a] += h;
      xm[p][a] -= h;
      vp[p][a] += h;
      vm[p][a] -= h;
      const double fdx = (loss(xp, v) - loss(xm, v)) / (2 * h), fdv = (loss(x, vp) - loss(x, vm)) / (2 * h);
      worst = std::max({worst, rel_err(dx[p][a], fdx, floor), rel_err(dv[p][a], fdv, floor)});
    }
  return worst;
}
}  // namespace

TEST_CASE("trajectory loss skips masked samples and its gradient is exact", "[learning]") {
  const double nan = std::nan("");
  std::vector<Vec2> x = {Vec2(1, 2), Vec2(3, 4), Vec2(0, 0)};
  std::vector<Vec2> target = {Vec2(1.5, 2), Vec2(nan, nan), Vec2(0, -1)};
  TrajectoryTarget t{{5}, {target}};
  CHECK(t.samples() == 2);
  double loss = 0;
  std::vector<Vec2> g(3, Vec2::Zero());
  trajectory_loss_at(x, target, 0.5, loss, &g);
  CHECK(loss == Approx(0.5 * (0.25 + 1.0)));
  CHECK(g[0].x() == Approx(2 * 0.5 * -0.5));
  CHECK(g[1].norm() == 0);  // masked: no pull towards a missing recording
  CHECK(g[2].y() == Approx(2 * 0.5 * 1.0));
  std::vector<Vec2> wrong(2);
  CHECK_THROWS_WITH(trajectory_loss_at(x, wrong, 1, loss, nullptr), Catch::Contains("3 positions against 2 targets"));
}

TEST_CASE("grid velocity loss: gradient with respect to positions and velocities matches differences", "[learning]") {
  const Grid g = test::box_grid(4, 3, 0.5);
  Rng rng(3);
  std::vector<Vec2> x, v;
  for (int i = 0; i < 25; ++i) {
    x.emplace_back(0.5 + 3 * rng.uniform(), 0.5 + 2 * rng.uniform());
    v.emplace_back(rng.uniform() - 0.5, rng.uniform() - 0.5);
  }
  // Observed: a shear flow on the nodes the particles cover, with a mask that leaves some out.
  GridVelocityField obs = grid_velocity_of(x, v, 1, g, 0.2);
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const size_t n = static_cast<size_t>(g.node(i, j));
      obs.velocity[n] = Vec2(0.3 * j * g.dx, -0.1);
      if ((i + j) % 5 == 0) obs.mask[n] = 0;
    }
  REQUIRE(obs.mask_sum() > 5);
  // The loss and the worst relative error of its gradient against central differences.
  auto check_gradient = [&](double empty_mass, double& worst) {
    std::vector<Vec2> dx(x.size(), Vec2::Zero()), dv(x.size(), Vec2::Zero());
    const double L = grid_velocity_loss(x, v, 1, g, obs, &dx, &dv, empty_mass);
    auto loss = [&](const std::vector<Vec2>& xs, const std::vector<Vec2>& vs) {
      return grid_velocity_loss(xs, vs, 1, g, obs, nullptr, nullptr, empty_mass);
    };
    worst = worst_gradient_error(loss, x, v, dx, dv, 1e-6);
    return L;
  };
  double worst = 0;
  const double L = check_gradient(0, worst);
  REQUIRE(L > 0);
  std::printf("grid velocity loss %.4f, worst relative gradient error %.2e\n", L, worst);
  CHECK(worst < 1e-5);
  // The variant that scores nodes the particles left as velocity 0 (video learning): exact
  // gradients too, away from the kink at M = empty_mass; a node with no mass costs |u|^2.
  const double m0 = 0.35;
  double worst0 = 0;
  const double L0 = check_gradient(m0, worst0);
  REQUIRE(L0 > 0);
  std::printf("grid velocity loss with empty nodes %.4f, worst relative gradient error %.2e\n", L0, worst0);
  CHECK(worst0 < 1e-5);
  GridVelocityField far = obs;
  std::fill(far.mask.begin(), far.mask.end(), 0.0);
  far.mask[static_cast<size_t>(g.node(g.nx - 1, g.ny - 1))] = 1;  // a corner no particle reaches
  far.velocity[static_cast<size_t>(g.node(g.nx - 1, g.ny - 1))] = Vec2(0.6, 0.8);
  CHECK(grid_velocity_loss(x, v, 1, g, far, nullptr, nullptr, m0) == Approx(1.0));
  CHECK(grid_velocity_loss(x, v, 1, g, far, nullptr, nullptr) == 0);
  // The particles' own field has zero loss; a field on another grid is an error naming both.
  CHECK(grid_velocity_loss(x, v, 1, g, grid_velocity_of(x, v, 1, g, 0.2), nullptr, nullptr) == Approx(0).margin(1e-20));
  GridVelocityField other = obs;
  other.nx += 1;
  CHECK_THROWS_WITH(grid_velocity_loss(x, v, 1, g, other, nullptr, nullptr), Catch::Contains("differs from the simulation"));
}

namespace {
const char* kRecoveryScene = R"({"format": "crowdmpm-scenario", "version": 1, "name": "recovery room",
  "domain": {"min": [0, 0], "max": [9, 6], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 10},
  "geometry": {"walls": [{"points": [[6, 0], [6, 2.4]], "thickness": 0.2}, {"points": [[6, 3.6], [6, 6]], "thickness": 0.2}],
               "obstacles": [{"circle": {"center": [4.6, 3.0], "radius": 0.35}}],
               "exits": [{"id": "out", "rect": [8.6, 0, 9, 6]}]},
  "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "desired_speed": 1.2,
              "behaviour": {"type": "goal", "target": "out"}}]})";

// A crowd of about 5 persons/m^2 rushing at the wall with the door (2-2.8 m/s), with random
// velocities and walking speeds: within a second it is compressed hard against the wall (J down
// to 0.5, so that the stress law's stiffness E and exponent gamma are told apart, not only
// their product, the stiffness at J = 1) and spreads out behind (J up to 2: the tension scale).
// Windows are short (1 s): over longer ones contacts that begin and end make the loss rough
// and the fit stalls (seen with 2-2.5 s windows: E and gamma stuck 20-35% off).
ObservedState random_crowd(Rng& rng, const Geometry& geo) {
  ObservedState s;
  long id = 1;
  for (double y = 0.45; y < 5.6; y += 0.45)
    for (double x = 3.45; x < 5.9; x += 0.45) {
      Vec2 p(x + 0.12 * (rng.uniform() - 0.5), y + 0.12 * (rng.uniform() - 0.5));
      if (geo.sdf(p) < 0.2) continue;
      s.ids.push_back(id++);
      s.x.push_back(p);
      s.v.emplace_back(2.0 + 0.8 * rng.uniform(), 0.6 * (rng.uniform() - 0.5));
      s.speed.push_back(2.2 + 0.6 * rng.uniform());
    }
  return s;
}

// Windows of `seconds` recorded at 20 frames/s from a model.
std::vector<TrainWindow> synthetic_windows(const ScenarioDef& s, const Model& truth, int count, double seconds, uint64_t seed) {
  const ScenarioDef windowed = window_scenario(s, false);
  Rng rng(seed);
  std::vector<TrainWindow> out;
  for (int n = 0; n < count; ++n) {
    TrainWindow w;
    w.start = random_crowd(rng, s.geo);
    w.framerate = 20;
    WindowSim ws = start_window(windowed, truth, w.start, WindowOptions{1, DesiredSpeed::Observed});
    const int per_frame = static_cast<int>(std::lround(1.0 / (w.framerate * s.dt)));
    double jmin = 1, jmax = 1;
    for (int k = 0; k < static_cast<int>(seconds * w.framerate); ++k) {
      ws.sim->run_steps(per_frame);
      for (double J : ws.sim->world().J) {
        jmin = std::min(jmin, J);
        jmax = std::max(jmax, J);
      }
      std::vector<Vec2> row;
      for (EntityId id : ws.ids) row.push_back(ws.sim->world().x[static_cast<size_t>(ws.sim->world().index_of(id))]);
      w.seen.push_back(row);
    }
    std::printf("synthetic window %d: %zu agents, J in [%.2f, %.2f]\n", n, w.start.ids.size(), jmin, jmax);
    out.push_back(std::move(w));
  }
  return out;
}
}  // namespace

TEST_CASE("area loss: density and flow in measurement areas, gradient matches differences", "[learning]") {
  // A training request may not ask for it with the grid velocity loss.
  TrainOptions bad;
  const json req = json::parse(R"({"loss": "grid_velocity", "area_weight": 1})");
  CHECK_THROWS_WITH(parse_train_options(JsonReader(req, "options"), bad), Catch::Contains("options.area_weight: the area loss is a term of the trajectory loss"));
  const double nan = std::nan("");
  Rng rng(5);
  std::vector<Vec2> x, v, seen_x, seen_v;
  for (int i = 0; i < 30; ++i) {
    x.emplace_back(4 * rng.uniform(), 3 * rng.uniform());
    v.emplace_back(rng.uniform() - 0.5, 1.2 * rng.uniform());
    seen_x.emplace_back(x.back() + Vec2(0.3 * (rng.uniform() - 0.5), 0.3 * (rng.uniform() - 0.5)));
    seen_v.emplace_back(v.back() + Vec2(0.2, -0.1));
  }
  seen_x[3] = Vec2(nan, nan);  // not recorded at this frame: counts on neither side
  seen_v[3] = Vec2(nan, nan);
  seen_v[7] = Vec2(nan, nan);  // no recorded velocity: counts in the densities only
  // A rectangle, a triangle and a circle, overlapping the people's edges (soft indicator).
  const std::vector<Shape> areas = {Shape::rect(Vec2(0.5, 0.5), Vec2(2.5, 2)),
                                    Shape::polygon({Vec2(1.5, 0.2), Vec2(3.8, 0.4), Vec2(2.8, 2.8)}), Shape::circle(Vec2(1, 2), 0.8)};
  std::vector<Vec2> dx(x.size(), Vec2::Zero()), dv(x.size(), Vec2::Zero());
  const double w = 0.7;
  const double L = area_loss_at(areas, x, v, seen_x, seen_v, w, &dx, &dv);
  REQUIRE(L > 0);
  auto loss = [&](const std::vector<Vec2>& xs, const std::vector<Vec2>& vs) {
    return area_loss_at(areas, xs, vs, seen_x, seen_v, w, nullptr, nullptr);
  };
  const double worst = worst_gradient_error(loss, x, v, dx, dv, 1e-5, 1e-3);
  std::printf("area loss %.4f, worst relative gradient error %.2e\n", L, worst);
  CHECK(worst < 1e-5);
  CHECK(dx[3].norm() == 0);  // not recorded: no pull
  CHECK(dv[3].norm() == 0);
  CHECK(dv[7].norm() == 0);
  CHECK(dx[7].norm() > 0);
  // The recorded state itself has zero loss; a far-away crowd has the squared recorded measures.
  CHECK(area_loss_at(areas, seen_x, seen_v, seen_x, seen_v, 1, nullptr, nullptr) == Approx(0).margin(1e-24));
  const std::vector<Shape> one = {Shape::rect(Vec2(0, 0), Vec2(2, 1))};
  const std::vector<Vec2> at = {Vec2(1, 0.5)}, moving = {Vec2(1.0, 0)}, away = {Vec2(50, 50)};
  // One person deep inside a 2 m^2 area walking 1 m/s: density 0.5, flow 0.5 (chi = 1 - 7e-3).
  CHECK(area_loss_at(one, away, moving, at, moving, 1, nullptr, nullptr) == Approx(0.5).epsilon(0.02));
  CHECK_THROWS_WITH(area_loss_at(one, at, moving, at, {}, 1, nullptr, nullptr), Catch::Contains("1 positions, 1 velocities against 1 recorded positions and 0"));
}

TEST_CASE("a window's loss with the area term: its gradient matches differences", "[learning]") {
  // The recovery room's crowd, recorded from a model with another tau and stiffness; the window's
  // loss (positions plus density and flow in two measurement areas) differentiated against
  // central differences of tau, E and v0_scale.
  ScenarioDef s = ScenarioDef::parse_text(kRecoveryScene);
  s.areas.push_back(MeasurementArea{"front", Shape::rect(Vec2(4.5, 1), Vec2(6, 5)), 0, 1e300});
  s.areas.push_back(MeasurementArea{"door", Shape::rect(Vec2(5.6, 2.2), Vec2(7, 3.8)), 0, 1e300});
  Model truth = Model::default_of("crowd"), start = truth;
  truth.set("tau", 0.3);
  truth.set("E", 30);
  auto windows = synthetic_windows(s, truth, 1, 0.5, 11);
  const ScenarioDef windowed = window_scenario(s, false);
  TrainOptions o, positions;
  o.area_weight = 2;
  ModelGradient g, g_pos;
  const double L = window_loss(windowed, windows[0], start, o, &g);
  const double L_pos = window_loss(windowed, windows[0], start, positions, &g_pos);
  REQUIRE(L > L_pos);  // the area term is there
  std::printf("window loss %.5f (positions %.5f)\n", L, L_pos);
  // The whole loss, and the area term alone (the difference of the two runs), against central
  // differences: a wrong area gradient cannot hide behind the position term's. Errors are taken
  // relative to the largest derivative (dL/dE is 3000 times smaller than dL/dtau here, and its
  // differences carry the round-off and kinks of the contacts).
  double worst = 0, worst_area = 0, scale = 0, scale_area = 0;
  for (const std::string name : {"tau", "E", "v0_scale"}) {
    const double h = 1e-5 * start.get(name);
    Model mp = start, mm = start;
    mp.set(name, start.get(name) + h);
    mm.set(name, start.get(name) - h);
    const double fd = (window_loss(windowed, windows[0], mp, o, nullptr) - window_loss(windowed, windows[0], mm, o, nullptr)) / (2 * h);
    const double fd_pos =
        (window_loss(windowed, windows[0], mp, positions, nullptr) - window_loss(windowed, windows[0], mm, positions, nullptr)) / (2 * h);
    const double analytic = g.params.*param_info(name).field, analytic_pos = g_pos.params.*param_info(name).field;
    std::printf("  %s: adjoint %.9g differences %.9g; area term %.9g against %.9g\n", name.c_str(), analytic, fd,
                analytic - analytic_pos, fd - fd_pos);
    worst = std::max(worst, std::abs(analytic - fd));
    worst_area = std::max(worst_area, std::abs((analytic - analytic_pos) - (fd - fd_pos)));
    scale = std::max(scale, std::abs(fd));
    scale_area = std::max(scale_area, std::abs(fd - fd_pos));
  }
  std::printf("worst error relative to the largest derivative: %.2e (area term %.2e)\n", worst / scale, worst_area / scale_area);
  CHECK(worst / scale < 1e-4);
  CHECK(worst_area / scale_area < 1e-4);
}

TEST_CASE("recovery: material parameters are recovered from trajectories the engine generated", "[learning][recovery]") {
  const ScenarioDef s = ScenarioDef::parse_text(kRecoveryScene);
  // The truth: every scalar away from the default, and a traction network that is not the default's.
  Model truth = Model::default_model();
  // The scene's crowd (about 4-5 /m^2 against the wall) is compressed only below the default's
  // rest density of 6; at 4 the stress law's E and gamma both act in it.
  truth.set("rest_density", 4);
  truth.set("E", 30);
  truth.set("gamma", 1.5);
  truth.set("tension_scale", 0.3);
  truth.set("tau", 0.4);
  truth.set("v0_scale", 1.1);
  truth.set("comfort_distance", 0.35);
  truth.set("alignment_time", 0.3);
  // The scene tells E from gamma by the crowd compressed against the wall. Held a body radius off
  // it (shoulder_clearance 0.2), the fit stalls with E 20% and gamma 16% off (their product
  // right); with the bodies pressed to wall_clearance it recovers both.
  truth.set("shoulder_clearance", 0);
  std::vector<double> theta = truth.traction.parameters();
  for (size_t k = 0; k < theta.size(); ++k) theta[k] += 0.15 * std::sin(1.0 + static_cast<double>(k));
  truth.traction.set_parameters(theta);
  const std::vector<TrainWindow> train = synthetic_windows(s, truth, 8, 1.0, 11);
  const std::vector<TrainWindow> val = synthetic_windows(s, truth, 2, 1.0, 12);
  // The start: every scalar perturbed by 20-35%, the network known.
  Model start = truth;
  const std::vector<std::pair<const char*, double>> factors = {{"E", 1.35},   {"gamma", 0.75},           {"tension_scale", 1.3},
                                                               {"tau", 1.25}, {"v0_scale", 0.8},         {"comfort_distance", 1.2},
                                                               {"alignment_time", 0.7}};
  for (auto [name, f] : factors) start.set(name, truth.get(name) * f);
  TrainOptions o;
  o.batch = static_cast<int>(train.size());
  o.iterations = 300;
  o.learning_rate = 0.05;
  o.eval_every = 5;
  o.patience = 15;
  o.lr_decay = 0.7;
  o.learn_network = false;
  o.threads = 2;  // windows in parallel; the result does not depend on it
  TrainResult r = train_on_windows({s}, train, val, start, o, [](const TrainProgress& p) {
    if (!std::isnan(p.validation_loss)) std::printf("  iteration %3d: training loss %.3e, validation %.3e\n", p.iteration, p.train_loss, p.validation_loss);
  });
  std::printf("recovery: validation loss %.3e -> %.3e (x%.0f) in %d iterations (best %d)\n", r.initial_validation,
              r.best_validation, r.initial_validation / r.best_validation, r.iterations, r.best_iteration);
  for (auto [name, f] : factors) {
    const double got = r.model.get(name), want = truth.get(name);
    std::printf("  %-17s truth %.4f start %.4f learned %.4f (error %.1f%%)\n", name, want, want * f, got,
                100 * std::abs(got - want) / want);
    CHECK(std::abs(got - want) <= 0.1 * want);
  }
  CHECK(r.best_validation * 100 <= r.initial_validation);
}

TEST_CASE("the grid velocity loss trains too: drive parameters recovered from velocity fields", "[learning]") {
  const ScenarioDef s = ScenarioDef::parse_text(kRecoveryScene);
  Model truth = Model::default_model();
  truth.set("rest_density", 4);  // as in the recovery above
  truth.set("comfort_distance", 0.3);
  truth.set("tau", 0.4);
  truth.set("v0_scale", 1.1);
  const std::vector<TrainWindow> train = synthetic_windows(s, truth, 4, 1.0, 21);
  const std::vector<TrainWindow> val = synthetic_windows(s, truth, 1, 1.0, 22);
  Model start = truth;
  start.set("tau", 0.55);
  start.set("v0_scale", 0.85);
  TrainOptions o;
  o.loss = TrainOptions::Loss::GridVelocity;
  o.params = {"tau", "v0_scale"};
  o.learn_network = false;
  o.batch = 4;
  o.iterations = 80;
  o.learning_rate = 0.05;
  o.patience = 10;
  TrainResult r = train_on_windows({s}, train, val, start, o);
  // Recorded velocities are one-frame differences, the simulation's are instantaneous: even the
  // truth has a loss. Training must come down to it.
  const double at_truth = window_loss(window_scenario(s, false), val[0], truth, o, nullptr);
  std::printf("grid velocity training: validation %.3e -> %.3e (truth %.3e); tau %.3f (0.4), v0_scale %.3f (1.1)\n",
              r.initial_validation, r.best_validation, at_truth, r.model.get("tau"), r.model.get("v0_scale"));
  CHECK(r.best_validation - at_truth < 0.1 * (r.initial_validation - at_truth));  // 90% of the way to the truth
  CHECK(r.best_validation < 1.2 * at_truth);
  CHECK(r.model.get("v0_scale") == Approx(1.1).epsilon(0.05));
  CHECK(r.model.get("tau") == Approx(0.4).epsilon(0.1));
}

TEST_CASE("real recordings: the learned model beats constant velocity and the default on held-out runs", "[learning][real]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("skipped: ../shared/data is absent, no real recording to learn from");
    return;
  }
  const std::string corr = data + "/real/fzj_hermes_2009_corridor_uo/", bott = data + "/real/fzj_crowdqueue_2018_bottleneck/";
  const ScenarioDef corridor = ScenarioDef::load(test::scenario_path("corridor"));
  const ScenarioDef bottleneck = ScenarioDef::load(test::scenario_path("bottleneck"));
  // Train on two corridor runs and one bottleneck run.
  std::vector<TrainDataset> sets = {
      {corridor, {TrajectorySet::read(corr + "uo-050-180-180.txt"), TrajectorySet::read(corr + "uo-100-180-180.txt")}},
      {bottleneck, {TrajectorySet::read(bott + "030_c_56_h0.txt")}}};
  TrainOptions o;
  o.iterations = 100;
  o.threads = 2;
  const Model start = Model::default_model();
  TrainResult r = train_model(sets, start, o);
  std::printf("real: validation loss %.4f -> %.4f m2 (best at %d of %d)\n", r.initial_validation, r.best_validation,
              r.best_iteration, r.iterations);
  CHECK(r.best_validation < 0.8 * r.initial_validation);
  // Evaluate on runs never seen in training, 4 s ahead.
  PredictOptions po;
  po.observe = 4;
  po.horizon = 4;
  po.threads = 2;
  const WindowOptions wo{2, DesiredSpeed::Observed};
  for (const auto& [scenario, file] : {std::pair<const ScenarioDef*, std::string>{&corridor, corr + "uo-145-180-180.txt"},
                                       {&bottleneck, bott + "040_c_56_h-.txt"}}) {
    const TrajectorySet t = TrajectorySet::read(file);
    const double cv = evaluate_predictor("cv", t, po, constant_velocity_predictor()).horizons[3].ade;
    const double def = evaluate_predictor("default", t, po, simulation_predictor(*scenario, start, wo)).horizons[3].ade;
    const double learned = evaluate_predictor("learned", t, po, simulation_predictor(*scenario, r.model, wo)).horizons[3].ade;
    std::printf("held out %s: ADE@4s constant velocity %.3f, default %.3f, learned %.3f m\n", file.c_str(), cv, def, learned);
    CHECK(learned < cv);
    CHECK(learned < def);
  }
}
