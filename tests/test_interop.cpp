// Interop files: JuPedSim's SQLite trajectory format (the version PedPy reads), written from a
// simulated run and read back; its tables and columns against the published schema.
#include <sqlite3.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

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

// ---- PedPy-style measurements against JPSreport's reference results ---------------------------

#include "engine/observe/analyze.hpp"
#include "engine/observe/jpsreport.hpp"

namespace {

// Columns of a JPSreport .dat file (comment lines start with '#').
std::vector<std::vector<double>> read_dat(const std::string& path) {
  std::ifstream in(path);
  REQUIRE(in);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::vector<double> r;
    double v;
    while (ls >> v) r.push_back(v);
    if (!r.empty()) rows.push_back(r);
  }
  return rows;
}

// An L-shaped room (non-convex), for triangulation checks.
const Polygon2 kLShape = {{0, 0}, {4, 0}, {4, 1}, {1, 1}, {1, 4}, {0, 4}};

struct Deviation {
  double mean_rel = 0, worst = 0;
  long worst_frame = -1;
  size_t frames = 0;
};

// Relative error of the means, and the worst per-frame error relative to max(|ref|, floor).
Deviation compare(const std::vector<std::pair<double, double>>& ours_ref, double floor) {
  Deviation d;
  double so = 0, sr = 0;
  long f = 0;
  for (const auto& [o, r] : ours_ref) {
    so += o, sr += r;
    const double e = std::abs(o - r) / std::max(std::abs(r), floor);
    if (e > d.worst) d.worst = e, d.worst_frame = f;
    ++f;
  }
  d.frames = ours_ref.size();
  d.mean_rel = std::abs(so - sr) / std::max(std::abs(sr), 1e-12);
  return d;
}

}  // namespace

TEST_CASE("analyze reproduces JPSreport's AO_300 bottleneck results", "[interop][data]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("SKIPPED: ../shared/data is absent (reference/jpsreport_bottleneck_AO_300)");
    return;
  }
  const std::string dir = data + "/reference/jpsreport_bottleneck_AO_300";
  const TrajectorySet t = TrajectorySet::read(dir + "/traj.txt");
  REQUIRE(t.framerate == 16);
  // tests/data/ao300_measurement.json holds geo.xml's walkable polygon, ini.xml's area 1 and
  // lines 2 and 4, and its <velocity frame_step="10">, which JPSreport halves: 5 frames each side.
  const std::string spec_path = test::repo_path("tests/data/ao300_measurement.json");
  const AnalysisSpec spec = AnalysisSpec::from_json(load_json_file(spec_path), spec_path);
  REQUIRE(spec.frame_step == 5);
  REQUIRE(spec.lines.size() == 2);
  // What `crowdmpm analyze --spec` writes: area_bottleneck.csv and nt_line4.csv.
  const std::string out = temp_file("crowdmpm_interop_ao300");
  std::filesystem::remove_all(out);
  const json summary = run_analysis(t, spec, out);
  CHECK(summary["lines"][1]["crossings"] == 348);
  // frame -> columns of a CSV file with a header line (the last column may be a letter).
  auto read_csv = [](const std::string& path) {
    std::ifstream in(path);
    REQUIRE(in);
    std::map<long, std::vector<double>> rows;
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::vector<double> r;
      std::stringstream ls(line);
      std::string cell;
      while (std::getline(ls, cell, ',')) r.push_back(std::isalpha(static_cast<unsigned char>(cell[0])) ? cell[0] - 'A' : std::stod(cell));
      rows[static_cast<long>(r.at(0))] = r;
    }
    return rows;
  };
  const auto area = read_csv(out + "/area_bottleneck.csv");  // frame,time,people,inside,cd,cs,vd,vs,los
  const auto line4 = read_csv(out + "/nt_line4.csv");        // frame,time,count
  REQUIRE(area.size() == 959);
  auto at = [&](double frame) -> const std::vector<double>& { return area.at(static_cast<long>(frame)); };
  const std::string res = dir + "/results/Fundamental_Diagram";
  std::vector<std::pair<double, double>> cd, cv, vd, vv, nt;
  for (const auto& r : read_dat(res + "/Classical_Voronoi/rho_v_Classic_traj.txt_id_1.dat")) {
    cd.emplace_back(at(r[0])[4], r[1]);
    cv.emplace_back(at(r[0])[5], r[2]);
  }
  for (const auto& r : read_dat(res + "/Classical_Voronoi/rho_v_Voronoi_Voronoi_traj.txt_id_1.dat")) {
    if (at(r[0])[2] < 4) continue;  // JPSreport makes no Voronoi diagram of fewer than 4 people
    vd.emplace_back(at(r[0])[6], r[1]);
    vv.emplace_back(at(r[0])[7], r[2]);
  }
  long exact = 0, rows = 0;
  for (const auto& r : read_dat(res + "/FlowVelocity/Flow_NT_traj_AO_300.txt_id_4.dat")) {
    ++rows;
    const auto& c = line4.at(static_cast<long>(r[0]));
    CHECK(c[1] == Approx(r[1]).margin(0.006));
    exact += static_cast<long>(c[2]) == static_cast<long>(r[2]);
    nt.emplace_back(c[2], r[2]);
  }
  CHECK(exact == rows);  // N(t) is a count: every frame exactly
  std::filesystem::remove_all(out);
  CHECK(cd.size() == 959);
  CHECK(vd.size() >= 900);
  // Within 1% in the mean and 5% per frame (relative to the value, or to half the reference's
  // rounding step plus 1% of its typical size for values near zero).
  const std::pair<const char*, Deviation> checks[] = {
      {"classic density", compare(cd, 0.1)}, {"classic speed", compare(cv, 0.1)},
      {"Voronoi density", compare(vd, 0.1)}, {"Voronoi speed", compare(vv, 0.1)}, {"N(t)", compare(nt, 1)}};
  for (const auto& [name, d] : checks) {
    INFO(name << ": " << d.frames << " frames, mean " << 100 * d.mean_rel << "% off, worst frame " << d.worst_frame
              << " " << 100 * d.worst << "% off");
    CHECK(d.mean_rel < 0.01);
    CHECK(d.worst < 0.05);
    std::printf("%s: %zu frames, mean %.3f%% off, worst frame %.2f%% off\n", name, d.frames, 100 * d.mean_rel, 100 * d.worst);
  }
}

