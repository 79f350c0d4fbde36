#include "engine/io/trajectory.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <unordered_map>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/io/jupedsim_sqlite.hpp"

namespace crowdmpm {

namespace {

// Largest |id| and frame: 1e12 frames is 2000 years at 16 fps, and sums and differences of such
// numbers stay far inside long's range.
constexpr double kMaxTrackNumber = 1e12;

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Metres per unit for "m", "cm", "mm"; 0 if not a unit.
double unit_scale(const std::string& u) {
  if (u == "m") return 1;
  if (u == "cm") return 0.01;
  if (u == "mm") return 0.001;
  return 0;
}

}  // namespace

TrajectorySet TrajectorySet::read(const std::string& path, double framerate_override, const InputPolicy& policy) {
  check_input_file(path, policy);  // a regular file below the limit before anything opens it (a pipe would block)
  if (is_sqlite_file(path)) return read_jupedsim_sqlite(path, framerate_override, policy);
  return parse(read_input_file(path, policy), path, framerate_override);
}

TrajectorySet TrajectorySet::parse(const std::string& text, const std::string& source, double framerate_override) {
  TrajectorySet t;
  t.source = source;
  double scale = 1;
  bool unit_given = false;
  std::istringstream in(text);
  std::string line;
  long lineno = 0;
  auto fail = [&](const std::string& why) -> void { throw Error(source + ":" + std::to_string(lineno) + ": " + why); };
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos) continue;
    if (line[start] == '#') {
      std::string c = lower(line.substr(start + 1));
      auto value_after = [&](const std::string& key) -> std::optional<std::string> {
        auto pos = c.find(key);
        if (pos == std::string::npos) return std::nullopt;
        std::string v = c.substr(pos + key.size());
        v.erase(0, v.find_first_not_of(" \t:="));
        return v;
      };
      if (c.find("original header") != std::string::npos) continue;  // provenance, not this file's format
      if (auto v = value_after("framerate"); v && t.framerate == 0) {
        char* end = nullptr;
        double fr = std::strtod(v->c_str(), &end);
        if (end == v->c_str() || !(fr > 0 && fr < 1e4)) fail("cannot read the frame rate (a number in (0, 10000)) from the header");
        t.framerate = fr;
      } else if (auto u = value_after("unit"); u && !unit_given) {
        std::string name = u->substr(0, u->find_first_of(" \t"));
        if (unit_scale(name) == 0) fail("unknown unit in the header (known: m, cm, mm)");
        scale = unit_scale(name);
        unit_given = true;
      } else if (!unit_given && c.find("x/") != std::string::npos) {
        std::string name = c.substr(c.find("x/") + 2);
        name = name.substr(0, name.find_first_of(" \t"));
        if (unit_scale(name) > 0) {
          scale = unit_scale(name);
          unit_given = true;
        }
      }
      continue;
    }
    std::istringstream row(line);
    std::vector<double> v;
    std::string tok;
    while (row >> tok) {
      char* end = nullptr;
      errno = 0;
      double d = std::strtod(tok.c_str(), &end);
      const std::string column = "column " + std::to_string(v.size() + 1);
      if (*end != '\0' || errno == ERANGE) fail(column + " is not a number");
      if (!std::isfinite(d)) fail(column + " is not a finite number");
      v.push_back(d);
    }
    if (v.size() < 4 || v.size() > 5) fail("expected \"id frame x y [z]\", got " + std::to_string(v.size()) + " values");
    // Bounded before the cast to long: a double beyond long's range does not convert (UB).
    if (v[0] != std::floor(v[0]) || v[1] != std::floor(v[1]) || v[1] < 0)
      fail("id and frame must be whole numbers (frame >= 0)");
    if (std::fabs(v[0]) > kMaxTrackNumber || v[1] > kMaxTrackNumber)
      fail("id and frame must be at most " + format_number(kMaxTrackNumber) + " in magnitude");
    t.points.push_back({static_cast<long>(v[0]), static_cast<long>(v[1]), v[2] * scale, v[3] * scale});
  }
  if (framerate_override > 0) t.framerate = framerate_override;
  if (t.framerate <= 0) throw Error(source + ": no \"# framerate: N\" header (give the frame rate explicitly)");
  t.sort_checked();
  return t;
}

namespace {
// The order of a recording's rows: by frame, then by id.
bool frame_then_id(const TrackPoint& a, const TrackPoint& b) { return a.frame != b.frame ? a.frame < b.frame : a.id < b.id; }
}  // namespace

void TrajectorySet::sort_checked() {
  if (points.empty()) throw Error(source + ": no trajectory rows");
  std::stable_sort(points.begin(), points.end(), frame_then_id);
  for (size_t i = 1; i < points.size(); ++i)
    if (points[i].frame == points[i - 1].frame && points[i].id == points[i - 1].id)
      throw Error(source + ": person " + std::to_string(points[i].id) + " appears twice in frame " +
                  std::to_string(points[i].frame));
}

