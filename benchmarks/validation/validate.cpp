// Validation against measurements of real crowds (DESIGN.md section 7): the fundamental diagram
// in a ring corridor and the flow through bottlenecks of several widths, for any model file.
//
//   validate fd --model M [--densities 0.5,1,...] [--threads N] [--warmup S] [--measure S]
//   validate bottleneck --model M [--widths 0.4,0.8,...] [--threads N] [--density D | --density D1,D2,...]
//                       [--people N | --people N1,N2,...] [--repeats K]
//   validate replay --model M --scenario S --trajectories T --line x0,y0,x1,y1 [--curve CSV] [--repeats K]
//   validate measure --trajectories T --box x0,y0,x1,y1   (classic density and speed, 1 /s)
//   validate chart --out PNG --title T --x LABEL --y LABEL --series SPEC [--series SPEC ...]
//     SPEC = NAME|CSV|XCOL|YCOL|STYLE|RRGGBB[|YCOL2]: columns of a CSV with a header row (lines
//     starting with # skipped), STYLE line, points, linepoints or band (YCOL..YCOL2 shaded)
//
// fd: a ring corridor 2.5 m wide (inner radius 6 m, so it bends gently), people placed at the
// density asked for, walking around it (behaviour "orbit", desired speed 1.34 m/s, Weidmann's
// free speed). After `warmup` seconds, the mean speed along the corridor of everyone is sampled
// every second for `measure` seconds: the classic density (people / corridor area) and mean speed
// of a closed system in steady state.
// bottleneck: a waiting crowd at `density` (3.5 /m^2; one value for every width, or one per
// width) fills a room 6 m deep (deeper where `people`, one value or one per width, asks for more
// people than that holds) in front of a wall with an opening of width b (0.4 m thick) and
// leaves through it; the flow is the passages
// between the 20th and the 80th percentile over their time span (persons/s).
// --repeats K (bottleneck and replay): a crowd squeezing through a door is chaotic, so one run
// is one draw; K runs (the waiting crowd placed with seeds 1..K; the replay exact and with its
// entry points jittered by 2 cm with seeds 2..K) give the mean and the spread.
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
#include "engine/io/chart.hpp"
#include "engine/observe/measure.hpp"
#include "engine/predict/replay.hpp"

using namespace crowdmpm;

