// The social_force model kind (Helbing, Farkas & Vicsek 2000): its pair forces, an evacuation
// with it, determinism, and fitting it with the trainer's central-difference gradients.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>

#include "engine/learn/train.hpp"
#include "engine/predict/predict.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
const char* kOpenRoom = R"({"format": "crowdmpm-scenario", "version": 1, "name": "open room",
  "domain": {"min": [0, 0], "max": [10, 10], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 10},
  "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "behaviour": {"type": "none"}}]})";

Model social_force() { return Model::default_of("social_force"); }
}  // namespace

TEST_CASE("social force: pair forces are equal and opposite, repulsive, with friction on overlap", "[social_force]") {
  ScenarioDef s = ScenarioDef::parse_text(kOpenRoom);
  Model m = social_force();
  Simulation sim(s, m, 1);
  AgentDef a;
  a.body_radius = 0.25;
  a.behaviour = 0;
  a.position = Vec2(5, 5);
  a.velocity = Vec2(0, 0.5);
  sim.add_agent(a);
  a.position = Vec2(5.45, 5);  // overlapping by 0.05 m
  a.velocity = Vec2(0, -0.5);
  sim.add_agent(a);
  StepInputs in = sim.step_inputs();
  World& w = sim.world();
  NeighbourGrid nb = sim.neighbour_grid();
  ThreadPool pool(1);
  nb.build(w, pool);
  kernel_social_force(in, nb, w, pool);
  const MaterialParams& P = m.params;
  const double overlap = 0.05;
  const double normal = P.sf_A * std::exp(overlap / P.sf_B) + P.sf_k * overlap;
  // Agent 0 is pushed to -x; the tangential friction opposes the relative sliding (+y for 0, whose
  // neighbour moves in -y relative... 0 moves +y, 1 moves -y: friction on 0 is -y).
  CHECK(w.pair_force[0].x() == Approx(-normal));
  CHECK(w.pair_force[1].x() == Approx(normal));
  CHECK(w.pair_force[0].y() == Approx(-P.sf_kappa * overlap * 1.0));
  CHECK((w.pair_force[0] + w.pair_force[1]).norm() == Approx(0).margin(1e-9));
  CHECK(w.pressure[0] > 0);
}

TEST_CASE("social force: the drill evacuates, nobody inside a wall, identical on 1 and 2 threads", "[social_force]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  const Model m = social_force();
  Simulation sim(s, m, 2);
  const size_t start = sim.world().size();
  double worst = 1e9;
  long steps = 0;
  uint64_t hash500 = 0;
  while (!sim.finished() && steps < 20000) {
    sim.step();
    ++steps;
    for (const Vec2& x : sim.world().x) worst = std::min(worst, s.geo.sdf(x));
    if (steps == 500) hash500 = sim.world().state_hash();
  }
  std::printf("social force drill: %zu agents out in %.1f s (%.2f persons/s), closest approach to a solid %.3f m\n", start,
              sim.time(), static_cast<double>(start) / sim.time(), worst);
  CHECK(sim.world().size() == 0);
  CHECK(sim.exit_events().size() == start);
  CHECK(worst >= 0);
  Simulation one(s, m, 1);
  one.run_steps(500);
  CHECK(one.world().state_hash() == hash500);
}

namespace {
// A dense block walking through a 1.2 m gap to a goal beyond it (nobody leaves: a goal, not an exit).
const char* kGapScene = R"({"format": "crowdmpm-scenario", "version": 1, "name": "gap",
  "domain": {"min": [0, 0], "max": [12, 8], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 10},
  "geometry": {"walls": [{"points": [[7, 0], [7, 3.4]], "thickness": 0.2}, {"points": [[7, 4.6], [7, 8]], "thickness": 0.2}]},
  "goals": [{"id": "beyond", "rect": [10.5, 0, 12, 8]}],
  "groups": [{"spawn": {"rect": [1, 1, 6.5, 7]}, "count": 130, "desired_speed": 1.3,
              "behaviour": {"type": "goal", "target": "beyond"}}]})";
}  // namespace

TEST_CASE("social force: the trainer fits its parameters by central differences", "[social_force][learning]") {
  ScenarioDef s = ScenarioDef::parse_text(kGapScene);
  Model truth = social_force();
  truth.set("tau", 0.35);
  truth.set("v0_scale", 1.15);
  truth.set("sf_A", 18);
  // Windows of 1.5 s at 10 frames/s, back to back, from one run of the truth.
  Simulation sim(s, truth, 2);
  std::vector<TrainWindow> windows;
  for (int n = 0; n < 4; ++n) {
    const World& world = sim.world();
    TrainWindow w;
    w.framerate = 10;
    for (EntityId id : world.id) w.start.ids.push_back(static_cast<long>(id));
    w.start.x = world.x;
    w.start.v = world.v;
    w.start.speed = world.v0;  // the trainer gives each person this desired speed
    const std::vector<EntityId> ids = world.id;
    for (int k = 0; k < 15; ++k) {
      sim.run_steps(10);
      std::vector<Vec2> row;
      for (EntityId id : ids) row.push_back(sim.world().x[static_cast<size_t>(sim.world().index_of(id))]);
      w.seen.push_back(row);
    }
    windows.push_back(std::move(w));
  }
  std::vector<TrainWindow> train(windows.begin(), windows.begin() + 3), val(windows.begin() + 3, windows.end());
  Model start = truth;
  start.set("tau", 0.5);
  start.set("v0_scale", 1.0);
  start.set("sf_A", 25);
  TrainOptions o;
  o.params = {"tau", "v0_scale", "sf_A"};
  o.batch = 3;
  o.iterations = 100;
  o.learning_rate = 0.05;
  o.patience = 10;
  o.lr_decay = 0.7;
  o.threads = 2;
  TrainResult r = train_on_windows({s}, train, val, start, o);
  std::printf("social force fit: validation %.3e -> %.3e in %d iterations; tau %.3f (0.35), v0_scale %.3f (1.15), sf_A %.2f (18)\n",
              r.initial_validation, r.best_validation, r.iterations, r.model.get("tau"), r.model.get("v0_scale"), r.model.get("sf_A"));
  CHECK(r.best_validation < 0.03 * r.initial_validation);
  CHECK(r.model.get("v0_scale") == Approx(1.15).epsilon(0.05));
  CHECK(r.model.get("tau") == Approx(0.35).epsilon(0.1));
  CHECK(r.model.get("sf_A") == Approx(18).epsilon(0.2));
}
