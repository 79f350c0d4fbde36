#pragma once
// Scenario JSON ("format": "crowdmpm-scenario", version 1): the venue, time stepping, the
// people and their behaviours, extra forces, measurement areas and outputs. Every field, unit
// and default is documented in docs/scenario-format.md.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/geometry/geometry.hpp"
#include "engine/sim/behaviour.hpp"
#include "engine/sim/model.hpp"
#include "engine/sim/terms.hpp"

namespace crowdmpm {

// Largest |coordinate| of a domain's corners (m): beyond it doubles resolve positions too coarsely.
constexpr double kMaxCoordinate = 1e8;

// A group of people placed at t = 0, or a source spawning them at a rate over a time window.
struct GroupDef {
  std::string id;
  std::string path;  // JSON path, for messages
  Shape region;
  bool is_source = false;
  int count = -1;       // group: exact count, or -1 when given by density
  double density = 0;   // group: persons/m^2 of free area
  double rate = 0, start = 0, end = 0;  // source: persons/s over [start, end)
  int max_count = 0;    // source: at most this many in total
  Vec2 velocity = Vec2::Zero();
  double desired_speed = 1.3;  // m/s; the mean when people draw their own
  // Free speeds drawn per person from a normal distribution (sd > 0) truncated to [min, max].
  double speed_sd = 0, speed_min = 1.3, speed_max = 1.3;
  std::optional<double> body_radius, comfort_distance;  // default: the model's
  Behaviour behaviour;
};

struct MeasurementArea {
  std::string id;
  Shape shape;
  double from = 0, to = 1e300;  // time window for averages, s
};

struct OutputsDef {
  bool trajectories = true, fields = true, pictures = true, video = true, metrics = true;
  bool trajectories_sqlite = true;  // trajectories.sqlite (JuPedSim format) beside trajectories.txt
  double pixels_per_metre = 0;  // 0: chosen from the domain size
  double pressure_max = 0;      // colour scale of the video; 0: chosen from the model stiffness
  double density_max = 8;       // persons/m^2, colour scale of density pictures
};

struct ScenarioDef {
  std::string name, description;
  std::string source;    // file name or "<string>", for messages
  std::string base_dir;  // relative model paths resolve from here
  Geometry geo;
  double cell_size = 0.5;  // MPM grid spacing, m
  double nav_cell = 0.1;   // navigation grid spacing, m
  double dt = 0.01, duration = 60, output_rate = 10;
  uint64_t seed = 1;
  bool stop_when_empty = true;
  std::optional<Model> model;  // null: the built-in default
  std::vector<GroupDef> groups;
  std::vector<Term> terms;  // "forces": the venue's force terms (sim/terms.hpp)
  std::vector<MeasurementArea> areas;
  OutputsDef outputs;
  json document;  // the JSON parse() read (its "extends" chain applied): what a snapshot keeps

  // parse() takes one JSON document as it is; parse_text() and load() first apply its
  // "extends" chain (a base file, relative to base_dir or to the file's folder).
  // Files it names ("model", "extends") resolve from base_dir (load: the file's folder) and must
  // stay inside it unless the policy allows outside paths; every file read obeys its size limit.
  static ScenarioDef parse(const json& j, const std::string& source, const std::string& base_dir,
                           const InputPolicy& policy = {});
  static ScenarioDef parse_text(const std::string& text, const std::string& base_dir = ".", const InputPolicy& policy = {});
  static ScenarioDef load(const std::string& path, const InputPolicy& policy = {});
  // The scenario JSON of a file with its "extends" chain applied: what load() validates.
  static json load_json(const std::string& path, const InputPolicy& policy = {});
  int steps_per_frame() const;
  // The scenario's own model, or the built-in default when it names none.
  Model model_or_default() const { return model ? *model : Model::default_model(); }
};

}  // namespace crowdmpm
