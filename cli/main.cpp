// crowdmpm: command-line tool over the engine.
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <cmath>
#include <filesystem>

#include "engine/core/output.hpp"
#include "engine/run/runner.hpp"
#include "engine/diagnosis/diagnose.hpp"
#include "engine/predict/predict.hpp"
#include "engine/io/render.hpp"
#include "engine/learn/train.hpp"
#include "engine/sim/snapshot.hpp"
#include "engine/vision/synthetic.hpp"
#include "engine/vision/video_job.hpp"
#include "engine/vision/video_learn.hpp"
#include "engine/observe/analyze.hpp"
#include "engine/observe/jpsreport.hpp"
#include "engine/report/report.hpp"

using namespace crowdmpm;

namespace {

const char* kUsage =
    "usage: crowdmpm <command> [options]\n"
    "\n"
    "commands:\n"
    "  simulate SCENARIO --out DIR [--model MODEL] [--threads N] [--duration S] [--quiet]\n"
    "           [--save-snapshot FILE [--snapshot-at S]]\n"
    "  simulate --resume SNAPSHOT --out DIR [--threads N] [--duration S]\n"
    "                      run a scenario (or continue a saved world) and write trajectories,\n"
    "                      fields, pictures, a video and metrics.json to DIR\n"
    "  validate SCENARIO [--model MODEL]\n"
    "                      check a scenario (and model) and print what it contains\n"
    "  predict --scenario S --trajectories T [--model M]... [--observe S] [--horizon S]\n"
    "          [--stride S] [--windows N] [--desired-speed observed|scenario|free]\n"
    "          [--threads N] [--out DIR]\n"
    "                      roll recorded states forward and report ADE/FDE and grid\n"
    "                      velocity errors against the recording, for constant velocity,\n"
    "                      the untrained default model and every model given\n"
    "  train --scenario S --trajectories T [T...] [--scenario S2 --trajectories ...]\n"
    "        --out MODEL.json [--model START] [options]\n"
    "  train --video V (--calibration CAL | --scale S) [--scenario S] --out MODEL.json\n"
    "  predict --video V (--calibration CAL | --scale S) [--scenario S] [--model M]...\n"
    "                      learn the material from recordings by gradient descent through\n"
    "                      the simulator; writes a model JSON the simulator loads\n"
    "  flow VIDEO --out DIR (--calibration CAL | --scale M_PER_PX) [options]\n"
    "                      optical flow of a video, rectified to the ground and splatted\n"
    "                      onto the simulator's grid: fields.npy and pictures\n"
    "  render-video SCENARIO --out DIR [options]\n"
    "                      film a simulated crowd through a tilted camera (synthetic video\n"
    "                      with its calibration and true grid velocity)\n"
    "  diagnose --scenario S (--observed T | --video V (--calibration C | --scale S)) --out DIR [options]\n"
    "                      find physics the scenario lacks: locate where the fitted model\n"
    "                      and the recording disagree, fit candidate terms, keep those that\n"
    "                      lower the held-out error (report.json, pictures, summary.txt)\n"
    "  analyze TRAJECTORIES --out DIR (--spec MEASUREMENTS.json | --scenario S)\n"
    "  analyze JPSREPORT_INI_OR_FOLDER --out DIR\n"
    "                      PedPy-style measurements of any trajectory file (text or JuPedSim\n"
    "                      SQLite): classic and Voronoi density and speed, N(t) over lines,\n"
    "                      fundamental diagram, level of service, crowd pressure\n"
    "  report DIR [--out FILE] [--scenario S]\n"
    "                      one self-contained HTML page of a simulate output folder: maps,\n"
    "                      N(t), evacuation time, areas over time, level of service, crowd\n"
    "                      pressure, the video\n"
    "  help [COMMAND]      show help\n"
    "\n"
    "Run 'crowdmpm <command> --help' for the options of one command.\n"
    "\n"
    "input options (every command):\n"
    "  --max-input-mb N   refuse input files above N MiB (default 256)\n"
    "  --allow-outside-paths\n"
    "                     let a scenario name model and extends files outside its folder\n";

const char* kDiagnoseHelp =
    "usage: crowdmpm diagnose --scenario S --observed TRAJECTORIES --out DIR [options]\n"
    "       crowdmpm diagnose --scenario S --video V (--calibration CAL | --scale S) --out DIR [options]\n"
    "\n"
    "Fits the model (its v0_scale, tau and time_gap, and Weidmann's speed-density law added\n"
    "to a material without one, option density_law; everyone walking at the recording's\n"
    "typical free speed, or each at their own pace where that fits far better, option\n"
    "desired_speed) on the recording's first part, locates\n"
    "where it and the recording still disagree (residuals of short rollouts restarted from the\n"
    "recorded state, tested against the fitted model's own noise), fits candidate force terms\n"
    "there (obstacle, constriction, drift, attractor, vortex, slow_zone, wall_friction,\n"
    "density_speed, counterflow) through the simulator and accepts a term only when it lowers the error on\n"
    "the recording's held-out last part clearly beyond noise\n"
    "(docs/diagnosis.md). Writes into DIR:\n"
    "  report.json        verdict, regions, hypotheses, accepted terms, held-out errors\n"
    "  summary.txt        what was found, in plain language\n"
    "  residual_before.png, residual_after.png\n"
    "                     residual velocity maps of the fitted baseline and with the terms\n"
    "  scenario.json, model.json\n"
    "                     the venue with the accepted terms and the refitted model\n"
    "\n"
    "options:\n"
    "  --scenario S       the venue the user believes (crowdmpm-scenario JSON); required\n"
    "  --observed T       the recording (PeTrack text; --trajectories is the same)\n"
    "  --video V          or a video: its people, detected in every frame and followed by its\n"
    "                     optical flow, are the recording (written to DIR/video_tracks.txt);\n"
    "                     with --calibration CAL or --scale S, and --first, --frames, --fps,\n"
    "                     --method (default farneback), --smoothing as 'crowdmpm flow'; other\n"
    "                     video options (\"tracks\": \"flow\" for a crowd too dense to see each\n"
    "                     person) in a request: docs/diagnosis.md\n"
    "  --out DIR          output folder; required\n"
    "  --model M          material model to start from (default: the scenario's)\n"
    "  --train-share F    first share of the recording for fitting (default 0.6)\n"
    "  --candidates A,B   candidate types to try (default: all)\n"
    "  --iterations N     optimiser iterations per fit (default 60)\n"
    "  --seed N           seed of the null simulations and minibatches\n"
    "  --threads N        worker threads (default: the machine's cores)\n"
    "  --options JSON     any other option of a diagnosis request, e.g.\n"
    "                     '{\"null_replicates\": 8, \"min_gain\": 0.15, \"cell\": 0.5}'\n";

const char* kSimulateHelp =
    "usage: crowdmpm simulate SCENARIO --out DIR [options]\n"
    "       crowdmpm simulate --resume SNAPSHOT --out DIR [options]\n"
    "\n"
    "Runs SCENARIO (a crowdmpm-scenario JSON file) and writes into DIR:\n"
    "  trajectories.txt   PeTrack text: id frame x y z (metres), '# framerate:' header\n"
    "  trajectories.sqlite  the same in JuPedSim's SQLite format (version 2, read by PedPy)\n"
    "  density.npy, velocity.npy, pressure.npy, fields.json\n"
    "                     per-frame grid fields (float32, shape frames x ny x nx [x 2])\n"
    "  pressure_mean.png, pressure_peak.png, density_mean.png, final.png\n"
    "  particles.mp4      particles coloured by pressure\n"
    "  metrics.json       agents remaining, exit flow N(t), evacuation time, peaks, areas\n"
    "\n"
    "options:\n"
    "  --out DIR          output folder (created if missing); required\n"
    "  --model MODEL      crowdmpm-model JSON to use instead of the scenario's model\n"
    "  --threads N        worker threads (results are identical for any N); default: the\n"
    "                     machine's cores\n"
    "  --duration S       override time.duration (seconds; with --resume, the simulated time\n"
    "                     at which the continued run ends)\n"
    "  --quiet            no progress bar\n"
    "  --save-snapshot FILE\n"
    "                     save the running world to FILE (docs/snapshot-format.md): at the\n"
    "                     first step reaching --snapshot-at S seconds, else at the end\n"
    "  --resume SNAPSHOT  continue a saved world (its scenario and model are in the file)\n"
    "                     to its duration; it continues exactly as the uninterrupted run,\n"
    "                     and DIR's outputs cover the time from the snapshot on\n";

const char* kPredictHelp =
    "usage: crowdmpm predict --scenario S --trajectories T [options]\n"
    "\n"
    "Takes the recorded state (positions; velocities over the last 0.5 s) at window starts\n"
    "every --stride seconds after the first --observe seconds, rolls it forward --horizon\n"
    "seconds with constant velocity, the untrained default model and every --model given, in\n"
    "the scenario's venue, and\n"
    "prints average and final displacement errors (ADE/FDE, m) at every whole second, and the\n"
    "grid velocity error at the horizon (m/s: per window, the RMS over grid nodes of the\n"
    "difference of predicted and recorded velocity fields; averaged over windows).\n"
    "People are compared only while both the recording and the prediction have them.\n"
    "\n"
    "options:\n"
    "  --scenario S       crowdmpm-scenario JSON with the recording's geometry (its first\n"
    "                     group's behaviour is given to the observed people)\n"
    "  --trajectories T   PeTrack text file (id frame x y [z], '# framerate:' header)\n"
    "  --model M          crowdmpm-model JSON to evaluate; repeat for several (the untrained\n"
    "                     default, the scenario's model or the built-in one, is always shown)\n"
    "  --desired-speed observed|scenario|free\n"
    "                     desired speed of the observed people (default observed: each\n"
    "                     person's walking speed over the last second; free: the 90th\n"
    "                     percentile of their walking speed along their track so far,\n"
    "                     each speed divided by the model's density-speed factor where\n"
    "                     it has one; scenario: the group's), times v0_scale\n"
    "  --observe S        seconds of recording before the first window (default 2)\n"
    "  --horizon S        seconds to predict (default 4)\n"
    "  --stride S         seconds between window starts (default: the horizon)\n"
    "  --windows N        at most N windows (default all)\n"
    "  --threads N        worker threads (default: the machine's cores)\n"
    "  --out DIR          write prediction.json and prediction.png (first window's paths)\n";

const char* kTrainHelp =
    "usage: crowdmpm train --scenario S --trajectories T [T...] [--scenario S2 --trajectories ...]\n"
    "                      --out MODEL.json [options]\n"
    "\n"
    "Cuts windows of --window seconds every --stride seconds from every recording; each starts\n"
    "from the recorded state (positions, velocities over the last 0.5 s, walking speeds over the\n"
    "last 1 s) in its scenario's venue, is simulated, and scored by the mean squared distance\n"
    "between simulated and recorded positions of the people seen at its start (people are\n"
    "masked once the recording loses them). Gradients of that loss through the simulator move\n"
    "the parameters with Adam (gradient-norm clipping); the last --validation share of every\n"
    "recording is held out, scored every --eval-every iterations, and training stops after\n"
    "--patience scores without improvement. The model with the best validation loss is written.\n"
    "Each --scenario applies to the --trajectories files after it.\n"
    "\n"
    "options:\n"
    "  --out MODEL.json   where to write the learned model; required\n"
    "  --model START      starting model (default: the first scenario's, else built-in);\n"
    "                     its kind (crowd, fluid or social_force) is the one learned\n"
    "  --material KIND    start from the built-in defaults as crowd, fluid or social_force\n"
    "                     (the social force model is fitted with central differences)\n"
    "  --params LIST      comma-separated scalars to learn (default: all the kind has; crowd:\n"
    "                     E,gamma,tension_scale,tau,v0_scale,comfort_distance,alignment_time,\n"
    "                     and time_gap, headway_gap, density_speed_gamma, density_speed_max,\n"
    "                     density_opening_speed, density_speed_floor\n"
    "                     where the starting model has them on (above 0);\n"
    "                     fluid: the same without tension_scale; social_force:\n"
    "                     tau,v0_scale,sf_A,sf_B,sf_k,sf_kappa); 'none': only the network and\n"
    "                     the scenario's force terms marked \"learn\" (fitted terms are written\n"
    "                     back as MODEL_STEM.SCENARIO_STEM.json beside the model)\n"
    "  --no-network       keep the traction network fixed\n"
    "  --loss trajectory|grid_velocity\n"
    "                     mean squared distance to the recorded positions (default), or the\n"
    "                     mass-weighted grid velocity against the recorded people's velocity\n"
    "                     field on the nodes they cover (the loss video learning uses)\n"
    "  --window S         seconds per window (default 2)\n"
    "  --stride S         seconds between windows (default 1)\n"
    "  --area-weight W    trajectory loss: plus W times the squared error of density and\n"
    "                     flow in the scenario's measurement areas (default 0: off)\n"
    "  --iterations N     Adam steps at most (default 120)\n"
    "  --batch N          windows per step (default 4)\n"
    "  --lr X             learning rate, in log units for positive scalars (default 0.03;\n"
    "                     halved, back at the best point, after a validation pass without\n"
    "                     improvement)\n"
    "  --clip X           gradient-norm clipping (default 1; 0 off)\n"
    "  --validation F     held-out share of every recording (default 0.25)\n"
    "  --eval-every N     iterations between validation passes (default 5)\n"
    "  --patience N       validation passes without improvement before stopping (default 6)\n"
    "  --seed N           minibatch sampling seed (default 1)\n"
    "  --desired-speed observed|scenario|free\n"
    "                     desired speed of the recorded people: their own walking speed at\n"
    "                     the window's start (default), the scenario group's (drawn from its\n"
    "                     distribution if it has one), or each person's free speed (90th\n"
    "                     percentile of their walking speed along their track so far, each\n"
    "                     speed divided by the model's density-speed factor where it has\n"
    "                     one: docs/learning.md), times v0_scale\n"
    "  --threads N        windows simulated and differentiated in parallel, one per thread;\n"
    "                     the model does not depend on N (default: the machine's cores)\n"
    "  --quiet            no progress lines\n"
    "\n"
    "From video: crowdmpm train --video V (--calibration CAL | --scale S) [--scenario S] --out M\n"
    "  The video's ground velocity fields (flow options as 'crowdmpm flow') are cut into clips\n"
    "  of --clip-length seconds (default 2.4) every --stride seconds (default 0.6) over the first\n"
    "  --train-share of the video (default 0.6; its last clips validate). Each clip starts from\n"
    "  particles sampled where the field moves at --density persons/m2 (default 6) with the\n"
    "  field's velocities, and is fitted with the grid velocity loss. Without --scenario the\n"
    "  venue is the ground in view, without walls, and people walk on the way they moved.\n"
    "  'crowdmpm predict --video ...' with the same options predicts the rest of the video from\n"
    "  its first held-out field and prints Err_vel at --horizons (default 7) horizons for\n"
    "  persistence, constant velocity, the untrained default and every --model; a particle\n"
    "  method's field is the mean of --ensemble (default 4) rollouts, each from the sampled\n"
    "  lattice shifted (a node empty in a rollout counts velocity 0 there, as in Err_vel).\n";

const char* kFlowHelp =
    "usage: crowdmpm flow VIDEO --out DIR (--calibration CAL | --scale M_PER_PX) [options]\n"
    "\n"
    "Reads VIDEO (any container OpenCV decodes), computes dense optical flow between consecutive\n"
    "frames, maps it to the ground plane (m/s) with the calibration, and splats it onto grid\n"
    "nodes with the MPM quadratic B-spline weights (mean over moving pixels, each weighted by\n"
    "the ground area it covers). Writes into DIR:\n"
    "  fields.npy         float32 (frames, ny, nx, 3): vx, vy (m/s), mask; grid in fields.npy.json\n"
    "  field_mean.png, field_middle.png   speed and arrows on the grid (metres)\n"
    "  frame_flow.png     the middle frame with its flow arrows\n"
    "  flow.json          video, calibration, grid, moving nodes, mean speed, processing speed\n"
    "\n"
    "options:\n"
    "  --calibration CAL  crowdmpm-calibration JSON: four or more image <-> ground point pairs\n"
    "                     (a homography), or a scale (docs/video.md)\n"
    "  --scale S          metres per pixel, for a video without calibration (treated as a top\n"
    "                     view: perspective is not removed; docs/video.md says what is lost)\n"
    "  --scenario S       use the scenario's grid (domain and cell size); else a grid covering\n"
    "                     the region of interest with --cell\n"
    "  --cell M           grid spacing without a scenario (default 0.5 m)\n"
    "  --method dis|farneback   optical flow (default dis)\n"
    "  --dis-preset N     0 ultrafast, 1 fast, 2 medium (default 2)\n"
    "  --smoothing A      temporal smoothing of the flow in [0, 1) (default 0: off)\n"
    "  --first N          first frame (default 0)\n"
    "  --frames N         frames to read (default: to the end)\n"
    "  --fps F            frame rate, when the container's is missing or wrong\n"
    "  --roi X,Y,X,Y,...  region of interest, a polygon in pixels (x right, y down)\n"
    "  --sample-stride N  pixels between flow samples (default 2)\n"
    "  --min-speed V      m/s below which a pixel counts as still (default 0.05)\n"
    "  --min-pixels P     pixels per frame below which a pixel's flow counts as still (default 0.2)\n"
    "  --glitch-ratio R   a field whose RMS speed is R times that of the 0.5 s before and after\n"
    "                     it, over a quarter of the view or more, is a camera glitch (jump, cut):\n"
    "                     cleared and listed (default 2; 0: off)\n"
    "  --quiet            no progress line\n";

const char* kRenderHelp =
    "usage: crowdmpm render-video SCENARIO --out DIR [options]\n"
    "\n"
    "Simulates SCENARIO and films it through a pinhole camera tilted over the ground: heads and\n"
    "shoulders as textured blobs, a textured floor, sensor noise, blur and Motion JPEG\n"
    "compression. Writes DIR/video.avi, DIR/calibration.json (the camera's image <-> ground\n"
    "pairs) and DIR/truth.npy (+ .json: the true grid velocity between consecutive frames, on\n"
    "the scenario's grid, as `flow` writes fields.npy).\n"
    "\n"
    "options:\n"
    "  --duration S       seconds filmed (default 10)\n"
    "  --settle S         seconds simulated before filming starts (default 3)\n"
    "  --fps F            frames per second (default 10; a whole number of time steps)\n"
    "  --tilt DEG         camera tilt from straight down (default 35)\n"
    "  --size WxH         image size (default 640x480)\n"
    "  --model MODEL      crowdmpm-model JSON instead of the scenario's\n"
    "  --threads N        worker threads (default: the machine's cores)\n";

const char* kAnalyzeHelp =
    "usage: crowdmpm analyze TRAJECTORIES --out DIR (--spec MEASUREMENTS.json | --scenario S)\n"
    "       crowdmpm analyze JPSREPORT_INI_OR_FOLDER --out DIR\n"
    "\n"
    "Measures a trajectory file (PeTrack text or JuPedSim SQLite, real or simulated) the way\n"
    "PedPy and JPSreport do (docs/analyze.md). --spec names the walkable area, measurement\n"
    "areas and lines; --scenario takes its measurement areas and its domain instead; a\n"
    "JPSreport project (ini.xml, or the folder holding it) gives its areas (area_B), lines\n"
    "(area_L), frame_step, trajectory file and geometry (geo.xml). Writes:\n"
    "  area_<id>.csv       per frame: people inside, classic and Voronoi density (persons/m2)\n"
    "                      and speed (m/s), Fruin level of service (A-F) of the Voronoi density\n"
    "  fd_<id>.csv         fundamental diagram: mean speed and specific flow per density bin\n"
    "  nt_<id>.csv         cumulative count N(t) of people crossing each line\n"
    "  crowd_pressure.csv, crowd_pressure.png\n"
    "                      Helbing's crowd pressure (local density x local velocity variance,\n"
    "                      1/s2) in the window with the highest peak\n"
    "  summary.json        means, peaks, level-of-service shares, crossings, mean flows\n"
    "\n"
    "options:\n"
    "  --spec FILE        measurement definitions (JSON, docs/analyze.md)\n"
    "  --scenario S       a scenario whose measurement areas and domain are used\n"
    "  --frame-step N     frames on each side for individual speeds (default 5, or the spec's)\n"
    "  --framerate F      frames per second, replacing the file's\n";

const char* kReportHelp =
    "usage: crowdmpm report DIR [--out FILE] [--scenario S]\n"
    "\n"
    "Writes DIR/report.html (or FILE): one HTML page with everything inlined (no network, no\n"
    "other files), for the folder `crowdmpm simulate SCENARIO --out DIR` wrote: the run's key\n"
    "numbers, N(t) per exit and the people in the venue over time, density and pressure over\n"
    "time in each measurement area, the density, pressure and Fruin level-of-service maps, a\n"
    "crowd-pressure (Helbing) danger map computed from the trajectories (also written as\n"
    "DIR/crowd_pressure.png), the crowd at peak density and at the end, and the video\n"
    "(re-encoded as WebM). docs/report.md.\n"
    "\n"
    "options:\n"
    "  --out FILE         the page (default DIR/report.html)\n"
    "  --scenario S       the venue for the crowd-pressure map (default: the scenario the run\n"
    "                     names in metrics.json)\n";

const char* kValidateHelp =
    "usage: crowdmpm validate SCENARIO [--model MODEL]\n"
    "\n"
    "Parses and checks SCENARIO and the model, places the groups, and prints a summary.\n"
    "Exit status 0 if valid, 1 with a message naming the JSON path otherwise.\n";

// --threads default: the machine's cores (results do not depend on the thread count).
int default_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(std::min(n, 256u));
}

