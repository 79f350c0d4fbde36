#pragma once
// Venue metrics gathered at every output frame: agents remaining, exit flow N(t), evacuation
// time, peak density and pressure with where and when, measurement-area averages, and the
// time-averaged and peak maps used for pictures.
#include <array>
#include <string>
#include <vector>

#include "engine/analysis/fields.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

struct AreaStats {
  double area = 0;           // m^2
  long frames = 0;           // frames inside the area's time window
  double density_sum = 0;    // persons/m^2 summed over frames
  double pressure_sum = 0;   // mean agent pressure inside, summed over frames with agents
  long pressure_frames = 0;
  double pressure_peak = 0;  // largest agent pressure inside at any frame
  double grid_pressure_sum = 0;  // mean node pressure inside, summed over frames
  std::vector<std::array<double, 3>> series;  // per frame in the window: time (s), density, mean agent pressure (0 if empty)
  double mean_density() const { return frames ? density_sum / static_cast<double>(frames) : 0; }
  double mean_pressure() const { return pressure_frames ? pressure_sum / static_cast<double>(pressure_frames) : 0; }
  double mean_grid_pressure() const { return frames ? grid_pressure_sum / static_cast<double>(frames) : 0; }
};

struct Peak {
  double value = 0, time = 0;
  Vec2 where = Vec2::Zero();
};

// Fruin's walkway level of service from the density (persons/m^2): the area per person against
// 35, 25, 15, 10 and 5 ft^2 (3.25, 2.32, 1.39, 0.93, 0.46 m^2): 'A' (at least 35 ft^2) ... 'F'
// (less than 5 ft^2; above 2.15 persons/m^2).
char fruin_level(double density);

class MetricsRecorder {
 public:
  explicit MetricsRecorder(const ScenarioDef& s);
  void record(const Simulation& sim, const FieldFrame& f);
  json to_json(const Simulation& sim) const;

  const std::vector<AreaStats>& areas() const { return areas_; }
  const AreaStats& area(const std::string& id) const;
  const Peak& peak_density() const { return peak_density_; }
  const Peak& peak_pressure() const { return peak_pressure_; }
  // Time-averaged and peak maps (same layout as FieldFrame).
  FieldFrame mean_map() const;
  const FieldFrame& peak_map() const { return peak_map_; }
  long frames() const { return frames_; }

 private:
  const ScenarioDef& s_;
  std::vector<double> times_;
  std::vector<long> remaining_;
  std::vector<std::vector<long>> exit_counts_;  // per frame, per exit (cumulative)
  std::vector<AreaStats> areas_;
  Peak peak_density_, peak_pressure_;
  FieldFrame sum_map_, peak_map_;
  long frames_ = 0;
};

}  // namespace crowdmpm
