#pragma once
// Observed states: where the people of a recording are at a frame, how fast they move, and a
// simulation started from that state (what training windows and predictions both start from).
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <limits>
#include <unordered_map>
#include <tuple>
#include <vector>

#include "engine/io/trajectory.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

// Every person's walking speed along their recorded track, and the density ahead of them: one
// sample per recorded frame, the speed over the speed window ending there (as free_speeds), and
// where it was walked. density_ahead(R, k) gives the persons/m^2 ahead of every recorded point
// (local_density_ahead with reach R and focus k among the recorded people of its frame, each
// heading the direction walked over the speed window; zero where they stand), computed once per
// kernel and kept. What a model with a density-speed law reads, with its own kernel, to tell a
// person's free speed from the speed a crowd held them to (start_window).
struct SpeedSample {
  long frame;
  float speed;   // m/s
  size_t point;  // index of the recorded point (TrajectorySet::points), for density_ahead
};
class SpeedHistory {
 public:
  std::unordered_map<long, std::vector<SpeedSample>> by_id;  // in frame order
  std::vector<Vec2> at, dir;                                 // every recorded point and its walking direction
  std::vector<size_t> frame_start;                           // points of one frame: [frame_start[i], frame_start[i + 1])
  // Persons/m^2 ahead of every recorded point (thread-safe; the reference stays valid).
  // With a walkable lattice (the venue's, Simulation::walkable), per walkable area, as the
  // material's law reads it (material_density).
  const std::vector<float>& density_ahead(double reach, double focus, const WalkableLattice* walk = nullptr) const;

 private:
  mutable std::mutex mutex_;
  mutable std::map<std::tuple<double, double, uint64_t>, std::unique_ptr<std::vector<float>>> cache_;
};
// A recording read at the wrong scale, checked where it meets its venue: throws Error naming it
// when more than half of its positions lie outside the venue's domain, or when its people stand
// closer than bodies allow (the median over its frames of the median nearest-neighbour distance
// below kMinBodySpacing): a recording in other units than its header states (metres when it
// states none), or of another venue. Says which units would fit (cm, mm or m) where one would.
constexpr double kMinBodySpacing = 0.1;  // m: the densest crowds measured stand 0.3-0.4 m apart
void check_recording_scale(const TrajectorySet& t, const Geometry& geo, const std::string& venue);

std::shared_ptr<const SpeedHistory> speed_history(const TrajectorySet& t, double speed_window);
// Each person's free speed under a model's density-speed law (MaterialParams::density_speed_gamma
// > 0): the 90th percentile, over their samples up to frame `last`, of speed / f(density), f the
// law's factor, floored at kLawFactorFloor (a person at the law's standstill density tells
// nothing of their free speed: tracking noise / f would), and at most kLawFreeSpeedCap.
constexpr double kLawFactorFloor = 0.25;
constexpr double kLawFreeSpeedCap = 2.2;  // m/s: Weidmann's free speeds N(1.34, 0.26) + 3.3 sd
std::unordered_map<long, double> free_speeds_by_law(const SpeedHistory& h, long last, const MaterialParams& P,
                                                    const WalkableLattice* walk = nullptr);

// The state of one recording window, ready to roll forward.
struct ObservedState {
  long frame = 0;
  std::vector<long> ids;
  std::vector<Vec2> x, v;
  std::vector<double> speed;  // m/s over the speed window (over the velocity window if the history is shorter)
  // m/s: each person's free walking speed so far, the 90th percentile of their speed over the
  // speed window along their track up to this frame (free_speeds), and at least `speed`.
  std::vector<double> free_speed;
  // The recording's speed history (speed_history), where the caller gave one: with it, a model
  // with a density-speed law takes each person's free speed as the 90th percentile of their
  // speed divided by the law's factor at the density they walked at (start_window).
  std::shared_ptr<const SpeedHistory> history;
};

// The frames observe_at takes a velocity over: the window's at the frame rate, at least one.
long velocity_lag_frames(double velocity_window, double framerate);

ObservedState observe_at(const TrajectorySet& t, long frame, double velocity_window, double speed_window = 1,
                         std::shared_ptr<const SpeedHistory> history = nullptr);

