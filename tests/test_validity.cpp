// Coarse checks against measurements of real crowds (benchmarks/validation/ has the full tables):
// the default model (version 2: headway speed adaptation, pressure referenced to density) walks
// the fundamental diagram inside the band between Weidmann's relation and the Juelich corridor
// measurement, its flows through the Hermes 2009 wide bottlenecks lie within 20% of the measured
// and its whole-run replays within 15%. Defects recorded here (they fail once fixed, then move to
// the checks above): through doors of about 1 m it passes ~35% more people than Seyfried 2009
// and Kretz 2006 measured; the version 1 default (scenarios/models/v1.json) keeps free speed at
// 3 persons/m^2.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <string>

#include "engine/analysis/validation.hpp"
#include "engine/predict/replay.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
double weidmann(double rho) { return 1.34 * (1 - std::exp(-1.913 * (1 / rho - 1 / 5.4))); }

// The models held to the measurements: the default and the shipped learned model (version 2).
std::vector<std::pair<const char*, Model>> models() {
  return {{"default", Model::default_model()}, {"learned_juelich", Model::load(test::repo_path("scenarios/models/learned_juelich.json"))}};
}
}  // namespace

TEST_CASE("default and learned model: fundamental diagram within the measured band at 1 and 3 persons/m2 and slow at 5", "[validity]") {
  for (const auto& [name, m] : models()) {
  // Band (issue 10): between Weidmann and the Juelich corridor value (1.27 at 1, 0.37 at 3),
  // widened by 25% or 0.15 m/s.
  const struct {
    double rho, lo, hi;
  } checks[] = {{1, 1.06 - 0.265, 1.27 + 0.3175}, {3, 0.33 - 0.15, 0.37 + 0.15}};
  for (const auto& c : checks) {
    const CorridorResult r = ring_corridor_speed(m, c.rho, 10, 10, 2);
    std::printf("%s model at %.2f persons/m2: %.3f m/s (Weidmann %.2f)\n", name, r.density, r.speed, weidmann(r.density));
    CHECK(r.speed > c.lo);
    CHECK(r.speed < c.hi);
  }
  const CorridorResult dense = ring_corridor_speed(m, 5.5, 10, 10, 2);
  std::printf("%s model at %.2f persons/m2: %.3f m/s, peak %d per m2\n", name, dense.density, dense.speed, dense.peak_per_m2);
  CHECK(dense.density > 4.9);
  CHECK(dense.speed < 0.3);
  CHECK(dense.speed > -0.05);  // stopped, not pushed backwards
  CHECK(dense.peak_per_m2 <= 10);
  }
}

TEST_CASE("default and learned model: wide bottleneck flow within 20 percent of Hermes 2009 at its densities in front", "[validity]") {
  for (const auto& [name, m] : models()) {
  const struct {
    double b, density, measured;
  } checks[] = {{2.4, 5.6, 6.07}, {3.0, 5.1, 7.17}};
  for (const auto& c : checks) {
    const BottleneckResult r = bottleneck_flow(m, c.b, c.density, 2, 350);  // a crowd as large as AO_300's
    std::printf("%s model, %.1f m bottleneck from %.1f persons/m2: %.2f persons/s (measured %.2f), peak %d per m2\n",
                name, c.b, c.density, r.flow, c.measured, r.peak_per_m2);
    CHECK(r.flow == Approx(c.measured).epsilon(0.2));
    CHECK(r.peak_per_m2 <= 10);
  }
  }
}

TEST_CASE("default model: narrow doors from a waiting crowd pass the measured flows within 20 percent", "[validity]") {
  // Single file at 0.4 m (Kretz 2006), two lanes at 0.8 m and 1.0 m (Seyfried 2009, Kretz 2006):
  // the door posts keep shoulders off (shoulder_clearance) and converging walkers take turns.
  const struct {
    double b, measured;
  } checks[] = {{0.4, 0.89}, {0.8, 1.29}, {1.0, 1.88}};
  for (const auto& c : checks) {
    const BottleneckResult r = bottleneck_flow(Model::default_model(), c.b, 3.5, 2);
    std::printf("default model, %.1f m door: %.2f persons/s (measured %.2f), peak %d per m2\n", c.b, r.flow, c.measured,
                r.peak_per_m2);
    CHECK(r.flow == Approx(c.measured).epsilon(0.2));
    CHECK(r.peak_per_m2 <= 10);
  }
}

