// Force terms (sim/terms.hpp): every law's vector-Jacobian product against central differences,
// their gradients through a whole simulated window, parsing and writing back, and fitting term
// parameters from trajectories the engine generated.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <map>

#include "engine/learn/differentiable.hpp"
#include "engine/learn/train.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
double rel_err(double a, double b, double floor) { return std::abs(a - b) / std::max({std::abs(a), std::abs(b), floor}); }

// A parameter set of each law, with its features near the unit square's centre region.
std::map<std::string, std::vector<double>> sample_params() {
  return {{"uniform", {0.3, -0.2}},
          {"radial", {0.4, 0.3, 0.8, 1.0, 0.3}},  // a smooth edge across the points: its range learnable
          {"vortex", {0.4, 0.3, -0.6, 0.9, 0.4}},
          {"obstacle", {0.4, 0.3, 0.5, 8, 0.3, 0.7}},
          {"slow_zone", {-0.5, -0.4, 1.2, 1.0, 0.4, 0.5}},
          {"wall_friction", {-0.8, -0.5, 1.4, 0.2, 1.5, 0.6}},
          {"density_speed", {1.9, 4.5}},
          {"counterflow", {-0.5, -0.4, 1.2, 1.0, 160, 0.5, 2.5, 0.4, 1, -0.2}},  // picked by motion too
          {"constriction", {0.4, 0.3, 0.6, 30, 0.2, 8, 0.3, 0.7, 1.5}}};
}

// L = a_bar . a + f_bar . f of one law at one point.
double scalar_of(const TermLaw& law, const std::vector<double>& p, const TermPoint& pt, const Vec2& a_bar, double f_bar) {
  Vec2 a = Vec2::Zero();
  double f = 1;
  law.eval(p.data(), pt, a, f);
  return a_bar.dot(a) + f_bar * f;
}
}  // namespace

TEST_CASE("every force term law's vector-Jacobian product matches central differences to 1e-6", "[terms][gradients]") {
  const auto params = sample_params();
  REQUIRE(term_laws().size() >= 5);
  Rng rng(5);
  size_t laws = 0, compared = 0;
  double worst = 0;
  for (const TermLaw* law : term_laws()) {
    INFO("law: " << law->type());
    REQUIRE(params.count(law->type()) == 1);  // every law has a sample here
    const std::vector<double> p = params.at(law->type());
    REQUIRE(p.size() == law->parameter_count());
    ++laws;
    for (int trial = 0; trial < 20; ++trial) {
      TermPoint pt;
      pt.x = Vec2(2 * rng.uniform() - 0.6, 2 * rng.uniform() - 0.6);
      pt.v = Vec2(rng.uniform() - 0.5, rng.uniform() - 0.5);
      const double angle = 2 * M_PI * rng.uniform();
      pt.heading = Vec2(std::cos(angle), std::sin(angle));  // read as it is (no derivative of its own)
      pt.density = 0.3 + 5 * rng.uniform();                  // likewise
      pt.id = 1 + static_cast<uint64_t>(trial);
      pt.group = 0;
      const Vec2 a_bar(rng.uniform() - 0.5, rng.uniform() - 0.5);
      const double f_bar = rng.uniform() - 0.5;
      Vec2 xb = Vec2::Zero(), vb = Vec2::Zero();
      std::vector<double> pb(p.size(), 0);
      law->vjp(p.data(), pt, a_bar, f_bar, xb, vb, pb.data());
      // Five-point central differences, error O(h^4).
      const double h = 1e-4;
      auto five = [&](auto&& at) { return (-at(2 * h) + 8 * at(h) - 8 * at(-h) + at(-2 * h)) / (12 * h); };
      auto check = [&](const char* what, double analytic, double fd) {
        // Floor 1e-5: five-point differences of values of order 10 carry round-off near 1e-12 / h.
        const double e = rel_err(analytic, fd, 1e-5);
        if (e > 1e-6) std::printf("  %s %s: vjp %.12g differences %.12g\n", law->type(), what, analytic, fd);
        worst = std::max(worst, e);
        ++compared;
      };
      for (int c = 0; c < 2; ++c) {
        check("x", xb[c], five([&](double d) {
          TermPoint q = pt;
          q.x[c] += d;
          return scalar_of(*law, p, q, a_bar, f_bar);
        }));
        check("v", vb[c], five([&](double d) {
          TermPoint q = pt;
          q.v[c] += d;
          return scalar_of(*law, p, q, a_bar, f_bar);
        }));
      }
      for (size_t k = 0; k < p.size(); ++k) {
        if (!law->field(k).learnable) continue;  // a hard cutoff's on/off switch (an edge)
        check("parameter", pb[k], five([&](double d) {
          std::vector<double> q = p;
          q[k] += d;
          return scalar_of(*law, q, pt, a_bar, f_bar);
        }));
      }
    }
  }
  std::printf("force term laws: %zu laws, %zu derivatives, worst relative error %.2e\n", laws, compared, worst);
  CHECK(laws == term_laws().size());
  CHECK(compared > 500);
  CHECK(worst < 1e-6);
}

