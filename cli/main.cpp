// crowdmpm: command-line tool over the engine.
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "engine/output.hpp"
#include "engine/predict.hpp"
#include "engine/render.hpp"

using namespace crowdmpm;

namespace {

const char* kUsage =
    "usage: crowdmpm <command> [options]\n"
    "\n"
    "commands:\n"
    "  simulate SCENARIO --out DIR [--model MODEL] [--threads N] [--duration S] [--quiet]\n"
    "                      run a scenario and write trajectories, fields, pictures, a video\n"
    "                      and metrics.json to DIR\n"
    "  validate SCENARIO [--model MODEL]\n"
    "                      check a scenario (and model) and print what it contains\n"
    "  predict --scenario S --trajectories T [--model M] [--observe S] [--horizon S]\n"
    "          [--stride S] [--windows N] [--threads N] [--out DIR]\n"
    "                      roll recorded states forward and report ADE/FDE against the\n"
    "                      recording, for constant velocity and the crowd model\n"
    "                      check a scenario (and model) and print what it contains\n"
    "  help [COMMAND]      show help\n"
    "\n"
    "Run 'crowdmpm <command> --help' for the options of one command.\n";

const char* kSimulateHelp =
    "usage: crowdmpm simulate SCENARIO --out DIR [options]\n"
    "\n"
    "Runs SCENARIO (a crowdmpm-scenario JSON file) and writes into DIR:\n"
    "  trajectories.txt   PeTrack text: id frame x y z (metres), '# framerate:' header\n"
    "  density.npy, velocity.npy, pressure.npy, fields.json\n"
    "                     per-frame grid fields (float32, shape frames x ny x nx [x 2])\n"
    "  pressure_mean.png, pressure_peak.png, density_mean.png, final.png\n"
    "  particles.mp4      particles coloured by pressure\n"
    "  metrics.json       agents remaining, exit flow N(t), evacuation time, peaks, areas\n"
    "\n"
    "options:\n"
    "  --out DIR          output folder (created if missing); required\n"
    "  --model MODEL      crowdmpm-model JSON to use instead of the scenario's model\n"
    "  --threads N        worker threads (results are identical for any N); default 1\n"
    "  --duration S       override time.duration (seconds)\n"
    "  --quiet            no progress bar\n";

const char* kPredictHelp =
    "usage: crowdmpm predict --scenario S --trajectories T [options]\n"
    "\n"
    "Takes the recorded state (positions; velocities over the last 0.5 s) at window starts\n"
    "every --stride seconds after the first --observe seconds, rolls it forward --horizon\n"
    "seconds with constant velocity and with the crowd model in the scenario's venue, and\n"
    "prints average and final displacement errors (ADE/FDE, m) at every whole second.\n"
    "People are compared only while both the recording and the prediction have them.\n"
    "\n"
    "options:\n"
    "  --scenario S       crowdmpm-scenario JSON with the recording's geometry (its first\n"
    "                     group's behaviour is given to the observed people)\n"
    "  --trajectories T   PeTrack text file (id frame x y [z], '# framerate:' header)\n"
    "  --model M          crowdmpm-model JSON (default: the scenario's, else built-in)\n"
    "  --observe S        seconds of recording before the first window (default 2)\n"
    "  --horizon S        seconds to predict (default 4)\n"
    "  --stride S         seconds between window starts (default: the horizon)\n"
    "  --windows N        at most N windows (default all)\n"
    "  --threads N        worker threads (default 1)\n"
    "  --out DIR          write prediction.json and prediction.png (first window's paths)\n";

const char* kValidateHelp =
    "usage: crowdmpm validate SCENARIO [--model MODEL]\n"
    "\n"
    "Parses and checks SCENARIO and the model, places the groups, and prints a summary.\n"
    "Exit status 0 if valid, 1 with a message naming the JSON path otherwise.\n";

struct Args {
  std::vector<std::string> positional;
  std::string out, model, scenario, trajectories;
  double observe = 2, horizon = 4, stride = -1;
  int windows = 0;
  int threads = 1;
  double duration = -1;
  bool quiet = false, help = false;
};

[[noreturn]] void usage_error(const std::string& msg) {
  std::fprintf(stderr, "crowdmpm: %s\n(run 'crowdmpm help' for usage)\n", msg.c_str());
  std::exit(2);
}

Args parse_args(int argc, char** argv, int first) {
  Args a;
  for (int i = first; i < argc; ++i) {
    std::string s = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) usage_error(std::string(name) + " needs a value");
      return argv[++i];
    };
    if (s == "--help" || s == "-h") a.help = true;
    else if (s == "--out") a.out = value("--out");
    else if (s == "--model") a.model = value("--model");
    else if (s == "--quiet") a.quiet = true;
    else if (s == "--scenario") a.scenario = value("--scenario");
    else if (s == "--trajectories") a.trajectories = value("--trajectories");
    else if (s == "--observe" || s == "--horizon" || s == "--stride") {
      std::string v = value(s.c_str());
      char* end = nullptr;
      double d = std::strtod(v.c_str(), &end);
      if (*end || !(d > 0) || d > 1e5) usage_error(s + " must be a number of seconds > 0, got '" + v + "'");
      (s == "--observe" ? a.observe : s == "--horizon" ? a.horizon : a.stride) = d;
    } else if (s == "--windows") {
      std::string v = value("--windows");
      char* end = nullptr;
      long n = std::strtol(v.c_str(), &end, 10);
      if (*end || n < 1 || n > 1000000) usage_error("--windows must be a whole number >= 1, got '" + v + "'");
      a.windows = static_cast<int>(n);
    }
    else if (s == "--threads") {
      std::string v = value("--threads");
      char* end = nullptr;
      long n = std::strtol(v.c_str(), &end, 10);
      if (*end || n < 1 || n > 256) usage_error("--threads must be a whole number in [1, 256], got '" + v + "'");
      a.threads = static_cast<int>(n);
    } else if (s == "--duration") {
      std::string v = value("--duration");
      char* end = nullptr;
      double d = std::strtod(v.c_str(), &end);
      if (*end || !(d > 0) || d > 1e6) usage_error("--duration must be a number of seconds in (0, 1e6], got '" + v + "'");
      a.duration = d;
    } else if (!s.empty() && s[0] == '-') usage_error("unknown option '" + s + "'");
    else a.positional.push_back(s);
  }
  return a;
}

