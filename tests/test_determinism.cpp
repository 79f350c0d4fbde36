// Determinism is a test, not a hope: the drill scenario hashed after a fixed number of steps must
// give the same value on every run and for every thread count, equal to the committed value.
#include <catch2/catch.hpp>

#include "support.hpp"

using namespace crowdmpm;

#include "expected_hashes.h"

namespace {
constexpr long kSteps = CMPM_EXPECTED_DRILL_STEPS;
constexpr uint64_t kExpectedDrillHash = CMPM_EXPECTED_DRILL_HASH;

uint64_t drill_hash(int threads) {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation sim(s, test::model_of(s), threads);
  sim.run_steps(kSteps);
  return sim.world().state_hash();
}
}  // namespace

TEST_CASE("drill state hash is identical across runs and thread counts", "[determinism]") {
  uint64_t one = drill_hash(1);
  uint64_t one_again = drill_hash(1);
  uint64_t two = drill_hash(2);
  uint64_t three = drill_hash(3);
  INFO("hash with 1 thread: 0x" << std::hex << one);
  CHECK(one == one_again);
  CHECK(one == two);
  CHECK(one == three);
  CHECK(one == kExpectedDrillHash);
}

TEST_CASE("a different seed gives a different state", "[determinism]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  s.seed = 2;
  Simulation sim(s, test::model_of(s), 1);
  sim.run_steps(10);
  ScenarioDef s1 = ScenarioDef::load(test::scenario_path("drill"));
  Simulation sim1(s1, test::model_of(s1), 1);
  sim1.run_steps(10);
  CHECK(sim.world().state_hash() != sim1.world().state_hash());
}
