// Interop files: JuPedSim's SQLite trajectory format (the version PedPy reads), written from a
// simulated run and read back; its tables and columns against the published schema.
#include <sqlite3.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <map>

#include "engine/io/jupedsim_sqlite.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {

std::string temp_file(const std::string& name) { return (std::filesystem::temp_directory_path() / name).string(); }

// Rows of a query as text, for schema checks.
std::vector<std::vector<std::string>> query(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  INFO(sql);
  REQUIRE(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK);
  std::vector<std::vector<std::string>> rows;
  while (sqlite3_step(st) == SQLITE_ROW) {
    rows.emplace_back();
    for (int c = 0; c < sqlite3_column_count(st); ++c) {
      const unsigned char* t = sqlite3_column_text(st, c);
      rows.back().push_back(t ? reinterpret_cast<const char*>(t) : "");
    }
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return rows;
}

struct Written {
  std::map<std::pair<long, long>, Vec2> xy;  // (frame, id) -> position
  long frames = 0;
};

// Simulates the drill for a few frames, writing each frame to a JuPedSim file.
Written simulate_to_sqlite(const std::string& path) {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation sim(s, test::model_of(s), 1);
  Written out;
  JupedsimSqliteWriter w(path, s.output_rate, rectangle_wkt(s.geo.lo.x(), s.geo.lo.y(), s.geo.hi.x(), s.geo.hi.y()),
                         s.geo.lo.x(), s.geo.lo.y(), s.geo.hi.x(), s.geo.hi.y());
  for (long f = 0; f < 6; ++f) {
    if (f > 0) sim.run_steps(s.steps_per_frame());
    w.write_frame(sim.world(), f);
    for (size_t p = 0; p < sim.world().size(); ++p)
      out.xy[{f, static_cast<long>(sim.world().id[p])}] = sim.world().x[p];
    ++out.frames;
  }
  w.close();
  return out;
}

}  // namespace

TEST_CASE("a simulated run written as JuPedSim SQLite reads back with identical positions", "[interop]") {
  const std::string path = temp_file("crowdmpm_interop_drill.sqlite");
  const Written written = simulate_to_sqlite(path);
  REQUIRE(is_sqlite_file(path));
  TrajectorySet t = TrajectorySet::read(path);  // recognised by its header
  CHECK(t.framerate == 10);
  REQUIRE(t.points.size() == written.xy.size());
  for (const TrackPoint& p : t.points) {
    auto it = written.xy.find({p.frame, p.id});
    REQUIRE(it != written.xy.end());
    // Bit for bit: 8-byte REAL columns.
    CHECK(p.x == it->second.x());
    CHECK(p.y == it->second.y());
  }
  // A TrajectorySet written and read again is the same set.
  const std::string copy = temp_file("crowdmpm_interop_copy.sqlite");
  write_jupedsim_sqlite(copy, t, rectangle_wkt(0, 0, 11, 8));
  TrajectorySet t2 = read_jupedsim_sqlite(copy);
  REQUIRE(t2.points.size() == t.points.size());
  for (size_t i = 0; i < t.points.size(); ++i) {
    CHECK(t2.points[i].id == t.points[i].id);
    CHECK(t2.points[i].frame == t.points[i].frame);
    CHECK(t2.points[i].x == t.points[i].x);
    CHECK(t2.points[i].y == t.points[i].y);
  }
  std::filesystem::remove(path);
  std::filesystem::remove(copy);
}

