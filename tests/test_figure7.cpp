// Source document Figure 7, measured on the hajj scenarios: time-averaged density over
// t = 40..80 s in a band beside the Hateem and a band beside the opposite wall of the Kaaba.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>

#include "support.hpp"

using namespace crowdmpm;

namespace {
std::pair<double, double> sides(const std::string& name) {
  ScenarioDef s = ScenarioDef::load(test::scenario_path(name));
  Simulation sim(s, test::model_of(s), 2);
  MetricsRecorder m(s);
  test::run_for(sim, s.duration, [&](const Simulation& sm) { m.record(sm, compute_fields(sm.world(), sm.grid())); });
  double north = m.area("north_side").mean_density(), south = m.area("south_side").mean_density();
  std::printf("figure7 %-16s north (Hateem side) %.2f /m2, south (opposite) %.2f /m2, ratio %.3f\n", name.c_str(), north,
              south, north / south);
  return {north, south};
}
}  // namespace

TEST_CASE("Figure 7: without the Hateem both sides of the Kaaba are alike", "[figure7]") {
  auto [north, south] = sides("hajj_no_hateem");
  CHECK(std::abs(north - south) / (0.5 * (north + south)) < 0.1);
}
