#include "engine/io/jupedsim_sqlite.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>

#include "engine/core/error.hpp"

namespace crowdmpm {

namespace {

// JuPedSim stores Python's hash() of the WKT; any 64-bit value unique within the file will do.
long long fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  long long out;
  std::memcpy(&out, &h, sizeof out);
  return out;
}

std::string number_text(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Closes a read-only connection on every path out.
struct ReadOnlyDb {
  sqlite3* db = nullptr;
  std::string path;
  explicit ReadOnlyDb(const std::string& p) : path(p) {
    if (sqlite3_open_v2(p.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
      std::string why = db ? sqlite3_errmsg(db) : "out of memory";
      sqlite3_close(db);
      db = nullptr;
      throw Error(p + ": cannot open as SQLite: " + why);
    }
  }
  ~ReadOnlyDb() { sqlite3_close(db); }
  ReadOnlyDb(const ReadOnlyDb&) = delete;
  ReadOnlyDb& operator=(const ReadOnlyDb&) = delete;
  // A prepared statement, or an Error saying what the file lacks.
  sqlite3_stmt* prepare(const char* sql, const std::string& lacks) const {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) != SQLITE_OK)
      throw Error(path + ": not a JuPedSim trajectory file: " + lacks + " (" + sqlite3_errmsg(db) + ")");
    return st;
  }
  // metadata value of key, or empty.
  std::string metadata(const char* key) const {
    sqlite3_stmt* st = prepare("SELECT value FROM metadata WHERE key = ?", "no metadata table");
    sqlite3_bind_text(st, 1, key, -1, SQLITE_STATIC);
    std::string v;
    if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0))
      v = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    sqlite3_finalize(st);
    return v;
  }
};

}  // namespace

std::string rectangle_wkt(double xmin, double ymin, double xmax, double ymax) {
  auto p = [](double x, double y) { return number_text(x) + " " + number_text(y); };
  return "POLYGON ((" + p(xmin, ymin) + ", " + p(xmax, ymin) + ", " + p(xmax, ymax) + ", " + p(xmin, ymax) + ", " +
         p(xmin, ymin) + "))";
}

bool is_sqlite_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;  // never open a pipe or a device
  std::ifstream in(path, std::ios::binary);
  char head[16] = {};
  if (!in.read(head, sizeof head)) return false;
  return std::memcmp(head, "SQLite format 3", 16) == 0;
}

JupedsimSqliteWriter::JupedsimSqliteWriter(const std::string& path, double framerate, const std::string& walkable_wkt,
                                           double xmin, double ymin, double xmax, double ymax)
    : path_(path) {
  if (!(framerate > 0) || !std::isfinite(framerate)) throw Error(path + ": frame rate must be positive, got " + number_text(framerate));
  // A new file, not rows appended to an old one.
  if (std::remove(path.c_str()) != 0 && errno != ENOENT)
    throw Error(path + ": cannot replace the existing file: " + std::strerror(errno));
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
    std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw Error(path + ": cannot create the SQLite file: " + why);
  }
  try {
    create(framerate, walkable_wkt, xmin, ymin, xmax, ymax);
  } catch (...) {
    // The destructor does not run for a constructor that throws.
    sqlite3_finalize(insert_);
    sqlite3_finalize(frame_);
    sqlite3_close(db_);
    insert_ = frame_ = nullptr;
    db_ = nullptr;
    throw;
  }
}