TEST_CASE("Fruin's level of service has its published walkway boundaries", "[interop]") {
  // ft^2 per person: A >= 35, B >= 25, C >= 15, D >= 10, E >= 5, F below (Fruin 1971).
  constexpr double ft2 = 0.09290304;
  CHECK(fruin_level(0) == 'A');
  CHECK(fruin_level(0.2) == 'A');                 // 53.8 ft^2
  CHECK(fruin_level(1 / (35 * ft2)) == 'A');      // exactly 35 ft^2
  CHECK(fruin_level(1 / (34.9 * ft2)) == 'B');
  CHECK(fruin_level(0.5) == 'C');                 // 21.5 ft^2
  CHECK(fruin_level(1.0) == 'D');                 // 10.8 ft^2
  CHECK(fruin_level(2.0) == 'E');                 // 5.4 ft^2
  CHECK(fruin_level(1 / (5 * ft2)) == 'E');       // 2.153 persons/m^2
  CHECK(fruin_level(2.2) == 'F');
  CHECK(fruin_level(6.0) == 'F');
  CHECK_THROWS_WITH(fruin_level(-1), Catch::Contains("density must be >= 0"));
}

TEST_CASE("Helbing's crowd pressure is density times the variance of the local velocity", "[interop]") {
  // A square lattice at 4 persons/m^2 (0.5 m apart) whose people all walk at +u or -u along x
  // in alternate frames: the local velocity swings between +u and -u, its variance over time is
  // u^2 and the pressure density * u^2 = 4 * 0.64 = 2.56 1/s^2 inside the crowd.
  TrajectorySet t;
  t.framerate = 10;
  const double u = 0.8;
  std::vector<Vec2> vel;
  for (long f = 0; f < 20; ++f)
    for (int i = 0; i < 40; ++i)
      for (int j = 0; j < 40; ++j) {
        t.points.push_back({i * 40 + j + 1, f, 0.5 * i, 0.5 * j});
        vel.emplace_back(f % 2 ? -u : u, 0);
      }
  const PressureField p = crowd_pressure(t, vel, 0, 19, Vec2(5, 5), Vec2(15, 15), 0.5, 0.7);
  for (size_t k = 0; k < p.pressure.size(); ++k) {
    CHECK(p.density[k] == Approx(4).epsilon(0.01));
    CHECK(p.pressure[k] == Approx(4 * u * u).epsilon(0.01));
  }
  // The same crowd walking steadily has no pressure.
  std::fill(vel.begin(), vel.end(), Vec2(u, 0));
  CHECK(crowd_pressure(t, vel, 0, 19, Vec2(5, 5), Vec2(15, 15), 0.5, 0.7).max_pressure() < 1e-12);
}

