// Diagnosis (docs/diagnosis.md): a concealed obstacle is found, placed and sized from a
// recording made by another model kind (social force), a recording with nothing concealed
// gives no finding, the report has the documented shape, and bad requests name their error.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <algorithm>
#include <map>
#include <vector>
#include <optional>
#include <tuple>

#include "engine/diagnosis/diagnose.hpp"
#include "engine/diagnosis/synthetic.hpp"
#include "engine/observe/observe.hpp"
#include "engine/observe/track_smoother.hpp"
#include "engine/vision/flow_tracks.hpp"
#include "engine/vision/synthetic.hpp"
#include "support.hpp"

using namespace crowdmpm;
namespace fs = std::filesystem;

namespace {
// A 14 m x 3 m corridor walked left to right; what the user believes.
const char* kCorridor = R"({"format": "crowdmpm-scenario", "version": 1, "name": "test corridor",
  "domain": {"min": [-2, -0.5], "max": [16, 3.5], "cell_size": 0.5},
  "time": {"dt": 0.01, "duration": 36, "output_rate": 10}, "seed": 7, "model": "default",
  "geometry": {"obstacles": [{"rect": [-2, -0.5, 16, 0]}, {"rect": [-2, 3, 16, 3.5]}],
               "exits": [{"id": "end", "rect": [15, 0, 16, 3]}]},
  "sources": [{"id": "in", "region": {"rect": [-1.8, 0.2, 0, 2.8]}, "rate": 3.5, "start": 0, "end": 36,
               "desired_speed": {"mean": 1.3, "sd": 0.15}, "behaviour": {"type": "goal", "target": "end"}}]})";

struct Case {
  fs::path dir;
  std::string belief, observed;
};

// The belief file and a recording of the truth (the belief plus `concealed` obstacles) by the
// social-force model with 0.03 m tracking noise.
Case make_case(const std::string& name, const json& concealed) {
  Case c;
  c.dir = fs::path(CROWDMPM_BINARY_DIR) / "tests" / "diagnosis" / name;
  fs::create_directories(c.dir);
  const json belief = json::parse(kCorridor);
  c.belief = (c.dir / "belief.json").string();
  c.observed = (c.dir / "observed.txt").string();
  save_json_file(belief, c.belief);
  json truth = belief;
  for (const auto& o : concealed) truth["geometry"]["obstacles"].push_back(o);
  const ScenarioDef t = ScenarioDef::parse(truth, "truth", c.dir.string());
  write_noisy_recording(t, Model::default_of("social_force"), 0.03, 11, 2, c.observed);
  return c;
}

json request_for(const Case& c) {
  return {{"scenario", c.belief},
          {"trajectories", c.observed},
          {"options", {{"iterations", 30}, {"null_replicates", 3}, {"threads", 2}, {"max_terms", 1},
                       {"candidates", {"obstacle", "constriction", "drift", "slow_zone"}}}}};
}
// People keeping paces of their own (0.9, 1.3 and 1.7 m/s in three lanes of kCorridor, y 0.5, 1.5
// and 2.5 m, no one in anyone's way), with uniform noise of +-0.01 m: 36 s at 10 fps.
void write_paces(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  REQUIRE(f);
  std::fprintf(f, "# framerate: 10\n# unit: m\n");
  uint32_t state = 12345;
  const auto noise = [&] {  // uniform in [-0.01, 0.01] m
    state = state * 1664525u + 1013904223u;
    return 0.02 * (static_cast<double>(state >> 8) / 16777216.0 - 0.5);
  };
  for (int frame = 0; frame < 360; ++frame)
    for (int i = 0; i < 57; ++i) {
      const int lane = i % 3;
      const double pace = 0.9 + 0.4 * lane + 0.02 * (i % 5), entered = 0.6 * i;
      const double x = -1.5 + pace * (0.1 * frame - entered);
      if (x < -1.5 || x > 15.2) continue;
      std::fprintf(f, "%d %d %.4f %.4f\n", i + 1, frame, x + noise(), 0.5 + lane + noise());
    }
  std::fclose(f);
}
}  // namespace