void JupedsimSqliteWriter::create(double framerate, const std::string& walkable_wkt, double xmin, double ymin, double xmax,
                                  double ymax) {
  exec("PRAGMA journal_mode = OFF");
  exec("PRAGMA synchronous = OFF");
  exec("BEGIN");
  exec("CREATE TABLE trajectory_data (frame INTEGER NOT NULL, id INTEGER NOT NULL, pos_x REAL NOT NULL, "
       "pos_y REAL NOT NULL, ori_x REAL NOT NULL, ori_y REAL NOT NULL)");
  exec("CREATE TABLE metadata(key TEXT NOT NULL UNIQUE PRIMARY KEY, value TEXT NOT NULL)");
  exec("CREATE TABLE geometry(hash INTEGER NOT NULL, wkt TEXT NOT NULL)");
  exec("CREATE UNIQUE INDEX geometry_hash ON geometry(hash)");
  exec("CREATE TABLE frame_data(frame INTEGER NOT NULL, geometry_hash INTEGER NOT NULL)");
  geometry_hash_ = fnv1a(walkable_wkt);
  sqlite3_stmt* st = nullptr;
  auto check = [&](int rc, int ok) {
    if (rc != ok) fail("writing the metadata");
  };
  check(sqlite3_prepare_v2(db_, "INSERT INTO metadata VALUES(?, ?)", -1, &st, nullptr), SQLITE_OK);
  const std::pair<std::string, std::string> meta[] = {
      {"version", "2"}, {"fps", number_text(framerate)}, {"xmin", number_text(xmin)},
      {"xmax", number_text(xmax)}, {"ymin", number_text(ymin)}, {"ymax", number_text(ymax)}};
  for (const auto& [k, v] : meta) {
    sqlite3_bind_text(st, 1, k.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(st, 2, v.c_str(), -1, SQLITE_TRANSIENT);
    const int rc = sqlite3_step(st);
    sqlite3_reset(st);
    if (rc != SQLITE_DONE) {
      sqlite3_finalize(st);
      fail("writing the metadata");
    }
  }
  sqlite3_finalize(st);
  check(sqlite3_prepare_v2(db_, "INSERT INTO geometry VALUES(?, ?)", -1, &st, nullptr), SQLITE_OK);
  sqlite3_bind_int64(st, 1, geometry_hash_);
  sqlite3_bind_text(st, 2, walkable_wkt.c_str(), -1, SQLITE_TRANSIENT);
  const int rc = sqlite3_step(st);
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) fail("writing the geometry");
  if (sqlite3_prepare_v2(db_, "INSERT INTO trajectory_data VALUES(?, ?, ?, ?, ?, ?)", -1, &insert_, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(db_, "INSERT INTO frame_data VALUES(?, ?)", -1, &frame_, nullptr) != SQLITE_OK)
    fail("preparing the inserts");
}

JupedsimSqliteWriter::~JupedsimSqliteWriter() {
  sqlite3_finalize(insert_);
  sqlite3_finalize(frame_);
  sqlite3_close(db_);
}

void JupedsimSqliteWriter::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string why = err ? err : "unknown error";
    sqlite3_free(err);
    throw Error(path_ + ": SQLite: " + why + " (in \"" + sql + "\")");
  }
}

void JupedsimSqliteWriter::fail(const std::string& what) {
  throw Error(path_ + ": SQLite error while " + what + ": " + (db_ ? sqlite3_errmsg(db_) : "file closed") +
              " (disk full?)");
}

void JupedsimSqliteWriter::write_rows(long frame, const std::vector<Row>& rows) {
  if (!db_) throw Error(path_ + ": write after close");
  for (const Row& r : rows) {
    sqlite3_bind_int64(insert_, 1, frame);
    sqlite3_bind_int64(insert_, 2, r.id);
    sqlite3_bind_double(insert_, 3, r.x);
    sqlite3_bind_double(insert_, 4, r.y);
    sqlite3_bind_double(insert_, 5, r.ori_x);
    sqlite3_bind_double(insert_, 6, r.ori_y);
    const int rc = sqlite3_step(insert_);
    sqlite3_reset(insert_);
    if (rc != SQLITE_DONE) fail("writing frame " + std::to_string(frame));
  }
  sqlite3_bind_int64(frame_, 1, frame);
  sqlite3_bind_int64(frame_, 2, geometry_hash_);
  const int rc = sqlite3_step(frame_);
  sqlite3_reset(frame_);
  if (rc != SQLITE_DONE) fail("writing frame " + std::to_string(frame));
}

void JupedsimSqliteWriter::write_frame(const World& w, long frame) {
  std::vector<size_t> order(w.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return w.id[a] < w.id[b]; });
  std::vector<Row> rows;
  rows.reserve(order.size());
  for (size_t p : order) {
    const double speed = w.v[p].norm();
    const double ox = speed > 1e-9 ? w.v[p].x() / speed : 1.0, oy = speed > 1e-9 ? w.v[p].y() / speed : 0.0;
    rows.push_back({static_cast<long>(w.id[p]), w.x[p].x(), w.x[p].y(), ox, oy});
  }
  write_rows(frame, rows);
}

void JupedsimSqliteWriter::close() {
  if (!db_) return;
  exec("CREATE INDEX frame_id_idx ON trajectory_data(frame, id)");
  exec("COMMIT");
  sqlite3_finalize(insert_);
  sqlite3_finalize(frame_);
  insert_ = frame_ = nullptr;
  const int rc = sqlite3_close(db_);
  db_ = nullptr;
  if (rc != SQLITE_OK) throw Error(path_ + ": closing the SQLite file failed");
}