namespace {
// A room with people walking to an exit on the right through every kind of term.
const char* kTermScene = R"({"format": "crowdmpm-scenario", "version": 1, "name": "terms room",
  "domain": {"min": [0, 0], "max": [12, 6], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 10},
  "geometry": {"exits": [{"id": "out", "rect": [11.6, 0, 12, 6]}]},
  "groups": [{"id": "walkers", "spawn": {"rect": [0.5, 0.5, 5, 5.5]}, "density": 1.2, "desired_speed": 1.2,
              "behaviour": {"type": "goal", "target": "out"}}],
  "forces": [{"type": "drift", "acceleration": [0.1, 0.35], "learn": ["acceleration"]},
             {"type": "vortex", "center": [6, 3], "strength": 0.5, "range": 3.5, "learn": ["strength"]},
             {"type": "slow_zone", "min": [3.5, -1], "max": [9, 7], "factor": 0.55, "learn": ["factor"]},
             {"type": "attractor", "center": [3, 1], "strength": 0.2, "range": 4, "edge": 0.6},
             {"type": "obstacle", "center": [4.5, 4.2], "radius": 0.3, "strength": 4, "softness": 0.2},
             {"type": "wall_friction", "from": [0, 0.2], "to": [12, 0.2], "coefficient": 0.8, "range": 0.8},
             {"type": "counterflow", "min": [2, 2], "max": [6, 5], "direction": 150, "share": 0.3, "push": 2, "by_motion": 1, "along": -1},
             {"type": "constriction", "center": [7, 3], "width": 1.5, "angle": 10, "strength": 4, "softness": 0.6}]})";
// The counter-flow picks by motion (its pick reads each person's velocity: that derivative goes
// through the window too; its id draw has none). The obstacle and the constriction do not steer
// here (steer 0, where their gradient in steer is still checked): the walking direction they
// steer by is read as it is, without its derivative.
// Not in this scene: density_speed, whose density is read as it is (TermPoint), so its window
// gradient leaves out how the parameters move the people that make the density; its law's own
// derivatives are checked above.
}  // namespace

