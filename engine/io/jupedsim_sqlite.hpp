#pragma once
// Trajectories in JuPedSim's SQLite format, version 2 (JuPedSim 1.1-1.4), the version PedPy's
// load_trajectory_from_jupedsim_sqlite and load_walkable_area_from_jupedsim_sqlite read:
//   trajectory_data(frame INTEGER, id INTEGER, pos_x REAL, pos_y REAL, ori_x REAL, ori_y REAL)
//     with index frame_id_idx(frame, id);
//   metadata(key TEXT PRIMARY KEY, value TEXT): version '2', fps, xmin, xmax, ymin, ymax;
//   geometry(hash INTEGER, wkt TEXT) with unique index geometry_hash(hash);
//   frame_data(frame INTEGER, geometry_hash INTEGER): one row per written frame.
// Positions are stored as 8-byte doubles, so a file reads back exactly as written. Reading also
// accepts versions 1 and 3 (ori_* columns absent or ignored). docs/scenario-format.md, "Outputs".
#include <string>
#include <vector>

#include "engine/core/input.hpp"
#include "engine/io/trajectory.hpp"
#include "engine/sim/world.hpp"

struct sqlite3;
struct sqlite3_stmt;

namespace crowdmpm {

// "POLYGON ((x y, ...))" of an axis-aligned rectangle, counter-clockwise, closed.
std::string rectangle_wkt(double xmin, double ymin, double xmax, double ymax);

// Whether the path is a regular file starting with SQLite's magic header ("SQLite format 3\0").
bool is_sqlite_file(const std::string& path);

class JupedsimSqliteWriter {
 public:
  // Creates (replacing) the file. walkable_wkt: the geometry row (a WKT polygon); its bounds
  // are not checked against the positions.
  JupedsimSqliteWriter(const std::string& path, double framerate, const std::string& walkable_wkt,
                       double xmin, double ymin, double xmax, double ymax);
  ~JupedsimSqliteWriter();
  JupedsimSqliteWriter(const JupedsimSqliteWriter&) = delete;
  JupedsimSqliteWriter& operator=(const JupedsimSqliteWriter&) = delete;
  // One frame: every live agent, in id order, orientation = unit velocity ((1, 0) at rest).
  void write_frame(const World& w, long frame);
  // One frame of given rows (id, x, y, orientation).
  struct Row {
    long id;
    double x, y, ori_x, ori_y;
  };
  void write_rows(long frame, const std::vector<Row>& rows);
  // Commits and closes; throws Error naming the file if anything failed.
  void close();

 private:
  void create(double framerate, const std::string& walkable_wkt, double xmin, double ymin, double xmax, double ymax);
  void exec(const char* sql);
  [[noreturn]] void fail(const std::string& what);
  sqlite3* db_ = nullptr;
  sqlite3_stmt* insert_ = nullptr;
  sqlite3_stmt* frame_ = nullptr;
  std::string path_;
  long long geometry_hash_ = 0;
};

// A TrajectorySet as a JuPedSim file: orientation from each person's displacement to the next
// frame (the previous one at its last frame; (1, 0) when it does not move).
void write_jupedsim_sqlite(const std::string& path, const TrajectorySet& t, const std::string& walkable_wkt);

// Reads trajectory_data and metadata 'fps' (framerate_override > 0 replaces it). Errors name
// the file and what is missing or malformed (not SQLite, no trajectory_data table, no fps,
// non-finite positions, duplicate (id, frame) rows).
TrajectorySet read_jupedsim_sqlite(const std::string& path, double framerate_override = 0,
                                   const InputPolicy& policy = {});

// The geometry row(s) of a JuPedSim file as WKT (version 1: the first, 2 and 3: every row).
std::vector<std::string> read_jupedsim_geometry(const std::string& path);

}  // namespace crowdmpm
