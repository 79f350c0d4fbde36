#pragma once
// Shared helpers for the engine tests: paths to shipped scenarios and shared data, and running
// a scenario in-process with a callback at every output frame.
#include <filesystem>
#include <functional>
#include <string>

#include "engine/run/runner.hpp"

namespace crowdmpm::test {

inline std::string repo_path(const std::string& rel) { return std::string(CROWDMPM_SOURCE_DIR) + "/" + rel; }
inline std::string scenario_path(const std::string& name) { return repo_path("scenarios/" + name + ".json"); }
// ../shared/data beside the repository; empty if absent (tests that need it skip).
inline std::string shared_data_dir() {
  std::string p = std::string(CROWDMPM_SOURCE_DIR) + "/../shared/data";
  return std::filesystem::exists(p) ? p : std::string();
}

inline Model model_of(const ScenarioDef& s) { return s.model_or_default(); }

// An MPM grid over the empty box [0, w] x [0, h] with the given spacing.
inline Grid box_grid(double w, double h, double dx) {
  Geometry geo;
  geo.lo = Vec2(0, 0);
  geo.hi = Vec2(w, h);
  Grid g;
  g.init(geo, dx);
  return g;
}

// Runs a scenario for `seconds` (or its duration), calling on_frame after every output frame.
inline void run_for(Simulation& sim, double seconds, const std::function<void(const Simulation&)>& on_frame) {
  const int spf = sim.scenario().steps_per_frame();
  on_frame(sim);
  while (sim.time() < seconds - 1e-9 && !sim.finished()) {
    for (int k = 0; k < spf && !sim.finished(); ++k) sim.step();
    on_frame(sim);
  }
}

}  // namespace crowdmpm::test