TEST_CASE("diagnosis finds a concealed obstacle and writes the documented report", "[diagnosis]") {
  const Case c = make_case("obstacle", json::array({{{"circle", {{"center", {7, 1.5}}, {"radius", 0.5}}}}}));
  json request = request_for(c);
  request["options"]["density_law"] = false;
  const DiagnoseJob job = parse_diagnose_job(request);
  const DiagnosisResult r = run_diagnosis(job, [](const std::string& s) { std::printf("  %s\n", s.c_str()); });
  const fs::path out = c.dir / "out";
  write_diagnosis(job, r, out.string());
  REQUIRE(r.terms.size() == 1);
  const Term& t = r.terms[0];
  CHECK(std::string(t.law->type()) == "obstacle");
  const double miss = std::hypot(t.params[0] - 7, t.params[1] - 1.5);
  std::printf("obstacle found at (%.2f, %.2f), radius %.2f (truth (7, 1.5), 0.5): %.2f m off; held-out %.3f -> %.3f m\n",
              t.params[0], t.params[1], t.params[2], miss, r.region_before, r.region_after);
  CHECK(miss < 1.0);
  CHECK(r.region_after < 0.9 * r.region_before);

  // The report: exactly the documented keys and types.
  const json rep = load_json_file((out / "report.json").string());
  const json& v = rep.at("verdict");
  CHECK(v.at("type") == "obstacle");
  for (const char* k : {"x", "y", "radius"}) CHECK(v.at("params").at(k).is_number());
  CHECK(v.at("heldout_error_before").is_number());
  CHECK(v.at("heldout_error_after").is_number());
  CHECK(v.at("heldout_error_after").get<double>() < v.at("heldout_error_before").get<double>());
  CHECK(!v.at("explanation").get<std::string>().empty());
  CHECK(v.at("error_unit").get<std::string>().find("m:") == 0);
  REQUIRE(!rep.at("regions").empty());
  for (const auto& g : rep.at("regions")) {
    CHECK(g.at("center").size() == 2);
    CHECK(g.at("radius").get<double>() > 0);
    CHECK(g.at("t_end").get<double>() > g.at("t_start").get<double>());
    CHECK(g.at("significance").get<double>() >= 0);
    CHECK(g.at("significance").get<double>() <= 1);
  }
  REQUIRE(!rep.at("hypotheses").empty());
  for (const auto& h : rep.at("hypotheses")) {
    CHECK(h.at("type").is_string());
    CHECK(h.at("params").is_object());
    CHECK(h.contains("heldout_error"));
    CHECK(h.contains("score"));
    CHECK((h.at("fit_start") == "baseline" || h.at("fit_start") == "refitted baseline"));
  }
  REQUIRE(rep.at("terms").size() == 1);
  CHECK(rep.at("terms")[0].at("type") == "obstacle");
  // Before and after are the baseline's and the final model's, each fitted on while it improved.
  const json& ff = rep.at("final_fits");
  for (const char* m : {"baseline", "model"}) {
    CHECK(ff.at(m).at("improving_fits").get<int>() >= 0);
    CHECK(ff.at(m).at("improving_fits").get<int>() <= 3);
    CHECK(ff.at(m).at("validation").get<double>() <= ff.at(m).at("validation_first").get<double>());
  }
  CHECK(v.at("heldout_error_global_before").get<double>() == Approx(r.heldout_before));
  // Everyone walked at the recording's typical free speed: people drawn around 1.3 m/s, sd 0.15
  // (read as it is: this request declines the default speed-density law).
  const json& ds = rep.at("desired_speed");
  CHECK(ds.at("mode") == "recording");
  CHECK(ds.at("speed").get<double>() == Approx(1.3).margin(0.15));
  CHECK(ds.at("effective").get<double>() ==
        Approx(ds.at("speed").get<double>() * rep.at("baseline_model").at("parameters").at("v0_scale").get<double>()));
  CHECK(ds.at("spread").get<double>() > 0.03);
  CHECK(ds.at("spread").get<double>() < 0.3);
  CHECK(ds.at("people").get<long>() > 20);
  CHECK(rep.at("density_law") == "none");  // the default crowd material has none, and the request declined Weidmann's
  for (const char* f : {"residual_before.png", "residual_after.png", "summary.txt", "scenario.json", "model.json"})
    CHECK(fs::file_size(out / f) > 0);
  // The venue with the term is a scenario the simulator runs.
  const ScenarioDef fitted = ScenarioDef::load((out / "scenario.json").string());
  CHECK(fitted.terms.size() == 1);
  // ... its crowd walking at the speeds read from the recording, which v0_scale was fitted to.
  REQUIRE(!fitted.groups.empty());
  CHECK(fitted.groups[0].desired_speed == Approx(ds.at("speed").get<double>()));
  CHECK(fitted.groups[0].speed_sd == Approx(ds.at("spread").get<double>()));
  Simulation sim(fitted, fitted.model_or_default(), 1);
  sim.run_steps(10);
}