void write_jupedsim_sqlite(const std::string& path, const TrajectorySet& t, const std::string& walkable_wkt) {
  if (t.points.empty()) throw Error(path + ": no trajectory rows to write");
  std::map<long, std::vector<size_t>> by_id;  // each person's rows in frame order
  for (size_t i = 0; i < t.points.size(); ++i) by_id[t.points[i].id].push_back(i);
  std::vector<Vec2> ori(t.points.size(), Vec2(1, 0));
  for (const auto& [id, rows] : by_id)
    for (size_t k = 0; k < rows.size(); ++k) {
      const size_t a = k + 1 < rows.size() ? rows[k] : (k > 0 ? rows[k - 1] : rows[k]);
      const size_t b = k + 1 < rows.size() ? rows[k + 1] : rows[k];
      const Vec2 d(t.points[b].x - t.points[a].x, t.points[b].y - t.points[a].y);
      if (d.norm() > 1e-9) ori[rows[k]] = d / d.norm();
    }
  const auto [lo, hi] = t.bounds();
  JupedsimSqliteWriter out(path, t.framerate, walkable_wkt, lo.x(), lo.y(), hi.x(), hi.y());
  std::vector<JupedsimSqliteWriter::Row> rows;
  for (size_t i = 0; i < t.points.size();) {
    const long f = t.points[i].frame;
    rows.clear();
    for (; i < t.points.size() && t.points[i].frame == f; ++i)
      rows.push_back({t.points[i].id, t.points[i].x, t.points[i].y, ori[i].x(), ori[i].y()});
    out.write_rows(f, rows);
  }
  out.close();
}

TrajectorySet read_jupedsim_sqlite(const std::string& path, double framerate_override, const InputPolicy& policy) {
  check_input_file(path, policy);
  ReadOnlyDb db(path);
  TrajectorySet t;
  t.source = path;
  if (framerate_override > 0) {
    t.framerate = framerate_override;
  } else {
    const std::string fps = db.metadata("fps");
    char* end = nullptr;
    t.framerate = fps.empty() ? 0 : std::strtod(fps.c_str(), &end);
    if (fps.empty() || !end || *end != '\0' || !(t.framerate > 0) || !std::isfinite(t.framerate))
      throw Error(path + ": metadata 'fps' is " + (fps.empty() ? "missing" : "not a positive number") +
                  " (give the frame rate explicitly)");
  }
  sqlite3_stmt* st = db.prepare("SELECT frame, id, pos_x, pos_y FROM trajectory_data", "no trajectory_data table");
  int rc;
  while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
    TrackPoint p;
    for (int c = 0; c < 4; ++c) {
      const int type = sqlite3_column_type(st, c);
      if (type != SQLITE_INTEGER && type != SQLITE_FLOAT) {
        sqlite3_finalize(st);
        throw Error(path + ": trajectory_data row " + std::to_string(t.points.size() + 1) + ": column " +
                    std::to_string(c + 1) + " is not a number");
      }
    }
    const double frame = sqlite3_column_double(st, 0), id = sqlite3_column_double(st, 1);
    p.x = sqlite3_column_double(st, 2);
    p.y = sqlite3_column_double(st, 3);
    if (frame != std::floor(frame) || frame < 0 || frame > 1e12 || id != std::floor(id) || std::fabs(id) > 1e12 ||
        !std::isfinite(p.x) || !std::isfinite(p.y)) {
      sqlite3_finalize(st);
      throw Error(path + ": trajectory_data row " + std::to_string(t.points.size() + 1) +
                  ": frame and id must be whole numbers (frame >= 0) and positions finite");
    }
    p.frame = static_cast<long>(frame);
    p.id = static_cast<long>(id);
    t.points.push_back(p);
  }
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) throw Error(path + ": reading trajectory_data failed: " + sqlite3_errmsg(db.db));
  t.sort_checked();
  return t;
}

std::vector<std::string> read_jupedsim_geometry(const std::string& path) {
  ReadOnlyDb db(path);
  const std::string version = db.metadata("version");
  sqlite3_stmt* st = db.prepare("SELECT wkt FROM geometry", "no geometry table");
  std::vector<std::string> out;
  while (sqlite3_step(st) == SQLITE_ROW)
    if (sqlite3_column_text(st, 0)) out.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
  sqlite3_finalize(st);
  if (version == "1" && out.size() > 1) out.resize(1);
  return out;
}

}  // namespace crowdmpm
