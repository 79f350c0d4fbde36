#include "engine/observe/pedestrian_measures.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/geometry/shape.hpp"

namespace crowdmpm {

namespace {

double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

double signed_area(const Polygon2& p) {
  double s = 0;
  for (size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) s += cross(p[j], p[i]);
  return 0.5 * s;
}

// The part of a convex polygon on the side (x - o) . n <= 0 (Sutherland-Hodgman, one edge).
Polygon2 clip_halfplane(const Polygon2& poly, const Vec2& o, const Vec2& n) {
  Polygon2 out;
  const size_t m = poly.size();
  for (size_t i = 0; i < m; ++i) {
    const Vec2& a = poly[i];
    const Vec2& b = poly[(i + 1) % m];
    const double da = (a - o).dot(n), db = (b - o).dot(n);
    if (da <= 0) out.push_back(a);
    if ((da < 0 && db > 0) || (da > 0 && db < 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

// Convex a ∩ convex b (b counter-clockwise).
Polygon2 clip_convex(Polygon2 a, const Polygon2& b) {
  for (size_t i = 0; i < b.size() && a.size() >= 3; ++i) {
    const Vec2 e = b[(i + 1) % b.size()] - b[i];
    a = clip_halfplane(a, b[i], Vec2(e.y(), -e.x()));  // outward normal of a ccw edge
  }
  return a.size() >= 3 ? a : Polygon2{};
}

Polygon2 ccw(Polygon2 p) {
  if (signed_area(p) < 0) std::reverse(p.begin(), p.end());
  return p;
}

// Length of the part of segment a-b inside a convex polygon (ccw).
double segment_inside(const Vec2& a, const Vec2& b, const Polygon2& conv) {
  double t0 = 0, t1 = 1;
  const Vec2 d = b - a;
  for (size_t i = 0; i < conv.size(); ++i) {
    const Vec2 e = conv[(i + 1) % conv.size()] - conv[i];
    const Vec2 n(e.y(), -e.x());
    const double num = (a - conv[i]).dot(n), den = d.dot(n);  // inside: num + s den <= 0
    if (std::abs(den) < 1e-15) {
      if (num > 0) return 0;
      continue;
    }
    const double s = -num / den;
    if (den > 0) t1 = std::min(t1, s);
    else t0 = std::max(t0, s);
    if (t0 >= t1) return 0;
  }
  return (t1 - t0) * d.norm();
}

// Strictly inside (shapely's contains): even-odd test, and a point on an edge is outside.
bool strictly_inside(const Polygon2& poly, const Vec2& p) {
  bool inside = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Vec2 &a = poly[i], &b = poly[j];
    const Vec2 ab = b - a;
    if (std::abs(cross(ab, p - a)) <= 1e-12 * std::max(1.0, ab.norm()) && (p - a).dot(p - b) <= 0) return false;
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < ab.x() * (p.y() - a.y()) / ab.y() + a.x()) inside = !inside;
  }
  return inside;
}

bool in_triangle(const Vec2& p, const Polygon2& tri) {
  const double c0 = cross(tri[1] - tri[0], p - tri[0]), c1 = cross(tri[2] - tri[1], p - tri[1]),
               c2 = cross(tri[0] - tri[2], p - tri[2]);
  return c0 >= 0 && c1 >= 0 && c2 >= 0;
}

double point_triangle_distance(const Vec2& p, const Polygon2& tri) {
  if (in_triangle(p, tri)) return 0;
  double d = 1e300;
  for (size_t i = 0; i < 3; ++i) {
    const Vec2 a = tri[i], b = tri[(i + 1) % 3];
    const Vec2 ab = b - a;
    const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    d = std::min(d, (a + ab * s - p).norm());
  }
  return d;
}

// The walkable area as triangles with their shared edges, for clipping Voronoi cells.
struct Triangulated {
  std::vector<Polygon2> tris;                                  // ccw
  std::vector<std::tuple<size_t, size_t, Vec2, Vec2>> shared;  // triangle pair and their common edge
};

Triangulated triangulated(const Polygon2& poly, const std::string& what) {
  Triangulated t;
  t.tris = triangulate(poly, what);
  for (auto& tri : t.tris) tri = ccw(tri);
  for (size_t i = 0; i < t.tris.size(); ++i)
    for (size_t j = i + 1; j < t.tris.size(); ++j)
      for (size_t a = 0; a < 3; ++a)
        for (size_t b = 0; b < 3; ++b) {
          const Vec2 &p = t.tris[i][a], &q = t.tris[i][(a + 1) % 3];
          const Vec2 &r = t.tris[j][b], &s = t.tris[j][(b + 1) % 3];
          if ((p - s).norm() < 1e-12 && (q - r).norm() < 1e-12) t.shared.emplace_back(i, j, p, q);
        }
  return t;
}

size_t find_root(std::vector<size_t>& parent, size_t i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

double polygon_area(const Polygon2& p) { return p.size() < 3 ? 0 : std::abs(signed_area(p)); }

std::vector<Polygon2> triangulate(const Polygon2& input, const std::string& what) {
  if (input.size() < 3) throw Error(what + ": a polygon needs at least 3 points");
  for (const Vec2& q : input)
    if (!std::isfinite(q.x()) || !std::isfinite(q.y()) || std::abs(q.x()) > 1e7 || std::abs(q.y()) > 1e7)
      throw Error(what + ": coordinates must be finite and within 1e7 m");
  Polygon2 p = ccw(input);
  if (p.size() > 3 && (p.front() - p.back()).norm() < 1e-12) p.pop_back();  // a ring that lists its start twice
  if (!(polygon_area(p) >= 1e-6)) throw Error(what + ": polygon has no area (below 1e-6 m^2)");
  // No two edges that are not neighbours may meet (a self-intersecting ring).
  const size_t n = p.size();
  auto side = [](const Vec2& a, const Vec2& b, const Vec2& c) { return cross(b - a, c - a); };
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) {
      if (j == i + 1 || (i == 0 && j == n - 1)) continue;
      const Vec2 &a = p[i], &b = p[(i + 1) % n], &c = p[j], &d = p[(j + 1) % n];
      const double d1 = side(c, d, a), d2 = side(c, d, b), d3 = side(a, b, c), d4 = side(a, b, d);
      const bool proper = ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
      const bool touch = segment_distance(a, c, d) < 1e-12 || segment_distance(b, c, d) < 1e-12 ||
                         segment_distance(c, a, b) < 1e-12 || segment_distance(d, a, b) < 1e-12;
      if (proper || touch)
        throw Error(what + ": polygon is self-intersecting (edges " + std::to_string(i + 1) + " and " + std::to_string(j + 1) + " meet)");
    }
  std::vector<size_t> idx(p.size());
  std::iota(idx.begin(), idx.end(), size_t{0});
  std::vector<Polygon2> out;
  size_t guard = 0;
  while (idx.size() > 3) {
    bool cut = false;
    for (size_t k = 0; k < idx.size(); ++k) {
      const Vec2 &a = p[idx[(k + idx.size() - 1) % idx.size()]], &b = p[idx[k]], &c = p[idx[(k + 1) % idx.size()]];
      if (cross(b - a, c - b) <= 1e-14) continue;  // reflex or flat
      bool empty = true;
      const Polygon2 tri{a, b, c};
      for (size_t m = 0; m < idx.size() && empty; ++m) {
        const Vec2& q = p[idx[m]];
        if (m == k || m == (k + 1) % idx.size() || m == (k + idx.size() - 1) % idx.size()) continue;
        if ((q - a).norm() < 1e-12 || (q - b).norm() < 1e-12 || (q - c).norm() < 1e-12) continue;
        if (in_triangle(q, tri)) empty = false;
      }
      if (!empty) continue;
      out.push_back(tri);
      idx.erase(idx.begin() + static_cast<long>(k));
      cut = true;
      break;
    }
    if (!cut || ++guard > 4 * p.size())
      throw Error(what + ": polygon could not be triangulated (self-intersecting?)");
  }
  out.push_back({p[idx[0]], p[idx[1]], p[idx[2]]});
  double sum = 0;
  for (const auto& tri : out) sum += polygon_area(tri);
  if (std::abs(sum - polygon_area(p)) > 1e-9 * std::max(1.0, polygon_area(p)))
    throw Error(what + ": polygon is self-intersecting");
  return out;
}

std::vector<Vec2> individual_velocities(const TrajectorySet& t, long n) {
  if (n < 1) throw Error("frame_step must be at least 1, got " + std::to_string(n));
  std::map<long, std::map<long, size_t>> rows;  // id -> frame -> index
  for (size_t i = 0; i < t.points.size(); ++i) rows[t.points[i].id][t.points[i].frame] = i;
  std::vector<Vec2> v(t.points.size(), Vec2::Zero());
  for (const auto& [id, frames] : rows)
    for (const auto& [f, i] : frames) {
      auto past = frames.find(f - n), future = frames.find(f + n);
      const Vec2 x(t.points[i].x, t.points[i].y);
      auto at = [&](size_t k) { return Vec2(t.points[k].x, t.points[k].y); };
      if (past != frames.end() && future != frames.end())
        v[i] = (at(future->second) - at(past->second)) * (t.framerate / (2.0 * static_cast<double>(n)));
      else if (future != frames.end())
        v[i] = (at(future->second) - x) * (t.framerate / static_cast<double>(n));
      else if (past != frames.end())
        v[i] = (x - at(past->second)) * (t.framerate / static_cast<double>(n));
    }
  return v;
}

std::vector<double> individual_speeds(const TrajectorySet& t, long n) {
  std::vector<double> s;
  for (const Vec2& v : individual_velocities(t, n)) s.push_back(v.norm());
  return s;
}

std::vector<AreaFrame> measure_area(const TrajectorySet& t, const Polygon2& area, const Polygon2& walkable,
                                    const std::vector<double>& speeds, double cutoff_radius, int cutoff_edges) {
  if (speeds.size() != t.points.size()) throw Error("measure_area: one speed per trajectory point is needed");
  if (cutoff_radius < 0 || (cutoff_radius > 0 && (cutoff_edges < 3 || cutoff_edges > 1000)))
    throw Error("Voronoi cut-off: radius must be >= 0 and edges in [3, 1000]");
  const double area_m2 = polygon_area(area);
  std::vector<Polygon2> area_tris = triangulate(area, "measurement area");
  for (auto& tri : area_tris) tri = ccw(tri);
  const Triangulated walk = triangulated(walkable, "walkable area");
  Vec2 wlo = walkable[0], whi = walkable[0];
  for (const Vec2& q : walkable) wlo = wlo.cwiseMin(q), whi = whi.cwiseMax(q);
  const double margin = 1 + (whi - wlo).norm();
  const Polygon2 box{wlo - Vec2(margin, margin), Vec2(whi.x() + margin, wlo.y() - margin), whi + Vec2(margin, margin),
                     Vec2(wlo.x() - margin, whi.y() + margin)};
  std::vector<AreaFrame> out;
  std::vector<Vec2> pts;
  // Recorded frames only: a gap in the recording has no rows to write (skip_gap).
  for (long f = t.frame_min(); f <= t.frame_max(); f = t.skip_gap(f + 1, 1)) {
    AreaFrame r;
    r.frame = f;
    r.time = static_cast<double>(f) / t.framerate;
    auto [b, e] = t.frame(f);
    r.people = e - b;
    pts.clear();
    for (auto p = b; p != e; ++p) pts.emplace_back(p->x, p->y);
    double speed_sum = 0;
    for (auto p = b; p != e; ++p)
      if (strictly_inside(area, Vec2(p->x, p->y))) {
        ++r.inside;
        speed_sum += speeds[static_cast<size_t>(p - t.points.data())];
      }
    r.classic_density = static_cast<double>(r.inside) / area_m2;
    r.classic_speed = r.inside ? speed_sum / static_cast<double>(r.inside) : 0;
    // People bucketed on a grid of about two per bucket, for nearest-first neighbour search.
    Vec2 plo = pts.empty() ? Vec2::Zero() : pts[0], phi = plo;
    for (const Vec2& q : pts) plo = plo.cwiseMin(q), phi = phi.cwiseMax(q);
    const double extent = std::max({phi.x() - plo.x(), phi.y() - plo.y(), 1e-3});
    const double bucket = std::max(0.25, extent * std::sqrt(2.0 / std::max<double>(1.0, static_cast<double>(pts.size()))));
    const int bx = static_cast<int>((phi.x() - plo.x()) / bucket) + 1, by = static_cast<int>((phi.y() - plo.y()) / bucket) + 1;
    std::vector<std::vector<size_t>> buckets(static_cast<size_t>(bx) * static_cast<size_t>(by));
    auto bucket_of = [&](const Vec2& q) {
      return std::pair<int, int>(std::min(bx - 1, static_cast<int>((q.x() - plo.x()) / bucket)),
                                 std::min(by - 1, static_cast<int>((q.y() - plo.y()) / bucket)));
    };
    for (size_t k = 0; k < pts.size(); ++k) {
      const auto [ix, iy] = bucket_of(pts[k]);
      buckets[static_cast<size_t>(iy) * static_cast<size_t>(bx) + static_cast<size_t>(ix)].push_back(k);
    }
    for (size_t i = 0; i < pts.size(); ++i) {
      // The Voronoi cell: the box cut by the bisector with every other person, ring of buckets
      // by ring, until everyone not yet seen is farther than twice the cell's reach.
      Polygon2 cell = box;
      if (cutoff_radius > 0) {  // start from the cut-off polygon (counter-clockwise) instead
        cell.clear();
        for (int k = 0; k < cutoff_edges; ++k) {
          const double a = 2 * M_PI * k / cutoff_edges;
          cell.push_back(pts[i] + cutoff_radius * Vec2(std::cos(a), std::sin(a)));
        }
      }
      const auto [cx, cy] = bucket_of(pts[i]);
      for (int ring = 0; cell.size() >= 3; ++ring) {
        double reach = 0;
        for (const Vec2& q : cell) reach = std::max(reach, (q - pts[i]).norm());
        if (ring > 0 && static_cast<double>(ring - 1) * bucket > 2 * reach) break;  // rings >= ring are at least (ring-1) buckets away
        if (ring > std::max(bx, by)) break;
        for (int iy = cy - ring; iy <= cy + ring; ++iy)
          for (int ix = cx - ring; ix <= cx + ring; ++ix) {
            if (std::max(std::abs(ix - cx), std::abs(iy - cy)) != ring || ix < 0 || iy < 0 || ix >= bx || iy >= by) continue;
            for (size_t j : buckets[static_cast<size_t>(iy) * static_cast<size_t>(bx) + static_cast<size_t>(ix)]) {
              const Vec2 d = pts[j] - pts[i];
              if (j == i || d.norm() < 1e-12) continue;  // two people at one point share the cell
              cell = clip_halfplane(cell, (pts[i] + pts[j]) * 0.5, d);
              if (cell.size() < 3) break;
            }
          }
      }
      if (cell.size() < 3) continue;
      // Clipped by the walkable area: pieces per triangle, joined across shared edges that the
      // cell covers; the component holding the person (or nearest to it) is the cell.
      std::vector<Polygon2> pieces(walk.tris.size());
      for (size_t k = 0; k < walk.tris.size(); ++k) pieces[k] = clip_convex(walk.tris[k], cell);
      std::vector<size_t> parent(walk.tris.size());
      std::iota(parent.begin(), parent.end(), size_t{0});
      for (const auto& [ti, tj, ea, eb] : walk.shared)
        if (!pieces[ti].empty() && !pieces[tj].empty() && segment_inside(ea, eb, cell) > 1e-9)
          parent[find_root(parent, ti)] = find_root(parent, tj);
      size_t home = walk.tris.size();
      double best = 1e300;
      for (size_t k = 0; k < walk.tris.size(); ++k) {
        if (pieces[k].empty()) continue;
        const double d = point_triangle_distance(pts[i], walk.tris[k]);
        if (d < best) best = d, home = k;
      }
      if (home == walk.tris.size()) continue;
      const size_t root = find_root(parent, home);
      double cell_area = 0, in_area = 0;
      for (size_t k = 0; k < walk.tris.size(); ++k) {
        if (pieces[k].empty() || find_root(parent, k) != root) continue;
        cell_area += polygon_area(pieces[k]);
        for (const auto& at : area_tris) in_area += polygon_area(clip_convex(pieces[k], at));
      }
      if (cell_area <= 0 || in_area <= 0) continue;
      r.voronoi_density += in_area / cell_area;
      r.voronoi_speed += in_area * speeds[static_cast<size_t>(b - t.points.data()) + i];
    }
    r.voronoi_density /= area_m2;
    r.voronoi_speed /= area_m2;
    out.push_back(r);
  }
  return out;
}

std::vector<LineCount> crossings(const TrajectorySet& t, const Vec2& a, const Vec2& b) {
  if ((b - a).norm() <= 0) throw Error("measurement line: its two points coincide");
  auto on_line = [&](const Vec2& p) { return segment_distance(p, a, b) < 1e-5; };
  auto intersects = [&](const Vec2& p, const Vec2& q) {
    const double d1 = cross(b - a, p - a), d2 = cross(b - a, q - a), d3 = cross(q - p, a - p), d4 = cross(q - p, b - p);
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
    return on_line(p) || on_line(q) || segment_distance(a, p, q) < 1e-12 || segment_distance(b, p, q) < 1e-12;
  };
  std::map<long, std::vector<const TrackPoint*>> rows;
  for (const auto& p : t.points) rows[p.id].push_back(&p);  // frame order: points are sorted by frame
  std::map<long, long> per_frame;
  for (const auto& [id, r] : rows)
    for (size_t k = 1; k < r.size(); ++k) {
      const Vec2 p(r[k - 1]->x, r[k - 1]->y), q(r[k]->x, r[k]->y);
      if (intersects(p, q)) {
        ++per_frame[r[k]->frame];
        break;
      }
    }
  std::vector<LineCount> out;
  long total = 0;
  for (long f = t.frame_min(); f <= t.frame_max(); f = t.skip_gap(f + 1, 1)) {
    auto it = per_frame.find(f);
    if (it != per_frame.end()) total += it->second;
    out.push_back({f, static_cast<double>(f) / t.framerate, total});
  }
  return out;
}

double PressureField::max_pressure() const {
  return pressure.empty() ? 0 : *std::max_element(pressure.begin(), pressure.end());
}

FieldFrame PressureField::grid() const {
  FieldFrame f;
  f.origin = lo;
  f.dx = cell;
  f.nx = nx;
  f.ny = ny;
  return f;
}

PressureField crowd_pressure(const TrajectorySet& t, const std::vector<Vec2>& velocities, long frame_begin,
                             long frame_end, const Vec2& lo, const Vec2& hi, double cell, double R) {
  if (velocities.size() != t.points.size()) throw Error("crowd pressure: one velocity per trajectory point is needed");
  if (!(cell > 0) || !(R > 0)) throw Error("crowd pressure: cell and R must be > 0");
  if (!(hi.x() > lo.x() && hi.y() > lo.y())) throw Error("crowd pressure: empty region");
  PressureField pf;
  pf.lo = lo;
  pf.cell = cell;
  // At most 4 million nodes (about 250 MB of work arrays): checked before any cast to int.
  const double gx = std::floor((hi.x() - lo.x()) / cell) + 1, gy = std::floor((hi.y() - lo.y()) / cell) + 1;
  if (!(gx * gy <= 4e6))
    throw Error("crowd pressure: a grid of " + format_number(gx) + " x " + format_number(gy) + " nodes (cell " +
                format_number(cell) + " m over " + format_number(hi.x() - lo.x()) + " x " + format_number(hi.y() - lo.y()) +
                " m) is too large: choose a larger cell");
  pf.nx = static_cast<int>(gx);
  pf.ny = static_cast<int>(gy);
  const size_t nodes = static_cast<size_t>(pf.nx) * static_cast<size_t>(pf.ny);
  std::vector<double> rho_sum(nodes, 0), frames_seen(nodes, 0);
  std::vector<Vec2> v_sum(nodes, Vec2::Zero());
  std::vector<double> v2_sum(nodes, 0);
  std::vector<double> w(nodes), wvx(nodes), wvy(nodes);
  const double norm = 1 / (M_PI * R * R), reach = 3 * R;  // exp(-9) cut-off
  long frames = 0;
  for (long f = t.skip_gap(std::max(frame_begin, t.frame_min()), 1); f <= std::min(frame_end, t.frame_max());
       f = t.skip_gap(f + 1, 1)) {
    auto [b, e] = t.frame(f);
    if (b == e) continue;
    ++frames;
    std::fill(w.begin(), w.end(), 0.0);
    std::fill(wvx.begin(), wvx.end(), 0.0);
    std::fill(wvy.begin(), wvy.end(), 0.0);
    for (auto p = b; p != e; ++p) {
      const Vec2 x(p->x, p->y);
      const Vec2& v = velocities[static_cast<size_t>(p - t.points.data())];
      const int i0 = std::max(0, static_cast<int>(std::ceil((x.x() - reach - lo.x()) / cell)));
      const int i1 = std::min(pf.nx - 1, static_cast<int>(std::floor((x.x() + reach - lo.x()) / cell)));
      const int j0 = std::max(0, static_cast<int>(std::ceil((x.y() - reach - lo.y()) / cell)));
      const int j1 = std::min(pf.ny - 1, static_cast<int>(std::floor((x.y() + reach - lo.y()) / cell)));
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) {
          const Vec2 node = lo + Vec2(i * cell, j * cell);
          const double f_w = norm * std::exp(-(node - x).squaredNorm() / (R * R));
          const size_t k = static_cast<size_t>(j) * static_cast<size_t>(pf.nx) + static_cast<size_t>(i);
          w[k] += f_w;
          wvx[k] += f_w * v.x();
          wvy[k] += f_w * v.y();
        }
    }
    for (size_t k = 0; k < nodes; ++k) {
      rho_sum[k] += w[k];
      if (w[k] < 1e-6 * norm) continue;  // nobody within reach: no local velocity
      const Vec2 V(wvx[k] / w[k], wvy[k] / w[k]);
      v_sum[k] += V;
      v2_sum[k] += V.squaredNorm();
      frames_seen[k] += 1;
    }
  }
  if (frames == 0) return PressureField{};  // nobody in the window: no field (pressure empty)
  pf.density.assign(nodes, 0);
  pf.pressure.assign(nodes, 0);
  for (size_t k = 0; k < nodes; ++k) {
    pf.density[k] = rho_sum[k] / static_cast<double>(frames);
    if (frames_seen[k] < 2) continue;
    const Vec2 mean = v_sum[k] / frames_seen[k];
    const double var = std::max(0.0, v2_sum[k] / frames_seen[k] - mean.squaredNorm());
    pf.pressure[k] = pf.density[k] * var;
  }
  return pf;
}

PressurePeak peak_crowd_pressure(const TrajectorySet& t, const std::vector<Vec2>& velocities, long window, const Vec2& lo,
                                 const Vec2& hi, double cell, double R) {
  if (window < 2 || window > 1'000'000'000) throw Error("crowd pressure: a window of " + std::to_string(window) + " frames");
  PressurePeak out;
  for (long f = t.frame_min(); f <= t.frame_max(); f = t.skip_gap(f + window, window)) {
    PressureField p = crowd_pressure(t, velocities, f, f + window - 1, lo, hi, cell, R);
    if (p.pressure.empty()) continue;
    out.windows.emplace_back(static_cast<double>(f) / t.framerate, p.max_pressure());
    if (out.field.pressure.empty() || p.max_pressure() > out.field.max_pressure()) {
      out.field = std::move(p);
      out.from = f;
      out.to = f + window;
    }
  }
  return out;
}

}  // namespace crowdmpm