namespace {
[[noreturn]] void usage(const std::string& msg) {
  std::fprintf(stderr, "validate: %s\nusage: validate fd|bottleneck|replay --model M [--densities LIST | --widths LIST] "
                       "[--threads N] [--warmup S] [--measure S] [--density D] [--people N] [--repeats K]\n"
                       "       validate replay --model M --scenario S --trajectories T --line x0,y0,x1,y1 [--curve CSV] [--repeats K]\n"
                       "       validate measure --trajectories T --box x0,y0,x1,y1\n"
                       "       validate chart --out PNG --title T --x LABEL --y LABEL --series NAME|CSV|XCOL|YCOL|STYLE|RRGGBB[|YCOL2] ...\n",
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

// Mean, standard deviation (n - 1), least and largest of repeated measurements.
struct Spread {
  double mean = 0, sd = 0, min = 0, max = 0;
};
Spread spread(const std::vector<double>& v) {
  Spread s;
  if (v.empty()) return s;
  s.min = *std::min_element(v.begin(), v.end());
  s.max = *std::max_element(v.begin(), v.end());
  for (double x : v) s.mean += x / static_cast<double>(v.size());
  for (double x : v) s.sd += v.size() > 1 ? (x - s.mean) * (x - s.mean) / static_cast<double>(v.size() - 1) : 0;
  s.sd = std::sqrt(s.sd);
  return s;
}

// J(b) per width; with repeats > 1 the crowd is placed with seeds 1..repeats and J is their mean
// (J_sd, J_min, J_max: the spread; passages, t20, t80 of seed 1; peak: the largest of all).
int run_bottleneck(const Model& model, const std::vector<double>& widths, int threads, const std::vector<double>& density,
                   const std::vector<double>& people, int repeats) {
  if (density.size() != 1 && density.size() != widths.size())
    usage("--density needs one value, or one per width (" + std::to_string(widths.size()) + ")");
  if (people.size() != 1 && people.size() != widths.size())
    usage("--people needs one value, or one per width (" + std::to_string(widths.size()) + ")");
  std::printf("b,density,agents,J,passages_used,t20,t80,peak_per_m2,wall_seconds,J_sd,J_min,J_max,repeats\n");
  for (size_t i = 0; i < widths.size(); ++i) {
    const double b = widths[i], rho = density[density.size() == 1 ? 0 : i];
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<double> flows;
    BottleneckResult first;
    int peak = 0;
    for (int k = 1; k <= repeats; ++k) {
      const BottleneckResult r = bottleneck_flow(model, b, rho, threads, people[people.size() == 1 ? 0 : i], static_cast<uint64_t>(k));
      if (k == 1) first = r;
      flows.push_back(r.flow);
      peak = std::max(peak, r.peak_per_m2);
    }
    const Spread J = spread(flows);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%g,%g,%zu,%.3f,%zu,%.2f,%.2f,%d,%.1f,%.3f,%.3f,%.3f,%d\n", b, rho, first.agents, J.mean, first.passages, first.t20,
                first.t80, peak, secs, J.sd, J.min, J.max, repeats);
    std::fflush(stdout);
  }
  return 0;
}
// N(t) of a whole-run replay against the recording, written as "t,recorded,simulated" rows to
// `curve` (if given); one summary row on stdout. With repeats > 1 the entry points are jittered
// with seeds 2..repeats beside the exact replay (replay_recording's jitter_seed): J_simulated and
// ratio are means over all, J_sd, ratio_min and ratio_max the spread, passages_simulated the
// exact replay's, and the curve's simulated N(t) the mean.
int run_replay(const Model& model, const std::string& scenario, const std::string& trajectories,
               const std::vector<double>& line, int threads, const std::string& curve, int repeats) {
  if (line.size() != 4) usage("--line needs x0,y0,x1,y1");
  const ScenarioDef sc = ScenarioDef::load(scenario);
  const TrajectorySet rec = TrajectorySet::read(trajectories);
  const PassageLine passage{Vec2(line[0], line[1]), Vec2(line[2], line[3])};
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<ReplayResult> runs = replay_repeats(sc, model, rec, passage, repeats, 30, threads);
  std::vector<double> flows, ratios;
  for (const ReplayResult& x : runs) {
    flows.push_back(x.simulated_flow);
    ratios.push_back(x.recorded_flow > 0 ? x.simulated_flow / x.recorded_flow : 0.0);
  }
  const ReplayResult& r = runs.front();
  const Spread J = spread(flows), ratio = spread(ratios);
  double duration = 0;
  for (const ReplayResult& x : runs) duration = std::max(duration, x.duration);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("people,placed,passages_recorded,passages_simulated,J_recorded,J_simulated,ratio,duration,wall_seconds,"
              "J_sd,ratio_min,ratio_max,repeats\n");
  std::printf("%zu,%zu,%zu,%zu,%.3f,%.3f,%.3f,%.1f,%.1f,%.3f,%.3f,%.3f,%d\n", r.people, r.placed, r.recorded.size(),
              r.simulated.size(), r.recorded_flow, J.mean, ratio.mean, duration, secs, J.sd, ratio.min, ratio.max, repeats);
  if (!curve.empty()) {
    std::FILE* f = std::fopen(curve.c_str(), "w");
    if (!f) throw Error("cannot write " + curve);
    std::fprintf(f, "t,recorded,simulated\n");
    const auto n = [](const std::vector<double>& v, double t) {
      return static_cast<double>(std::upper_bound(v.begin(), v.end(), t) - v.begin());
    };
    for (double t = 0; t <= duration + 1e-9; t += 0.5) {
      double sim = 0;
      for (const ReplayResult& x : runs) sim += n(x.simulated, t) / static_cast<double>(runs.size());
      std::fprintf(f, "%.1f,%ld,%.2f\n", t, static_cast<long>(n(r.recorded, t)), sim);
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

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t b = 0;
  for (size_t e; (e = s.find(sep, b)) != std::string::npos; b = e + 1) out.push_back(s.substr(b, e - b));
  out.push_back(s.substr(b));
  return out;
}

// One chart series from columns of a CSV file (rows whose cells there are not numbers are skipped).
ChartSeries read_series(const std::string& spec) {
  const std::vector<std::string> f = split(spec, '|');
  if (f.size() != 6 && f.size() != 7) usage("--series needs NAME|CSV|XCOL|YCOL|STYLE|RRGGBB[|YCOL2], got '" + spec + "'");
  ChartSeries s;
  s.name = f[0];
  const std::string& style = f[4];
  s.style = style == "line" ? ChartSeries::Style::Line : style == "points" ? ChartSeries::Style::Points
          : style == "linepoints" ? ChartSeries::Style::LinePoints : style == "band" ? ChartSeries::Style::Band
          : (usage("--series style must be line, points, linepoints or band, got '" + style + "'"), ChartSeries::Style::Line);
  if (s.style == ChartSeries::Style::Band && f.size() != 7) usage("a band series needs YCOL2 (its upper edge): " + spec);
  if (f[5].size() != 6 || f[5].find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
    usage("--series colour must be RRGGBB in hexadecimal, got '" + f[5] + "'");
  const long rgb = std::strtol(f[5].c_str(), nullptr, 16);
  s.rgb = {static_cast<int>(rgb >> 16), static_cast<int>((rgb >> 8) & 255), static_cast<int>(rgb & 255)};
  std::FILE* in = std::fopen(f[1].c_str(), "r");
  if (!in) throw Error(f[1] + ": cannot open the CSV for the chart");
  std::vector<std::string> header;
  char line[4096];
  int cx = -1, cy = -1, cy2 = -1;
  while (std::fgets(line, sizeof line, in)) {
    std::string l(line);
    while (!l.empty() && (l.back() == '\n' || l.back() == '\r')) l.pop_back();
    if (l.empty() || l[0] == '#') continue;
    const std::vector<std::string> cells = split(l, ',');
    if (header.empty()) {
      header = cells;
      for (size_t i = 0; i < cells.size(); ++i) {
        if (cells[i] == f[2]) cx = static_cast<int>(i);
        if (cells[i] == f[3]) cy = static_cast<int>(i);
        if (f.size() == 7 && cells[i] == f[6]) cy2 = static_cast<int>(i);
      }
      if (cx < 0 || cy < 0 || (f.size() == 7 && cy2 < 0)) {
        std::fclose(in);
        throw Error(f[1] + ": the header has no column '" + (cx < 0 ? f[2] : cy < 0 ? f[3] : f[6]) + "'");
      }
      continue;
    }
    auto num = [&](int c, double& v) {
      if (c >= static_cast<int>(cells.size())) return false;
      char* end = nullptr;
      v = std::strtod(cells[static_cast<size_t>(c)].c_str(), &end);
      return end != cells[static_cast<size_t>(c)].c_str() && *end == 0 && std::isfinite(v);
    };
    double x, y, y2 = 0;
    if (!num(cx, x) || !num(cy, y) || (cy2 >= 0 && !num(cy2, y2))) continue;
    s.points.emplace_back(x, y);
    if (cy2 >= 0) s.upper.emplace_back(x, y2);
  }
  std::fclose(in);
  return s;
}

int main(int argc, char** argv) {
  if (argc < 2) usage("needs fd or bottleneck");
  const std::string what = argv[1];
  std::string model_path;
  std::vector<double> densities = {0.5, 1, 1.5, 2, 2.5, 3, 3.5, 4, 4.5, 5, 5.5, 6};
  std::vector<double> widths = {0.4, 0.8, 1.0, 1.2, 1.8, 2.4, 3.0, 5.0};
  int threads = 1, repeats = 1;
  double warmup = 20, measure = 30;
  std::vector<double> density = {3.5};
  std::vector<double> people = {0};
  std::string scenario, trajectories, curve, out_png;
  Chart chart;
  std::vector<std::string> series;
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
    else if (a == "--repeats") {
      const std::string n = value();
      char* end = nullptr;
      const long k = std::strtol(n.c_str(), &end, 10);
      if (n.empty() || *end || k < 1 || k > 1000) usage("--repeats needs a whole number from 1 to 1000, got '" + n + "'");
      repeats = static_cast<int>(k);
    }
    else if (a == "--warmup") warmup = parse_list(value()).at(0);
    else if (a == "--measure") measure = parse_list(value()).at(0);
    else if (a == "--density") density = parse_list(value());
    else if (a == "--people") {
      people = parse_list(value(), true);
      for (double n : people)
        if (n < 0) usage("--people: " + format_number(n) + " is negative (0: the 6 m room as it is)");
    }
    else if (a == "--scenario") scenario = value();
    else if (a == "--trajectories") trajectories = value();
    else if (a == "--curve") curve = value();
    else if (a == "--line" || a == "--box") line = parse_list(value(), true);
    else if (a == "--out") out_png = value();
    else if (a == "--title") chart.title = value();
    else if (a == "--x") chart.x_label = value();
    else if (a == "--y") chart.y_label = value();
    else if (a == "--series") series.push_back(value());
    else usage("unknown option '" + a + "'");
  }
  try {
    if (what == "chart") {
      if (out_png.empty() || series.empty()) usage("chart needs --out PNG and at least one --series");
      for (const std::string& spec : series) chart.series.push_back(read_series(spec));
      write_chart_png(out_png, chart);
      return 0;
    }
    const Model model = model_path.empty() || model_path == "default" ? Model::default_model() : Model::load(model_path);
    if (what == "fd") return run_fd(model, densities, threads, warmup, measure);
    if (what == "bottleneck") return run_bottleneck(model, widths, threads, density, people, repeats);
    if (what == "replay") return run_replay(model, scenario, trajectories, line, threads, curve, repeats);
    if (what == "measure") return run_measure(trajectories, line);
    usage("unknown check '" + what + "' (fd, bottleneck, replay, measure or chart)");
  } catch (const Error& e) {
    std::fprintf(stderr, "validate: %s\n", e.what());
    return 1;
  }
}
