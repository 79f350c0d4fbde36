#pragma once
// `crowdmpm analyze`: PedPy-style measurements of a trajectory file (text or JuPedSim SQLite)
// written into a folder (docs/analyze.md).
#include <string>
#include <vector>

#include "engine/core/json_reader.hpp"
#include "engine/observe/pedestrian_measures.hpp"

namespace crowdmpm {

struct AnalysisSpec {
  struct Area {
    std::string id;
    Polygon2 polygon;
  };
  struct Line {
    std::string id;
    Vec2 from = Vec2::Zero(), to = Vec2::Zero();
  };
  Polygon2 walkable;  // empty: the trajectories' bounding box grown by 1 m
  std::vector<Area> areas;
  std::vector<Line> lines;
  long frame_step = 5;           // frames on each side for individual speeds (PedPy's frame_step)
  double pressure_cell = 0.5;    // m, grid of the crowd-pressure map
  double pressure_radius = 0.7;  // m, R of the Gaussian weight
  double pressure_window = 10;   // s, window over which the velocity variance is taken
  double fd_bin = 0.5;           // persons/m^2, density bins of the fundamental diagram
  double cutoff_radius = 0;      // m, Voronoi cells cut by a polygon of this radius (0: no cut-off)
  int cutoff_edges = 12;         // its edges

  // {"walkable_area": [[x, y], ...], "areas": [{"id", "rect" | "polygon"}], "lines": [{"id",
  // "from", "to"}], "frame_step", "pressure": {"cell", "radius", "window"}, "fd_bin",
  // "voronoi_cutoff": {"radius", "edges"}}; errors
  // name the JSON path.
  static AnalysisSpec from_json(const json& j, const std::string& source);
  // Throws Error naming `where` if two areas or two lines share an id (they name output files).
  void check_unique_ids(const std::string& where) const;
  // From a scenario file: its measurement areas and its domain as the walkable area.
  static AnalysisSpec from_scenario(const std::string& path, const InputPolicy& policy);
};

// Writes DIR/area_<id>.csv, DIR/fd_<id>.csv, DIR/nt_<id>.csv, DIR/crowd_pressure.csv and
// DIR/crowd_pressure.png (peak window), DIR/summary.json; returns the summary.
json run_analysis(const TrajectorySet& t, const AnalysisSpec& spec, const std::string& out_dir);

}  // namespace crowdmpm