TEST_CASE("diagnosis finds a concealed gate as a wall with an opening", "[diagnosis]") {
  // A wall across the corridor at x = 9 with a 1.4 m opening at y = 1.5 (a gate the plan lacks).
  const Case c = make_case("gate", json::array({{{"rect", {8.8, 0, 9.0, 0.8}}}, {{"rect", {8.8, 2.2, 9.0, 3}}}}));
  const DiagnoseJob job = parse_diagnose_job(request_for(c));
  const DiagnosisResult r = run_diagnosis(job, [](const std::string& s) { std::printf("  %s\n", s.c_str()); });
  REQUIRE(r.terms.size() == 1);
  const Term& t = r.terms[0];
  CHECK(std::string(t.law->type()) == "constriction");
  const double miss = std::hypot(t.params[0] - 8.9, t.params[1] - 1.5);
  std::printf("gate found: opening %.2f m at (%.2f, %.2f) heading %.0f degrees (truth 1.4 m at (8.9, 1.5), 0): %.2f m off; "
              "held-out %.3f -> %.3f m\n", t.params[2], t.params[0], t.params[1], t.params[3], miss, r.region_before, r.region_after);
  CHECK(miss < 1.0);
  CHECK(std::abs(t.params[2] - 1.4) < 0.5);
  CHECK(std::cos(t.params[3] * M_PI / 180) > 0.9);  // across the corridor's flow
  CHECK(r.region_after < 0.9 * r.region_before);
  // Reported as an obstacle of that shape, at the opening.
  write_diagnosis(job, r, (c.dir / "out").string());
  const json v = load_json_file((c.dir / "out" / "report.json").string()).at("verdict");
  CHECK(v.at("type") == "obstacle");
  CHECK(v.at("params").at("shape") == "constriction");
  CHECK(v.at("params").at("radius").get<double>() == Approx(0.5 * t.params[2]));
}

TEST_CASE("diagnosis of a recording with nothing concealed finds nothing", "[diagnosis]") {
  const Case c = make_case("control", json::array());
  const DiagnoseJob job = parse_diagnose_job(request_for(c));
  const DiagnosisResult r = run_diagnosis(job);
  for (const Hypothesis& h : r.hypotheses)
    std::printf("  control: %s %s\n", h.term.law->type(), h.why.c_str());
  CHECK(r.terms.empty());
  write_diagnosis(job, r, (c.dir / "out").string());
  const json rep = load_json_file((c.dir / "out" / "report.json").string());
  CHECK(rep.at("verdict").at("type") == "none");
  CHECK(rep.at("terms").empty());
  CHECK(rep.at("final_fits").is_null());  // nothing accepted: the baseline as fitted
  // The recorded tracks were smoothed under the noise they show: 0.03 m, as written.
  const json& sm = rep.at("recording").at("smoother");
  CHECK(sm.at("method") == "rts");
  CHECK(sm.at("position_noise_m").get<double>() == Approx(0.03).margin(0.006));
  CHECK(sm.at("acceleration_noise_m2_s3").get<double>() > 0);
  // The null adds the error the smoothed tracks carry: the smoother's steady state under those
  // levels, less than the noise the tracks were read with.
  const SmoothedError left = smoothed_error(job.track_noise, 1 / job.recording.framerate,
                                            velocity_lag_frames(job.options.residual.velocity_window, job.recording.framerate));
  std::printf("  control: the null's error %.4f m, %.4f m/s\n", r.null_error.position, r.null_error.velocity);
  CHECK(rep.at("null_error").at("position_m").get<double>() == Approx(left.position));
  CHECK(rep.at("null_error").at("velocity_m_s").get<double>() == Approx(left.velocity));
  CHECK(left.position > 0.005);
  CHECK(left.position < 0.7 * job.track_noise.position);
  // ... moved by about the noise, person by person and frame by frame as read; "none" keeps them as read.
  json as_read = request_for(c);
  as_read["options"]["smoother"] = "none";
  const DiagnoseJob raw = parse_diagnose_job(as_read);
  CHECK_FALSE(raw.trajectories_smoothed);
  const TrajectorySet read = TrajectorySet::read(c.observed);
  REQUIRE(raw.recording.points.size() == read.points.size());
  REQUIRE(job.recording.points.size() == read.points.size());
  double moved2 = 0, unchanged2 = 0;
  for (size_t k = 0; k < read.points.size(); ++k) {
    const TrackPoint &a = read.points[k], &s = job.recording.points[k], &n = raw.recording.points[k];
    REQUIRE(s.id == a.id);
    REQUIRE(s.frame == a.frame);
    moved2 += std::pow(s.x - a.x, 2) + std::pow(s.y - a.y, 2);
    unchanged2 += std::pow(n.x - a.x, 2) + std::pow(n.y - a.y, 2);
  }
  const double moved = std::sqrt(moved2 / (2.0 * static_cast<double>(read.points.size())));
  std::printf("  control: smoothing moved the tracked positions by %.4f m RMS per axis\n", moved);
  CHECK(moved > 0.015);
  CHECK(moved < 0.04);
  CHECK(unchanged2 == 0);
  // By default the baseline got Weidmann's law, and the speeds were read under it: higher than
  // walked (the law slows people at any density; the social-force crowd slows less), the fitted
  // v0_scale bringing them back down.
  CHECK(rep.at("density_law").get<std::string>().rfind("Weidmann's speed-density law added", 0) == 0);
  const json& ds = rep.at("desired_speed");
  const double v0_scale = rep.at("baseline_model").at("parameters").at("v0_scale").get<double>();
  CHECK(ds.at("speed").get<double>() > 1.3);
  CHECK(ds.at("effective").get<double>() == Approx(ds.at("speed").get<double>() * v0_scale));
  CHECK(ds.at("effective").get<double>() > 1.1);
  CHECK(ds.at("effective").get<double>() < 2.0);
}