TEST_CASE("version 1 default: the crowd keeps near free speed at 3 persons/m2 (the defect model 2 fixes)", "[validity]") {
  const CorridorResult r = ring_corridor_speed(Model::load(test::repo_path("scenarios/models/v1.json")), 3, 10, 10, 2);
  std::printf("v1 model at %.2f persons/m2: %.3f m/s (Weidmann %.2f)\n", r.density, r.speed, weidmann(r.density));
  CHECK(r.speed > 1.0);
}

TEST_CASE("replays: recorded flows as measured and the default and learned model within 15 percent of AO_300 and the CrowdQueue runs", "[validity][real]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("skipped: ../shared/data is absent, no recording to replay");
    return;
  }
  const TrajectorySet ao = TrajectorySet::read(data + "/real/fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt");
  // The recording's own flow through the 3.0 m bottleneck (issue 10: 7.1 persons/s).
  const std::vector<double> ao_passages = recorded_passages(ao, PassageLine{Vec2(-0.6, 0), Vec2(2.4, 0)});
  CHECK(ao_passages.size() == ao.person_count());
  CHECK(middle_flow(ao_passages) == Approx(7.1).epsilon(0.05));
  // A crowd squeezing through a bottleneck is chaotic (one replay is one draw, +-10% through the
  // CrowdQueue gate): the mean flow of the exact replay and three with jittered entry points.
  constexpr int kRepeats = 4;
  for (const auto& [name, m] : models()) {
    const std::vector<ReplayResult> ar = replay_repeats(ScenarioDef::load(test::scenario_path("bottleneck_ao")), m, ao,
                                                        PassageLine{Vec2(-0.6, 0), Vec2(2.4, 0)}, kRepeats, 30, 2);
    std::printf("replay AO_300: %zu people placed, recorded %.3f persons/s, %s model %.3f (mean of %d; exact replay %.3f, %zu passages)\n",
                ar[0].placed, ar[0].recorded_flow, name, mean_simulated_flow(ar), kRepeats, ar[0].simulated_flow, ar[0].simulated.size());
    CHECK(ar[0].placed == ar[0].people);
    CHECK(mean_simulated_flow(ar) == Approx(ar[0].recorded_flow).epsilon(0.15));
    const ScenarioDef cq = ScenarioDef::load(test::scenario_path("bottleneck"));
    for (const char* run : {"030_c_56_h0", "040_c_56_h-"}) {
      // The learned model was trained on 030: acceptance holds models to runs they were not trained on.
      if (std::string(name) == "learned_juelich" && std::string(run) == "030_c_56_h0") continue;
      const TrajectorySet rec = TrajectorySet::read(data + "/real/fzj_crowdqueue_2018_bottleneck/" + run + ".txt");
      const std::vector<ReplayResult> r = replay_repeats(cq, m, rec, PassageLine{Vec2(-0.25, -0.6), Vec2(0.25, -0.6)}, kRepeats, 30, 2);
      std::printf("replay %s: %zu people placed, recorded %.3f persons/s, %s model %.3f (mean of %d; exact replay %.3f)\n", run,
                  r[0].placed, r[0].recorded_flow, name, mean_simulated_flow(r), kRepeats, r[0].simulated_flow);
      CHECK(r[0].placed == r[0].people);
      CHECK(r[0].recorded_flow == Approx(1.16).epsilon(0.06));  // issue 10: 1.18 and 1.14
      for (const ReplayResult& x : r) CHECK(x.simulated.size() == x.people);  // everyone passes the gate
      CHECK(mean_simulated_flow(r) == Approx(r[0].recorded_flow).epsilon(0.15));
    }
  }
}
