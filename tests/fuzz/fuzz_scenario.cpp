// Scenario JSON: parse (with its extends chain and model confined to an empty folder), check,
// build the world when it is small, and step it a few times. Every input must end in a world or
// in crowdmpm::Error, never a crash, leak, undefined behaviour or hang.
#include <cstddef>
#include <cstdint>
#include <string>

#include "engine/sim/simulation.hpp"
#include "fuzz_common.hpp"

using namespace crowdmpm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    InputPolicy policy;
    policy.max_bytes = 1 << 20;
    const ScenarioDef s = ScenarioDef::parse_text(text, fuzz::scratch_dir() + "/crowdmpm_fuzz_empty", policy);
    if (!fuzz::small_enough(s)) return 0;
    Simulation sim(s, s.model_or_default(), 1);
    sim.run_steps(3);
    (void)sim.world().state_hash();
  } catch (const Error&) {
  }
  return 0;
}
