#pragma once
// The experiments real crowds were measured in, as scenarios any model runs (DESIGN.md section
// 7; benchmarks/validation/ and tests/test_validity.cpp use the same ones):
// - a ring corridor 2.5 m wide (inner radius 6 m, so it bends gently) with people at a given
//   density walking around it (behaviour "orbit", desired speed 1.34 m/s, Weidmann's free speed):
//   after a warm-up, the mean speed along the corridor, sampled every second, is the speed of the
//   fundamental diagram at the classic density (people / corridor area);
// - a waiting crowd at a given density in a room 6 m deep in front of a 0.4 m thick wall with an
//   opening of width b, leaving through it: the flow J(b) is the passages from the 20th to the
//   80th percentile over their time span.
#include <cstdint>
#include <vector>

#include "engine/sim/simulation.hpp"

namespace crowdmpm {

struct CorridorResult {
  double density = 0;     // persons/m^2 actually placed (people / corridor area)
  size_t agents = 0;
  double speed = 0;       // m/s, mean over agents and samples
  double speed_sd = 0;    // m/s, standard deviation of the per-second means
  int peak_per_m2 = 0;    // most people in any 1 m x 1 m box over the samples
};
CorridorResult ring_corridor_speed(const Model& m, double density, double warmup, double measure, int threads = 1);

struct BottleneckResult {
  size_t agents = 0;
  double flow = 0;        // persons/s; 0 when fewer than 10 people passed in the whole run
  size_t passages = 0;    // passages the flow was measured over (20th to 80th percentile)
  double t20 = 0, t80 = 0;  // s
  int peak_per_m2 = 0;
};
// people > 0: the room is made deeper than 6 m where needed to hold that many at the density
// (the crowd of the experiment measured; a shallow crowd drains before the flow settles).
// seed: the scenario's seed, which places the waiting crowd (the flow through a door is chaotic:
// seeds 1, 2, ... give the spread of J).
BottleneckResult bottleneck_flow(const Model& m, double width, double density, int threads = 1, double people = 0,
                                 uint64_t seed = 1);

// Most people in any 1 m x 1 m box whose corner lies on a 0.25 m lattice.
int peak_box_count(const World& w);

}  // namespace crowdmpm
