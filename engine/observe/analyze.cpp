#include "engine/observe/analyze.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>

#include "engine/core/error.hpp"
#include "engine/core/output.hpp"
#include "engine/geometry/shape.hpp"
#include "engine/io/render.hpp"
#include "engine/sim/scenario.hpp"

namespace crowdmpm {

namespace fs = std::filesystem;

namespace {

// A writable file; errors name it.
struct OutFile {
  std::FILE* f;
  std::string path;
  explicit OutFile(const std::string& p) : f(std::fopen(p.c_str(), "w")), path(p) {
    if (!f) throw Error(p + ": cannot write");
  }
  ~OutFile() {
    if (f) std::fclose(f);
  }
  OutFile(const OutFile&) = delete;
  OutFile& operator=(const OutFile&) = delete;
  void close() {
    const bool bad = std::ferror(f) != 0;
    if (std::fclose(f) != 0 || bad) {
      f = nullptr;
      throw Error(path + ": write failed (disk full?)");
    }
    f = nullptr;
  }
};

void check_id(const std::string& id, const std::string& where) {
  if (id.empty() || id.size() > 64 ||
      !std::all_of(id.begin(), id.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'; }))
    throw Error(where + ": id \"" + id + "\" must be 1-64 letters, digits, '_' or '-' (it names output files)");
}

}  // namespace

AnalysisSpec AnalysisSpec::from_json(const json& j, const std::string& source) {
  AnalysisSpec s;
  JsonReader r(j, source);
  r.require_object();
  r.allow_only({"walkable_area", "areas", "lines", "frame_step", "pressure", "fd_bin", "voronoi_cutoff", "description"});
  if (auto w = r.get("walkable_area")) {
    s.walkable = w->as_points(3);
    triangulate(s.walkable, w->path());
  }
  if (auto areas = r.get("areas"))
    for (size_t i = 0; i < areas->size(); ++i) {
      JsonReader a = areas->item(i);
      const Shape shape = parse_region(a, {"id"});
      if (shape.kind != Shape::Kind::Polygon) a.fail("a measurement area must be a rect or a polygon");
      Area area{a.string("id", std::nullopt), shape.points};
      check_id(area.id, a.path());
      triangulate(area.polygon, a.path());
      s.areas.push_back(area);
    }
  if (auto lines = r.get("lines"))
    for (size_t i = 0; i < lines->size(); ++i) {
      JsonReader l = lines->item(i);
      l.allow_only({"id", "from", "to"});
      Line line{l.string("id", std::nullopt), l.vec2("from", std::nullopt), l.vec2("to", std::nullopt)};
      check_id(line.id, l.path());
      if ((line.to - line.from).norm() <= 0) l.fail("from and to coincide");
      s.lines.push_back(line);
    }
  s.frame_step = r.integer("frame_step", 1, 1000, 5);
  if (auto p = r.get("pressure")) {
    p->allow_only({"cell", "radius", "window"});
    s.pressure_cell = p->in_range("cell", 0.05, 10, 0.5);
    s.pressure_radius = p->in_range("radius", 0.1, 10, 0.7);
    s.pressure_window = p->in_range("window", 0.1, 3600, 10);
  }
  s.fd_bin = r.in_range("fd_bin", 0.05, 5, 0.5);
  if (auto c = r.get("voronoi_cutoff")) {
    c->allow_only({"radius", "edges"});
    s.cutoff_radius = c->in_range("radius", 0.05, 100, std::nullopt);
    s.cutoff_edges = c->integer("edges", 3, 1000, 12);
  }
  if (s.areas.empty() && s.lines.empty()) r.fail("no \"areas\" and no \"lines\": nothing to measure");
  s.check_unique_ids(source);
  return s;
}

void AnalysisSpec::check_unique_ids(const std::string& where) const {
  std::set<std::string> a, l;
  for (const auto& x : areas)
    if (!a.insert(x.id).second) throw Error(where + ": two measurement areas have the id \"" + x.id + "\"");
  for (const auto& x : lines)
    if (!l.insert(x.id).second) throw Error(where + ": two measurement lines have the id \"" + x.id + "\"");
}

AnalysisSpec AnalysisSpec::from_scenario(const std::string& path, const InputPolicy& policy) {
  const ScenarioDef sc = ScenarioDef::load(path, policy);
  AnalysisSpec s;
  const Vec2 lo = sc.geo.lo, hi = sc.geo.hi;
  s.walkable = {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())};
  for (const auto& a : sc.areas) {
    if (a.shape.kind != Shape::Kind::Polygon) continue;
    check_id(a.id, path + ": measurement area");
    s.areas.push_back({a.id, a.shape.points});
    triangulate(a.shape.points, path + ": measurement area \"" + a.id + "\"");
  }
  if (s.areas.empty()) throw Error(path + ": the scenario has no rect or polygon measurement areas (give --spec)");
  return s;
}

json run_analysis(const TrajectorySet& t, const AnalysisSpec& spec, const std::string& out_dir) {
  prepare_output_folder(out_dir);
  auto file = [&](const std::string& name) { return (fs::path(out_dir) / name).string(); };
  if (t.points.empty()) throw Error(t.source + ": no trajectory rows to analyze");
  const auto [lo, hi] = t.bounds();
  Polygon2 walkable = spec.walkable;
  if (walkable.empty()) {
    const Vec2 a = lo - Vec2(1, 1), b = hi + Vec2(1, 1);
    walkable = {a, Vec2(b.x(), a.y()), b, Vec2(a.x(), b.y())};
  }
  const std::vector<Vec2> velocities = individual_velocities(t, spec.frame_step);
  std::vector<double> speeds;
  speeds.reserve(velocities.size());
  for (const Vec2& v : velocities) speeds.push_back(v.norm());
  json summary = {{"source", t.source},
                  {"framerate", t.framerate},
                  {"frames", {t.frame_min(), t.frame_max()}},
                  {"people", t.person_count()},
                  {"frame_step", spec.frame_step},
                  {"voronoi_cutoff", spec.cutoff_radius > 0 ? json{{"radius", spec.cutoff_radius}, {"edges", spec.cutoff_edges}} : json(nullptr)},
                  {"units", {{"density", "persons/m^2"}, {"speed", "m/s"}, {"flow", "persons/s"}, {"crowd_pressure", "1/s^2"}}},
                  {"areas", json::array()},
                  {"lines", json::array()}};
  for (const auto& area : spec.areas) {
    const std::vector<AreaFrame> m = measure_area(t, area.polygon, walkable, speeds, spec.cutoff_radius, spec.cutoff_edges);
    OutFile out(file("area_" + area.id + ".csv"));
    std::fprintf(out.f, "frame,time_s,people,inside,classic_density,classic_speed,voronoi_density,voronoi_speed,level_of_service\n");
    std::map<char, long> los;
    double sum_cd = 0, sum_vd = 0, max_cd = 0, max_vd = 0;
    std::map<long, std::array<double, 5>> bins;  // bin -> frames, sum classic speed, sum flow, voronoi frames, sum voronoi speed
    for (const AreaFrame& f : m) {
      const char level = fruin_level(f.voronoi_density);
      ++los[level];
      std::fprintf(out.f, "%ld,%.4f,%ld,%ld,%.5f,%.5f,%.5f,%.5f,%c\n", f.frame, f.time, f.people, f.inside, f.classic_density,
                   f.classic_speed, f.voronoi_density, f.voronoi_speed, level);
      sum_cd += f.classic_density, sum_vd += f.voronoi_density;
      max_cd = std::max(max_cd, f.classic_density), max_vd = std::max(max_vd, f.voronoi_density);
      if (f.inside > 0) {
        auto& b = bins[static_cast<long>(std::floor(f.classic_density / spec.fd_bin))];
        b[0] += 1, b[1] += f.classic_speed, b[2] += f.classic_density * f.classic_speed;
      }
      if (f.voronoi_density > 0) {
        auto& b = bins[static_cast<long>(std::floor(f.voronoi_density / spec.fd_bin))];
        b[3] += 1, b[4] += f.voronoi_speed;  // area-weighted mean speed over the area
      }
    }
    out.close();
    // The fundamental diagram: mean speed per density bin, classic and Voronoi (PedPy #499).
    OutFile fd(file("fd_" + area.id + ".csv"));
    std::fprintf(fd.f, "density_from,density_to,classic_frames,classic_speed,specific_flow,voronoi_frames,voronoi_speed\n");
    json fd_rows = json::array();
    for (const auto& [k, b] : bins) {
      const double d0 = static_cast<double>(k) * spec.fd_bin, d1 = d0 + spec.fd_bin;
      const double cs = b[0] > 0 ? b[1] / b[0] : NAN, flow = b[0] > 0 ? b[2] / b[0] : NAN,
                   vs = b[3] > 0 ? b[4] / b[3] : NAN;
      std::fprintf(fd.f, "%.3f,%.3f,%.0f,%.4f,%.4f,%.0f,%.4f\n", d0, d1, b[0], cs, flow, b[3], vs);
    }
    fd.close();
    json level_share = json::object();
    for (const auto& [c, n] : los) level_share[std::string(1, c)] = static_cast<double>(n) / static_cast<double>(m.size());
    summary["areas"].push_back({{"id", area.id},
                                {"area_m2", polygon_area(area.polygon)},
                                {"mean_classic_density", sum_cd / static_cast<double>(m.size())},
                                {"mean_voronoi_density", sum_vd / static_cast<double>(m.size())},
                                {"max_classic_density", max_cd},
                                {"max_voronoi_density", max_vd},
                                {"level_of_service_share", level_share},
                                {"files", {"area_" + area.id + ".csv", "fd_" + area.id + ".csv"}}});
  }
  for (const auto& line : spec.lines) {
    const std::vector<LineCount> n = crossings(t, line.from, line.to);
    OutFile out(file("nt_" + line.id + ".csv"));
    std::fprintf(out.f, "frame,time_s,cumulative_count\n");
    for (const auto& c : n) std::fprintf(out.f, "%ld,%.4f,%ld\n", c.frame, c.time, c.count);
    out.close();
    // Mean flow between the first and the last crossing.
    long first = -1, last = -1;
    for (const auto& c : n) {
      if (c.count > 0 && first < 0) first = c.frame;
      if (c.count == n.back().count && last < 0) last = c.frame;
    }
    const long total = n.empty() ? 0 : n.back().count;
    const double span = first >= 0 && last > first ? static_cast<double>(last - first) / t.framerate : 0;
    summary["lines"].push_back({{"id", line.id},
                                {"crossings", total},
                                {"mean_flow", span > 0 ? static_cast<double>(total - 1) / span : 0.0},
                                {"file", "nt_" + line.id + ".csv"}});
  }
  // Crowd pressure in consecutive windows; the map of the window with the highest peak.
  const long window = std::max(2L, std::lround(spec.pressure_window * t.framerate));
  const PressurePeak peak =
      peak_crowd_pressure(t, velocities, window, lo - Vec2(1, 1), hi + Vec2(1, 1), spec.pressure_cell, spec.pressure_radius);
  const PressureField& worst = peak.field;
  const long worst_from = peak.from;
  json windows = json::array();
  for (const auto& [from, max] : peak.windows) windows.push_back({{"from_s", from}, {"max", max}});
  if (!worst.pressure.empty()) {
    OutFile out(file("crowd_pressure.csv"));
    std::fprintf(out.f, "x,y,mean_density,crowd_pressure\n");
    size_t kmax = 0;
    for (int j = 0; j < worst.ny; ++j)
      for (int i = 0; i < worst.nx; ++i) {
        const size_t k = static_cast<size_t>(j) * static_cast<size_t>(worst.nx) + static_cast<size_t>(i);
        if (worst.pressure[k] > worst.pressure[kmax]) kmax = k;
        std::fprintf(out.f, "%.3f,%.3f,%.5f,%.6f\n", worst.lo.x() + i * worst.cell, worst.lo.y() + j * worst.cell,
                     worst.density[k], worst.pressure[k]);
      }
    out.close();
    const FieldFrame ff = worst.grid();
    Geometry geo;
    geo.lo = worst.lo;
    geo.hi = worst.lo + Vec2((worst.nx - 1) * worst.cell, (worst.ny - 1) * worst.cell);
    const double top = std::max(0.02, worst.max_pressure());
    write_field_png(file("crowd_pressure.png"), geo, View::fit(geo, 0), ff, worst.pressure, 0, top,
                    "crowd pressure (Helbing 2007), " + format_number(static_cast<double>(worst_from) / t.framerate) +
                        "-" + format_number(static_cast<double>(worst_from + window) / t.framerate) + " s",
                    "1/s^2");
    const int i = static_cast<int>(kmax % static_cast<size_t>(worst.nx)), j = static_cast<int>(kmax / static_cast<size_t>(worst.nx));
    summary["crowd_pressure"] = {{"radius_m", spec.pressure_radius},
                                 {"window_s", spec.pressure_window},
                                 {"max", worst.max_pressure()},
                                 {"at", {worst.lo.x() + i * worst.cell, worst.lo.y() + j * worst.cell}},
                                 {"window_from_s", static_cast<double>(worst_from) / t.framerate},
                                 {"turbulence_onset_exceeded", worst.max_pressure() > 0.02},
                                 {"windows", windows},
                                 {"files", {"crowd_pressure.csv", "crowd_pressure.png"}}};
  }
  save_json_file(summary, file("summary.json"));
  return summary;
}

}  // namespace crowdmpm