TEST_CASE("force term parameter gradients through a simulated window match central differences", "[terms][gradients]") {
  const ScenarioDef s = ScenarioDef::parse_text(kTermScene);
  REQUIRE(s.terms.size() == 8);
  // Without the headway adaptation: its min over the people ahead has kinks that differences
  // straddle in a walking crowd (its own adjoint is checked in test_gradients).
  Model model = Model::default_model();
  model.set("time_gap", 0);
  const int steps = 12;
  auto loss_of = [&](const ScenarioDef& sc) {
    Simulation sim(sc, model, 1);
    double L = 0;
    for (int k = 0; k < steps; ++k) {
      sim.step();
      for (size_t p = 0; p < sim.world().size(); ++p) L += (sim.world().x[p] - Vec2(8, 3)).squaredNorm();
    }
    return L;
  };
  Simulation sim(s, model, 1);
  REQUIRE(sim.world().size() > 20);
  WindowGradient wg;
  const ModelGradient g = wg.run(sim, steps, [&](int, const World& w, std::vector<Vec2>& d, std::vector<Vec2>&) {
    for (size_t p = 0; p < w.size(); ++p) d[p] = 2 * (w.x[p] - Vec2(8, 3));
    return true;
  });
  REQUIRE(g.terms.size() == s.terms.size());
  double worst = 0;
  int compared = 0;
  for (size_t t = 0; t < s.terms.size(); ++t)
    for (size_t k = 0; k < s.terms[t].params.size(); ++k) {
      const Term& term = s.terms[t];
      if (!term.law->why_not_learnable(term.law->field(k).key, term.params.data()).empty())
        continue;  // an edge, or the vortex's range: a hard cutoff
      // Five-point differences at 1e-3: their truncation error (h^4) is far below the round-off of a
      // loss summed over every person and step, which at 1e-4 reached 1e-7 (2.5e-5 of the small
      // derivative in the counter-flow's `along`; at 1e-3 it agrees with the adjoint to 1e-6).
      const double h = 1e-3 * std::max(1.0, std::abs(s.terms[t].params[k]));
      auto at_offset = [&](double d) {
        ScenarioDef sc = s;
        sc.terms[t].params[k] += d;
        return loss_of(sc);
      };
      const double fd = (-at_offset(2 * h) + 8 * at_offset(h) - 8 * at_offset(-h) + at_offset(-2 * h)) / (12 * h);
      const double e = rel_err(g.terms[t][k], fd, 1e-3);
      std::printf("  %s.%s: adjoint %.10g differences %.10g (%.1e)\n", s.terms[t].law->type(),
                  s.terms[t].parameter_names()[k].c_str(), g.terms[t][k], fd, e);
      worst = std::max(worst, e);
      ++compared;
    }
  CHECK(compared >= 30);
  CHECK(worst < 1e-5);
}