struct Args {
  std::vector<std::string> positional;
  std::string out, model, scenario, trajectories;  // the first --model, --scenario, --trajectories
  std::vector<std::string> models;
  std::vector<std::pair<std::string, std::vector<std::string>>> datasets;  // scenario, its trajectories
  double observe = 2, horizon = 4, stride = -1;
  int windows = 0;
  int threads = default_threads();
  double duration = -1;
  bool quiet = false, help = false;
  std::string desired_speed = "observed";
  std::string material;  // train: start from the default parameters of this model kind
  json train = json::object();  // train: the "options" of a training request (parse_train_job)
  json diagnose = json::object();  // diagnose: --options (the "options" of a diagnosis request)
  bool train_share_given = false;
  bool density_given = false;
  bool method_given = false;
  bool stride_given = false;
  InputPolicy input;  // --max-input-mb, --allow-outside-paths
  std::string save_snapshot, resume;
  std::string spec;        // analyze
  long frame_step = 0;     // analyze: 0 = the spec's
  double framerate = 0;    // analyze: 0 = the file's
  double snapshot_at = -1;
  // flow, render-video
  VideoSource video;
  std::string calibration;
  double settle = 3, tilt = 35, render_fps = 10;
  VideoLearnOptions video_learn;
  int width = 640, height = 480;
};

