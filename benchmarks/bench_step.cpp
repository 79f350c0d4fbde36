// Throughput benchmark: agent-steps per second of the full crowd-material step (drive, traction
// network, P2G, grid update, G2P, projection) on a dense lattice whose rows walk in opposite
// directions. Prints one CSV row (see benchmarks/README.md for recorded results).
//
//   bench_step [--agents N] [--density D | --spacing S] [--threads T] [--steps S] [--warmup W]
//              [--scenario FILE] [--header] [--profile] [--cost-model] [--backward [--checkpoint K]]
// The default scene is a hexagonal lattice (rows walking east and west) at --density persons/m²
// or with --spacing metres between neighbours (0.6 m is the peers' benchmark, 3.2 /m²).
// --scenario runs a scenario file instead (e.g. scenarios/drill.json); agent-steps then count
// the agents present at each step. --backward times the gradient of a position loss over the
// --steps window (WindowGradient) against the forward pass over the same window.
// --profile prints each kernel's share of the step time; --cost-model adds flops and bytes per
// agent-step and the fraction of this machine's measured limits (cost_model.hpp).
#include <sys/utsname.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "cost_model.hpp"
#include "engine/learn/differentiable.hpp"
#include "engine/sim/simulation.hpp"

using namespace crowdmpm;

