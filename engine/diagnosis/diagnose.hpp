#pragma once
// Diagnosis of missing physics (DESIGN.md section 6): given the venue a user believes
// (scenario), a material model and a recording, fit the model on the recording's first part,
// locate where it and the recording still disagree (residuals.hpp), try the candidate force
// terms that could explain each significant region (each initialised from the region and
// fitted through the simulator with gradients), and accept a term only when it lowers the
// error on the recording's later, held-out part clearly beyond noise. Up to max_terms terms
// are added greedily; otherwise the verdict is "none". docs/diagnosis.md has the method.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/diagnosis/residuals.hpp"
#include "engine/vision/flow_tracks.hpp"
#include "engine/vision/video_job.hpp"

namespace crowdmpm {

// Where a term acts: the people passing within `distance` m of the segment [from, to] (a disc
// round a point when from == to) judge it; distance < 0: everyone (a venue-wide term).
struct Reach {
  Vec2 from = Vec2::Zero(), to = Vec2::Zero();
  double distance = -1;  // m
  bool everyone() const { return distance < 0; }
  Vec2 center() const { return 0.5 * (from + to); }
  double radius() const { return everyone() ? -1 : 0.5 * (to - from).norm() + distance; }  // of the disc round it
};

struct DiagnoseOptions {
  double train_share = 0.6;   // first share of the recording: fitting and localisation; the rest is held out
  double window = 3;          // s of each fitting and held-out rollout
  double stride = 1;          // s between their starts
  ResidualOptions residual;
  // "desired_speed": "recording" (also the first reading of "auto", below): every person of every window (fitting, null and
  // held-out alike) walks at the recording's typical free speed, the median over the people of
  // the training part (free_speed_distribution), times the fitted v0_scale; residual.desired_speed
  // is then taken as Scenario, with the scenario's groups set to that speed. One person's free speed read
  // from a few seconds of their own noisy track scatters more than people do, and a fit then
  // "explains" that scatter with terms that shrink it (a forward drift with a lower v0_scale).
  // Otherwise residual.desired_speed says ("free", "observed" or "scenario").
  bool recording_speed = true;
  // "desired_speed": "auto" (the default): the baseline is fitted twice, with "recording" and with
  // "observed" (each person walks at their own speed at the window's start, times v0_scale), and
  // the second is kept for everything after only where its validation loss is under half the
  // first's (kOwnPaceShare in diagnose.cpp): a crowd whose people keep paces of their own (agents
  // with individual preferred speeds) that one typical speed cannot fit. An observed speed
  // carries whatever slowed the person, so that reading hides part of a concealed effect.
  bool auto_speed = true;
  // "density_law" (default true): a crowd material without a speed-density law of its own gets
  // Weidmann's (kWeidmannGamma, kWeidmannMaxDensity) in the baseline, its density_speed_gamma
  // and density_speed_max fitted with the other parameters (DiagnoseJob::density_law_added): a
  // baseline that does not slow people where it is dense "misses" that in every dense recording
  // (benchmarks/results/diagnosis_real.md). About 2-5 times slower (the density ahead of everyone
  // every step); false keeps the material as given.
  bool density_law = true;
  int null_replicates = 6;
  double alpha = 0.01;        // a region is significant below this p-value
  int max_regions = 3;        // regions tried per round, strongest first
  int max_terms = 3;
  // A term is accepted when, on the held-out part and among the people passing its region
  // (everyone for a venue-wide term), the RMS error falls by at least min_gain (share), the
  // paired gain over people is at least min_gain_z standard errors and the information
  // criterion n ln(MSE) + k ln(n) there falls, while the error of everyone rises by no more than
  // 2%; of the terms that pass, the one with the lowest held-out error of everyone is added.
  // A venue-wide term (drift, density_speed) needs min_gain_venue instead of min_gain: it is
  // judged on everyone, whose error also holds misfit no venue-wide term acts on (a door's jam),
  // where a local term is judged only on the people it acts on.
  double min_gain = 0.1;
  double min_gain_venue = 0.05;
  double min_gain_z = 3;
  std::vector<std::string> candidates;  // law types to try; empty: all diagnosis candidates
  // Material parameters refitted with every term (default: those of v0_scale, tau and time_gap
  // the model kind learns: the free speed, the relaxation and the speed-headway relation).
  std::vector<std::string> params;
  bool params_given = false;
  int iterations = 60;
  double learning_rate = 0.05;
  // The baseline's fit is run again from where it stopped (fresh optimiser state and learning
  // rate) while its validation loss falls by more than 0.1%, at most this many times: one run of
  // `iterations` minibatch steps often stops short of the parameters a second run finds. Each
  // round's candidates start from the round's refitted baseline (one more run of the fit) where
  // that predicts the held-out part by min_gain better, which takes up much of that. Off by
  // default: with 3 the suite at 0.02 m found the same effects as with one fit
  // (benchmarks/results/diagnosis.md); the other levels are not measured.
  int baseline_restarts = 0;
  // For the report only (selection is unaffected): where terms were accepted, the baseline and
  // the final model (the accepted terms and the material refitted with them) are each fitted
  // again the same way, while the validation loss falls by more than 0.1%, at most this many
  // times, and the held-out errors before and after are those of the two models so converged.
  // A candidate's fit starts from the baseline and stops after `iterations` steps, usually short
  // of the material parameters a further fit finds with the term in place (the suite's slow zone:
  // the next round's refit alone predicts everyone 19% better), while the baseline had no new
  // term to adapt to.
  int final_restarts = 3;
  // How the baseline's parameters are fitted ("baseline_optimizer") and how every candidate term
  // and the round's refitted baseline are ("optimizer"): "adam" (minibatches of 4 windows, the
  // default) or "lbfgs" (full batch, deterministic; on the suite's room several times slower).
  bool baseline_lbfgs = false;
  bool candidates_lbfgs = false;
  int threads = 1;
  uint64_t seed = 1;
  // Where no term is accepted, the people the report's held-out errors before and after cover
  // (region_before, region_after; default everyone). Not read from a request: for programs that
  // compare diagnoses of one recording in one place (the suite's --truth-given).
  Reach report_reach;
};

// Where a term acts, whose passers-by judge it (docs/diagnosis.md step 6): within a metre of an
// obstacle's rim, within an attractor's or vortex's range (at most 3 m), over a zone's extent,
// along a wall as far out as its drag reaches, along a constriction's wall near its opening;
// everyone for the venue-wide terms (drift, density_speed).
Reach term_reach(const Term& t);
// The candidate types diagnosis tries, by their report names (drift, attractor, ...).
const std::vector<std::string>& diagnosis_candidates();

// The effective sample size of the selection's information criterion: one person's errors over
// overlapping held-out windows are not independent, so a person compared in W windows of
// `window` s started every `stride` s counts as the 1 + (W - 1) min(stride / window, 1) disjoint
// windows their time spans. `windows`: W of each person compared (each at least 1).
double effective_sample_size(const std::vector<long>& windows, double stride, double window);

// The straight stretch of wall nearest to x (what a wall_friction candidate drags along): from
// the wall's point nearest to x, followed both ways in 0.25 m steps for as long as a probe 0.1 m
// out from it still finds the wall 0.1 m away with the same normal; it ends at a corner, an
// opening or the domain's edge. Empty when there is no such stretch of at least 0.5 m.
std::optional<std::pair<Vec2, Vec2>> straight_wall(const Geometry& geo, const Vec2& x);

struct Region {
  Vec2 center = Vec2::Zero();
  double radius = 0;
  double t_start = 0, t_end = 0, significance = 1, statistic = 0;
  int round = 0;
};

struct Hypothesis {
  Term term;
  int round = 0, region = -1;         // the region it was initialised from (-1: the whole venue)
  Reach judged;                       // the people passing there judge the term
  double heldout_error = 0;           // RMS position error of the people passing there, m
  double heldout_error_global = 0;    // the same over everyone, m
  double baseline_error = 0;          // the baseline's regional error it is compared with, m
  double gain = 0, gain_z = 0, score = 0, baseline_score = 0;
  bool accepted = false;
  bool from_refit = false;            // its fit started from the round's refitted baseline
  std::string why;                    // why it was accepted or not
};

struct DiagnosisResult {
  Model baseline;                     // the fitted baseline
  Model model;                        // refitted with the accepted terms
  std::vector<Term> terms;            // accepted, in order
  // The believed scenario's own force terms as the baseline fitted them (those it marks "learn";
  // the others as given), in its order: the venue the accepted terms are added to.
  std::vector<Term> scenario_terms;
  std::vector<Region> regions;
  std::vector<Hypothesis> hypotheses;
  double heldout_before = 0, heldout_after = 0;          // global RMS position error, m
  double region_before = 0, region_after = 0;            // over the people passing the first accepted term's region (global if none)
  Reach region;                                          // where the first accepted term acts (everyone if none)
  ResidualMap residual_before, residual_after;           // on the training part
  double tracking_noise = 0;          // m, estimated from second differences of the tracks (as smoothed)
  TrackError null_error;              // the errors the null adds (step 4 of docs/diagnosis.md)
  SpeedDistribution free_speed;       // of the training part's people, where recording_speed
  bool recording_speed = true;        // the desired-speed reading used (chosen where auto_speed)
  DesiredSpeed desired_speed = DesiredSpeed::Scenario;  // the windows' reading (Scenario under recording_speed)
  // With auto_speed: the baseline fit's validation loss (m^2) with each reading.
  double validation_recording = std::numeric_limits<double>::quiet_NaN(), validation_observed = std::numeric_limits<double>::quiet_NaN();
  // The further fits of the baseline and of the final model for the report (final_restarts):
  // how many improved each, and the validation loss (m^2) before and after them; validation_first
  // is 0 where none were made (no accepted term).
  struct FurtherFits {
    int improving = 0;
    double validation_first = 0, validation = 0;
  };
  FurtherFits final_baseline, final_model;
  double train_end = 0, heldout_start = 0, heldout_end = 0;  // s
  long train_windows = 0, heldout_windows = 0;
  std::string explanation;
};

// A diagnosis request (what `crowdmpm diagnose` and the C ABI's cmpm_Diagnose run):
//   {"scenario": PATH, "trajectories": PATH, "model": PATH (default: the scenario's),
//    or instead of "trajectories" a video, whose tracks become the recording: its people
//    detected in every frame and followed by its optical flow ("tracks": "detect",
//    detected_tracks), or points laid where its flow moves and carried by it ("flow",
//    flow_tracks; for crowds too dense to see each person), flow_tracks.hpp:
//    "video": {"path": PATH, "calibration": PATH | "scale": metres per pixel, "first": 0,
//              "frames": 0 (to the end), "fps": 0 (the container's), "method": "farneback" | "dis",
//              "smoothing": 0, "tracks": "detect" | "flow",
//              detection: "body_radius": 0.18 (m), "head_radius": 0.11 (m), "contrast": 4, "coast": 1 (s),
//              "smoother": "rts" | "none", "smooth": 0 (s),
//              flow tracks: "cell": 0.25 (m), "min_speed": 0.2 (m/s), "min_moving_share": 0.3,
//              "density": 1.5 (persons/m^2), "seed_speed": 0.3 (m/s), "presence": 2 (s)},
//    "options": {"train_share", "window", "stride", "horizon", "residual_stride", "cell",
//                "time_bin", "z_threshold", "null_replicates", "alpha", "max_terms",
//                "min_gain", "min_gain_venue", "min_gain_z", "candidates", "params", "iterations",
//                "learning_rate", "baseline_restarts", "final_restarts", "threads", "seed", "desired_speed", "density_law", "baseline_optimizer",
//                "optimizer"}}
struct DiagnoseJob {
  std::string scenario_path, trajectories_path;  // trajectories_path: the video's, for a video
  bool from_video = false;
  VideoSource video;          // what a video request gave
  bool detect = true;         // its people detected and followed (detected_tracks), or flow's tracks (flow_tracks)
  DetectOptions detection;
  // Recorded trajectories are smoothed like a video's detected tracks (options "smoother": "rts",
  // the default, or "none"): each track replaced by the Rauch-Tung-Striebel smoother's estimate
  // under the noise levels the recording shows itself (engine/observe/track_smoother.hpp).
  bool trajectories_smoothed = false;
  TrackNoise track_noise;     // the noise levels the tracks were smoothed under (detected tracks, or smoothed trajectories)
  FlowTrackOptions tracks;
  ScenarioDef scenario;
  Model model;                // with Weidmann's law added where density_law_added
  bool density_law_added = false;
  TrajectorySet recording;
  DiagnoseOptions options;
};
DiagnoseJob parse_diagnose_job(const json& request, const std::string& base_dir = "");

using DiagnoseProgress = std::function<void(const std::string&)>;
DiagnosisResult run_diagnosis(const DiagnoseJob& job, const DiagnoseProgress& progress = nullptr);

// The report (the shape: verdict, regions, hypotheses, terms) as JSON.
json diagnosis_json(const DiagnoseJob& job, const DiagnosisResult& r);
// Writes report.json, summary.txt, residual_before.png, residual_after.png, the scenario with
// the accepted terms (scenario.json) and the refitted model (model.json) into out_dir; for a
// video, also the tracks it gave (video_tracks.txt, PeTrack text).
void write_diagnosis(const DiagnoseJob& job, const DiagnosisResult& r, const std::string& out_dir);

}  // namespace crowdmpm
