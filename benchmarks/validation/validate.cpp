// Validation against measurements of real crowds (DESIGN.md section 7): the fundamental diagram
// in a ring corridor and the flow through bottlenecks of several widths, for any model file.
//
//   validate fd --model M [--densities 0.5,1,...] [--threads N] [--warmup S] [--measure S]
//   validate bottleneck --model M [--widths 0.4,0.8,...] [--threads N] [--density D | --density D1,D2,...]
//   validate replay --model M --scenario S --trajectories T --line x0,y0,x1,y1 [--curve CSV]
//   validate measure --trajectories T --box x0,y0,x1,y1   (classic density and speed, 1 /s)
//
// fd: a ring corridor 2.5 m wide (inner radius 6 m, so it bends gently), people placed at the
// density asked for, walking around it (behaviour "orbit", desired speed 1.34 m/s, Weidmann's
// free speed). After `warmup` seconds, the mean speed along the corridor of everyone is sampled
// every second for `measure` seconds: the classic density (people / corridor area) and mean speed
// of a closed system in steady state.
// bottleneck: a waiting crowd at `density` (3.5 /m^2; one value for every width, or one per
// width) fills a room 6 m deep in front of a wall with an opening of width b (0.4 m thick) and
// leaves through it; the flow is the passages
// between the 20th and the 80th percentile over their time span (persons/s).
// Both print CSV on stdout and report the peak count of people in any 1 m x 1 m box (sampled
// every second on a 0.25 m lattice of box positions).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "engine/analysis/validation.hpp"
#include "engine/observe/measure.hpp"
#include "engine/predict/replay.hpp"

using namespace crowdmpm;

namespace {
[[noreturn]] void usage(const std::string& msg) {
  std::fprintf(stderr, "validate: %s\nusage: validate fd|bottleneck|replay --model M [--densities LIST | --widths LIST] "
                       "[--threads N] [--warmup S] [--measure S] [--density D]\n"
                       "       validate replay --model M --scenario S --trajectories T --line x0,y0,x1,y1 [--curve CSV]\n"
                       "       validate measure --trajectories T --box x0,y0,x1,y1\n",
               msg.c_str());
  std::exit(2);
}

// Comma-separated numbers; positive ones only unless `any_sign`.
std::vector<double> parse_list(const std::string& s, bool any_sign = false) {
  std::vector<double> out;
  size_t b = 0;
  while (b < s.size()) {
    size_t e = s.find(',', b);
    if (e == std::string::npos) e = s.size();
    char* end = nullptr;
    const std::string item = s.substr(b, e - b);
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end || !std::isfinite(v) || !(any_sign || v > 0))
      usage("'" + item + "' is not a " + (any_sign ? "number" : "positive number"));
    out.push_back(v);
    b = e + 1;
  }
  return out;
}

int run_fd(const Model& model, const std::vector<double>& densities, int threads, double warmup, double measure) {
  std::printf("rho_target,agents,rho,speed_mean,speed_sd_over_samples,peak_per_m2,wall_seconds\n");
  for (double rho : densities) {
    const auto t0 = std::chrono::steady_clock::now();
    const CorridorResult r = ring_corridor_speed(model, rho, warmup, measure, threads);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%g,%zu,%.3f,%.3f,%.3f,%d,%.1f\n", rho, r.agents, r.density, r.speed, r.speed_sd, r.peak_per_m2, secs);
    std::fflush(stdout);
  }
  return 0;
}