// Each person's free walking speed, estimated as the 90th percentile of their speed over
// speed_window (s) along their recorded track up to frame `last` (the person unhindered, on
// entering or leaving, rather than held back in a queue). Recorded id -> m/s; people seen for
// less than speed_window by then are left out.
std::unordered_map<long, double> free_speeds(const TrajectorySet& t, double speed_window,
                                             long last = std::numeric_limits<long>::max());

// The free speeds of a recording's people, summarised: each person's free speed up to frame
// `last` (free_speeds; under a model's density-speed law, free_speeds_by_law, when `law` is given
// and has one), then their median and robust spread (1.4826 x the median absolute deviation)
// over people. What a crowd's desired speeds are drawn from when each person's own estimate is
// too noisy to trust. Throws when nobody was seen walking for speed_window by then.
struct SpeedDistribution {
  double median = 0, sd = 0;  // m/s
  long people = 0;
};
SpeedDistribution free_speed_distribution(const TrajectorySet& t, double speed_window, long last,
                                          const MaterialParams* law = nullptr);

// Where a window's agents get their desired speed: the scenario's first group (its speed, or
// drawn per person from its distribution, desired_speed {mean, sd, min, max}; times the model's
// v0_scale), each person's own observed walking speed (times v0_scale), or each person's free
// speed so far (ObservedState::free_speed, times v0_scale): what they walked when unhindered, not
// the speed a queue holds them to at the window's start.
enum class DesiredSpeed { Scenario, Observed, Free };
// "scenario", "observed" or "free" (the JSON and command-line spelling).
const char* desired_speed_name(DesiredSpeed d);
// The recording's speed history where desired speeds are free speeds (the only use of it), else
// null: what training, prediction and diagnosis windows pass to observe_at.
std::shared_ptr<const SpeedHistory> speed_history_for(const TrajectorySet& t, double speed_window, DesiredSpeed d);

struct WindowOptions {
  int threads = 1;
  DesiredSpeed desired_speed = DesiredSpeed::Observed;
};

// A scenario ready to take observed agents: its groups and sources emptied, no time limit.
// keep_exits false: exits become goals of the same shape (nobody leaves, as gradients need;
// training masks people once the recording loses them).
ScenarioDef window_scenario(const ScenarioDef& scenario, bool keep_exits);

// A simulation started from an observed state: the observed agents placed (moved out of solids
// if a recorded head leans over a barrier; body radius at most half the distance to the nearest
// observed neighbour) with the behaviour of the scenario's first group. ids[i] is the entity of
// observed agent i, 0 if it could not be placed.
struct WindowSim {
  std::unique_ptr<Simulation> sim;
  std::vector<EntityId> ids;
};
WindowSim start_window(const ScenarioDef& windowed, const Model& model, const ObservedState& s, const WindowOptions& o);

// People walking into an observed region across its edge: a camera sees only part of a crowd,
// and during a prediction (or a training clip) the people outside its view walk in. Each point
// is a place on the region's edge where the observed flow points inward; it adds a person there
// at `rate` persons/s (density x inward speed x the edge length it stands for), times the
// model's v0_scale when desired speeds are the observed ones (the speed the model walks them
// at), whenever nobody is closer than half the sampling spacing (the point stays due until the
// spot clears, at most two people owed).
struct EdgeInflow {
  struct Point {
    Vec2 x, v;    // m, m/s: where people enter, and their velocity
    double rate;  // persons/s
  };
  std::vector<Point> points;
  double density = 0;  // persons/m2 of the crowd it continues (spacing of the clear spot, body size)
};

// One simulation's inflow: after_step adds the people due after each step (agents are appended,
// so a gradient window can run through it: WindowGradient::run's after_step).
class InflowRun {
 public:
  InflowRun(const EdgeInflow& inflow, DesiredSpeed desired_speed);
  void after_step(Simulation& sim);

 private:
  const EdgeInflow& inflow_;
  DesiredSpeed desired_speed_;
  std::vector<double> due_;
};

}  // namespace crowdmpm