TEST_CASE("diagnosis from a rendered video: its people are detected and followed and a concealed obstacle is found",
          "[diagnosis][vision]") {
  const fs::path dir = fs::path(CROWDMPM_BINARY_DIR) / "tests" / "diagnosis" / "video";
  fs::create_directories(dir);
  const json belief = json::parse(kCorridor);
  save_json_file(belief, (dir / "belief.json").string());
  json truth = belief;
  truth["geometry"]["obstacles"].push_back({{"circle", {{"center", {7, 1.5}}, {"radius", 0.5}}}});
  const ScenarioDef t = ScenarioDef::parse(truth, "truth", dir.string());
  const Model sfm = Model::default_of("social_force");
  // Filmed from 20 degrees off straight down at 40 pixels per metre, 10 frames per second.
  RenderOptions ro;
  ro.camera.tilt_deg = 20;
  ro.camera.width = 720;
  ro.camera.height = 160;
  ro.duration = t.duration;
  {
    Simulation sim(t, sfm, 2);
    const RenderResult rr = render_synthetic_video(sim, ro, (dir / "video.avi").string());
    save_json_file(rr.calibration.to_json({t.geo.lo, Vec2(t.geo.hi.x(), t.geo.lo.y()), t.geo.hi, Vec2(t.geo.lo.x(), t.geo.hi.y())}),
                   (dir / "calibration.json").string());
  }
  write_noisy_recording(t, sfm, 0, 1, 2, (dir / "filmed.txt").string());
  const TrajectorySet filmed = TrajectorySet::read((dir / "filmed.txt").string());
  const json request = {{"scenario", (dir / "belief.json").string()},
                        {"video", {{"path", (dir / "video.avi").string()}, {"calibration", (dir / "calibration.json").string()}}},
                        {"options", {{"iterations", 30}, {"null_replicates", 3}, {"threads", 2}, {"max_terms", 1},
                                     {"candidates", {"obstacle", "drift", "slow_zone"}}}}};
  const DiagnoseJob job = parse_diagnose_job(request);
  REQUIRE(job.from_video);
  const TrajectorySet& seen = job.recording;
  CHECK(seen.framerate == 10);
  // The people found: about as many as were filmed, each where somebody was (at their head,
  // not at the blob their head and shoulders make: `head_radius` 0 is measured beside).
  struct Found {
    long frames = 0;
    double count_error = 0, median = 0, q90 = 0, rms = 0, mean_dy = 0;  // dy: found minus filmed, across the view
    double velocity_rms = 0;  // m/s: a found person's step to the next frame against the nearest filmed one's
    size_t n = 0;
  };
  const auto compare = [&filmed](const TrajectorySet& seen) {
    Found r;
    std::vector<double> off;  // each found person's distance to the nearest filmed one
    long steps = 0;
    const auto at_frame = [](const TrajectorySet& t, long id, long f) -> const TrackPoint* {
      const auto [b, e] = t.frame(f);
      const auto it = std::lower_bound(b, e, id, [](const TrackPoint& p, long i) { return p.id < i; });
      return it != e && it->id == id ? it : nullptr;
    };
    for (long f = 50; f < filmed.frame_max(); f += 10) {
      const auto [a, b] = filmed.frame(f);
      const auto [c, d] = seen.frame(f);
      // People in view: the corridor, not the entrance behind its start.
      long in_view = 0, seen_in_view = 0;
      for (auto p = a; p != b; ++p) in_view += p->x > 0;
      for (auto q = c; q != d; ++q) {
        if (q->x <= 0) continue;
        ++seen_in_view;
        double best = 1e9, dy = 0;
        const TrackPoint* nearest = nullptr;
        for (auto p = a; p != b; ++p)
          if (std::hypot(p->x - q->x, p->y - q->y) < best) best = std::hypot(p->x - q->x, p->y - q->y), dy = q->y - p->y, nearest = p;
        off.push_back(best);
        const TrackPoint* q1 = at_frame(seen, q->id, f + 1);
        const TrackPoint* p1 = nearest && best < 0.3 ? at_frame(filmed, nearest->id, f + 1) : nullptr;
        if (q1 && p1) {
          r.velocity_rms += std::pow((q1->x - q->x - p1->x + nearest->x) * seen.framerate, 2) +
                            std::pow((q1->y - q->y - p1->y + nearest->y) * seen.framerate, 2);
          ++steps;
        }
        r.rms += best * best;
        r.mean_dy += dy;
      }
      r.count_error += std::abs(static_cast<double>(seen_in_view - in_view)) / static_cast<double>(std::max(1L, in_view));
      ++r.frames;
    }
    r.n = off.size();
    if (off.empty()) return r;
    std::sort(off.begin(), off.end());
    r.median = off[off.size() / 2];
    r.q90 = off[off.size() * 9 / 10];
    r.rms = std::sqrt(r.rms / static_cast<double>(off.size()));
    r.mean_dy /= static_cast<double>(off.size());
    r.velocity_rms = std::sqrt(r.velocity_rms / static_cast<double>(std::max(1L, steps)));
    r.count_error /= static_cast<double>(r.frames);
    return r;
  };
  const Found at = compare(seen);
  DetectOptions bodies = job.detection;
  bodies.head_radius = 0;
  const Found body = compare(detected_tracks(job.video, job.scenario.geo, bodies));
  std::printf("video people found: %zu in %ld frames, off the nearest filmed one by %.3f m (median), %.3f m (90%%), %.3f m (rms), "
              "mean %.3f m across; mean count error %.3f; velocity over a frame off by %.3f m/s (rms); at the bodies' blobs: "
              "%.3f m (rms), mean %.3f m across\n",
              at.n, at.frames, at.median, at.q90, at.rms, at.mean_dy, at.count_error, at.velocity_rms, body.rms, body.mean_dy);
  REQUIRE(at.n > 500);
  CHECK(at.count_error < 0.15);
  CHECK(at.median < 0.1);
  CHECK(at.q90 < 0.2);
  CHECK(std::abs(at.mean_dy) < 0.03);
  CHECK(body.mean_dy < -0.05);  // toward the camera, where it sees the shoulders
  CHECK(body.rms > 1.3 * at.rms);
  // Smoothed (the default smoother): a head's place jitters by 2-3 cm from frame to frame, 0.3-0.4
  // m/s over one frame at 10 fps; the smoothed tracks' steps are a few centimetres per second off.
  CHECK(at.velocity_rms < 0.2);
  // Followed: most of what was seen belongs to tracks of 3 s or more.
  std::map<long, long> length;
  for (const TrackPoint& p : seen.points) ++length[p.id];
  long long_points = 0;
  for (const auto& [id, n] : length) long_points += n >= 30 ? n : 0;
  CHECK(long_points > 0.8 * static_cast<double>(seen.points.size()));

  const DiagnosisResult r = run_diagnosis(job, [](const std::string& s) { std::printf("  %s\n", s.c_str()); });
  write_diagnosis(job, r, (dir / "out").string());
  CHECK(fs::file_size(dir / "out" / "video_tracks.txt") > 0);
  REQUIRE(r.terms.size() == 1);
  CHECK(std::string(r.terms[0].law->type()) == "obstacle");
  const double miss = std::hypot(r.terms[0].params[0] - 7, r.terms[0].params[1] - 1.5);
  std::printf("from video: obstacle at (%.2f, %.2f), radius %.2f (truth (7, 1.5), 0.5): %.2f m off; held-out %.3f -> %.3f m\n",
              r.terms[0].params[0], r.terms[0].params[1], r.terms[0].params[2], miss, r.region_before, r.region_after);
  CHECK(miss < 1.0);
  CHECK(r.region_after < 0.9 * r.region_before);
}

