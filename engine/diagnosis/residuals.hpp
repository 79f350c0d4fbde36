#pragma once
// Locating where a model and a recording disagree (DESIGN.md section 6, step 2).
//
// Short rollouts restart from the observed state every `stride` seconds, so that a local force
// does not smear downstream: each person's residual is how far the recording moved them beyond
// the model over `horizon` seconds, as a velocity r = (x_recorded(h) - x_model(h)) / h (m/s),
// placed where they were recorded at h / 2. Residuals are binned on a grid of `cell` metres
// over time bins; a cell's statistic pools its 3 x 3 neighbourhood,
//   z = |mean r| sqrt(n_people) / sigma,
// sigma being the robust spread (1.4826 MAD) of one residual component over the whole set and
// n_people the distinct people seen there (the samples of one person are not independent).
// Cells with z above the threshold form clusters (8-connected); a cluster's statistic is its
// sum of z^2. Its significance comes from a null made by the fitted model itself: the same
// rollouts where the "recording" is the model's own motion from the recorded state, observed
// with the recording's tracking noise, binned and clustered the same way (null_residuals).
#include <vector>

#include "engine/learn/train.hpp"

namespace crowdmpm {

struct ResidualOptions {
  double horizon = 1.5;  // s of each rollout
  double stride = 0.5;   // s between rollout starts
  double cell = 0.5;     // m
  double time_bin = 5;   // s
  double z_threshold = 3.5;
  int min_people = 4;    // distinct people a cell needs to be tested
  // Samples within this distance of a source's region are left out: people who enter during a
  // rollout are not in it, so the people near an inflow meet fewer others than recorded.
  double source_margin = 2.0;  // m
  double velocity_window = 0.5, speed_window = 1;  // s, as TrainOptions
  DesiredSpeed desired_speed = DesiredSpeed::Free;
  int threads = 1;
};

struct ResidualSample {
  Vec2 x = Vec2::Zero();  // recorded position at the rollout's middle, m
  double t = 0;           // s (recording time at the middle)
  Vec2 r = Vec2::Zero();  // m/s
  long id = 0;
  Vec2 moved = Vec2::Zero();  // the recorded displacement over the rollout / its length, m/s
};
// Where people are at a rollout's end: +1 recorded, -1 simulated (the density residual).
struct PositionSample {
  Vec2 x = Vec2::Zero();
  double t = 0;
  double weight = 0;
};
struct ResidualSet {
  std::vector<ResidualSample> velocity;
  std::vector<PositionSample> positions;
  long rollouts = 0;
};

// Rollouts of (scenario, model) started from the recording every o.stride between frames
// `from` and `to` (rollouts end by `to`); samples near the scenario's sources are left out.
ResidualSet recorded_residuals(const ScenarioDef& scenario, const Model& model, const TrajectorySet& t, long from,
                               long to, const ResidualOptions& o);
// The error a recording's tracks carry, each axis: of a position (m) and of a velocity taken
// over ResidualOptions::velocity_window (m/s).
struct TrackError {
  double position = 0, velocity = 0;
};
// White position noise of sd `noise` (m) on raw tracks: the velocity over the window's frames
// errs by sqrt(2) noise / their time.
TrackError white_track_error(double noise, double velocity_window, double framerate);

// The same rollouts with the model as the truth: the "recorded" start is the recorded state
// with independent Gaussian errors of the sds `error` gives on positions and velocities, the
// "recorded" end the model's motion from the recorded state plus the position error.
ResidualSet null_residuals(const ScenarioDef& scenario, const Model& model, const TrajectorySet& t, long from, long to,
                           const ResidualOptions& o, const TrackError& error, uint64_t seed);

// Tracking noise of a recording (m): from second differences of positions at the frame rate,
// sd = sqrt(median(|d2|^2) / (6 ln 2)) per component pair, the motion's own acceleration being
// far below it at 10-25 frames/s.
double tracking_noise(const TrajectorySet& t);

// Residuals binned on the venue: bins (time, y, x), and the all-time map (y, x).
struct ResidualMap {
  Vec2 origin = Vec2::Zero();
  double cell = 0.5;
  int nx = 0, ny = 0, nt = 0;
  double t0 = 0, time_bin = 5;
  double sigma = 0;  // m/s, robust sd of one component
  // All-time, per cell (pooled over its 3 x 3 neighbourhood for z):
  std::vector<Vec2> mean;       // mean residual of the cell itself, m/s
  std::vector<double> people;   // distinct people in the pooled neighbourhood
  std::vector<double> z;
  std::vector<double> density;  // (recorded - simulated) people per m^2 per rollout, pooled
  // Per time bin and cell (not pooled):
  std::vector<Vec2> sum_t;
  std::vector<double> count_t;
  size_t index(int ix, int iy) const { return static_cast<size_t>(iy) * nx + ix; }
  Vec2 centre(int ix, int iy) const { return origin + Vec2((ix + 0.5) * cell, (iy + 0.5) * cell); }
  // Root mean square of the cell means over cells with enough people (m/s).
  double rms(int min_people) const;
};
ResidualMap bin_residuals(const ResidualSet& s, const Geometry& geo, const ResidualOptions& o);

struct Cluster {
  Vec2 center = Vec2::Zero();  // z^2-weighted, m
  double radius = 0;           // of a disc with the cluster's area, m
  Vec2 lo = Vec2::Zero(), hi = Vec2::Zero();  // bounding box of its cells, m
  double t_start = 0, t_end = 0;
  double statistic = 0;        // sum of z^2
  double significance = 1;     // p-value against the null
  Vec2 mean_residual = Vec2::Zero();  // m/s over its samples
  Vec2 flow = Vec2::Zero();           // the recorded mean velocity of its samples (ResidualSample::moved), m/s
  Vec2 hole = Vec2::Zero();    // where the model puts people the recording does not have (nearby)
  double radial = 0, tangential = 0;  // mean residual components about the centre (out, counter-clockwise), m/s
  std::vector<size_t> cells;
};
// Clusters of the all-time map, strongest first (significance left at 1).
std::vector<Cluster> find_clusters(const ResidualMap& m, const ResidualSet& s, const ResidualOptions& o);
// p-values of clusters against null maps: the share of a Gaussian fitted to the nulls' largest
// cluster statistics (0 where a null has none) lying above each cluster's statistic.
void assess_clusters(std::vector<Cluster>& clusters, const std::vector<double>& null_maxima, const ResidualOptions& o);

}  // namespace crowdmpm