TEST_CASE("force terms parse, name their errors and write back what they read", "[terms]") {
  const ScenarioDef s = ScenarioDef::parse_text(kTermScene);
  for (const Term& t : s.terms) {
    json j = t.to_json();
    Term back = Term::parse(JsonReader(j, "forces[0]"), {"walkers"});
    CHECK(back.law == t.law);
    CHECK(back.params == t.params);
    CHECK(back.learn == t.learn);
  }
  CHECK(s.terms[0].learned_count() == 2);
  CHECK(s.terms[3].learned_count() == 0);
  auto error_of = [](const std::string& force) {
    std::string text = std::string(kTermScene);
    text = text.substr(0, text.find("\"forces\"")) + "\"forces\": [" + force + "]}";
    try {
      ScenarioDef::parse_text(text);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK_THAT(error_of(R"({"type": "vortex", "center": [1, 1], "strength": 1, "learn": ["range"]})"),
             Catch::Contains("forces[0].learn[0]") && Catch::Contains("cannot be learned") && Catch::Contains("edge > 0"));
  CHECK(error_of(R"({"type": "vortex", "center": [1, 1], "strength": 1, "range": 2, "edge": 0.5, "learn": ["range"]})").empty());
  CHECK_THAT(error_of(R"({"type": "attractor", "center": [1, 1], "strength": 1, "learn": ["edge"]})"),
             Catch::Contains("forces[0].learn[0]") && Catch::Contains("cannot be learned"));
  CHECK_THAT(error_of(R"({"type": "slow_zone", "min": [1, 1], "max": [0, 3], "factor": 0.5})"),
             Catch::Contains("forces[0].max") && Catch::Contains("above and right of min"));
  CHECK_THAT(error_of(R"({"type": "obstacle", "center": [1, 1]})"), Catch::Contains("forces[0].radius") && Catch::Contains("required"));
  CHECK_THAT(error_of(R"({"type": "drift", "acceleration": [1, 1], "learn": ["speed"]})"),
             Catch::Contains("forces[0].learn[0]") && Catch::Contains("learnable: acceleration"));
  CHECK_THAT(error_of(R"({"type": "slow_zone", "min": [1, 1], "max": [2, 3], "factor": 9})"),
             Catch::Contains("forces[0].factor") && Catch::Contains("[0, 5]"));
  CHECK_THAT(error_of(R"({"type": "counterflow", "min": [0, 0], "max": [2, 2], "direction": 0, "share": 1, "by_motion": 0.5})"),
             Catch::Contains("forces[0].by_motion") && Catch::Contains("0 or 1"));
  CHECK_THAT(error_of(R"({"type": "counterflow", "min": [0, 0], "max": [2, 2], "direction": 0, "share": 1, "learn": ["by_motion"]})"),
             Catch::Contains("forces[0].learn[0]") && Catch::Contains("cannot be learned"));
}

TEST_CASE("a counterflow picked by motion acts on the people moving its way or held up and not on those walking against it", "[terms]") {
  const TermLaw* law = find_term_law("counterflow");
  REQUIRE(law != nullptr);
  // The box [0, 4] x [0, 4], heading 180 degrees (-x), pushed at 2 m/s^2; by id, everyone drawn (share 1.0 picks
  // the draws below 1 with weights from 0.5 up), by motion the share is not read.
  const std::vector<double> by_id = {0, 0, 4, 4, 180, 1, 2, 0.5, 0, -0.3};
  std::vector<double> by_motion = by_id;
  by_motion[8] = 1;
  const auto apply = [&](const std::vector<double>& p, const Vec2& v, uint64_t id) {
    TermPoint pt;
    pt.x = Vec2(2, 2);
    pt.v = v;
    pt.id = id;
    Vec2 a = Vec2::Zero();
    double f = 1;
    law->eval(p.data(), pt, a, f);
    return std::make_pair(a, f);
  };
  for (uint64_t id = 1; id <= 50; ++id) {
    INFO("id " << id);
    // By id: the same for every motion.
    const auto [a_with, f_with] = apply(by_id, Vec2(1.3, 0), id);
    const auto [a_back, f_back] = apply(by_id, Vec2(-1, 0), id);
    CHECK(a_with.isApprox(a_back));
    CHECK(f_with == Approx(f_back));
    // By motion: walking against the direction (+x at 1.3 m/s): not picked, own drive kept.
    const auto [a_walk, f_walk] = apply(by_motion, Vec2(1.3, 0), id);
    CHECK(f_walk > 0.99);
    CHECK(a_walk.norm() < 0.02);
    // Held up (0.1 m/s) or already heading the direction: picked, pushed along -x.
    for (const Vec2& v : {Vec2(0.1, 0.05), Vec2(-0.8, 0)}) {
      const auto [a, f] = apply(by_motion, v, id);
      CHECK(f < 0.15);
      CHECK(a.x() < -1.6);
      CHECK(std::abs(a.y()) < 1e-9);
    }
  }
}

namespace {
// Windows of `seconds` at 20 frames/s from the engine with the true terms, each starting from
// the walkers of the scenario at a different seed (so at different places and speeds).
std::vector<TrainWindow> term_windows(const ScenarioDef& truth, const Model& m, int count, double seconds, uint64_t seed) {
  std::vector<TrainWindow> out;
  for (int n = 0; n < count; ++n) {
    ScenarioDef sc = truth;
    sc.seed = seed + static_cast<uint64_t>(n);
    Simulation placed(sc, m, 1);
    TrainWindow w;
    Rng rng(sc.seed);
    for (size_t p = 0; p < placed.world().size(); ++p) {
      w.start.ids.push_back(static_cast<long>(placed.world().id[p]));
      w.start.x.push_back(placed.world().x[p]);
      w.start.v.emplace_back(0.8 + 0.4 * rng.uniform(), 0.3 * (rng.uniform() - 0.5));
      w.start.speed.push_back(1.0 + 0.4 * rng.uniform());
    }
    w.framerate = 20;
    WindowSim ws = start_window(window_scenario(truth, false), m, w.start, WindowOptions{1, DesiredSpeed::Observed});
    const int per_frame = static_cast<int>(std::lround(1.0 / (w.framerate * truth.dt)));
    for (int k = 0; k < static_cast<int>(seconds * w.framerate); ++k) {
      ws.sim->run_steps(per_frame);
      std::vector<Vec2> row;
      for (EntityId id : ws.ids) row.push_back(ws.sim->world().x[static_cast<size_t>(ws.sim->world().index_of(id))]);
      w.seen.push_back(row);
    }
    out.push_back(std::move(w));
  }
  return out;
}
}  // namespace

TEST_CASE("fitting: a drift, a vortex strength and a slow-zone factor are recovered from engine trajectories", "[terms][learning]") {
  const ScenarioDef truth = ScenarioDef::parse_text(kTermScene);
  // Route choice off: the truth would recompute its routes each second while a training window
  // holds those of its start (no adjoint of the route choice), a bias of ~7% in the drift.
  Model m = Model::default_model();
  m.set("route_congestion", 0);
  const std::vector<TrainWindow> train = term_windows(truth, m, 6, 2.5, 100);
  const std::vector<TrainWindow> val = term_windows(truth, m, 2, 2.5, 200);
  // The start: the terms' learned parameters 40-60% off.
  ScenarioDef start = truth;
  start.terms[0].params = {0.2, 0.15};
  start.terms[1].params[2] = 0.25;
  start.terms[2].params[4] = 0.85;
  TrainOptions o;
  o.learn_scalars = false;  // the material is known: only the terms are fitted
  o.learn_network = false;
  o.batch = static_cast<int>(train.size());
  o.iterations = 150;
  o.learning_rate = 0.05;
  o.eval_every = 5;
  o.patience = 8;
  o.lr_decay = 0.7;
  o.threads = 2;
  const TrainResult r = train_on_windows({start}, train, val, m, o);
  REQUIRE(r.terms.size() == 1);
  const std::vector<Term>& got = r.terms[0];
  const struct {
    const char* what;
    double learned, want;
  } checks[] = {{"drift x", got[0].params[0], 0.1},
                {"drift y", got[0].params[1], 0.35},
                {"vortex strength", got[1].params[2], 0.5},
                {"slow-zone factor", got[2].params[4], 0.55}};
  std::printf("term fit: validation loss %.3e -> %.3e in %d iterations (best %d)\n", r.initial_validation,
              r.best_validation, r.iterations, r.best_iteration);
  for (const auto& c : checks) std::printf("  %-17s truth %.4f learned %.4f\n", c.what, c.want, c.learned);
  // The drift's x share is small beside the walkers' own drive: held to 5% of the drift's size.
  CHECK(std::abs(got[0].params[0] - 0.1) < 0.05 * std::hypot(0.1, 0.35));
  CHECK(got[0].params[1] == Approx(0.35).epsilon(0.05));
  CHECK(got[1].params[2] == Approx(0.5).epsilon(0.05));
  CHECK(got[2].params[4] == Approx(0.55).epsilon(0.05));
  // Parameters not marked "learn" stay as they were.
  CHECK(got[3].params == truth.terms[3].params);
  CHECK(got[1].params[0] == truth.terms[1].params[0]);
}

TEST_CASE("training fails with the cause when windows fail for a reason other than instability", "[terms][learning]") {
  const ScenarioDef s = ScenarioDef::parse_text(kTermScene);
  Model m = Model::default_model();
  const std::vector<TrainWindow> train = term_windows(s, m, 2, 0.5, 300), val = term_windows(s, m, 1, 0.5, 400);
  // Nine layers: the simulation runs them, the backward pass supports eight.
  TractionNet deep;
  int prev = TractionNet::kInputs;
  for (int l = 0; l < 9; ++l) {
    DenseLayer L;
    L.in = prev;
    L.out = l == 8 ? 1 : 3;
    L.weights.assign(static_cast<size_t>(L.in * L.out), 0.1);
    L.biases.assign(static_cast<size_t>(L.out), 0.1);
    L.activation = l == 8 ? Activation::Identity : Activation::Tanh;
    deep.layers.push_back(L);
    prev = L.out;
  }
  m.traction = deep;
  TrainOptions o;
  o.iterations = 3;
  std::string message;
  try {
    train_on_windows({s}, train, val, m, o);
  } catch (const Error& e) {
    message = e.what();
  }
  INFO("message: " << message);
  CHECK_THAT(message, Catch::Contains("window at frame") && Catch::Contains("at most 8 layers"));
}