TEST_CASE("diagnosis reads each person's own pace where the baseline fits it better", "[diagnosis]") {
  // People keeping paces of their own (write_paces), as agents of a simulator with individual
  // preferred speeds walk: with everyone at one speed the baseline cannot fit them, with each at
  // their own it can.
  const fs::path dir = fs::path(CROWDMPM_BINARY_DIR) / "tests" / "diagnosis" / "paces";
  fs::create_directories(dir);
  const std::string belief = (dir / "belief.json").string(), rec = (dir / "paces.txt").string();
  save_json_file(json::parse(kCorridor), belief);
  write_paces(rec);
  const json request = {{"scenario", belief},
                        {"trajectories", rec},
                        {"options", {{"iterations", 30}, {"null_replicates", 3}, {"threads", 2}, {"max_terms", 0}}}};
  const DiagnoseJob job = parse_diagnose_job(request);
  CHECK(job.options.auto_speed);  // the default
  const DiagnosisResult r = run_diagnosis(job, [](const std::string& s) { std::printf("  %s\n", s.c_str()); });
  std::printf("paces: baseline validation loss %.4f m2 with everyone at the median free speed, %.4f m2 each at their own\n",
              r.validation_recording, r.validation_observed);
  CHECK(r.validation_observed < 0.5 * r.validation_recording);
  CHECK(!r.recording_speed);
  CHECK(r.desired_speed == DesiredSpeed::Observed);
  write_diagnosis(job, r, (dir / "out").string());
  const json ds = load_json_file((dir / "out" / "report.json").string()).at("desired_speed");
  CHECK(ds.at("mode") == "observed");
  CHECK(ds.at("validation_loss_observed_m2").get<double>() == Approx(r.validation_observed));
  CHECK(ds.at("validation_loss_recording_m2").get<double>() == Approx(r.validation_recording));
  CHECK(!ds.contains("speed"));  // no typical speed was used
  // Asked for one reading, the diagnosis keeps it.
  json fixed = request;
  fixed["options"]["desired_speed"] = "recording";
  CHECK(!parse_diagnose_job(fixed).options.auto_speed);
  CHECK(parse_diagnose_job(fixed).options.recording_speed);
}