TEST_CASE("a JPSreport project (ini.xml and geo.xml) reads as the analyze spec written by hand", "[interop][data]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("SKIPPED: ../shared/data is absent (reference/jpsreport_bottleneck_AO_300)");
    return;
  }
  const std::string dir = data + "/reference/jpsreport_bottleneck_AO_300";
  const JpsreportProject p = read_jpsreport_project(dir);  // the folder: its ini.xml
  const std::string spec_path = test::repo_path("tests/data/ao300_measurement.json");
  const AnalysisSpec hand = AnalysisSpec::from_json(load_json_file(spec_path), spec_path);
  CHECK(std::filesystem::equivalent(p.trajectories, dir + "/traj.txt"));
  CHECK(p.spec.frame_step == 5);  // frame_step="10", halved as JPSreport does
  CHECK(p.spec.walkable == hand.walkable);
  REQUIRE(p.spec.areas.size() == 1);
  CHECK(p.spec.areas[0].id == "area1");
  CHECK(polygon_area(p.spec.areas[0].polygon) == Approx(polygon_area(hand.areas[0].polygon)));
  REQUIRE(p.spec.lines.size() == 2);
  CHECK(p.spec.lines[1].id == "line4");
  CHECK(p.spec.lines[1].from == hand.lines[1].from);
  CHECK(p.spec.lines[1].to == hand.lines[1].to);
  CHECK(p.notes.empty());
}

TEST_CASE("malformed JPSreport project files are named with their line", "[interop]") {
  const std::string dir = temp_file("crowdmpm_interop_jps");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  };
  CHECK_THROWS_WITH(read_jpsreport_project(write("a.xml", "<JPSreport>\n<trajectories>\n</JPSreport>")),
                    Catch::Contains("a.xml:3: closing tag </JPSreport> does not match"));
  CHECK_THROWS_WITH(read_jpsreport_project(write("b.xml", "<other/>")), Catch::Contains("no <JPSreport> element"));
  CHECK_THROWS_WITH(read_jpsreport_project(write("c.xml", "<JPSreport><trajectories><file name=\"t.txt\"/></trajectories>"
                                                          "<measurement_areas><area_L id=\"1\"><start x=\"0\" y=\"a\"/>"
                                                          "<end x=\"1\" y=\"0\"/></area_L></measurement_areas></JPSreport>")),
                    Catch::Contains("y=\"a\" is not a number"));
  CHECK_THROWS_WITH(read_jpsreport_project(dir), Catch::Contains("ini.xml: cannot open file for reading (no such file)"));
  // Nesting is bounded (no stack overflow), files named inside stay in the ini's folder, ids differ.
  std::string deep;
  for (int i = 0; i < 100000; ++i) deep += "<a>";
  CHECK_THROWS_WITH(read_jpsreport_project(write("d.xml", deep)), Catch::Contains("nested deeper than"));
  const std::string lines = "<measurement_areas><area_L id=\"1\"><start x=\"0\" y=\"0\"/><end x=\"1\" y=\"0\"/></area_L>";
  CHECK_THROWS_WITH(read_jpsreport_project(write("e.xml", "<JPSreport><geometry file=\"/etc/hostname\"/><trajectories><file name=\"t.txt\"/>"
                                                          "</trajectories>" + lines + "</measurement_areas></JPSreport>")),
                    Catch::Contains("lies outside the folder"));
  CHECK_THROWS_WITH(read_jpsreport_project(write("f.xml", "<JPSreport><trajectories><file name=\"t.txt\"/></trajectories>" + lines +
                                                          lines.substr(std::string("<measurement_areas>").size()) +
                                                          "</measurement_areas></JPSreport>")),
                    Catch::Contains("two measurement lines have the id \"line1\""));
  CHECK_THROWS_WITH(AnalysisSpec::from_json(json::parse(R"({"areas": [{"id": "a", "rect": [0, 0, 1, 1]}, {"id": "a", "rect": [1, 1, 2, 2]}]})"), "s.json"),
                    Catch::Contains("s.json: two measurement areas have the id \"a\""));
  std::filesystem::remove_all(dir);
}

TEST_CASE("measurement polygons that cross themselves or have no area are refused", "[interop]") {
  CHECK_THROWS_WITH(triangulate({{3, 0}, {0, 3}, {1, 0}, {3, 2}, {0, 0}}, "area x"), Catch::Contains("area x: polygon is self-intersecting"));
  CHECK_THROWS_WITH(triangulate({{0, 0}, {1, 1}, {1, 0}, {0, 1}}, "bow"), Catch::Contains("bow: polygon"));
  CHECK_THROWS_WITH(triangulate({{0, 0}, {1e-160, 0}, {1e-160, 1e-160}}, "tiny"), Catch::Contains("no area"));
  CHECK_THROWS_WITH(triangulate({{0, 0}, {NAN, 0}, {1, 1}}, "nan"), Catch::Contains("finite"));
  // A ring that repeats its start, and one with a vertex in the middle of an edge, are fine.
  double sum = 0;
  for (const auto& tri : triangulate({{0, 0}, {2, 0}, {4, 0}, {4, 3}, {0, 3}, {0, 0}}, "ok")) sum += polygon_area(tri);
  CHECK(sum == Approx(12));
  sum = 0;
  for (const auto& tri : triangulate(kLShape, "L")) sum += polygon_area(tri);
  CHECK(sum == Approx(polygon_area(kLShape)));
}