int run_bottleneck(const Model& model, const std::vector<double>& widths, int threads, const std::vector<double>& density) {
  if (density.size() != 1 && density.size() != widths.size())
    usage("--density needs one value, or one per width (" + std::to_string(widths.size()) + ")");
  std::printf("b,density,agents,J,passages_used,t20,t80,peak_per_m2,wall_seconds\n");
  for (size_t i = 0; i < widths.size(); ++i) {
    const double b = widths[i], rho = density[density.size() == 1 ? 0 : i];
    const auto t0 = std::chrono::steady_clock::now();
    const BottleneckResult r = bottleneck_flow(model, b, rho, threads);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%g,%g,%zu,%.3f,%zu,%.2f,%.2f,%d,%.1f\n", b, rho, r.agents, r.flow, r.passages, r.t20, r.t80, r.peak_per_m2, secs);
    std::fflush(stdout);
  }
  return 0;
}
// N(t) of a whole-run replay against the recording, written as "t,recorded,simulated" rows to
// `curve` (if given); one summary row on stdout.
int run_replay(const Model& model, const std::string& scenario, const std::string& trajectories,
               const std::vector<double>& line, int threads, const std::string& curve) {
  if (line.size() != 4) usage("--line needs x0,y0,x1,y1");
  const ScenarioDef sc = ScenarioDef::load(scenario);
  const TrajectorySet rec = TrajectorySet::read(trajectories);
  const auto t0 = std::chrono::steady_clock::now();
  const ReplayResult r = replay_recording(sc, model, rec, PassageLine{Vec2(line[0], line[1]), Vec2(line[2], line[3])}, 30, threads);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("people,placed,passages_recorded,passages_simulated,J_recorded,J_simulated,ratio,duration,wall_seconds\n");
  std::printf("%zu,%zu,%zu,%zu,%.3f,%.3f,%.3f,%.1f,%.1f\n", r.people, r.placed, r.recorded.size(), r.simulated.size(),
              r.recorded_flow, r.simulated_flow, r.recorded_flow > 0 ? r.simulated_flow / r.recorded_flow : 0.0, r.duration, secs);
  if (!curve.empty()) {
    std::FILE* f = std::fopen(curve.c_str(), "w");
    if (!f) throw Error("cannot write " + curve);
    std::fprintf(f, "t,recorded,simulated\n");
    for (double t = 0; t <= r.duration + 1e-9; t += 0.5) {
      const auto n = [&](const std::vector<double>& v) { return std::upper_bound(v.begin(), v.end(), t) - v.begin(); };
      std::fprintf(f, "%.1f,%ld,%ld\n", t, static_cast<long>(n(r.recorded)), static_cast<long>(n(r.simulated)));
    }
    std::fclose(f);
  }
  return 0;
}
// Classic density and speed samples (one a second) in the box of a recording, as CSV rows.
int run_measure(const std::string& trajectories, const std::vector<double>& box) {
  if (box.size() != 4) usage("--box needs x0,y0,x1,y1");
  const TrajectorySet rec = TrajectorySet::read(trajectories);
  std::printf("t,rho,speed\n");
  for (const DensitySpeed& s : classic_density_speed(rec, Vec2(box[0], box[1]), Vec2(box[2], box[3]), 1))
    if (std::isfinite(s.speed)) std::printf("%.2f,%.4f,%.4f\n", s.time, s.density, s.speed);
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) usage("needs fd or bottleneck");
  const std::string what = argv[1];
  std::string model_path;
  std::vector<double> densities = {0.5, 1, 1.5, 2, 2.5, 3, 3.5, 4, 4.5, 5, 5.5, 6};
  std::vector<double> widths = {0.4, 0.8, 1.0, 1.2, 1.8, 2.4, 3.0, 5.0};
  int threads = 1;
  double warmup = 20, measure = 30;
  std::vector<double> density = {3.5};
  std::string scenario, trajectories, curve;
  std::vector<double> line;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--model") model_path = value();
    else if (a == "--densities") densities = parse_list(value());
    else if (a == "--widths") widths = parse_list(value());
    else if (a == "--threads") threads = std::max(1, std::atoi(value().c_str()));
    else if (a == "--warmup") warmup = parse_list(value()).at(0);
    else if (a == "--measure") measure = parse_list(value()).at(0);
    else if (a == "--density") density = parse_list(value());
    else if (a == "--scenario") scenario = value();
    else if (a == "--trajectories") trajectories = value();
    else if (a == "--curve") curve = value();
    else if (a == "--line" || a == "--box") line = parse_list(value(), true);
    else usage("unknown option '" + a + "'");
  }
  try {
    const Model model = model_path.empty() || model_path == "default" ? Model::default_model() : Model::load(model_path);
    if (what == "fd") return run_fd(model, densities, threads, warmup, measure);
    if (what == "bottleneck") return run_bottleneck(model, widths, threads, density);
    if (what == "replay") return run_replay(model, scenario, trajectories, line, threads, curve);
    if (what == "measure") return run_measure(trajectories, line);
    usage("unknown check '" + what + "' (fd or bottleneck)");
  } catch (const Error& e) {
    std::fprintf(stderr, "validate: %s\n", e.what());
    return 1;
  }
}
