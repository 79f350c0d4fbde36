#pragma once
// PedPy-style measurements on any trajectory set, real or simulated (`crowdmpm analyze`,
// docs/analyze.md): individual speeds, classic and Voronoi density and speed per frame in a
// measurement area, N(t) over a line, Fruin's level of service and Helbing's crowd pressure.
// The definitions follow PedPy (and JPSreport, whose reference results tests/test_interop.cpp
// reproduces): see each function.
#include <string>
#include <vector>

#include "engine/analysis/metrics.hpp"  // fruin_level
#include "engine/io/trajectory.hpp"

namespace crowdmpm {

using Polygon2 = std::vector<Vec2>;  // simple polygon, implicitly closed, either orientation

double polygon_area(const Polygon2& p);  // unsigned
// Triangles of a simple polygon (ear clipping); throws Error for a self-intersecting or
// degenerate polygon.
std::vector<Polygon2> triangulate(const Polygon2& p, const std::string& what);

// Each point's speed (m/s, index as t.points), PedPy's BORDER_SINGLE_SIDED with frame_step n:
// |X(t+n) - X(t-n)| / (2n / fps) where both frames exist for that person, else the one-sided
// difference over n / fps, else 0 (a person seen for fewer than n + 1 frames on both sides).
// Velocity vectors likewise (individual_velocities).
std::vector<double> individual_speeds(const TrajectorySet& t, long n);
std::vector<Vec2> individual_velocities(const TrajectorySet& t, long n);

struct AreaFrame {
  long frame = 0;
  double time = 0;              // frame / fps (s)
  long people = 0;              // people in the whole frame
  long inside = 0;              // people strictly inside the area
  double classic_density = 0;   // inside / area (persons/m^2)
  double classic_speed = 0;     // mean individual speed of those inside (m/s), 0 when none
  double voronoi_density = 0;   // sum_i |V_i ∩ M| / |V_i| / |M|
  double voronoi_speed = 0;     // sum_i |V_i ∩ M| v_i / |M|
};

// Per frame, from frame_min to frame_max (frames without rows give zeros). Voronoi cells are
// the ordinary Voronoi cells of the frame's people clipped by the walkable area (a simple
// polygon); where clipping splits a cell, the part holding the person is kept (PedPy's rule).
// With cutoff_radius > 0 each cell is also cut by the regular cutoff_edges-gon with its vertices
// on the circle of that radius round the person (PedPy's Cutoff(radius, quad_segments =
// edges / 4), JPSreport's cut_by_circle).
std::vector<AreaFrame> measure_area(const TrajectorySet& t, const Polygon2& area, const Polygon2& walkable,
                                    const std::vector<double>& speeds, double cutoff_radius = 0, int cutoff_edges = 12);

// N(t) over the segment a-b: a person crosses at the first frame t whose step X(t-1) -> X(t)
// meets the segment (either direction; a step that ends on it counts, as in JPSreport; PedPy
// counts the next step instead); counted once. Returns the cumulative count for every recorded
// frame from frame_min to frame_max.
struct LineCount {
  long frame = 0;
  double time = 0;
  long count = 0;
};
std::vector<LineCount> crossings(const TrajectorySet& t, const Vec2& a, const Vec2& b);


// Helbing, Johansson and Al-Abideen (2007) crowd pressure on a grid: with Gaussian weights
// f(d) = exp(-|d|^2 / R^2) / (pi R^2), the local density rho(r, t) = sum_j f(r_j - r) and the
// local velocity V(r, t) = sum_j v_j f / sum_j f; the pressure P(r) = mean_t rho(r, t) *
// Var_t V(r, t) (the variance of the local velocity over the frames of the window, both
// components summed), in 1/s^2. Nodes at spacing `cell` over [lo, hi] (at most 4 million, else
// Error). A window without people gives an empty field (pressure.empty()).
struct PressureField {
  Vec2 lo = Vec2::Zero();
  double cell = 0;
  int nx = 0, ny = 0;
  std::vector<double> density;   // mean local density, persons/m^2 (row-major, y rows)
  std::vector<double> pressure;  // 1/s^2
  double max_pressure() const;
  FieldFrame grid() const;  // the node layout (no values), for pictures of density or pressure
};
PressureField crowd_pressure(const TrajectorySet& t, const std::vector<Vec2>& velocities, long frame_begin,
                             long frame_end, const Vec2& lo, const Vec2& hi, double cell, double R);

// Crowd pressure in consecutive windows of `window` frames over the recorded frames: the field
// of the window with the highest peak (empty if nobody is ever there) and each window's peak.
struct PressurePeak {
  PressureField field;
  long from = 0, to = 0;                          // frames of the peak window
  std::vector<std::pair<double, double>> windows;  // (window start in s, its peak 1/s^2)
};
PressurePeak peak_crowd_pressure(const TrajectorySet& t, const std::vector<Vec2>& velocities, long window, const Vec2& lo,
                                 const Vec2& hi, double cell, double R);

}  // namespace crowdmpm