TEST_CASE("the believed scenario's own terms marked learn are fitted with the baseline and saved as fitted", "[diagnosis]") {
  // Also: a region asked for by a program (report_reach) is what the report's errors cover.
  // The user believes in a sideways drift of 0.6 m/s^2 and asks for its strength to be fitted;
  // the recorded people walk straight along their lanes (write_paces).
  const fs::path dir = fs::path(CROWDMPM_BINARY_DIR) / "tests" / "diagnosis" / "own_terms";
  fs::create_directories(dir);
  const std::string belief = (dir / "belief.json").string(), rec = (dir / "paces.txt").string();
  json b = json::parse(kCorridor);
  b["forces"] = json::array({{{"type", "drift"}, {"acceleration", {0, 0.6}}, {"learn", {"acceleration"}}}});
  save_json_file(b, belief);
  write_paces(rec);
  const json request = {{"scenario", belief},
                        {"trajectories", rec},
                        {"options", {{"iterations", 30}, {"null_replicates", 3}, {"threads", 2}, {"max_terms", 0}}}};
  const DiagnoseJob job = parse_diagnose_job(request);
  const DiagnosisResult r = run_diagnosis(job);
  REQUIRE(r.scenario_terms.size() == 1);
  const double ay = r.scenario_terms[0].params[1];
  std::printf("own terms: the believed drift's sideways 0.6 m/s^2 fitted to %.3f\n", ay);
  CHECK(ay < 0.45);  // nobody drifts sideways: the fit lowers it
  write_diagnosis(job, r, (dir / "out").string());
  // Saved as fitted (not as believed), in the scenario to simulate and in the report.
  const json sc = load_json_file((dir / "out" / "scenario.json").string());
  REQUIRE(sc.at("forces").size() == 1);
  CHECK(sc.at("forces")[0].at("acceleration")[1].get<double>() == Approx(ay));
  const json rep = load_json_file((dir / "out" / "report.json").string());
  REQUIRE(rep.at("scenario_terms").size() == 1);
  CHECK(rep.at("scenario_terms")[0].at("acceleration")[1].get<double>() == Approx(ay));
  CHECK(rep.at("terms").empty());
  CHECK(r.region_before == Approx(r.heldout_before));  // no term accepted: everyone
  // Asked for a region (DiagnoseOptions::report_reach), the errors before and after cover the
  // people passing within a metre of the slow lane's middle: a share of everyone, another error.
  DiagnoseJob here = job;
  here.options.report_reach = Reach{Vec2(7, 0.5), Vec2(7, 0.5), 1.0};
  const DiagnosisResult rr = run_diagnosis(here);
  CHECK(rr.heldout_before == Approx(r.heldout_before));
  CHECK(std::isfinite(rr.region_before));
  CHECK(rr.region_before != Approx(rr.heldout_before).epsilon(1e-3));
  CHECK(rr.region_after == Approx(rr.region_before));
  const json v = diagnosis_json(here, rr).at("verdict");
  CHECK(v.at("error_unit").get<std::string>().find("the report's region asked for") != std::string::npos);
}

