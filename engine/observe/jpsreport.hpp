#pragma once
// JPSreport's project files as an analyze spec: `crowdmpm analyze ini.xml` (or the folder that
// holds it) reads the measurement areas (area_B: bounding boxes and polygons, area_L: lines),
// the velocity frame_step (which JPSreport halves), the trajectory file and the geometry file
// (geo.xml: the subroom polygon is the walkable area). docs/analyze.md, "JPSreport projects".
#include <string>
#include <vector>

#include "engine/observe/analyze.hpp"

namespace crowdmpm {

struct JpsreportProject {
  AnalysisSpec spec;
  std::string trajectories;        // path of the trajectory file
  std::vector<std::string> notes;  // what was read approximately, for the user
};

// ini: the path of the ini file or of a folder holding ini.xml. Errors name the file and the
// element that is missing or malformed.
JpsreportProject read_jpsreport_project(const std::string& ini, const InputPolicy& policy = {});

}  // namespace crowdmpm