TEST_CASE("the JuPedSim SQLite file has the published version 2 tables and columns", "[interop]") {
  const std::string path = temp_file("crowdmpm_interop_schema.sqlite");
  const Written written = simulate_to_sqlite(path);
  // JuPedSim 1.1-1.4 (python_modules/jupedsim/jupedsim/sqlite_serialization.py, version 2):
  // name, declared type, NOT NULL of every column, in order.
  const std::map<std::string, std::vector<std::vector<std::string>>> schema = {
      {"trajectory_data", {{"frame", "INTEGER", "1"}, {"id", "INTEGER", "1"}, {"pos_x", "REAL", "1"},
                           {"pos_y", "REAL", "1"}, {"ori_x", "REAL", "1"}, {"ori_y", "REAL", "1"}}},
      {"metadata", {{"key", "TEXT", "1"}, {"value", "TEXT", "1"}}},
      {"geometry", {{"hash", "INTEGER", "1"}, {"wkt", "TEXT", "1"}}},
      {"frame_data", {{"frame", "INTEGER", "1"}, {"geometry_hash", "INTEGER", "1"}}}};
  auto tables = query(path, "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name");
  REQUIRE(tables.size() == schema.size());
  for (const auto& [table, columns] : schema) {
    auto info = query(path, "PRAGMA table_info(" + table + ")");
    REQUIRE(info.size() == columns.size());
    for (size_t c = 0; c < columns.size(); ++c) {
      INFO(table << "." << columns[c][0]);
      CHECK(info[c][1] == columns[c][0]);
      CHECK(info[c][2] == columns[c][1]);
      CHECK(info[c][3] == columns[c][2]);
    }
  }
  auto indexes = query(path, "SELECT name, tbl_name FROM sqlite_master WHERE type = 'index' AND sql IS NOT NULL ORDER BY name");
  REQUIRE(indexes.size() == 2);
  CHECK(indexes[0] == std::vector<std::string>{"frame_id_idx", "trajectory_data"});
  CHECK(indexes[1] == std::vector<std::string>{"geometry_hash", "geometry"});
  CHECK(query(path, "PRAGMA index_info(frame_id_idx)").size() == 2);
  // Metadata as PedPy reads it: version 2 (load_walkable_area_from_jupedsim_sqlite), fps.
  CHECK(query(path, "SELECT value FROM metadata WHERE key = 'version'")[0][0] == "2");
  CHECK(query(path, "select value from metadata where key = 'fps'")[0][0] == "10");
  for (const char* k : {"xmin", "xmax", "ymin", "ymax"})
    CHECK(query(path, std::string("SELECT value FROM metadata WHERE key = '") + k + "'").size() == 1);
  // PedPy's trajectory query, and one frame_data row per frame naming the geometry row.
  CHECK(query(path, "select frame, id, pos_x as x, pos_y as y from trajectory_data").size() == written.xy.size());
  CHECK(query(path, "SELECT frame FROM frame_data").size() == static_cast<size_t>(written.frames));
  CHECK(query(path, "SELECT COUNT(*) FROM frame_data JOIN geometry ON frame_data.geometry_hash = geometry.hash")[0][0] ==
        std::to_string(written.frames));
  CHECK(query(path, "SELECT wkt FROM geometry")[0][0] == "POLYGON ((0 0, 11 0, 11 8, 0 8, 0 0))");
  CHECK(read_jupedsim_geometry(path) == std::vector<std::string>{"POLYGON ((0 0, 11 0, 11 8, 0 8, 0 0))"});
  // Orientation is a unit vector.
  for (const auto& r : query(path, "SELECT ori_x * ori_x + ori_y * ori_y FROM trajectory_data"))
    CHECK(std::stod(r[0]) == Approx(1).margin(1e-12));
  std::filesystem::remove(path);
}

TEST_CASE("JuPedSim SQLite input errors name the file and what is wrong", "[interop]") {
  const std::string path = temp_file("crowdmpm_interop_bad.sqlite");
  std::filesystem::remove(path);
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db, "CREATE TABLE metadata(key TEXT, value TEXT)", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(db);
  CHECK_THROWS_WITH(TrajectorySet::read(path), Catch::Contains(path) && Catch::Contains("metadata 'fps' is missing"));
  CHECK_THROWS_WITH(TrajectorySet::read(path, 16), Catch::Contains("no trajectory_data table"));
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db,
                       "INSERT INTO metadata VALUES('fps', '16'); CREATE TABLE trajectory_data(frame, id, pos_x, pos_y);"
                       "INSERT INTO trajectory_data VALUES(0, 1, 'abc', 2)",
                       nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(db);
  CHECK_THROWS_WITH(TrajectorySet::read(path), Catch::Contains("trajectory_data row 1: column 3 is not a number"));
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db, "DELETE FROM trajectory_data", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(db);
  CHECK_THROWS_WITH(TrajectorySet::read(path), Catch::Contains("no trajectory rows"));
  // A file that is only the SQLite header is not silently an empty recording.
  { std::ofstream(path, std::ios::binary | std::ios::trunc) << std::string("SQLite format 3\0garbage", 23); }
  CHECK_THROWS_WITH(TrajectorySet::read(path), Catch::Contains(path));
  std::filesystem::remove(path);
}