bool g_progress_line = false;  // a progress bar is on the terminal line: end it before errors

void progress_bar(double t, double duration, size_t agents) {
  g_progress_line = true;
  const int width = 40;
  double f = duration > 0 ? std::min(1.0, t / duration) : 1;
  int filled = static_cast<int>(f * width);
  std::fprintf(stderr, "\r[%.*s%*s] %5.1f / %.1f s  %zu agents ", filled, "========================================",
               width - filled, "", t, duration, agents);
  std::fflush(stderr);
}

int cmd_simulate(const Args& a) {
  if (a.help) { std::fputs(kSimulateHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("simulate needs exactly one SCENARIO file");
  if (a.out.empty()) usage_error("simulate needs --out DIR");
  ScenarioDef s = ScenarioDef::load(a.positional[0]);
  if (a.duration > 0) s.duration = a.duration;
  Model m = !a.model.empty() ? Model::load(a.model) : s.model_or_default();
  RunOptions opt;
  opt.out_dir = a.out;
  opt.threads = a.threads;
  bool tty = isatty(fileno(stderr)) && !a.quiet;
  if (tty) opt.progress = progress_bar;
  RunSummary r = run_scenario(s, m, opt);
  if (tty) std::fputc('\n', stderr);
  char evac[64] = "not complete";
  if (r.evacuation_time) std::snprintf(evac, sizeof evac, "%.1f s", *r.evacuation_time);
  std::printf("%s: %.1f s simulated in %.1f s (%ld steps, %d thread%s); %ld spawned, %ld exited, %zu remaining; "
              "evacuation %s; peak density %.2f /m2 at (%.1f, %.1f) t=%.1f s; peak pressure %.2f at (%.1f, %.1f) t=%.1f s; outputs in %s\n",
              s.name.c_str(), r.time, r.wall_seconds, r.steps, a.threads, a.threads == 1 ? "" : "s", r.spawned, r.exited,
              r.remaining, evac, r.peak_density.value, r.peak_density.where.x(), r.peak_density.where.y(), r.peak_density.time,
              r.peak_pressure.value, r.peak_pressure.where.x(), r.peak_pressure.where.y(), r.peak_pressure.time, a.out.c_str());
  return 0;
}

int cmd_predict(const Args& a) {
  if (a.help) { std::fputs(kPredictHelp, stdout); return 0; }
  if (a.scenario.empty() || a.trajectories.empty()) usage_error("predict needs --scenario and --trajectories");
  if (!a.positional.empty()) usage_error("predict takes no positional arguments (got '" + a.positional[0] + "')");
  ScenarioDef s = ScenarioDef::load(a.scenario);
  Model m = !a.model.empty() ? Model::load(a.model) : s.model_or_default();
  TrajectorySet t = TrajectorySet::read(a.trajectories);
  PredictOptions o;
  o.observe = a.observe;
  o.horizon = a.horizon;
  o.stride = a.stride > 0 ? a.stride : a.horizon;
  o.threads = a.threads;
  o.max_windows = a.windows;
  if (o.observe + o.horizon > t.duration())
    usage_error("--observe + --horizon (" + format_number(o.observe + o.horizon) + " s) exceed the recording (" +
                format_number(t.duration()) + " s)");
  std::vector<PredictionReport> reports = {
      evaluate_predictor("constant velocity", t, o, constant_velocity_predictor()),
      evaluate_predictor(std::string("crowd model (") + material_name(m.material) + ")", t, o, simulation_predictor(s, m, a.threads))};
  std::printf("%s: %zu people, %.1f s at %g fps; %ld windows of %g s\n", a.trajectories.c_str(), t.person_count(),
              t.duration(), t.framerate, reports[0].windows, o.horizon);
  std::printf("%-28s", "method");
  for (const auto& h : reports[0].horizons) std::printf("   ADE@%gs  FDE@%gs", h.horizon, h.horizon);
  std::printf("\n");
  for (const auto& r : reports) {
    std::printf("%-28s", r.method.c_str());
    for (const auto& h : r.horizons) std::printf("  %7.3f  %7.3f", h.ade, h.fde);
    std::printf("\n");
  }
  if (!a.out.empty()) {
    std::filesystem::create_directories(a.out);
    json j = {{"scenario", a.scenario}, {"trajectories", a.trajectories}, {"observe_s", o.observe},
              {"horizon_s", o.horizon}, {"stride_s", o.stride}, {"units", "metres"}, {"methods", json::array()}};
    for (const auto& r : reports) j["methods"].push_back(report_to_json(r));
    std::ofstream(a.out + "/prediction.json") << j.dump(2) << "\n";
    // Paths of the first window: recorded, constant velocity, model.
    long f0 = t.frame_min() + std::lround(o.observe * t.framerate);
    ObservedState st = observe_at(t, f0, o.velocity_window);
    std::vector<double> times;
    for (long k = 1; k <= std::lround(o.horizon * t.framerate); ++k) times.push_back(static_cast<double>(k) / t.framerate);
    auto as_paths = [&](const std::vector<std::vector<Vec2>>& per_time) {
      std::vector<std::vector<Vec2>> paths(st.ids.size());
      for (size_t i = 0; i < st.ids.size(); ++i) {
        paths[i].push_back(st.x[i]);
        for (const auto& row : per_time) paths[i].push_back(row[i]);
      }
      return paths;
    };
    std::vector<std::vector<Vec2>> recorded(times.size(), std::vector<Vec2>(st.ids.size(), Vec2(NAN, NAN)));
    for (size_t k = 0; k < times.size(); ++k) {
      auto [b, e] = t.frame(f0 + static_cast<long>(k) + 1);
      for (auto p = b; p != e; ++p)
        for (size_t i = 0; i < st.ids.size(); ++i)
          if (st.ids[i] == p->id) recorded[k][i] = Vec2(p->x, p->y);
    }
    std::vector<PathSet> sets = {{"recorded", 60, 160, 60, as_paths(recorded)},
                                 {"const. velocity", 200, 120, 40, as_paths(constant_velocity_predictor()(st, times))},
                                 {"crowd model", 40, 40, 210, as_paths(simulation_predictor(s, m, a.threads)(st, times))}};
    write_paths_png(a.out + "/prediction.png", s.geo, View::fit(s.geo, s.outputs.pixels_per_metre), sets,
                    "prediction from t = " + format_number(o.observe) + " s, " + format_number(o.horizon) + " s ahead");
    std::printf("wrote %s/prediction.json and %s/prediction.png\n", a.out.c_str(), a.out.c_str());
  }
  return 0;
}

int cmd_validate(const Args& a) {
  if (a.help) { std::fputs(kValidateHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("validate needs exactly one SCENARIO file");
  ScenarioDef s = ScenarioDef::load(a.positional[0]);
  Model m = !a.model.empty() ? Model::load(a.model) : s.model_or_default();
  Simulation sim(s, m, 1);
  std::printf("%s: valid. domain [%g, %g] x [%g, %g] m, cell %g m, dt %g s, duration %g s; %zu solids, %zu exits, "
              "%zu groups/sources, %zu agents placed; material %s\n",
              a.positional[0].c_str(), s.geo.lo.x(), s.geo.hi.x(), s.geo.lo.y(), s.geo.hi.y(), s.cell_size, s.dt, s.duration,
              s.geo.solids.size(), s.geo.exits.size(), s.groups.size(), sim.world().size(), material_name(m.material));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  std::string cmd = argv[1];
  try {
    if (cmd == "help" || cmd == "--help" || cmd == "-h") {
      std::string sub = argc > 2 ? argv[2] : "";
      std::fputs(sub == "simulate" ? kSimulateHelp : sub == "validate" ? kValidateHelp : sub == "predict" ? kPredictHelp : kUsage, stdout);
      return 0;
    }
    Args a = parse_args(argc, argv, 2);
    if (cmd == "simulate") return cmd_simulate(a);
    if (cmd == "validate") return cmd_validate(a);
    if (cmd == "predict") return cmd_predict(a);
    usage_error("unknown command '" + cmd + "'");
  } catch (const Error& e) {
    std::fprintf(stderr, "%scrowdmpm: error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%scrowdmpm: internal error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 3;
  }
}
