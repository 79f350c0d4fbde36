// Soak runs (issue 13): each scenario for a long stretch of simulated time (an hour, or until it
// empties), checked every simulated second for non-finite states, agent centres inside solids
// or outside the domain, and people lost or duplicated (spawned = present + exited, ids unique);
// with the peak density and the wall-clock time. One markdown table row per scenario.
// usage: soak [--seconds S] [--threads N] [--allow-outside-paths] SCENARIO...
// Exit status 1 if any check failed.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <unordered_set>
#include <vector>

#include "engine/analysis/fields.hpp"
#include "engine/sim/simulation.hpp"

using namespace crowdmpm;

namespace {

struct SoakResult {
  std::string name;
  double simulated = 0, wall = 0;
  long steps = 0, spawned = 0, exited = 0, present = 0;
  long agent_steps = 0;
  bool nonfinite = false;
  std::string unstable;         // the engine's message when it stopped on a non-finite state
  long inside_solid = 0;        // agent-checks with the centre more than 1 mm inside a solid or outside
  double deepest = 0;           // the deepest such centre, m
  long lost = 0, duplicated = 0;
  double peak_density = 0;      // persons/m^2, grid node
  double peak_time = 0;
  bool ok() const { return !nonfinite && inside_solid == 0 && lost == 0 && duplicated == 0; }
};

SoakResult soak(const std::string& path, double seconds, int threads, const InputPolicy& policy) {
  ScenarioDef s = ScenarioDef::load(path, policy);
  SoakResult r;
  r.name = path.substr(path.find_last_of('/') + 1);
  s.duration = seconds;
  Simulation sim(s, s.model_or_default(), threads);
  const auto t0 = std::chrono::steady_clock::now();
  const long per_check = std::max(1L, std::lround(1.0 / s.dt));
  auto check = [&]() {
    const World& w = sim.world();
    std::unordered_set<EntityId> ids;
    for (size_t p = 0; p < w.size(); ++p) {
      if (!w.x[p].allFinite() || !w.v[p].allFinite()) r.nonfinite = true;
      const double d = s.geo.sdf(w.x[p]);
      if (d < -1e-3) {
        ++r.inside_solid;
        r.deepest = std::max(r.deepest, -d);
      }
      if (!ids.insert(w.id[p]).second) ++r.duplicated;
    }
    const long accounted = static_cast<long>(w.size()) + static_cast<long>(sim.exit_events().size());
    if (accounted < sim.spawned()) r.lost = std::max(r.lost, sim.spawned() - accounted);
    if (accounted > sim.spawned()) r.duplicated = std::max(r.duplicated, accounted - sim.spawned());
    const FieldFrame f = compute_fields(w, sim.grid());
    for (double rho : f.density)
      if (rho > r.peak_density) {
        r.peak_density = rho;
        r.peak_time = sim.time();
      }
  };
  check();
  try {
    while (!sim.finished()) {
      for (long k = 0; k < per_check && !sim.finished(); ++k) {
        r.agent_steps += static_cast<long>(sim.world().size());
        sim.step();
      }
      check();
    }
  } catch (const UnstableError& e) {
    r.nonfinite = true;
    r.unstable = e.what();
  }
  r.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.simulated = sim.time();
  r.steps = sim.steps();
  r.spawned = sim.spawned();
  r.exited = static_cast<long>(sim.exit_events().size());
  r.present = static_cast<long>(sim.world().size());
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 3600;
  int threads = 1;
  InputPolicy policy;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seconds" && i + 1 < argc) seconds = std::atof(argv[++i]);
    else if (a == "--threads" && i + 1 < argc) threads = std::atoi(argv[++i]);
    else if (a == "--allow-outside-paths") policy.allow_outside_paths = true;
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "soak: unknown option %s\nusage: soak [--seconds S] [--threads N] SCENARIO...\n", a.c_str());
      return 2;
    } else files.push_back(a);
  }
  if (files.empty() || !(seconds > 0) || threads < 1) {
    std::fprintf(stderr, "usage: soak [--seconds S] [--threads N] SCENARIO...\n");
    return 2;
  }
  bool all_ok = true;
  std::printf("| scenario | simulated s | steps | spawned | exited | present | NaN | centres in solids | lost | duplicated | peak density /m² (t) | wall s | agent-steps/s |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& f : files) {
    SoakResult r;
    try {
      r = soak(f, seconds, threads, policy);
    } catch (const Error& e) {
      std::printf("| %s | error: %s |\n", f.c_str(), e.what());
      all_ok = false;
      continue;
    }
    all_ok = all_ok && r.ok();
    std::printf("| %s | %.0f | %ld | %ld | %ld | %ld | %s | %ld%s | %ld | %ld | %.1f (%.0f s) | %.1f | %.2g |\n", r.name.c_str(),
                r.simulated, r.steps, r.spawned, r.exited, r.present, r.nonfinite ? "**yes**" : "no", r.inside_solid,
                r.inside_solid ? (" (deepest " + std::to_string(r.deepest) + " m)").c_str() : "", r.lost, r.duplicated,
                r.peak_density, r.peak_time, r.wall, r.wall > 0 ? static_cast<double>(r.agent_steps) / r.wall : 0.0);
    if (!r.unstable.empty()) std::printf("<!-- %s: %s -->\n", r.name.c_str(), r.unstable.c_str());
    std::fflush(stdout);
  }
  return all_ok ? 0 : 1;
}