int main(int argc, char** argv) {
  long agents = 10000, steps = 200, warmup = 20;
  double density = 5, spacing = 0;
  std::string scenario_file;
  int threads = 1;
  bool header = false, profile = false, cost_model = false, backward = false;
  int checkpoint = 0;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) { std::fprintf(stderr, "%s needs a value\n", a.c_str()); std::exit(2); }
      return argv[++i];
    };
    if (a == "--agents") agents = std::atol(next());
    else if (a == "--density") density = std::atof(next());
    else if (a == "--threads") threads = std::atoi(next());
    else if (a == "--spacing") spacing = std::atof(next());
    else if (a == "--scenario") scenario_file = next();
    else if (a == "--steps") steps = std::atol(next());
    else if (a == "--warmup") warmup = std::atol(next());
    else if (a == "--header") header = true;
    else if (a == "--profile") profile = true;
    else if (a == "--cost-model") profile = cost_model = true;
    else if (a == "--backward") backward = true;
    else if (a == "--checkpoint") checkpoint = std::atoi(next());
    else { std::fprintf(stderr, "unknown option %s\n", a.c_str()); return 2; }
  }
  if (spacing > 0) density = 2 / (std::sqrt(3.0) * spacing * spacing);
  if (agents < 1 || !(density > 0 && density <= 7) || threads < 1 || steps < 1) {
    std::fprintf(stderr, "need --agents >= 1, --density in (0, 7], --threads >= 1, --steps >= 1\n");
    return 2;
  }
  std::unique_ptr<ScenarioDef> scenario;
  std::unique_ptr<Simulation> owned;
  if (!scenario_file.empty()) {
    try {
      scenario = std::make_unique<ScenarioDef>(ScenarioDef::load(scenario_file));
      owned = std::make_unique<Simulation>(*scenario, scenario->model_or_default(), threads);
    } catch (const Error& e) {
      std::fprintf(stderr, "bench_step: %s\n", e.what());
      return 1;
    }
    density = 0;  // not a lattice
  } else {
    // Hexagonal lattice at the requested density, square block, 10 m of free space on each side.
    const double a = std::sqrt(2 / (std::sqrt(3.0) * density)), row = a * std::sqrt(3.0) / 2;
    const long per_row = static_cast<long>(std::ceil(std::sqrt(static_cast<double>(agents) * row / a)));
    const double width = static_cast<double>(per_row) * a;
    const double height = std::ceil(static_cast<double>(agents) / static_cast<double>(per_row)) * row;
    char text[2048];
    std::snprintf(text, sizeof text, R"({"format": "crowdmpm-scenario", "version": 1, "name": "bench",
      "domain": {"min": [-10, -10], "max": [%.3f, %.3f], "cell_size": 0.5},
      "time": {"dt": 0.01, "duration": 1e5, "output_rate": 10},
      "geometry": {"exits": [{"id": "east", "rect": [%.3f, -10, %.3f, %.3f]}, {"id": "west", "rect": [-10, -10, -9.5, %.3f]}]},
      "groups": [{"id": "east", "spawn": {"rect": [0, 0, 1, 1]}, "count": 0, "behaviour": {"type": "goal", "target": "east"}},
                 {"id": "west", "spawn": {"rect": [0, 0, 1, 1]}, "count": 0, "behaviour": {"type": "goal", "target": "west"}}]})",
                  width + 10, height + 10, width + 9.5, width + 10, height + 10, height + 10);
    scenario = std::make_unique<ScenarioDef>(ScenarioDef::parse_text(text));
    owned = std::make_unique<Simulation>(*scenario, Model::default_model(), threads);
    const int east = 1, west = 2;  // behaviours of the two groups (0 is "none")
    std::vector<AgentDef> defs(static_cast<size_t>(agents));
    for (long k = 0; k < agents; ++k) {
      AgentDef& d = defs[static_cast<size_t>(k)];
      long r = k / per_row, c = k % per_row;
      d.position = Vec2((static_cast<double>(c) + 0.5 * static_cast<double>(r & 1)) * a + 0.05, static_cast<double>(r) * row + 0.05);
      d.behaviour = (r & 1) ? west : east;
      d.group = (r & 1) ? 1 : 0;
      d.velocity = Vec2((r & 1) ? -1.0 : 1.0, 0);
    }
    owned->add_agents(defs);
  }
  Simulation& sim = *owned;
  sim.run_steps(warmup);
  if (backward) {
    // Forward alone, then forward with stored states plus the backward pass, same window.
    std::vector<Vec2> x0 = sim.world().x, v0 = sim.world().v;
    std::vector<Mat2> C0 = sim.world().C;
    std::vector<double> J0 = sim.world().J;
    auto reset = [&]() {
      sim.world().x = x0;
      sim.world().v = v0;
      sim.world().C = C0;
      sim.world().J = J0;
    };
    auto t0 = std::chrono::steady_clock::now();
    sim.run_steps(steps);
    const double forward = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    reset();
    WindowGradient wg(checkpoint);
    t0 = std::chrono::steady_clock::now();
    ModelGradient g = wg.run(sim, static_cast<int>(steps), [](int, const World& w, std::vector<Vec2>& d, std::vector<Vec2>&) {
      for (size_t p = 0; p < w.size(); ++p) d[p] = w.x[p];  // gradient of 0.5 |x|^2
      return true;
    });
    const double both = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("backward,agents=%ld,steps=%ld,threads=%d,checkpoint_every=%d,forward_s=%.3f,"
                "forward_with_storage_and_backward_s=%.3f,backward_over_forward=%.2f,stored_bytes_per_agent_step=%zu,"
                "peak_stored_steps=%zu,dE=%.4g\n",
                agents, steps, threads, checkpoint, forward, both, (both - forward) / forward, wg.stored_bytes_per_agent_step(),
                wg.peak_stored_steps(), g.params.E);
    return 0;
  }
  sim.set_profiling(profile);
  double agent_steps = 0;
  auto t0 = std::chrono::steady_clock::now();
  for (long k = 0; k < steps; ++k) {
    agent_steps += static_cast<double>(sim.world().size());
    sim.step();
  }
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double rate = agent_steps / secs;
  agents = std::lround(agent_steps / static_cast<double>(steps));
  long pairs = 0;
  for (size_t p = 0; p < sim.world().size(); ++p) pairs += sim.world().pair_virial[p] > 0;
  struct utsname u;
  uname(&u);
  if (header) std::printf("machine,compiler,flags,scene,agents,density,threads,steps,seconds,agent_steps_per_s,agents_in_contact\n");
  std::printf("%s %s,%s,%s,%s,%ld,%.2f,%d,%ld,%.3f,%.0f,%ld\n", u.sysname, u.machine,
#if defined(__clang__)
              "clang " __clang_version__,
#else
              "gcc " __VERSION__,
#endif
              CROWDMPM_BENCH_FLAGS, scenario_file.empty() ? "lattice" : scenario->name.c_str(), agents, density, threads, steps, secs, rate, pairs);
  if (profile) {
    const StepProfile& pr = sim.profile();
    double total = 0;
    for (double x : pr.seconds) total += x;
    std::vector<bench::KernelCost> costs;
    bench::MachineLimits lim{};
    if (cost_model) {
      costs = bench::kernel_costs(sim, sim.pair_stats());
      lim = bench::probe_machine(threads);
      std::fprintf(stderr, "machine limits (%d thread%s): compute %.2f GFLOP/s (1 thread %.2f), triad bandwidth %.2f GB/s (1 thread %.2f)\n",
                   threads, threads > 1 ? "s" : "", lim.gflops_n / 1e9, lim.gflops_1 / 1e9, lim.gbytes_n / 1e9, lim.gbytes_1 / 1e9);
      PairStats ps = sim.pair_stats();
      std::fprintf(stderr, "neighbours per agent: %.1f candidates, %.1f within reach\n",
                   static_cast<double>(ps.candidates) / static_cast<double>(agents), static_cast<double>(ps.pairs) / static_cast<double>(agents));
      std::fprintf(stderr, "%-12s %6s %9s %8s %8s %8s %7s %7s %7s\n", "kernel", "share", "ns/a-s", "flop/a-s", "B/a-s",
                   "GFLOP/s", "GB/s", "%peakF", "%peakB");
    }
    for (int k = 0; k < StepProfile::kParts; ++k) {
      const double ns = 1e9 * pr.seconds[k] / (static_cast<double>(agents) * static_cast<double>(pr.steps));
      const bench::KernelCost* c = nullptr;
      for (const auto& kc : costs)
        if (kc.name == StepProfile::kNames[k]) c = &kc;
      if (!c) {
        std::fprintf(stderr, "  %-12s %6.1f%% %9.1f\n", StepProfile::kNames[k], 100 * pr.seconds[k] / total, ns);
        continue;
      }
      const double gf = c->flops / ns, gb = c->bytes / ns;  // per ns = G per s
      std::fprintf(stderr, "%-12s %5.1f%% %9.1f %8.0f %8.0f %8.2f %7.2f %6.1f%% %6.1f%%\n", StepProfile::kNames[k],
                   100 * pr.seconds[k] / total, ns, c->flops, c->bytes, gf, gb, 100 * gf * 1e9 / lim.gflops_n,
                   100 * gb * 1e9 / lim.gbytes_n);
    }
  }
  return 0;
}