std::pair<Vec2, Vec2> TrajectorySet::bounds() const {
  if (points.empty()) return {Vec2::Zero(), Vec2::Zero()};
  Vec2 lo(points[0].x, points[0].y), hi = lo;
  for (const auto& p : points) lo = lo.cwiseMin(Vec2(p.x, p.y)), hi = hi.cwiseMax(Vec2(p.x, p.y));
  return {lo, hi};
}

size_t TrajectorySet::person_count() const {
  std::set<long> ids;
  for (const auto& p : points) ids.insert(p.id);
  return ids.size();
}

std::vector<std::vector<size_t>> TrajectorySet::tracks() const {
  std::unordered_map<long, size_t> slot;
  std::vector<std::vector<size_t>> out;
  for (size_t i = 0; i < points.size(); ++i) {
    const auto [it, fresh] = slot.try_emplace(points[i].id, out.size());
    if (fresh) out.emplace_back();
    out[it->second].push_back(i);
  }
  for (auto& idx : out)
    std::stable_sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return points[a].frame < points[b].frame; });
  return out;
}

long TrajectorySet::skip_gap(long f, long stride) const {
  auto [b, e] = frame(f);
  if (b != e) return f;
  if (e == points.data() + points.size()) return frame_max() + 1;
  const long next = e->frame;  // the first recorded frame after f
  const long k = (next - f + stride - 1) / stride;
  return f + k * stride;
}

long TrajectorySet::frame_step() const {
  std::map<long, size_t> steps;  // frames between consecutive rows -> how often
  for (const auto& track : tracks())
    for (size_t k = 1; k < track.size(); ++k) ++steps[points[track[k]].frame - points[track[k - 1]].frame];
  long best = 1;
  size_t most = 0;
  for (const auto& [step, n] : steps)
    if (n > most) best = step, most = n;
  return best;
}

size_t TrajectorySet::fill_frames(long max_gap) {
  const std::vector<std::vector<size_t>> each = tracks();
  auto filled_gap = [&](const std::vector<size_t>& track, size_t k) {
    const long gap = points[track[k]].frame - points[track[k - 1]].frame;
    return gap >= 2 && gap <= max_gap ? gap - 1 : 0L;
  };
  size_t added = 0;
  for (const auto& track : each)
    for (size_t k = 1; k < track.size(); ++k) added += static_cast<size_t>(filled_gap(track, k));
  if (added == 0) return 0;
  const size_t recorded = points.size();
  points.reserve(recorded + added);  // appended in place: no second copy of the added rows
  for (const auto& track : each)
    for (size_t k = 1; k < track.size(); ++k) {
      if (filled_gap(track, k) == 0) continue;
      const TrackPoint a = points[track[k - 1]], b = points[track[k]];
      const double gap = static_cast<double>(b.frame - a.frame);
      for (long f = a.frame + 1; f < b.frame; ++f) {
        const double w = static_cast<double>(f - a.frame) / gap;
        points.push_back({a.id, f, a.x + w * (b.x - a.x), a.y + w * (b.y - a.y)});
      }
    }
  // Every (frame, id) is unique (only frames strictly between one person's rows are added), so an
  // unstable sort gives the same order as sort_checked's, without its buffer.
  std::sort(points.begin(), points.end(), frame_then_id);
  return added;
}

std::pair<const TrackPoint*, const TrackPoint*> TrajectorySet::frame(long f) const {
  auto lo = std::lower_bound(points.begin(), points.end(), f, [](const TrackPoint& p, long fr) { return p.frame < fr; });
  auto hi = std::upper_bound(lo, points.end(), f, [](long fr, const TrackPoint& p) { return fr < p.frame; });
  const TrackPoint* base = points.data();
  return {base + (lo - points.begin()), base + (hi - points.begin())};
}

TrajectoryWriter::TrajectoryWriter(const std::string& path, double framerate, const std::string& comment) : path_(path) {
  f_ = std::fopen(path.c_str(), "w");
  if (!f_) throw Error(path + ": cannot open for writing: " + std::strerror(errno));
  std::fprintf(f_, "# framerate: %.10g\n# unit: m\n# %s\n# id frame x y z\n", framerate, comment.c_str());
}

TrajectoryWriter::~TrajectoryWriter() {
  if (f_) std::fclose(f_);
}

void TrajectoryWriter::write_frame(const World& w, long frame) {
  std::vector<size_t> order(w.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return w.id[a] < w.id[b]; });
  for (size_t p : order)
    std::fprintf(f_, "%llu %ld %.5f %.5f 0\n", static_cast<unsigned long long>(w.id[p]), frame, w.x[p].x(), w.x[p].y());
}

void TrajectoryWriter::write_points(const TrajectorySet& t) {
  for (const TrackPoint& p : t.points) std::fprintf(f_, "%ld %ld %.5f %.5f 0\n", p.id, p.frame, p.x, p.y);
}

void TrajectoryWriter::close() {
  if (f_ && std::fclose(f_) != 0) {
    f_ = nullptr;
    throw Error(path_ + ": write failed (disk full?)");
  }
  f_ = nullptr;
}

}  // namespace crowdmpm
