#pragma once
// Whole-run replays of recorded experiments (issue 10): the recorded people are placed where the
// recording first shows them, at the first frame or when they enter the view later (the
// recorded arrivals), and the model walks them through the venue; the passages through a line
// (a bottleneck) over time, N(t), are compared with the recording's.
#include <cstdint>
#include <string>
#include <vector>

#include "engine/io/trajectory.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

// A directed passage line from a to b: a person passes when their path crosses the segment.
struct PassageLine {
  Vec2 a = Vec2::Zero(), b = Vec2::Zero();
};

struct ReplayResult {
  std::vector<double> recorded, simulated;  // passage times (s after the first frame), sorted
  size_t people = 0;                        // in the recording
  size_t placed = 0;                        // of them placed in the simulation
  double recorded_flow = 0, simulated_flow = 0;  // persons/s over the middle 60% of passages (0 if < 10)
  double duration = 0;                      // s simulated
};

// Passage times of the people of a recording through the line (each person counted once, at the
// first crossing).
std::vector<double> recorded_passages(const TrajectorySet& t, const PassageLine& line);
// Flow over the passages from the 20th to the 80th percentile (persons/s); 0 with fewer than 10.
double middle_flow(const std::vector<double>& passage_times);

// Replays the recording in the scenario's venue with the model: every recorded person enters
// at their first recorded position and time (velocity from their first 0.5 s), with the
// behaviour and desired speed of the scenario's first group and the model's body radius and
// comfort distance (not shrunk to fit a dense recording). Runs until everyone recorded has
// entered and the simulation has been quiet for `extra` seconds, or the recording's duration
// plus `extra`.
// jitter_seed > 0 moves every entry point by a Gaussian offset of kReplayJitter per axis drawn
// from that seed: a crowd squeezing through a bottleneck is chaotic (a change of 1e-7 in one
// parameter moves a CrowdQueue replay's flow by 10%), so one replay is one draw; repeats with
// seeds 1, 2, ... give the spread (benchmarks/validation/validate.cpp --repeats).
constexpr double kReplayJitter = 0.02;  // m: the order of a camera tracker's position error
ReplayResult replay_recording(const ScenarioDef& scenario, const Model& model, const TrajectorySet& recording,
                              const PassageLine& line, double extra = 30, int threads = 1, uint64_t jitter_seed = 0);
// `repeats` replays: the exact one (jitter_seed 0), then jitter seeds 2, 3, ..., repeats.
std::vector<ReplayResult> replay_repeats(const ScenarioDef& scenario, const Model& model, const TrajectorySet& recording,
                                         const PassageLine& line, int repeats, double extra = 30, int threads = 1);
// Mean of the simulated flows of replays.
double mean_simulated_flow(const std::vector<ReplayResult>& runs);

}  // namespace crowdmpm