TEST_CASE("diagnosis requests name what is wrong", "[diagnosis]") {
  const fs::path dir = fs::path(CROWDMPM_BINARY_DIR) / "tests" / "diagnosis" / "bad";
  fs::create_directories(dir);
  const std::string belief = (dir / "belief.json").string(), rec = (dir / "short.txt").string();
  save_json_file(json::parse(kCorridor), belief);
  {
    std::FILE* f = std::fopen(rec.c_str(), "w");
    std::fprintf(f, "# framerate: 10\n");
    for (int k = 0; k < 30; ++k) std::fprintf(f, "1 %d %.2f 1.5\n", k, 0.1 * k);
    std::fclose(f);
  }
  auto fails_with = [&](const json& req, const std::string& what) {
    INFO(req.dump());
    try {
      const DiagnoseJob job = parse_diagnose_job(req);
      run_diagnosis(job);
      FAIL("no error; expected one naming " << what);
    } catch (const Error& e) {
      INFO(e.what());
      CHECK(std::string(e.what()).find(what) != std::string::npos);
    }
  };
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"cel", 1}}}}, "cel");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"candidates", {"ghost"}}}}}, "ghost");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"train_share", 2}}}}, "train_share");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"params", {"nonsense"}}}}}, "nonsense");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"optimizer", "newton"}}}}, "optimizer");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"desired_speed", "typical"}}}}, "desired_speed");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"density_law", "yes"}}}}, "density_law");
  {
    // Weidmann's law is added to a crowd material without one unless declined, and then refitted.
    const DiagnoseJob plain = parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}, {"options", {{"density_law", false}}}});
    CHECK_FALSE(plain.density_law_added);
    CHECK(plain.model.params.density_speed_gamma == 0);
    const auto& q = plain.options.params;
    CHECK(std::find(q.begin(), q.end(), "density_speed_gamma") == q.end());
    const DiagnoseJob law = parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}});
    CHECK(law.density_law_added);
    CHECK(law.model.params.density_speed_gamma == Approx(kWeidmannGamma));
    CHECK(law.model.params.density_speed_max == Approx(kWeidmannMaxDensity));
    const auto& p = law.options.params;
    CHECK(std::find(p.begin(), p.end(), "density_speed_gamma") != p.end());
    CHECK(std::find(p.begin(), p.end(), "density_speed_max") != p.end());
  }
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"smoother", "kalman"}}}}, "options.smoother");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}}}, {"options", {{"smoother", "none"}}}},
             "options.smoother: applies to \"trajectories\"");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"baseline_optimizer", "sgd"}}}}, "baseline_optimizer");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"baseline_restarts", 2.5}}}}, "baseline_restarts");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"baseline_restarts", 21}}}}, "baseline_restarts");
  CHECK(parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}, {"options", {{"baseline_restarts", 3}}}}).options.baseline_restarts == 3);
  CHECK(parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}}).options.baseline_restarts == 0);
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"final_restarts", -1}}}}, "final_restarts");
  CHECK(parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}, {"options", {{"final_restarts", 0}}}}).options.final_restarts == 0);
  CHECK(parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}}).options.final_restarts == 3);
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"options", {{"min_gain_venue", 1.5}}}}, "min_gain_venue");
  CHECK(parse_diagnose_job({{"scenario", belief}, {"trajectories", rec}, {"options", {{"min_gain_venue", 0.08}}}}).options.min_gain_venue == 0.08);
  {
    const DiagnoseJob job = parse_diagnose_job(
        {{"scenario", belief}, {"trajectories", rec}, {"options", {{"baseline_optimizer", "lbfgs"}, {"optimizer", "adam"}}}});
    CHECK(job.options.baseline_lbfgs);
    CHECK_FALSE(job.options.candidates_lbfgs);
  }
  fails_with({{"scenario", belief}, {"trajectories", (dir / "missing.txt").string()}}, "missing.txt");
  fails_with({{"scenario", belief}}, "trajectories");
  fails_with({{"scenario", belief}, {"trajectories", rec}, {"video", {{"path", rec}, {"scale", 0.01}}}}, "\"trajectories\" or \"video\"");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}}}}, "\"calibration\"");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"tracks", "guess"}}}}, "tracks");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"density", 2}}}}, "video.density: applies to \"tracks\": \"flow\"");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"tracks", "flow"}, {"contrast", 3}}}},
             "video.contrast: applies to \"tracks\": \"detect\"");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"head_radius", 0.3}}}}, "video.head_radius");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"head_radius", 0.01}}}}, "video.head_radius");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"smoother", "kalman"}}}}, "video.smoother");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"tracks", "flow"}, {"smoother", "none"}}}},
             "video.smoother: applies to \"tracks\": \"detect\"");
  fails_with({{"scenario", belief}, {"video", {{"path", rec}, {"scale", 0.01}, {"first", 2.5}}}}, "video.first");
  fails_with({{"scenario", belief}, {"video", {{"path", (dir / "missing.avi").string()}, {"scale", 0.01}}}}, "missing.avi");
  fails_with({{"scenario", belief}, {"trajectories", rec}}, "too short to diagnose");
}

