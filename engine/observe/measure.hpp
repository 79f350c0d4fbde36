#pragma once
// Measurements on recorded (or simulated) trajectories, after the methods of PedPy and the
// Juelich archive's analyses.
#include <vector>

#include "engine/io/trajectory.hpp"

namespace crowdmpm {

struct DensitySpeed {
  double time = 0;     // s after the first frame
  double density = 0;  // persons/m^2 in the area
  double speed = 0;    // m/s, mean speed of the people in it (NaN when empty)
};

// Classic density and speed in a rectangular measurement area [lo, hi] every `every` seconds:
// people inside / area, and the mean of their speeds from the displacement to the next frame.
std::vector<DensitySpeed> classic_density_speed(const TrajectorySet& t, const Vec2& lo, const Vec2& hi, double every = 1);

}  // namespace crowdmpm
