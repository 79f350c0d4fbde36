// Route choice under congestion (model parameter route_congestion, docs/model-format.md step 0):
// the navigation field under a cost, the routes' updates, holding them through a gradient window
// and restoring them from a snapshot.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>

#include "engine/geometry/navigation.hpp"
#include "engine/learn/differentiable.hpp"
#include "engine/sim/snapshot.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
// A corridor 20 m x 6 m with its exit at the right end, and 60 people walking to it.
const char* kCorridor = R"({"format": "crowdmpm-scenario", "version": 1, "name": "route corridor",
  "domain": {"min": [0, 0], "max": [20, 6], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 30},
  "geometry": {"exits": [{"id": "out", "rect": [19.5, 0, 20, 6]}]},
  "groups": [{"spawn": {"rect": [1, 1, 7, 5]}, "count": 60, "desired_speed": 1.3,
              "behaviour": {"type": "goal", "target": "out"}}]})";
}  // namespace

TEST_CASE("navigation: a costly patch bends the route round it and an empty cost restores the shortest path", "[routes]") {
  Geometry geo;
  geo.lo = Vec2(0, 0);
  geo.hi = Vec2(20, 10);
  const Shape exit = Shape::rect(Vec2(19.5, 0), Vec2(20, 10));
  NavField f(geo, {&exit}, 0.1, 0.1);
  const Vec2 before(7.5, 5.2);
  const Vec2 straight = f.direction(before);
  CHECK(straight.x() > 0.999);
  const double free_distance = f.distance(Vec2(1, 5));
  std::vector<double> cost(static_cast<size_t>(f.nx()) * f.ny(), 1.0);
  for (int j = 0; j < f.ny(); ++j)
    for (int i = 0; i < f.nx(); ++i)
      if ((f.cell_centre(i, j) - Vec2(10, 5)).norm() < 2) cost[static_cast<size_t>(j) * f.nx() + i] = 10;
  f.set_cost(cost);
  const Vec2 bent = f.direction(before);
  std::printf("route round a patch of cost 10: direction at (7.5, 5.2) (%.3f, %.3f), was (%.3f, %.3f)\n", bent.x(), bent.y(),
              straight.x(), straight.y());
  CHECK(bent.y() > 0.3);  // round the patch on the side it is nearer to
  // Round the patch (radius 2) costs more than straight through empty space, less than through it.
  CHECK(f.distance(Vec2(1, 5)) > free_distance + 0.1);
  CHECK(f.distance(Vec2(1, 5)) < free_distance + 4 * 9);
  f.set_cost({});
  CHECK(f.direction(before).x() > 0.999);
  CHECK(f.distance(Vec2(1, 5)) == free_distance);
  CHECK_THROWS_WITH(f.set_cost(std::vector<double>(7, 1.0)), Catch::Contains("7 values for") && Catch::Contains("cells"));
}

TEST_CASE("route choice: routes follow the crowd's pace once a second and are off at route_congestion 0", "[routes]") {
  const ScenarioDef s = ScenarioDef::parse_text(kCorridor);
  Model m = Model::default_model();
  REQUIRE(m.get("route_congestion") > 0);
  Simulation sim(s, m, 2);
  CHECK(sim.route_pace().empty());
  sim.step();  // the first step computes the routes: everyone starts at rest, pace 0
  const std::vector<double> at_start = sim.route_pace();
  REQUIRE(at_start.size() == sim.grid().nodes());
  double lo = 1, hi = 0;
  for (double p : at_start) {
    lo = std::min(lo, p);
    hi = std::max(hi, p);
  }
  // Inside the standing crowd the pace is the background's share; far from it, 1.
  CHECK(lo < 0.5);
  CHECK(hi == Approx(1).margin(1e-9));
  sim.run_steps(99);
  CHECK(sim.route_pace() == at_start);  // not recomputed within the second
  sim.step();                           // step 100 begins the next second
  CHECK(sim.route_pace() != at_start);
  Model off = m;
  off.set("route_congestion", 0);
  sim.set_model(off);
  sim.step();
  CHECK(sim.route_pace().empty());  // shortest paths again
}

TEST_CASE("a gradient window holds the routes of its start", "[routes][gradients]") {
  const ScenarioDef s = ScenarioDef::parse_text(kCorridor);
  Simulation sim(s, Model::default_model(), 1);
  sim.run_steps(50);
  const std::vector<double> before = sim.route_pace();
  REQUIRE(!before.empty());
  WindowGradient wg(40);  // checkpointed: segments run again must see the same routes
  wg.run(sim, 120, [&](int k, const World& w, std::vector<Vec2>& dx, std::vector<Vec2>& dv) {
    if (k != 120) return false;
    for (size_t p = 0; p < w.size(); ++p) {
      dx[p] = w.x[p] - Vec2(19, 3);
      dv[p] = Vec2::Zero();
    }
    return true;
  });
  CHECK(sim.steps() == 170);       // crossed step 100, where a free run recomputes
  CHECK(sim.route_pace() == before);
  CHECK(!sim.routes_held());       // released after the window
  sim.run_steps(31);               // through step 200
  CHECK(sim.route_pace() != before);
}

TEST_CASE("a snapshot restores the routes: the restored run continues bit-identically", "[routes][snapshot]") {
  const ScenarioDef s = ScenarioDef::parse_text(kCorridor);
  Simulation sim(s, Model::default_model(), 2);
  sim.run_steps(150);  // half-way through a second: the routes are those of step 100
  const std::string bytes = save_snapshot(sim);
  auto restored = restore_snapshot(bytes, "routes.snap", 1);
  CHECK(restored->route_pace() == sim.route_pace());
  sim.run_steps(120);
  restored->run_steps(120);
  CHECK(restored->world().state_hash() == sim.world().state_hash());
}
