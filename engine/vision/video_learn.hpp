#pragma once
// Learning the crowd material from a video's velocity fields, and predicting them (the source
// document's protocol): particles are sampled where the crowd moves at a given density with
// velocities from the field; clips of the first part of the video are fitted with the grid
// velocity loss (train.hpp, TrainWindow::fields); the last part is held out and predicted from
// the state at its start, scored by Err_vel (mean squared grid velocity error, m^2/s^2, over the
// observed nodes away from the view's border) at evenly spread horizons, against persistence of
// the last observed field and constant velocity of the particles.
#include <string>
#include <vector>

#include "engine/learn/train.hpp"
#include "engine/predict/predict.hpp"
#include "engine/vision/video_job.hpp"

namespace crowdmpm {

struct VideoLearnOptions {
  double density = 6;       // persons/m^2 sampled where the field moves
  double clip = 2.4;        // s per training clip
  double stride = 0.6;      // s between clip starts
  double train_share = 0.6; // the first share of the fields trains (its last clips validate); the rest is held out
  int start_frames = 5;     // a start state's velocities: the mean of this many fields up to the start
  // A crowd that waits does not move and flow does not see it; a node that moved within this
  // many seconds before the start is taken as still occupied (at velocity 0 if it no longer moves).
  double presence = 2;
  int horizons = 7;         // prediction horizons spread evenly over the held-out part
  double min_mass = 0.1;    // persons on a node's stencil for the prediction to have a velocity there
  // Desired speeds of the sampled particles: their observed speed (the only choice without a
  // scenario's distribution), or the scenario group's.
  DesiredSpeed desired_speed = DesiredSpeed::Observed;
  // The edge of the view keeps feeding the crowd as last seen, in predictions and in training
  // clips alike (edge_inflow): where a clip's start field flows into the view across its edge,
  // particles enter at the sampling density with the velocity seen there. Without it an open
  // view empties from upstream, and training would fit a material that holds the crowd back
  // to make up for the people who never walked in.
  bool inflow = true;
  // A prediction by particles is the mean of this many rollouts from the same field, each with
  // its lattice of sampled particles shifted (ensemble_offset); the first is unshifted. Err_vel
  // scores a mean square, and which nodes a single lattice leaves empty is chance: the mean
  // over placements is the expected field (a node empty in a rollout counts 0 there, as in Err_vel).
  int ensemble = 4;
  void check() const;
};

// Particles on a hexagonal lattice at `density` over the nodes the field keeps (each lattice
// point belongs to its nearest node), velocities interpolated from the field with the B-spline
// weights of the kept nodes. ids 1..n; speed = free speed = |v|. With a venue, points closer
// than half the lattice spacing to a wall, an obstacle or the domain's edge are left out (flow
// splatted across a wall would otherwise put people inside it, and pushing them out piles them up).
// `offset` shifts the lattice by that fraction of its period (x: the spacing, y: two rows).
ObservedState sample_particles(const GridVelocityField& field, double density, const Geometry* venue = nullptr,
                               const Vec2& offset = Vec2::Zero());

// The k-th lattice shift of an ensemble (k = 0: none): the additive recurrence of the plastic
// number, which covers the unit square evenly for every count.
Vec2 ensemble_offset(int k);

// The field a state at fields[start] is sampled from: the mean of the last vo.start_frames fields
// where they move, and velocity 0 where the crowd moved within vo.presence seconds but no longer does.
GridVelocityField start_field(const std::vector<GridVelocityField>& fields, size_t start, double fps, const VideoLearnOptions& vo);

// The inflow across the edge of the view that a start field implies (EdgeInflow): one point per
// moving node next to an unseen one (`covered`: the nodes the camera sees) whose velocity points
// into the view, at density x inward speed x dx persons per second; none closer than half the
// sampling spacing to a wall.
EdgeInflow edge_inflow(const GridVelocityField& start, const std::vector<char>& covered, const Geometry& venue, double density);

// Training and validation windows from fields[0, end) (validation: the last share of the clips),
// each with its start field's edge inflow when vo.inflow (`covered` as in edge_inflow; empty: no
// inflow). A clip (with the fields its start state is sampled from) never contains a camera glitch.
void make_video_windows(const ScenarioDef& venue, const std::vector<GridVelocityField>& fields, double fps, size_t end,
                        const VideoLearnOptions& vo, double validation_fraction, std::vector<TrainWindow>& train,
                        std::vector<TrainWindow>& validation, const std::vector<size_t>& glitches = {},
                        const std::vector<char>& covered = {});

struct VideoHorizon {
  double seconds = 0;  // after the start of the held-out part
  long frame = 0;      // field index
  double err_vel = 0;  // m^2/s^2
  long nodes = 0;
  double empty = 0;    // share of those nodes where the prediction has nobody (scored as velocity 0)
};
struct VideoPrediction {
  std::string method;
  std::vector<VideoHorizon> horizons;
};

// Predicts fields[start + h] for the horizons from the state at `start` (the first field of the
// held-out part): persistence, constant velocity, and each model rolled forward in the scenario.
// `covered`: nodes the camera sees (a node next to an unseen one is border and not scored).
// The held-out part ends before the first camera glitch after `start` (held_out_end): after a
// jump or a cut the image shows other ground.
std::vector<VideoPrediction> predict_video(const ScenarioDef& scenario, const std::vector<Model>& models,
                                           const std::vector<GridVelocityField>& fields, const std::vector<char>& covered,
                                           double fps, size_t start, const VideoLearnOptions& vo, int threads,
                                           const std::vector<size_t>& glitches = {});
// The end (exclusive) of the held-out part that starts at `start`: the first glitch after it, or fields.
size_t held_out_end(size_t fields, size_t start, const std::vector<size_t>& glitches);

json video_prediction_json(const std::vector<VideoPrediction>& p);

// The venue of a video seen without a scenario: the ground the region of interest covers (grid
// spacing src.cell) and a margin of two cells whose outer half is exits (people walk out of view),
// one empty group whose people walk on the way they moved when placed (the heading behaviour),
// a time step dividing the frame interval (at most 0.01 s).
ScenarioDef video_venue(const VideoSource& src);

// The Err_vel of every method against the horizon, as a chart.
void write_video_prediction_png(const std::string& path, const std::vector<VideoPrediction>& p, const std::string& title);

}  // namespace crowdmpm