TEST_CASE("a gap of 1e9 frames in a recording costs nothing to measure", "[interop]") {
  TrajectorySet t;
  t.source = "gap.txt";
  t.framerate = 25;
  for (long id = 1; id <= 5; ++id) {
    t.points.push_back({id, 0, 0.5 * static_cast<double>(id), 0.0});
    t.points.push_back({id, 1, 0.5 * static_cast<double>(id), 0.1});
    t.points.push_back({id, 1000000000, 0.5 * static_cast<double>(id), 1.0});
  }
  t.sort_checked();
  const auto speeds = individual_speeds(t, 1);
  const auto m = measure_area(t, {{0, -1}, {3, -1}, {3, 2}, {0, 2}}, {{-1, -2}, {4, -2}, {4, 3}, {-1, 3}}, speeds);
  REQUIRE(m.size() == 3);  // the recorded frames only
  CHECK(m[2].frame == 1000000000);
  CHECK(m[2].inside == 5);
  CHECK(crossings(t, Vec2(0, 0.5), Vec2(3, 0.5)).size() == 3);
  const PressurePeak p = peak_crowd_pressure(t, individual_velocities(t, 1), 50, Vec2(-1, -1), Vec2(4, 2), 0.5, 0.7);
  CHECK(p.windows.size() == 2);
}

TEST_CASE("a Voronoi cut-off bounds a lone person's cell by the cut-off polygon", "[interop]") {
  // One person alone in a 10 m x 10 m hall: the cell is the hall, or with a cut-off of 0.8 m and
  // 12 edges the 12-gon of area 3 r^2 = 1.92 m^2. The density in a small square round the person
  // is 1 / (cell area).
  TrajectorySet t;
  t.source = "lone.txt";
  t.framerate = 10;
  t.points.push_back({1, 0, 0.0, 0.0});
  t.points.push_back({2, 0, 4.0, 4.0});  // far away: its bisector does not reach the 12-gon
  const Polygon2 hall = {{-5, -5}, {5, -5}, {5, 5}, {-5, 5}}, square = {{-0.1, -0.1}, {0.1, -0.1}, {0.1, 0.1}, {-0.1, 0.1}};
  const std::vector<double> speeds(2, 0.0);
  const double r = 0.8;
  CHECK(measure_area(t, square, hall, speeds, r, 12)[0].voronoi_density == Approx(1 / (3 * r * r)).epsilon(1e-9));
  // Without it the cell is the hall on the person's side of the bisector x + y = 4: 100 m^2 less
  // the triangle (-1, 5), (5, 5), (5, -1) of 18 m^2.
  CHECK(measure_area(t, square, hall, speeds)[0].voronoi_density == Approx(1 / 82.0).epsilon(1e-9));
  const auto spec = AnalysisSpec::from_json(json::parse(R"({"areas": [{"id": "a", "rect": [0, 0, 1, 1]}], "voronoi_cutoff": {"radius": 0.8}})"), "c.json");
  CHECK(spec.cutoff_radius == 0.8);
  CHECK(spec.cutoff_edges == 12);
}

TEST_CASE("N(t) counts each person once at the first step that meets the line", "[interop]") {
  TrajectorySet t;
  t.source = "line.txt";
  t.framerate = 10;
  // Person 1 steps onto the line at frame 1 (counted there, as JPSreport does) and goes on;
  // person 2 crosses between frames 2 and 3, comes back and crosses again (counted once);
  // person 3 walks beside the line's end and never meets it.
  const double y1[] = {0, 0.5, 1, 1.5}, y2[] = {0, 0.2, 0.4, 0.7}, y3[] = {0, 0.4, 0.8, 1.2};
  for (long f = 0; f < 4; ++f) {
    t.points.push_back({1, f, 1.0, y1[f]});
    t.points.push_back({2, f, 2.0, y2[f]});
    t.points.push_back({3, f, 5.0, y3[f]});
  }
  for (long f = 4; f < 6; ++f) t.points.push_back({2, f, 2.0, f == 4 ? 0.3 : 0.8});
  t.sort_checked();
  const auto n = crossings(t, Vec2(0, 0.5), Vec2(3, 0.5));
  REQUIRE(n.size() == 6);
  const long expected[] = {0, 1, 1, 2, 2, 2};
  for (size_t k = 0; k < 6; ++k) CHECK(n[k].count == expected[k]);
  CHECK(n[3].time == Approx(0.3));
}
