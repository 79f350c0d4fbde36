// Every shipped scenario: no agent ever ends a step inside a wall or obstacle, and agents are
// conserved: spawned = remaining + exited at every frame.
#include <catch2/catch.hpp>
#include <filesystem>

#include "support.hpp"

using namespace crowdmpm;

TEST_CASE("no agent inside a solid and agents conserved in every shipped scenario", "[scenarios]") {
  for (const auto& entry : std::filesystem::directory_iterator(test::repo_path("scenarios"))) {
    if (entry.path().extension() != ".json") continue;
    ScenarioDef s = ScenarioDef::load(entry.path().string());
    Simulation sim(s, test::model_of(s), 2);
    const double seconds = std::min(s.duration, 20.0);
    double worst = 1e300;
    long frames = 0, bad_count = 0;
    test::run_for(sim, seconds, [&](const Simulation& sm) {
      const World& w = sm.world();
      for (size_t p = 0; p < w.size(); ++p) worst = std::min(worst, s.geo.sdf(w.x[p]));
      if (sm.spawned() != static_cast<long>(w.size() + sm.exit_events().size())) ++bad_count;
      ++frames;
    });
    std::printf("scenarios %-28s %5zu agents left after %5.1f s, closest approach to a solid %.3f m\n",
                s.name.c_str(), sim.world().size(), sim.time(), worst);
    INFO("scenario " << s.name);
    CHECK(frames > 1);
    CHECK(sim.spawned() > 0);
    CHECK(worst >= 0);
    CHECK(bad_count == 0);
  }
}

TEST_CASE("exits retire agents and record when and where", "[scenarios]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill_wide_exit"));
  Simulation sim(s, test::model_of(s), 2);
  sim.run_steps(2000);
  REQUIRE(!sim.exit_events().empty());
  double last = 0;
  for (const auto& e : sim.exit_events()) {
    CHECK(e.exit == 0);
    CHECK(e.time >= last);
    last = e.time;
    CHECK(sim.world().index_of(e.id) == -1);
  }
}

TEST_CASE("sources spawn at their rate inside their window", "[scenarios]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("corridor"));
  Simulation sim(s, test::model_of(s), 1);
  sim.run_steps(std::lround(10.0 / s.dt));
  // 2.5 persons/s for 10 s.
  CHECK(sim.spawned() >= 24);
  CHECK(sim.spawned() <= 26);
}
