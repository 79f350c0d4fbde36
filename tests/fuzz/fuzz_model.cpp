// Model JSON: parse and validate; a model that loads must save and load back to the same JSON,
// and must step a small room without a crash (an unstable model ends in UnstableError).
#include <cstddef>
#include <cstdint>
#include <string>

#include "engine/sim/simulation.hpp"

using namespace crowdmpm;

namespace {
const char* kRoom = R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [6, 4]},
  "time": {"dt": 0.005, "duration": 10}, "seed": 2,
  "geometry": {"exits": [{"id": "door", "rect": [5.5, 1.5, 6, 2.5]}], "obstacles": [{"circle": {"center": [3, 2], "radius": 0.4}}]},
  "groups": [{"id": "g", "spawn": {"rect": [0.5, 0.5, 2.5, 3.5]}, "count": 20, "behaviour": {"type": "goal", "target": "door"}}]})";
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const ScenarioDef room = ScenarioDef::parse_text(kRoom);
  const std::string text(reinterpret_cast<const char*>(data), size);
  Model m;
  try {
    m = Model::parse(JsonReader(parse_json_text(text, "fuzz"), ""), "fuzz");
  } catch (const Error&) {
    return 0;
  }
  const std::string saved = m.to_json().dump();
  const Model again = Model::parse(JsonReader(parse_json_text(saved, "saved"), ""), "saved");
  if (again.to_json().dump() != saved) __builtin_trap();  // a save that does not load back the same
  try {
    Simulation sim(room, m, 1);
    sim.run_steps(4);
  } catch (const Error&) {
  }
  return 0;
}
