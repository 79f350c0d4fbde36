#include "cost_model.hpp"

#include <chrono>
#include <thread>

namespace crowdmpm::bench {

namespace {
constexpr double kTranscendental = 20;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// 16 independent multiply-add chains (the compiler vectorises them with SSE2): 2 flops each.
double compute_kernel(long iters) {
  double acc[16];
  for (int j = 0; j < 16; ++j) acc[j] = 1.0 + j * 1e-3;
  for (long i = 0; i < iters; ++i)
    for (int j = 0; j < 16; ++j) acc[j] = acc[j] * 0.9999999 + 1e-7;
  double s = 0;
  for (double a : acc) s += a;
  return s;
}

double measure_flops(int threads) {
  const long iters = 20000000;
  std::vector<std::thread> pool;
  std::vector<double> sink(static_cast<size_t>(threads));
  auto t0 = std::chrono::steady_clock::now();
  for (int t = 0; t < threads; ++t) pool.emplace_back([&, t] { sink[static_cast<size_t>(t)] = compute_kernel(iters); });
  for (auto& th : pool) th.join();
  double secs = seconds_since(t0);
  volatile double keep = sink[0];
  (void)keep;
  return 2.0 * 16 * static_cast<double>(iters) * threads / secs;
}

double measure_bandwidth(int threads) {
  const size_t n = size_t{1} << 24;  // 3 arrays of 128 MiB
  std::vector<double> a(n, 1.0), b(n, 2.0), c(n, 0.5);
  double best = 0;
  for (int rep = 0; rep < 3; ++rep) {
    std::vector<std::thread> pool;
    auto t0 = std::chrono::steady_clock::now();
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&, t] {
        size_t lo = n * static_cast<size_t>(t) / static_cast<size_t>(threads);
        size_t hi = n * static_cast<size_t>(t + 1) / static_cast<size_t>(threads);
        for (size_t i = lo; i < hi; ++i) a[i] = b[i] + 0.5 * c[i];
      });
    for (auto& th : pool) th.join();
    double secs = seconds_since(t0);
    best = std::max(best, 3.0 * 8 * static_cast<double>(n) / secs);  // 2 reads + 1 write
  }
  return best;
}
}  // namespace

MachineLimits probe_machine(int threads) {
  MachineLimits m;
  m.threads = threads;
  m.gflops_1 = measure_flops(1);
  m.gflops_n = threads > 1 ? measure_flops(threads) : m.gflops_1;
  m.gbytes_1 = measure_bandwidth(1);
  m.gbytes_n = threads > 1 ? measure_bandwidth(threads) : m.gbytes_1;
  return m;
}

std::vector<KernelCost> kernel_costs(const Simulation& sim, const PairStats& st) {
  const double n = static_cast<double>(std::max<size_t>(1, sim.world().size()));
  const double cand = static_cast<double>(st.candidates) / n, pairs = static_cast<double>(st.pairs) / n;
  const double ahead = static_cast<double>(st.ahead) / n;
  const double nodes = static_cast<double>(sim.grid().nodes()) / n;
  // Traction network: 2 in out + out per dense layer, plus each activation (exp-based tanh and
  // softplus: one transcendental each, a few flops around it).
  double mlp = 0;
  const TractionNet& net = sim.model().traction;
  for (const auto& L : net.layers) {
    mlp += 2.0 * L.in * L.out + L.out;
    if (L.activation != Activation::Identity && L.activation != Activation::Relu) mlp += L.out * (kTranscendental + 3);
  }
  if (!net.layers.empty()) mlp += kTranscendental + 4;  // output softplus
  const bool traction = sim.model().has_traction();
  // Bytes: Vec2 16, Mat2 32, double 8, int 4. Agent arrays a kernel reads and writes, once.
  return {
      // desired direction: bilinear navigation lookup (4 cells) and normalise ~30; drive 8.
      {"drive", 38, 16 + 16 + 8 + 4 + 4 + 16 + 16 + 4 * 16},
      // counting sort by cell: cell index 6 flops; reads x, writes cell and order.
      {"neighbours", 6, 16 + 4 + 4 + 4},
      // per candidate ahead: offset 2, along and side 6, lane tests 4, the other's lane 10; per
      // agent: speed and acceleration 8. Reads x, heading, radius, free speed, id of neighbours.
      {"headway", ahead * 22 + 8, 16 + 16 + 8 + 8 + 16},
      // per candidate: difference and length 6; per pair: features 22, network, phi (a log) 4,
      // force and virial 8; per agent: stress (one pow) and pressure 12. Reads x, v, heading,
      // radius, comfort, F, J; writes force, virial, pressure; neighbours' x via the cell lists.
      {"traction", traction ? cand * 6 + pairs * (22 + mlp + kTranscendental + 4 + 8) + kTranscendental + 12 : 12,
       16 + 16 + 16 + 8 + 8 + 32 + 8 + 16 + 8 + 8 + 4},
      // stencil 25, stress (pow) 32, scatter 9 x 29; reads x, v, C, F, J; writes stencil,
      // momentum, affine, stress and reads them back; grid nodes (mass, two velocities) once.
      {"p2g", 25 + kTranscendental + 12 + 9 * 29, 16 + 16 + 32 + 32 + 8 + 2 * (64 + 16 + 32 + 32 + 4) + nodes * 40},
      // per node: two divisions, boundary test ~8; nodes read and written.
      {"grid_update", nodes * 8, nodes * (8 + 16 + 16 + 1) * 2},
      // 9 x (weight 1, dpos 4, PIC/FLIP sums 8, C 12) + update 30; reads grid (cache), x, v, C,
      // J, accel, force; writes x, v, C, J.
      {"g2p", 9 * 25 + 30, 16 + 16 + 32 + 8 + 16 + 16 + 16 + 16 + 32 + 8},
      // signed distance to the nearest solid: domain box 6 (+ per solid, here none).
      {"project", 6, 16},
      {"exits", 2, 16},
  };
}

}  // namespace crowdmpm::bench
