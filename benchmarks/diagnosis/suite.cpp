// The diagnosis suite (benchmarks/diagnosis/README.md): recordings made by the social-force
// model kind with one effect concealed from the scenario handed to the diagnosis, at several
// tracking-noise levels, and controls with nothing concealed; each is diagnosed as
// `crowdmpm diagnose` does and scored (identification, false findings, localisation and
// parameter error, held-out error before and after).
//
// usage: diagnosis_suite SUITE.json --out DIR [--threads N] [--only SCENE:EFFECT[,SCENE:EFFECT...]]
//                        [--noise SD] [--options JSON] [--video] [--truth-given]
// --video: each case is filmed instead (suite.json "video": the synthetic renderer's tilted
// camera, textured heads, sensor noise, blur, Motion JPEG) and diagnosed from the video's optical
// flow (the "video" request of a diagnosis), once per case instead of once per noise level.
// --truth-given: every concealed case's recording is also diagnosed with the effect given (the
// belief plus the concealed obstacle, walls or force, in its place; a force's strength fitted
// with the baseline; the belief's model; no term added: given.json and given/ in its folder), and
// the table adds that baseline's held-out error of the people passing where the effect acts (as
// a term of its kind would be judged; everyone for a drift, a density law and the constriction)
// and of everyone: how far the baseline material gets with the concealed physics known, against
// which the error before and after the diagnosis's terms can be read. Where the diagnosis
// accepts no term, its own before and after are then taken over the same people.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "engine/core/input.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/diagnosis/diagnose.hpp"
#include "engine/diagnosis/synthetic.hpp"
#include "engine/vision/synthetic.hpp"

using namespace crowdmpm;
namespace fs = std::filesystem;