TEST_CASE("the selection's effective sample size counts the disjoint windows each person spans", "[diagnosis]") {
  // One person in one window counts once, whatever the overlap.
  CHECK(effective_sample_size({1}, 1, 3) == Approx(1));
  // Seven 3 s windows every 1 s span 9 s: three disjoint windows.
  CHECK(effective_sample_size({7}, 1, 3) == Approx(3));
  // Windows that do not overlap are independent: each counts.
  CHECK(effective_sample_size({7}, 3, 3) == Approx(7));
  CHECK(effective_sample_size({7}, 5, 3) == Approx(7));
  // People add up; a count below one is one window.
  CHECK(effective_sample_size({1, 4, 0}, 1, 3) == Approx(1 + 2 + 1));
  CHECK(effective_sample_size({}, 1, 3) == 0);
}

TEST_CASE("a wall friction candidate drags along the whole straight wall beside its region", "[diagnosis]") {
  // The test corridor (walls y = 0 and y = 3 over the whole domain, x in [-2, 16]) with a block
  // reaching down from the upper wall over x in [5, 9] to y = 2.5.
  json venue = json::parse(kCorridor);
  venue["geometry"]["obstacles"].push_back({{"rect", {5, 2.5, 9, 3}}});
  const ScenarioDef s = ScenarioDef::parse(venue, "walls", CROWDMPM_BINARY_DIR);
  const auto close = [](const Vec2& a, double x, double y) {
    INFO("(" << a.x() << ", " << a.y() << ") against (" << x << ", " << y << ")");
    CHECK(std::abs(a.x() - x) < 0.35);
    CHECK(std::abs(a.y() - y) < 0.05);
  };
  const auto ends = [](const std::optional<std::pair<Vec2, Vec2>>& w) {
    REQUIRE(w);
    return w->first.x() < w->second.x() ? *w : std::make_pair(w->second, w->first);
  };
  // The lower wall, from the domain's left edge to its right one.
  auto [a, b] = ends(straight_wall(s.geo, Vec2(7, 0.8)));
  close(a, -2, 0);
  close(b, 16, 0);
  // The block's lower face, corner to corner.
  std::tie(a, b) = ends(straight_wall(s.geo, Vec2(7, 2.0)));
  close(a, 5, 2.5);
  close(b, 9, 2.5);
  // The upper wall left of the block ends where the block begins.
  std::tie(a, b) = ends(straight_wall(s.geo, Vec2(2, 2.4)));
  close(a, -2, 3);
  close(b, 5, 3);
}
