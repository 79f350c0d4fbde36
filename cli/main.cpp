// crowdmpm: command-line tool over the engine.
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "engine/output.hpp"

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

const char* kValidateHelp =
    "usage: crowdmpm validate SCENARIO [--model MODEL]\n"
    "\n"
    "Parses and checks SCENARIO and the model, places the groups, and prints a summary.\n"
    "Exit status 0 if valid, 1 with a message naming the JSON path otherwise.\n";

struct Args {
  std::vector<std::string> positional;
  std::string out, model;
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
  Model m = !a.model.empty() ? Model::load(a.model) : s.model ? *s.model : Model::default_model();
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

int cmd_validate(const Args& a) {
  if (a.help) { std::fputs(kValidateHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("validate needs exactly one SCENARIO file");
  ScenarioDef s = ScenarioDef::load(a.positional[0]);
  Model m = !a.model.empty() ? Model::load(a.model) : s.model ? *s.model : Model::default_model();
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
      std::fputs(sub == "simulate" ? kSimulateHelp : sub == "validate" ? kValidateHelp : kUsage, stdout);
      return 0;
    }
    Args a = parse_args(argc, argv, 2);
    if (cmd == "simulate") return cmd_simulate(a);
    if (cmd == "validate") return cmd_validate(a);
    usage_error("unknown command '" + cmd + "'");
  } catch (const Error& e) {
    std::fprintf(stderr, "%scrowdmpm: error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%scrowdmpm: internal error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 3;
  }
}