namespace {

struct Row {
  std::string scene, effect, verdict;
  double noise = 0;
  bool correct = false, finding = false;
  double loc_error = NAN, param_error = NAN;
  std::string param_name;
  double before = NAN, after = NAN, global_before = NAN, global_after = NAN, seconds = 0;
  // Video: the flow's tracks against what was filmed (track_quality).
  double ghosts = NAN, velocity_error = NAN, speed_ratio = NAN;
  // --truth-given: the held-out error of everyone with the concealed effect in the scenario.
  double given = NAN, given_region = NAN;  // the second over the people passing where it acts
};

// Every 5th frame from 2 s on, each flow track's velocity (to the next frame) against the mean
// velocity of the filmed people within 0.6 m of it: the share of tracks with nobody there
// (ghosts), the RMS velocity error (m/s) and the ratio of mean speeds.
void track_quality(const TrajectorySet& filmed, const TrajectorySet& tracks, Row& row) {
  auto velocities = [](const TrajectorySet& t, long f) {
    std::vector<std::pair<Vec2, Vec2>> out;
    const auto [a0, a1] = t.frame(f);
    const auto [b0, b1] = t.frame(f + 1);
    for (const TrackPoint* a = a0; a != a1; ++a)
      for (const TrackPoint* b = b0; b != b1; ++b)
        if (b->id == a->id) out.emplace_back(Vec2(a->x, a->y), t.framerate * Vec2(b->x - a->x, b->y - a->y));
    return out;
  };
  long n = 0, ghosts = 0, matched = 0;
  double se = 0, speed_filmed = 0, speed_tracks = 0;
  for (long f = tracks.frame_min() + static_cast<long>(2 * tracks.framerate); f < tracks.frame_max(); f += 5) {
    const auto truth = velocities(filmed, f);
    for (const auto& [x, v] : velocities(tracks, f)) {
      ++n;
      Vec2 u = Vec2::Zero();
      int k = 0;
      for (const auto& [y, w] : truth)
        if ((y - x).norm() < 0.6) u += w, ++k;
      if (k == 0) {
        ++ghosts;
        continue;
      }
      u /= k;
      se += (v - u).squaredNorm();
      speed_filmed += u.norm();
      speed_tracks += v.norm();
      ++matched;
    }
  }
  if (n == 0 || matched == 0) return;
  row.ghosts = static_cast<double>(ghosts) / static_cast<double>(n);
  row.velocity_error = std::sqrt(se / static_cast<double>(matched));
  row.speed_ratio = speed_tracks / speed_filmed;
}

// The parameter compared for each type, in the report's names.
const char* compared_param(const std::string& type) {
  if (type == "obstacle") return "radius";
  if (type == "constriction") return "width";
  if (type == "attractor" || type == "vortex") return "strength";
  if (type == "slow_zone") return "factor";
  if (type == "counterflow") return "direction";  // degrees
  return "";
}

// What --truth-given fits of a concealed force: its strength, not its place.
json given_learns(const std::string& type) {
  if (type == "drift") return {"acceleration"};
  if (type == "attractor" || type == "vortex") return {"strength"};  // its range has a hard edge, as generated
  if (type == "slow_zone") return {"factor"};
  if (type == "wall_friction") return {"coefficient", "range"};
  if (type == "density_speed") return {"gamma", "max_density"};
  if (type == "counterflow") return {"share", "push"};
  throw Error("--truth-given: no strength to fit for a concealed force of type " + type);
}

std::string fmt(double v, int d = 3) {
  if (!std::isfinite(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", d, v);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::string suite_path, out_dir, only;
    int threads = 2;
    double only_noise = -1;
    json extra = json::object();
    bool video = false, truth_given = false;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw Error(a + " needs a value");
        return argv[++i];
      };
      if (a == "--out") out_dir = value();
      else if (a == "--threads") threads = std::stoi(value());
      else if (a == "--only") only = value();
      else if (a == "--noise") only_noise = std::stod(value());
      else if (a == "--options") extra = json::parse(value());
      else if (a == "--video") video = true;
      else if (a == "--truth-given") truth_given = true;
      else if (!a.empty() && a[0] == '-') throw Error("unknown option " + a);
      else suite_path = a;
    }
    if (suite_path.empty() || out_dir.empty()) throw Error("usage: diagnosis_suite SUITE.json --out DIR [--threads N] [--only SCENE:EFFECT] [--noise SD] [--options JSON] [--video] [--truth-given]");
    const json suite = load_json_file(suite_path);
    const fs::path scenes = fs::path(suite_path).parent_path() / "scenes";
    const Model generator = Model::parse(JsonReader(suite.at("generator_model"), "generator_model"), suite_path);
    std::vector<Row> rows;
    const auto& cases = suite.at("cases");
    for (size_t ci = 0; ci < cases.size(); ++ci) {
      const json& c = cases[ci];
      const std::string scene = c.at("scene"), effect = c.at("effect");
      if (!only.empty() && ("," + only + ",").find("," + scene + ":" + effect + ",") == std::string::npos) continue;
      const json belief = load_json_file((scenes / (scene + ".json")).string());
      json truth = belief;
      truth["seed"] = belief.value("seed", 1) + static_cast<int>(ci);
      truth["model"] = suite.at("generator_model");
      if (c.contains("obstacle")) truth["geometry"]["obstacles"].push_back({{"id", "concealed"}, {"circle", c.at("obstacle")}});
      if (c.contains("force")) truth["forces"] = json::array({c.at("force")});
      // A concealed wall with an opening: its solid pieces; "opening" {center, width} is the truth compared.
      if (c.contains("walls"))
        for (const json& w : c.at("walls")) truth["geometry"]["obstacles"].push_back(w);
      // Video: one pass per case (noise -1 in the rows: the renderer's noise and the codec's).
      const std::vector<double> levels = video ? std::vector<double>{-1} : suite.at("noise").get<std::vector<double>>();
      for (double noise : levels) {
        if (!video && only_noise >= 0 && std::abs(noise - only_noise) > 1e-9) continue;
        const fs::path dir = fs::path(out_dir) / (scene + "_" + effect + "_" + (video ? std::string("video") : fmt(noise, 2)));
        fs::create_directories(dir);
        save_json_file(belief, (dir / "belief.json").string());
        save_json_file(truth, (dir / "truth.json").string());
        const ScenarioDef truth_def = ScenarioDef::load((dir / "truth.json").string());
        json options = extra;
        options["threads"] = threads;
        json request = {{"scenario", (dir / "belief.json").string()}, {"options", options}};
        if (video) {
          // The camera: pixels_per_metre over the domain's width, the height its depth needs at the tilt.
          const json& vc = suite.at("video");
          RenderOptions ro;
          const Vec2 lo = truth_def.geo.lo, hi = truth_def.geo.hi;
          const double ppm = vc.at("pixels_per_metre").get<double>();
          ro.camera.tilt_deg = vc.at("tilt_deg").get<double>();
          auto even16 = [](double px) { return 16 * std::max(4, static_cast<int>(std::ceil(px / 16))); };
          ro.camera.width = even16(ppm * (hi.x() - lo.x()));
          ro.camera.height = even16(ppm * (hi.y() - lo.y()) * std::cos(ro.camera.tilt_deg * M_PI / 180));
          ro.fps = vc.at("fps").get<double>();
          ro.duration = truth_def.duration;
          ro.seed = 1000 + ci;
          Simulation sim(truth_def, generator, threads);
          const RenderResult rr = render_synthetic_video(sim, ro, (dir / "video.avi").string());
          save_json_file(rr.calibration.to_json({lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}), (dir / "calibration.json").string());
          // What was filmed, as exact tracks (to compare the tracks the flow gives with).
          write_noisy_recording(truth_def, generator, 0, 0, threads, (dir / "filmed.txt").string());
          json v = {{"path", (dir / "video.avi").string()}, {"calibration", (dir / "calibration.json").string()}};
          request["video"] = v;
        } else {
          write_noisy_recording(truth_def, generator, noise, 1000 + ci * 10 + static_cast<uint64_t>(noise * 1000), threads,
                                (dir / "observed.txt").string());
          request["trajectories"] = (dir / "observed.txt").string();
        }
        const auto t0 = std::chrono::steady_clock::now();
        DiagnoseJob job = parse_diagnose_job(request);
        // --truth-given: where no term is accepted, the errors before and after are those of the
        // people passing where the concealed effect acts, as the given run's are.
        Reach truth_reach;
        if (truth_given) {
          if (c.contains("obstacle")) {  // where an obstacle term there would be judged
            const json o = {{"type", "obstacle"}, {"center", c.at("obstacle").at("center")}, {"radius", c.at("obstacle").at("radius")}};
            truth_reach = term_reach(Term::parse(JsonReader(o, "concealed obstacle"), {}));
          } else if (c.contains("force")) {
            truth_reach = term_reach(truth_def.terms.at(0));
          }
          job.options.report_reach = truth_reach;
        }
        // Each case's progress (fits, fitted parameters, every candidate's comparison) in its folder.
        std::ofstream log((dir / "progress.log").string());
        const DiagnosisResult r = run_diagnosis(job, [&log](const std::string& line) { log << line << "\n" << std::flush; });
        write_diagnosis(job, r, dir.string());
        Row row;
        row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        row.scene = scene;
        row.effect = effect;
        row.noise = noise;
        const json report = diagnosis_json(job, r);
        const json& v = report.at("verdict");
        row.verdict = v.at("type");
        // A wall with an opening is reported as an obstacle of that shape; it is not the round
        // obstacle a case conceals.
        if (v.at("params").value("shape", "") == "constriction") row.verdict = "constriction";
        row.finding = row.verdict != "none";
        row.correct = row.verdict == effect;
        row.before = v.at("heldout_error_before");
        row.after = v.at("heldout_error_after");
        row.global_before = v.at("heldout_error_global_before");
        row.global_after = v.at("heldout_error_global_after");
        if (row.correct && effect != "none") {
          const json& p = v.at("params");
          const json& truth_params = c.contains("obstacle") ? c.at("obstacle") : c.contains("opening") ? c.at("opening") : c.at("force");
          if (truth_params.contains("center") && p.contains("x"))
            row.loc_error = std::hypot(p.at("x").get<double>() - truth_params.at("center")[0].get<double>(),
                                       p.at("y").get<double>() - truth_params.at("center")[1].get<double>());
          row.param_name = compared_param(effect);
          if (!row.param_name.empty() && p.contains(row.param_name))
            row.param_error = std::abs(p.at(row.param_name).get<double>() - truth_params.at(row.param_name).get<double>());
          if (row.param_name == "direction")  // the angle between the two directions
            row.param_error = std::abs(std::remainder(row.param_error, 360.0));
          if (effect == "drift")
            row.param_error = std::hypot(p.at("ax").get<double>() - truth_params.at("acceleration")[0].get<double>(),
                                         p.at("ay").get<double>() - truth_params.at("acceleration")[1].get<double>()),
            row.param_name = "acceleration";
        }
        if (video) track_quality(TrajectorySet::read((dir / "filmed.txt").string()), job.recording, row);
        if (truth_given && effect != "none") {
          // The same recording (a video's tracks as the diagnosis read them), the believed venue
          // with the concealed effect, the believed model; only the baseline is fitted.
          json given = truth;
          given["model"] = belief.contains("model") ? belief.at("model") : json("default");
          // A force's strength is fitted with the baseline (its place and form as concealed):
          // the generator's values act through the generator's relaxation time, not the
          // material's (the suite's corridor attractor at 0.02 m, given as generated: held-out
          // error 0.254 -> 0.492 m).
          if (given.contains("forces"))
            for (json& f : given["forces"]) f["learn"] = given_learns(f.at("type"));
          save_json_file(given, (dir / "given.json").string());
          json o = options;
          o["max_terms"] = 0;
          const json g = {{"scenario", (dir / "given.json").string()},
                          {"trajectories", (dir / (video ? "video_tracks.txt" : "observed.txt")).string()},
                          {"options", o}};
          DiagnoseJob gj = parse_diagnose_job(g);
          gj.options.report_reach = truth_reach;
          std::ofstream glog((dir / "given_progress.log").string());
          const DiagnosisResult gr = run_diagnosis(gj, [&glog](const std::string& line) { glog << line << "\n" << std::flush; });
          write_diagnosis(gj, gr, (dir / "given").string());
          row.given = gr.heldout_before;
          row.given_region = gr.region_before;
        }
        std::printf("%-9s %-10s %s: verdict %-10s %s  held-out %s -> %s m (everyone %s -> %s%s)  loc %s m  %s error %s  (%.0f s)\n",
                    scene.c_str(), effect.c_str(), video ? "video     " : ("noise " + fmt(noise, 2)).c_str(), row.verdict.c_str(),
                    effect == "none" ? (row.finding ? "FALSE FINDING" : "ok") : (row.correct ? "correct" : "WRONG"),
                    fmt(row.before).c_str(), fmt(row.after).c_str(), fmt(row.global_before).c_str(), fmt(row.global_after).c_str(),
                    std::isfinite(row.given) ? ("; effect given " + fmt(row.given_region) + ", everyone " + fmt(row.given)).c_str() : "", fmt(row.loc_error, 2).c_str(), row.param_name.empty() ? "param" : row.param_name.c_str(),
                    fmt(row.param_error, 2).c_str(), row.seconds);
        std::fflush(stdout);
        rows.push_back(row);
      }
    }
    // The table.
    std::ofstream t(fs::path(out_dir) / "table.md");
    t << "| scene | concealed | noise (m) | verdict | result | held-out error in region (m) | everyone (m) | localisation error (m) | parameter error | time (s) |"
      << (video ? " tracks with nobody filmed within 0.6 m | track velocity RMS error (m/s) | track / filmed speed |" : "")
      << (truth_given ? " effect given: in region (m) | effect given: everyone (m) |" : "") << "\n"
      << "|---|---|---|---|---|---|---|---|---|---|" << (video ? "---|---|---|" : "") << (truth_given ? "---|---|" : "") << "\n";
    for (const Row& r : rows) {
      t << "| " << r.scene << " | " << r.effect << " | " << (r.noise < 0 ? std::string("video") : fmt(r.noise, 2)) << " | " << r.verdict << " | "
        << (r.effect == "none" ? (r.finding ? "false finding" : "no finding (right)") : (r.correct ? "correct" : "wrong")) << " | "
        << fmt(r.before) << " → " << fmt(r.after) << " | " << fmt(r.global_before) << " → " << fmt(r.global_after) << " | "
        << fmt(r.loc_error, 2) << " | " << (r.param_name.empty() ? "-" : r.param_name + " " + fmt(r.param_error, 2)) << " | "
        << fmt(r.seconds, 0) << " |";
      if (video) t << " " << fmt(100 * r.ghosts, 1) << "% | " << fmt(r.velocity_error, 3) << " | " << fmt(r.speed_ratio, 2) << " |";
      if (truth_given) t << " " << fmt(r.given_region) << " | " << fmt(r.given) << " |";
      t << "\n";
    }
    t << "\n";
    const std::vector<double> levels = video ? std::vector<double>{-1} : suite.at("noise").get<std::vector<double>>();
    for (double noise : levels) {
      int n = 0, ok = 0, controls = 0, false_findings = 0;
      for (const Row& r : rows) {
        if (std::abs(r.noise - noise) > 1e-9) continue;
        if (r.effect == "none") {
          ++controls;
          false_findings += r.finding;
        } else {
          ++n;
          ok += r.correct;
        }
      }
      if (n + controls == 0) continue;
      t << "- " << (video ? std::string("video") : "noise " + fmt(noise, 2) + " m") << ": top-1 identification " << ok << "/" << n << ", false findings on controls "
        << false_findings << "/" << controls << "\n";
    }
    double worst_loc = 0, least_gain = 1;
    int correct = 0, located = 0;
    for (const Row& r : rows) {
      if (!r.correct || r.effect == "none") continue;
      ++correct;
      if (std::isfinite(r.loc_error)) {
        ++located;
        worst_loc = std::max(worst_loc, r.loc_error);
      }
      least_gain = std::min(least_gain, 1 - r.after / r.before);
    }
    if (correct == 0) {
      t << "- no correct identification (so no localisation error or held-out reduction to give)\n";
    } else {
      if (located == 0)
        t << "- no obstacle, attractor or vortex correctly found (no localisation error to give)\n";
      else
        t << "- largest localisation error of a correctly found obstacle, attractor or vortex: " << fmt(worst_loc, 2) << " m\n";
      t << "- smallest held-out error reduction of a correct identification: " << fmt(100 * least_gain, 1) << "%\n";
    }
    std::printf("table: %s\n", (fs::path(out_dir) / "table.md").string().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "diagnosis_suite: %s\n", e.what());
    return 1;
  }
}
