#include "engine/analysis/validation.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace crowdmpm {

// Most people in any 1 m x 1 m box whose corner lies on a 0.25 m lattice.
int peak_box_count(const World& w) {
  if (w.size() == 0) return 0;
  Vec2 lo = w.x[0], hi = w.x[0];
  for (const Vec2& x : w.x) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const double h = 0.25;
  const int nx = static_cast<int>((hi.x() - lo.x()) / h) + 5, ny = static_cast<int>((hi.y() - lo.y()) / h) + 5;
  std::vector<int> cells(static_cast<size_t>(nx) * static_cast<size_t>(ny), 0);
  for (const Vec2& x : w.x) {
    const int i = static_cast<int>((x.x() - lo.x()) / h) + 4, j = static_cast<int>((x.y() - lo.y()) / h) + 4;
    ++cells[static_cast<size_t>(j) * static_cast<size_t>(nx) + static_cast<size_t>(i)];
  }
  int best = 0;
  for (int j = 3; j < ny; ++j)
    for (int i = 3; i < nx; ++i) {
      int n = 0;
      for (int dj = 0; dj < 4; ++dj)
        for (int di = 0; di < 4; ++di) n += cells[static_cast<size_t>(j - dj) * static_cast<size_t>(nx) + static_cast<size_t>(i - di)];
      best = std::max(best, n);
    }
  return best;
}


CorridorResult ring_corridor_speed(const Model& model, double rho, double warmup, double measure, int threads) {
  const double r_in = 6, r_out = 8.5;
  const double area = M_PI * (r_out * r_out - r_in * r_in);
  const std::string scenario = R"({"format": "crowdmpm-scenario", "version": 1, "name": "ring corridor",
    "domain": {"min": [-9.5, -9.5], "max": [9.5, 9.5], "cell_size": 0.5},
    "time": {"dt": 0.01, "duration": )" + format_number(warmup + measure + 1) + R"(},
    "geometry": {"walls": [{"arc": {"center": [0, 0], "radius": )" + format_number(r_out + 0.1) + R"(, "from": 0, "to": 360}, "thickness": 0.2}],
                 "obstacles": [{"circle": {"center": [0, 0], "radius": )" + format_number(r_in) + R"(}}]},
    "groups": [{"spawn": {"circle": {"center": [0, 0], "radius": )" + format_number(r_out) + R"(}}, "density": )" + format_number(rho) + R"(,
                "desired_speed": 1.34, "behaviour": {"type": "orbit", "center": [0, 0]}}]})";
  Simulation sim(ScenarioDef::parse_text(scenario), model, threads);
  const World& w = sim.world();
  const long per_second = std::lround(1 / sim.scenario().dt);
  sim.run_steps(std::lround(warmup) * per_second);
  std::vector<double> samples;
  CorridorResult r;
  for (long s = 0; s < std::lround(measure); ++s) {
    sim.run_steps(per_second);
    double sum = 0;
    for (size_t p = 0; p < w.size(); ++p) {
      const Vec2 x = w.x[p];
      sum += w.v[p].dot(Vec2(-x.y(), x.x()) / std::max(x.norm(), 1e-9));  // along the counter-clockwise tangent
    }
    samples.push_back(w.size() ? sum / static_cast<double>(w.size()) : 0);
    r.peak_per_m2 = std::max(r.peak_per_m2, peak_box_count(w));
  }
  for (double v : samples) r.speed += v / static_cast<double>(samples.size());
  for (double v : samples) r.speed_sd += (v - r.speed) * (v - r.speed) / static_cast<double>(samples.size());
  r.speed_sd = std::sqrt(r.speed_sd);
  r.agents = w.size();
  r.density = static_cast<double>(w.size()) / area;
  return r;
}

BottleneckResult bottleneck_flow(const Model& model, double b, double density, int threads, double people, uint64_t seed) {
  const double W = std::max(8.0, b + 6), depth = std::max(6.0, people / (W * density)), y0 = W / 2 - b / 2, y1 = W / 2 + b / 2;
  const std::string scenario = R"({"format": "crowdmpm-scenario", "version": 1, "name": "bottleneck", "seed": )" +
                               std::to_string(seed) + R"(,
    "domain": {"min": [0, 0], "max": [)" + format_number(depth + 2.4) + ", " + format_number(W) + R"(], "cell_size": 0.5},
    "time": {"dt": 0.01, "duration": 400},
    "geometry": {"obstacles": [{"rect": [)" + format_number(depth) + ", 0, " + format_number(depth + 0.4) + ", " + format_number(y0) + R"(]},
                               {"rect": [)" + format_number(depth) + ", " + format_number(y1) + ", " + format_number(depth + 0.4) + ", " + format_number(W) + R"(]}],
                 "exits": [{"id": "out", "rect": [)" + format_number(depth + 1.4) + ", 0, " + format_number(depth + 2.4) + ", " + format_number(W) + R"(]}]},
    "groups": [{"spawn": {"rect": [0, 0, )" + format_number(depth) + ", " + format_number(W) + R"(]}, "density": )" + format_number(density) + R"(,
                "desired_speed": 1.34, "behaviour": {"type": "goal", "target": "out"}}]})";
  Simulation sim(ScenarioDef::parse_text(scenario), model, threads);
  BottleneckResult r;
  r.agents = sim.world().size();
  const long per_second = std::lround(1 / sim.scenario().dt);
  r.peak_per_m2 = peak_box_count(sim.world());
  while (!sim.finished()) {
    sim.run_steps(per_second);
    r.peak_per_m2 = std::max(r.peak_per_m2, peak_box_count(sim.world()));
  }
  const auto& ev = sim.exit_events();
  if (ev.size() < 10) {  // a jam that never clears: no flow
    r.passages = ev.size();
    return r;
  }
  const size_t k20 = ev.size() / 5, k80 = (ev.size() * 4) / 5;
  r.t20 = ev[k20].time;
  r.t80 = ev[k80].time;
  r.passages = k80 - k20;
  if (r.t80 > r.t20) r.flow = static_cast<double>(r.passages) / (r.t80 - r.t20);
  return r;
}

}  // namespace crowdmpm