[[noreturn]] void usage_error(const std::string& msg);

// The numeric train options and their keys in a training request's "options".
const char* train_option_key(const std::string& flag) {
  static const std::pair<const char*, const char*> keys[] = {
      {"--window", "window"},       {"--iterations", "iterations"}, {"--batch", "batch"},
      {"--lr", "learning_rate"},    {"--clip", "clip"},             {"--validation", "validation"},
      {"--eval-every", "eval_every"}, {"--patience", "patience"},   {"--seed", "seed"},
      {"--area-weight", "area_weight"}};
  for (const auto& [f, k] : keys)
    if (flag == f) return k;
  return nullptr;
}

double parse_double(const std::string& name, const std::string& v, double lo, double hi, const char* what) {
  char* end = nullptr;
  double d = std::strtod(v.c_str(), &end);
  if (v.empty() || *end || !(d >= lo && d <= hi)) usage_error(name + " must be " + what + ", got '" + v + "'");
  return d;
}

// A whole number in [lo, hi] ("3", "3.0", "1e2"; "2.5" and "abc" are usage errors naming the option).
long parse_whole(const std::string& name, const std::string& v, double lo, double hi, const char* what) {
  const double d = parse_double(name, v, lo, hi, what);
  if (d != std::floor(d)) usage_error(name + " must be " + what + " (a whole number), got '" + v + "'");
  return static_cast<long>(d);
}

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
    else if (s == "--spec") a.spec = value("--spec");
    else if (s == "--frame-step") a.frame_step = parse_whole(s, value("--frame-step"), 1, 1000, "a number of frames in [1, 1000]");
    else if (s == "--framerate") a.framerate = parse_double(s, value("--framerate"), 0.01, 10000, "frames per second in [0.01, 10000]");
    else if (s == "--model") {
      a.models.push_back(value("--model"));
      a.model = a.models.front();
    } else if (s == "--quiet") a.quiet = true;
    else if (s == "--scenario") {
      a.datasets.push_back({value("--scenario"), {}});
      if (a.scenario.empty()) a.scenario = a.datasets.back().first;
    } else if (s == "--options") {
      const std::string v = value("--options");
      try {
        a.diagnose = json::parse(v);
      } catch (const std::exception& e) {
        usage_error("--options must be a JSON object such as '{\"null_replicates\": 4}': " + std::string(e.what()));
      }
      if (!a.diagnose.is_object()) usage_error("--options must be a JSON object, got '" + v + "'");
    } else if (s == "--candidates") {
      const std::string v = value("--candidates");
      json list = json::array();
      for (size_t b = 0; b <= v.size();) {
        size_t e = v.find(',', b);
        if (e == std::string::npos) e = v.size();
        if (e > b) list.push_back(v.substr(b, e - b));
        b = e + 1;
      }
      a.diagnose["candidates"] = list;
    } else if (s == "--trajectories" || s == "--observed") {
      if (a.datasets.empty()) a.datasets.push_back({"", {}});  // reported as missing --scenario
      a.datasets.back().second.push_back(value("--trajectories"));
      while (i + 1 < argc && argv[i + 1][0] != '-') a.datasets.back().second.push_back(argv[++i]);
      if (a.trajectories.empty()) a.trajectories = a.datasets.back().second.front();
    } else if (s == "--observe" || s == "--horizon" || s == "--stride") {
      double d = parse_double(s, value(s.c_str()), 1e-3, 1e5, "a number of seconds > 0");
      (s == "--observe" ? a.observe : s == "--horizon" ? a.horizon : a.stride) = d;
      if (s == "--stride") a.stride_given = true;
    } else if (s == "--desired-speed") {
      a.desired_speed = value("--desired-speed");
      if (a.desired_speed != "observed" && a.desired_speed != "scenario" && a.desired_speed != "free")
        usage_error("--desired-speed must be 'observed', 'scenario' or 'free', got '" + a.desired_speed + "'");
    } else if (s == "--params") {
      std::string v = value("--params");
      json list = json::array();
      size_t b = 0;
      while (b <= v.size()) {
        size_t e = v.find(',', b);
        if (e == std::string::npos) e = v.size();
        if (e > b) list.push_back(v.substr(b, e - b));
        b = e + 1;
      }
      if (list.empty()) usage_error("--params needs at least one parameter name (or 'none')");
      if (list.size() == 1 && list[0] == "none") list = json::array();  // only the network and force terms
      a.train["params"] = list;
    } else if (s == "--loss") {
      a.train["loss"] = value("--loss");
    } else if (s == "--material") {
      a.material = value("--material");
    } else if (s == "--no-network") {
      a.train["learn_network"] = false;
    } else if (const char* key = train_option_key(s)) {
      // Ranges are checked by parse_train_job, the same checks as a JSON training request's.
      const std::string v = value(s.c_str());
      char* end = nullptr;
      const double d = std::strtod(v.c_str(), &end);
      if (v.empty() || *end || !std::isfinite(d)) usage_error(s + " must be a number, got '" + v + "'");
      a.train[key] = d;
    }
    else if (s == "--save-snapshot") a.save_snapshot = value("--save-snapshot");
    else if (s == "--resume") a.resume = value("--resume");
    else if (s == "--snapshot-at") a.snapshot_at = parse_double(s, value("--snapshot-at"), 0, 1e9, "a time in seconds >= 0");
    else if (s == "--max-input-mb") {
      a.input.max_bytes = static_cast<uint64_t>(
          parse_double(s, value("--max-input-mb"), 1e-3, 1e9, "a size in MiB in [0.001, 1e9]") * 1024 * 1024);
    } else if (s == "--allow-outside-paths") {
      a.input.allow_outside_paths = true;
    }
    else if (s == "--video") a.video.path = value("--video");
    else if (s == "--density") {
      a.video_learn.density = parse_double(s, value(s.c_str()), 0.01, 12, "persons/m2 in [0.01, 12]");
      a.density_given = true;
    }
    else if (s == "--clip-length") a.video_learn.clip = parse_double(s, value(s.c_str()), 0.01, 1e4, "seconds > 0");
    else if (s == "--train-share") {
      a.video_learn.train_share = parse_double(s, value(s.c_str()), 0.05, 0.95, "a share in [0.05, 0.95]");
      a.train_share_given = true;
    }
    else if (s == "--ensemble") a.video_learn.ensemble = static_cast<int>(parse_whole(s, value(s.c_str()), 1, 64, "1..64 rollouts"));
    else if (s == "--horizons") a.video_learn.horizons = static_cast<int>(parse_whole(s, value(s.c_str()), 1, 100, "1..100"));
    else if (s == "--calibration") a.video.calibration = value("--calibration");
    else if (s == "--scale") a.video.scale = parse_double(s, value("--scale"), 1e-6, 100, "metres per pixel in (0, 100]");
    else if (s == "--cell") a.video.cell = parse_double(s, value("--cell"), 0.05, 10, "a grid spacing in [0.05, 10] m");
    else if (s == "--method") {
      a.video.flow.method = flow_method(value("--method"));
      a.method_given = true;
    }
    else if (s == "--dis-preset") a.video.flow.dis_preset = static_cast<int>(parse_whole(s, value("--dis-preset"), 0, 2, "0, 1 or 2"));
    else if (s == "--smoothing") a.video.flow.smoothing = parse_double(s, value("--smoothing"), 0, 0.99, "in [0, 0.99]");
    else if (s == "--first") a.video.video.first = parse_whole(s, value("--first"), 0, 1e9, "a frame number >= 0");
    else if (s == "--frames") a.video.video.count = parse_whole(s, value("--frames"), 2, 1e9, "a number of frames >= 2");
    else if (s == "--fps") {
      const double f = parse_double(s, value("--fps"), 0.1, 999, "frames per second in [0.1, 999]");
      a.video.video.fps = f;
      a.render_fps = f;
    } else if (s == "--roi") {
      std::vector<double> v;
      std::string t = value("--roi");
      size_t b = 0;
      while (b <= t.size()) {
        size_t e = t.find(',', b);
        if (e == std::string::npos) e = t.size();
        v.push_back(parse_double("--roi", t.substr(b, e - b), -1e6, 1e6, "a list of pixel coordinates x,y,x,y,..."));
        b = e + 1;
      }
      if (v.size() % 2 || v.size() < 6) usage_error("--roi needs at least three x,y pixel pairs, got " + std::to_string(v.size()) + " numbers");
      for (size_t k = 0; k < v.size(); k += 2) a.video.video.roi.emplace_back(v[k], v[k + 1]);
    } else if (s == "--sample-stride") a.video.field.sample_stride = static_cast<int>(parse_whole(s, value(s.c_str()), 1, 64, "1..64 pixels"));
    else if (s == "--min-speed") a.video.field.min_speed = parse_double(s, value(s.c_str()), 0, 10, "a speed in [0, 10] m/s");
    else if (s == "--min-pixels") a.video.field.min_pixels = parse_double(s, value(s.c_str()), 0, 9.99, "pixels per frame in [0, 10)");
    else if (s == "--glitch-ratio") {
      a.video.field.glitch_ratio = parse_double(s, value(s.c_str()), 0, 100, "0 (off) or a ratio in (1, 100)");
      if (a.video.field.glitch_ratio > 0 && a.video.field.glitch_ratio <= 1) usage_error("--glitch-ratio must be 0 (off) or above 1");
    }
    else if (s == "--settle") a.settle = parse_double(s, value(s.c_str()), 0, 1e4, "seconds >= 0");
    else if (s == "--tilt") a.tilt = parse_double(s, value(s.c_str()), 0, 79, "degrees in [0, 79]");
    else if (s == "--size") {
      const std::string t = value("--size");
      int w = 0, h = 0;
      char tail = 0;
      if (std::sscanf(t.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 16 || h < 16 || w > 8192 || h > 8192)
        usage_error("--size must be WIDTHxHEIGHT in pixels (16..8192), got '" + t + "'");
      a.width = w;
      a.height = h;
    }
    else if (s == "--windows") {
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
  if (a.out.empty()) usage_error("simulate needs --out DIR");
  if (a.snapshot_at >= 0 && a.save_snapshot.empty()) usage_error("--snapshot-at needs --save-snapshot FILE");
  RunOptions opt;
  opt.out_dir = a.out;
  opt.threads = a.threads;
  opt.snapshot_path = a.save_snapshot;
  opt.snapshot_at = a.snapshot_at;
  bool tty = isatty(fileno(stderr)) && !a.quiet;
  if (tty) opt.progress = progress_bar;
  std::unique_ptr<Simulation> sim;
  if (!a.resume.empty()) {
    if (!a.positional.empty()) usage_error("simulate --resume takes no SCENARIO (the snapshot holds it)");
    if (!a.model.empty()) usage_error("simulate --resume takes no --model (the snapshot holds it)");
    sim = load_snapshot_file(a.resume, a.threads, a.input);
  } else {
    if (a.positional.size() != 1) usage_error("simulate needs exactly one SCENARIO file (or --resume SNAPSHOT)");
    ScenarioDef sd = ScenarioDef::load(a.positional[0], a.input);
    Model m = !a.model.empty() ? Model::load(a.model, a.input) : sd.model_or_default();
    sim = std::make_unique<Simulation>(sd, m, a.threads);
  }
  if (a.duration > 0) sim->set_duration(a.duration);
  const ScenarioDef& s = sim->scenario();
  RunSummary r = run_simulation(*sim, opt);
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

DesiredSpeed desired_speed_of(const Args& a) {
  return a.desired_speed == "scenario" ? DesiredSpeed::Scenario : a.desired_speed == "free" ? DesiredSpeed::Free : DesiredSpeed::Observed;
}


int cmd_predict_video(const Args& a);

int cmd_predict(const Args& a) {
  if (a.help) { std::fputs(kPredictHelp, stdout); return 0; }
  if (!a.video.path.empty()) return cmd_predict_video(a);
  if (a.scenario.empty() || a.trajectories.empty()) usage_error("predict needs --scenario and --trajectories");
  size_t n_scen = 0, n_traj = 0;  // in any order
  for (const auto& [scen, trajs] : a.datasets) {
    n_scen += scen.empty() ? 0 : 1;
    n_traj += trajs.size();
  }
  if (n_scen > 1 || n_traj > 1) usage_error("predict takes one --scenario and one --trajectories file");
  if (!a.positional.empty()) usage_error("predict takes no positional arguments (got '" + a.positional[0] + "')");
  PredictOptions po;
  po.observe = a.observe;
  po.horizon = a.horizon;
  po.stride = a.stride > 0 ? a.stride : a.horizon;
  po.threads = a.threads;
  po.max_windows = a.windows;
  po.input = a.input;
  const PredictJob job = load_predict_job(a.scenario, a.trajectories, a.models, po, desired_speed_of(a));
  if (po.observe + po.horizon > job.recording.duration())
    usage_error("--observe + --horizon (" + format_number(po.observe + po.horizon) + " s) exceed the recording (" +
                format_number(job.recording.duration()) + " s)");
  const ScenarioDef& s = job.scenario;
  const TrajectorySet& t = job.recording;
  const PredictOptions& o = job.options;
  const std::vector<Model>& models = job.models;
  const WindowOptions wo{a.threads, desired_speed_of(a)};
  if (!a.out.empty()) prepare_output_folder(a.out);
  const std::vector<PredictionReport> reports = run_prediction(job);
  std::printf("%s: %zu people, %.1f s at %g fps; %ld windows of %g s; desired speed %s\n", a.trajectories.c_str(),
              t.person_count(), t.duration(), t.framerate, reports[0].windows, o.horizon, a.desired_speed.c_str());
  if (job.interpolated_rows > 0)
    std::printf("the recording has a row every %ld frames: compared with %zu positions between them interpolated linearly "
                "(windows start on recorded rows)\n", job.frame_step, job.interpolated_rows);
  else if (job.frame_step > 1)
    std::printf("the recording has a row every %ld frames, not filled in (rows more than a second apart, or too many): "
                "seconds without rows have no error\n", job.frame_step);
  std::printf("%-34s", "method");
  for (const auto& h : reports[0].horizons) std::printf("   ADE@%gs  FDE@%gs", h.horizon, h.horizon);
  std::printf("  gridV@%gs\n", reports[0].horizons.back().horizon);
  for (const auto& r : reports) {
    std::printf("%-34s", r.method.c_str());
    for (const auto& h : r.horizons) std::printf("  %7.3f  %7.3f", h.ade, h.fde);
    std::printf("  %8.3f\n", r.horizons.back().grid_velocity_rms);
  }
  if (!a.out.empty()) {
    save_json_file(prediction_json(job, reports), a.out + "/prediction.json");
    // Paths of the first window: recorded, constant velocity, the first model given (else the default).
    long f0 = t.frame_min() + std::lround(o.observe * t.framerate);
    ObservedState st = observe_at(t, f0, o.velocity_window, o.speed_window, speed_history(t, o.speed_window));
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
    const Model& shown = models.size() > 1 ? models[1] : models[0];
    std::vector<PathSet> sets = {{"recorded", 60, 160, 60, as_paths(recorded)},
                                 {"const. velocity", 200, 120, 40, as_paths(constant_velocity_predictor()(st, times))},
                                 {model_label(shown), 40, 40, 210, as_paths(simulation_predictor(s, shown, wo)(st, times))}};
    write_paths_png(a.out + "/prediction.png", s.geo, View::fit(s.geo, s.outputs.pixels_per_metre), sets,
                    "prediction from t = " + format_number(o.observe) + " s, " + format_number(o.horizon) + " s ahead");
    std::printf("wrote %s/prediction.json and %s/prediction.png\n", a.out.c_str(), a.out.c_str());
  }
  return 0;
}

// A "flow: frame k of n" line on a terminal, none otherwise.
FlowProgress flow_progress(bool tty) {
  if (!tty) return nullptr;
  return [](long done, long total) {
    g_progress_line = true;
    std::fprintf(stderr, "\rflow: frame %ld of %ld ", done, total);
    std::fflush(stderr);
  };
}

// The venue, the fields and the split of a video (train --video, predict --video).
struct VideoData {
  ScenarioDef venue;
  VideoFields fields;
  size_t split = 0;  // fields[0, split) train; the rest is held out
};

VideoData load_video_data(const Args& a) {
  VideoSource src = a.video;
  src.video.input = a.input;
  VideoData d;
  d.venue = a.scenario.empty() ? video_venue(src) : ScenarioDef::load(a.scenario, a.input);
  const bool tty = isatty(fileno(stderr)) && !a.quiet;
  const FlowProgress progress = flow_progress(tty);
  d.fields = load_video_fields(src, &d.venue, progress);
  if (tty) {
    std::fputc('\n', stderr);
    g_progress_line = false;
  }
  d.split = static_cast<size_t>(std::lround(a.video_learn.train_share * static_cast<double>(d.fields.flow.fields.size())));
  return d;
}

int cmd_train_video(const Args& a) {
  if (!a.datasets.empty() && !a.datasets[0].second.empty()) usage_error("train takes --video or --trajectories, not both");
  const VideoData d = load_video_data(a);
  json options = a.train;
  options["threads"] = a.threads;
  options["desired_speed"] = a.desired_speed;
  if (!options.contains("loss")) options["loss"] = "grid_velocity";
  TrainOptions o;
  parse_train_options(JsonReader(options, "options"), o);
  if (o.loss != TrainOptions::Loss::GridVelocity) usage_error("a video trains with --loss grid_velocity only (nobody is tracked)");
  VideoLearnOptions vo = a.video_learn;
  if (a.stride_given) vo.stride = a.stride;
  vo.desired_speed = o.desired_speed;
  o.window = vo.clip;  // what messages about too short a video name
  o.grid_min_mass = vo.min_mass;  // an observed node the particles left costs as in Err_vel
  std::vector<TrainWindow> train, val;
  const double fps = d.fields.flow.info.fps;
  make_video_windows(d.venue, d.fields.flow.fields, fps, d.split, vo, o.validation_fraction, train, val, d.fields.flow.glitches,
                     d.fields.flow.covered);
  const Model start = !a.model.empty() ? Model::load(a.model, a.input) : d.venue.model_or_default();
  if (!a.quiet)
    std::printf("training %s material on %zu clips of %g s (%zu validation) from fields 0..%zu of %zu; %g persons/m2 sampled\n",
                material_name(start.material), train.size(), vo.clip, val.size(), d.split, d.fields.flow.fields.size(), vo.density);
  TrainResult r = train_on_windows({d.venue}, train, val, start, o, [&](const TrainProgress& p) {
    if (a.quiet || std::isnan(p.validation_loss)) return;
    std::printf("  iter %4d  train loss %.5f  |grad| %.3g  validation %.5f%s\n", p.iteration, p.train_loss, p.grad_norm,
                p.validation_loss, p.improved ? "  (best)" : "");
    std::fflush(stdout);
  });
  Model m = r.model;
  m.name = std::string("learned ") + material_name(m.material);
  m.description = "learned from the optical flow of " + a.video.path + " (fields 0.." + std::to_string(d.split) +
                  ", grid velocity loss); validation loss " + format_number(r.initial_validation) + " -> " +
                  format_number(r.best_validation) + " (m/s)2";
  save_model(m, a.out);
  std::printf("validation grid velocity loss %.5f -> %.5f (m/s)2 (best at iteration %d of %d%s); wrote %s\n", r.initial_validation,
              r.best_validation, r.best_iteration, r.iterations, r.early_stopped ? ", stopped early" : "", a.out.c_str());
  return 0;
}

int cmd_predict_video(const Args& a) {
  if (!a.out.empty()) prepare_output_folder(a.out);
  const VideoData d = load_video_data(a);
  std::vector<Model> models{d.venue.model_or_default()};
  for (const auto& p : a.models) models.push_back(Model::load(p, a.input));
  VideoLearnOptions vo = a.video_learn;
  vo.desired_speed = desired_speed_of(a);
  const auto& glitches = d.fields.flow.glitches;
  const auto preds = predict_video(d.venue, models, d.fields.flow.fields, d.fields.flow.covered, d.fields.flow.info.fps, d.split,
                                   vo, a.threads, glitches);
  const size_t end = held_out_end(d.fields.flow.fields.size(), d.split, glitches);
  if (end < d.fields.flow.fields.size())
    std::printf("field %zu is a camera glitch: the held-out part ends before it\n", end);
  std::printf("Err_vel (m2/s2, observed nodes away from the view's border) from field %zu of %zu:\n%-26s", d.split,
              d.fields.flow.fields.size(), "horizon (s)");
  for (const auto& h : preds[0].horizons) std::printf(" %9.2f", h.seconds);
  std::printf("\n");
  for (const auto& p : preds) {
    std::printf("%-26s", p.method.c_str());
    for (const auto& h : p.horizons) std::printf(" %9.5f", h.err_vel);
    std::printf("\n");
  }
  if (!a.out.empty()) {
    save_json_file(json{{"video", a.video.path}, {"fields", d.fields.flow.fields.size()}, {"start", d.split}, {"end", end},
                        {"camera_glitches", glitches}, {"fps", d.fields.flow.info.fps}, {"unit", "m2/s2"},
                        {"methods", video_prediction_json(preds)}},
                   a.out + "/prediction.json");
    write_video_prediction_png(a.out + "/prediction.png", preds, "grid velocity error on the held-out part of the video");
  }
  return 0;
}

int cmd_train(const Args& a) {
  if (a.help) { std::fputs(kTrainHelp, stdout); return 0; }
  if (a.out.empty()) usage_error("train needs --out MODEL.json");
  if (!a.positional.empty()) usage_error("train takes no positional arguments (got '" + a.positional[0] + "')");
  if (a.models.size() > 1) usage_error("train takes one --model (the starting point)");
  check_output_file(a.out, "model file");
  if (!a.video.path.empty()) return cmd_train_video(a);
  if (a.datasets.empty()) usage_error("train needs --scenario S --trajectories T [T...]");
  // The same request a program sends through the C ABI (cmpm_TrainModel), checked by the same
  // parse_train_job.
  json request = {{"datasets", json::array()}};
  for (const auto& [scen, trajs] : a.datasets) {
    if (scen.empty()) usage_error("--trajectories must follow the --scenario they were recorded in");
    if (trajs.empty()) usage_error("--scenario " + scen + " has no --trajectories after it");
    request["datasets"].push_back({{"scenario", scen}, {"trajectories", trajs}});
  }
  if (!a.model.empty() && !a.material.empty()) usage_error("train takes --model or --material, not both");
  if (!a.model.empty()) request["model"] = a.model;
  if (!a.material.empty()) request["material"] = a.material;
  json options = a.train;
  if (a.stride_given) options["stride"] = a.stride;
  options["threads"] = a.threads;
  options["desired_speed"] = a.desired_speed;
  request["options"] = options;
  request["input"] = {{"max_bytes", a.input.max_bytes}, {"allow_outside_paths", a.input.allow_outside_paths}};
  const TrainJob job = parse_train_job(request);
  const TrainOptions& o = job.options;
  const bool show = !a.quiet;
  if (show)
    std::printf("training %s material from %zu scenario(s); windows of %g s every %g s\n", material_name(job.start.material),
                job.data.size(), o.window, o.stride);
  TrainResult r = train_model(job.data, job.start, o, [&](const TrainProgress& p) {
    if (!show) return;
    if (std::isnan(p.validation_loss))
      std::printf("  iter %4d  train loss %.5f  |grad| %.3g\n", p.iteration, p.train_loss, p.grad_norm);
    else
      std::printf("  iter %4d  train loss %.5f  |grad| %.3g  validation %.5f%s\n", p.iteration, p.train_loss,
                  p.grad_norm, p.validation_loss, p.improved ? "  (best)" : "");
    std::fflush(stdout);
  });
  const Model m = describe_learned(job, r);
  save_model(m, a.out);
  std::printf("validation %s loss %.5f -> %.5f %s (best at iteration %d of %d%s); %ld windows skipped; wrote %s\n",
              loss_name(o).c_str(), r.initial_validation, r.best_validation, loss_unit(o),
              r.best_iteration, r.iterations, r.early_stopped ? ", stopped early" : "", r.skipped_windows, a.out.c_str());
  std::vector<ScenarioDef> venues;
  for (const auto& d : job.data) venues.push_back(d.scenario);
  const Fitted start = Fitted::of(job.start, venues), fitted{m, r.terms};
  const ParamMap learned(start, o.params, false, o.learn_scalars);
  for (const auto& name : learned.scalars())
    std::printf("  %-18s %.5g (start %.5g)\n", name.c_str(), m.get(name), job.start.get(name));
  const std::vector<double> u0 = learned.get(start), u1 = learned.get(fitted);
  const auto names = learned.term_parameter_names(start);
  for (size_t k = 0; k < names.size(); ++k)
    std::printf("  %-18s %.5g (start %.5g) in %s\n", names[k].second.c_str(), u1[learned.scalars().size() + k],
                u0[learned.scalars().size() + k], venues[names[k].first].source.c_str());
  // Venues whose force terms were fitted: written back as scenarios that simulate runs.
  for (const std::string& f : write_fitted_scenarios(job, r, a.out)) std::printf("wrote %s\n", f.c_str());
  return 0;
}

int cmd_flow(const Args& a) {
  if (a.help) { std::fputs(kFlowHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("flow needs exactly one VIDEO file");
  if (a.out.empty()) usage_error("flow needs --out DIR");
  VideoSource src = a.video;
  src.path = a.positional[0];
  src.video.input = a.input;
  std::optional<ScenarioDef> sc;
  if (!a.scenario.empty()) sc = ScenarioDef::load(a.scenario, a.input);
  const bool tty = isatty(fileno(stderr)) && !a.quiet;
  const FlowProgress progress = flow_progress(tty);
  const json j = run_flow_job(src, sc ? &*sc : nullptr, a.out, progress);
  if (tty) std::fputc('\n', stderr);
  std::printf("%s: %zu fields of %d x %d nodes (%s, %s) from %d x %d frames at %.3g fps; %.0f moving nodes per frame, "
              "mean speed %.3f m/s; %.1f frames/s processed; outputs in %s\n",
              src.path.c_str(), j["fields"].get<size_t>(), j["grid"]["nx"].get<int>(), j["grid"]["ny"].get<int>(),
              j["method"].get<std::string>().c_str(), j["calibrated"].get<bool>() ? "homography" : "scale",
              j["width"].get<int>(), j["height"].get<int>(), j["fps"].get<double>(), j["moving_nodes_per_frame"].get<double>(),
              j["mean_speed"].get<double>(), j["frames_per_second_processed"].get<double>(), a.out.c_str());
  if (!j["camera_glitches"].empty())
    std::printf("camera glitches (cleared: no node observed): fields %s\n", j["camera_glitches"].dump().c_str());
  return 0;
}

int cmd_render_video(const Args& a) {
  if (a.help) { std::fputs(kRenderHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("render-video needs exactly one SCENARIO file");
  if (a.out.empty()) usage_error("render-video needs --out DIR");
  ScenarioDef sd = ScenarioDef::load(a.positional[0], a.input);
  Model m = !a.model.empty() ? Model::load(a.model, a.input) : sd.model_or_default();
  Simulation sim(sd, m, a.threads);
  prepare_output_folder(a.out);
  for (double t = 0; t + 0.5 * sd.dt < a.settle; t += sd.dt) sim.step();
  RenderOptions ro;
  ro.camera.tilt_deg = a.tilt;
  ro.camera.width = a.width;
  ro.camera.height = a.height;
  ro.fps = a.render_fps;
  ro.duration = a.duration > 0 ? a.duration : 10;
  const RenderResult r = render_synthetic_video(sim, ro, a.out + "/video.avi");
  const Vec2 lo = sd.geo.lo, hi = sd.geo.hi;
  save_json_file(r.calibration.to_json({lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}), a.out + "/calibration.json");
  write_fields_npy(a.out + "/truth.npy", r.truth, ro.fps, 0);
  std::printf("%s: %ld frames of %d x %d at %.3g fps, tilt %.0f deg; %zu people, mean density %.2f /m2 where they are; "
              "outputs in %s (video.avi, calibration.json, truth.npy)\n",
              a.positional[0].c_str(), r.frames, a.width, a.height, ro.fps, a.tilt, sim.world().size(), r.mean_density, a.out.c_str());
  return 0;
}

int cmd_diagnose(const Args& a) {
  if (a.help) { std::fputs(kDiagnoseHelp, stdout); return 0; }
  const bool video = !a.video.path.empty();
  if (a.scenario.empty() || a.trajectories.empty() == !video)
    usage_error("diagnose needs --scenario and a recording: --observed TRAJECTORIES or --video V (one of them)");
  if (video && a.video.calibration.empty() == !(a.video.scale > 0))
    usage_error("diagnose --video needs --calibration CAL or --scale S (one of them)");
  if (a.out.empty()) usage_error("diagnose needs --out DIR");
  if (!a.positional.empty()) usage_error("diagnose takes no positional arguments (got '" + a.positional[0] + "')");
  if (a.datasets.size() > 1 || (!video && a.datasets[0].second.size() > 1)) usage_error("diagnose takes one --scenario and one --observed file");
  json options = a.diagnose;
  options["threads"] = a.threads;
  if (a.train_share_given) options["train_share"] = a.video_learn.train_share;
  for (const char* k : {"iterations", "seed"})
    if (a.train.contains(k)) options[k] = a.train[k];
  json request = {{"scenario", a.scenario}, {"options", options},
                  {"input", {{"max_bytes", a.input.max_bytes}, {"allow_outside_paths", a.input.allow_outside_paths}}}};
  if (video) {
    const VideoSource& v = a.video;
    json jv = {{"path", v.path}, {"first", v.video.first}, {"frames", v.video.count}, {"fps", v.video.fps}, {"smoothing", v.flow.smoothing}};
    if (a.method_given) jv["method"] = v.flow.method == FlowOptions::Method::Dis ? "dis" : "farneback";
    if (!v.calibration.empty()) jv["calibration"] = v.calibration;
    else jv["scale"] = v.scale;
    if (a.density_given) usage_error("diagnose --video follows detected people; --density is for flow tracks (\"tracks\": \"flow\" in a request)");
    if (!v.video.roi.empty()) usage_error("diagnose --video reads the whole frame (--roi is not supported here)");
    request["video"] = jv;
  } else {
    request["trajectories"] = a.trajectories;
  }
  if (!a.model.empty()) request["model"] = a.model;
  const DiagnoseJob job = parse_diagnose_job(request);
  prepare_output_folder(a.out);  // before the minutes of work, not after
  std::printf("%s: %zu %s, %.1f s at %g fps, in %s\n", job.trajectories_path.c_str(), job.recording.person_count(),
              video ? "tracks" : "people", job.recording.duration(), job.recording.framerate, a.scenario.c_str());
  const DiagnosisResult r = run_diagnosis(job, [&](const std::string& line) {
    if (!a.quiet) std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  });
  write_diagnosis(job, r, a.out);
  std::printf("%s\n", r.explanation.c_str());
  std::printf("wrote %s/report.json, summary.txt, residual_before.png, residual_after.png, scenario.json, model.json%s\n", a.out.c_str(),
              video ? ", video_tracks.txt" : "");
  return 0;
}

int cmd_analyze(const Args& a) {
  if (a.help) { std::fputs(kAnalyzeHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("analyze needs exactly one TRAJECTORIES file");
  if (a.out.empty()) usage_error("analyze needs --out DIR");
  const std::string& input = a.positional[0];
  const bool project = a.spec.empty() && a.scenario.empty() &&
                       (std::filesystem::is_directory(input) || (input.size() > 4 && input.substr(input.size() - 4) == ".xml"));
  if (!project && a.spec.empty() == a.scenario.empty())
    usage_error("analyze needs --spec FILE or --scenario S (one of them), or a JPSreport ini.xml (or its folder)");
  AnalysisSpec spec;
  std::string trajectories = input;
  if (project) {
    JpsreportProject p = read_jpsreport_project(input, a.input);
    spec = p.spec;
    trajectories = p.trajectories;
    for (const auto& n : p.notes) std::printf("note: %s\n", n.c_str());
  } else {
    spec = !a.spec.empty() ? AnalysisSpec::from_json(load_json_file(a.spec, a.input), a.spec)
                           : AnalysisSpec::from_scenario(a.scenario, a.input);
  }
  if (a.frame_step > 0) spec.frame_step = a.frame_step;
  const TrajectorySet t = TrajectorySet::read(trajectories, a.framerate, a.input);
  std::printf("%s: %zu people, frames %ld-%ld at %g fps\n", trajectories.c_str(), t.person_count(), t.frame_min(),
              t.frame_max(), t.framerate);
  const json summary = run_analysis(t, spec, a.out);
  for (const auto& area : summary["areas"])
    std::printf("area %s: mean density %.3f (classic) %.3f (Voronoi) persons/m2, peak %.3f (Voronoi)\n",
                area["id"].get<std::string>().c_str(), area["mean_classic_density"].get<double>(),
                area["mean_voronoi_density"].get<double>(), area["max_voronoi_density"].get<double>());
  for (const auto& line : summary["lines"])
    std::printf("line %s: %ld crossings, mean flow %.3f persons/s\n", line["id"].get<std::string>().c_str(),
                line["crossings"].get<long>(), line["mean_flow"].get<double>());
  if (summary.contains("crowd_pressure"))
    std::printf("crowd pressure: peak %.4f 1/s2 at (%.1f, %.1f) m\n", summary["crowd_pressure"]["max"].get<double>(),
                summary["crowd_pressure"]["at"][0].get<double>(), summary["crowd_pressure"]["at"][1].get<double>());
  std::printf("wrote %s/summary.json\n", a.out.c_str());
  return 0;
}

int cmd_report(const Args& a) {
  if (a.help) { std::fputs(kReportHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("report needs exactly one DIR (an output folder of crowdmpm simulate)");
  ReportOptions opt;
  opt.out = a.out;
  opt.scenario = a.scenario;
  opt.input = a.input;
  std::printf("wrote %s\n", write_report(a.positional[0], opt).c_str());
  return 0;
}

int cmd_validate(const Args& a) {
  if (a.help) { std::fputs(kValidateHelp, stdout); return 0; }
  if (a.positional.size() != 1) usage_error("validate needs exactly one SCENARIO file");
  ScenarioDef s = ScenarioDef::load(a.positional[0], a.input);
  Model m = !a.model.empty() ? Model::load(a.model, a.input) : s.model_or_default();
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
      std::fputs(sub == "simulate"   ? kSimulateHelp
                 : sub == "validate" ? kValidateHelp
                 : sub == "predict"  ? kPredictHelp
                 : sub == "train"    ? kTrainHelp
                 : sub == "flow"     ? kFlowHelp
                 : sub == "render-video" ? kRenderHelp
                 : sub == "diagnose" ? kDiagnoseHelp
                 : sub == "analyze"  ? kAnalyzeHelp
                 : sub == "report"   ? kReportHelp
                                     : kUsage,
                 stdout);
      return 0;
    }
    Args a = parse_args(argc, argv, 2);
    if (cmd == "simulate") return cmd_simulate(a);
    if (cmd == "validate") return cmd_validate(a);
    if (cmd == "predict") return cmd_predict(a);
    if (cmd == "train") return cmd_train(a);
    if (cmd == "flow") return cmd_flow(a);
    if (cmd == "render-video") return cmd_render_video(a);
    if (cmd == "diagnose") return cmd_diagnose(a);
    if (cmd == "analyze") return cmd_analyze(a);
    if (cmd == "report") return cmd_report(a);
    usage_error("unknown command '" + cmd + "'");
  } catch (const Error& e) {
    std::fprintf(stderr, "%scrowdmpm: error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%scrowdmpm: internal error: %s\n", g_progress_line ? "\n" : "", e.what());
    return 3;
  }
}
