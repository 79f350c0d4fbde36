#include "engine/geometry/shape.hpp"

#include <algorithm>
#include <cmath>

namespace crowdmpm {

double segment_distance(const Vec2& p, const Vec2& a, const Vec2& b) {
  Vec2 ab = b - a;
  double len2 = ab.squaredNorm();
  double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

static void set_bbox(Shape& s) {
  s.lo = Vec2(1e300, 1e300);
  s.hi = -s.lo;
  for (const auto& q : s.points) {
    s.lo = s.lo.cwiseMin(q);
    s.hi = s.hi.cwiseMax(q);
  }
}

Shape Shape::polygon(std::vector<Vec2> pts) {
  Shape s;
  s.kind = Kind::Polygon;
  s.points = std::move(pts);
  set_bbox(s);
  return s;
}

Shape Shape::rect(Vec2 a, Vec2 b) {
  return polygon({a, Vec2(b.x(), a.y()), b, Vec2(a.x(), b.y())});
}

Shape Shape::circle(Vec2 c, double r) {
  Shape s;
  s.kind = Kind::Circle;
  s.center = c;
  s.radius = r;
  s.lo = c - Vec2(r, r);
  s.hi = c + Vec2(r, r);
  return s;
}

Shape Shape::polyline(std::vector<Vec2> pts, double thickness) {
  Shape s;
  s.kind = Kind::Polyline;
  s.points = std::move(pts);
  s.radius = 0.5 * thickness;
  set_bbox(s);
  s.lo -= Vec2(s.radius, s.radius);
  s.hi += Vec2(s.radius, s.radius);
  return s;
}

double Shape::sdf(const Vec2& p) const {
  switch (kind) {
    case Kind::Circle: return (p - center).norm() - radius;
    case Kind::Polyline: {
      double d = 1e300;
      for (size_t i = 0; i + 1 < points.size(); ++i)
        d = std::min(d, segment_distance(p, points[i], points[i + 1]));
      return d - radius;
    }
    case Kind::Polygon: {
      double d = 1e300;
      bool inside = false;
      const size_t n = points.size();
      for (size_t i = 0, j = n - 1; i < n; j = i++) {
        const Vec2& a = points[i];
        const Vec2& b = points[j];
        d = std::min(d, segment_distance(p, a, b));
        if ((a.y() > p.y()) != (b.y() > p.y()) &&
            p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
          inside = !inside;
      }
      return inside ? -d : d;
    }
  }
  return 1e300;
}

bool Shape::contains(const Vec2& p) const {
  if (p.x() < lo.x() || p.y() < lo.y() || p.x() > hi.x() || p.y() > hi.y()) return false;
  if (kind != Kind::Polygon) return sdf(p) < 0;
  bool inside = false;
  const size_t n = points.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Vec2& a = points[i];
    const Vec2& b = points[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      inside = !inside;
  }
  // On an edge counts as outside, as with sdf(p) < 0.
  return inside && sdf(p) < 0;
}

double Shape::area() const {
  switch (kind) {
    case Kind::Circle: return M_PI * radius * radius;
    case Kind::Polyline: {
      double len = 0;
      for (size_t i = 0; i + 1 < points.size(); ++i) len += (points[i + 1] - points[i]).norm();
      return len * 2 * radius;
    }
    case Kind::Polygon: {
      double a = 0;
      for (size_t i = 0, j = points.size() - 1; i < points.size(); j = i++)
        a += points[j].x() * points[i].y() - points[i].x() * points[j].y();
      return std::abs(0.5 * a);
    }
  }
  return 0;
}

static double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

static bool segments_cross(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a);
  double d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}

Shape parse_region(const JsonReader& r, const std::vector<std::string>& other_keys) {
  r.require_object();
  std::vector<std::string> keys = {"rect", "polygon", "circle"};
  keys.insert(keys.end(), other_keys.begin(), other_keys.end());
  r.allow_only(keys);
  int kinds = r.has("rect") + r.has("polygon") + r.has("circle");
  if (kinds != 1) r.fail("must have exactly one of \"rect\", \"polygon\" or \"circle\"");
  if (r.has("rect")) {
    auto rect = std::optional<JsonReader>(r.at("rect"));
    auto v = rect->as_numbers();
    if (v.size() != 4) rect->fail("must be [xmin, ymin, xmax, ymax] (metres)");
    if (!(v[2] > v[0] && v[3] > v[1]))
      rect->fail("must have xmax > xmin and ymax > ymin, got [" + format_number(v[0]) + ", " +
                 format_number(v[1]) + ", " + format_number(v[2]) + ", " + format_number(v[3]) + "]");
    return Shape::rect(Vec2(v[0], v[1]), Vec2(v[2], v[3]));
  }
  if (r.has("circle")) {
    auto c = std::optional<JsonReader>(r.at("circle"));
    c->require_object();
    c->allow_only({"center", "radius"});
    return Shape::circle(c->vec2("center", std::nullopt), c->positive("radius", std::nullopt));
  }
  auto poly = r.at("polygon");
  auto pts = poly.as_points(3);
  Shape s = Shape::polygon(pts);
  if (s.area() < 1e-9) poly.fail("polygon has zero area");
  const size_t n = pts.size();
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j)
      if (segments_cross(pts[i], pts[(i + 1) % n], pts[j], pts[(j + 1) % n]))
        poly.fail("polygon edges " + std::to_string(i) + " and " + std::to_string(j) +
                  " cross each other (self-intersecting)");
  return s;
}

// cos and sin of an angle in degrees, exact at multiples of 90 degrees, so that an arc ending
// there meets a straight wall drawn to the same point without a sliver of a gap.
static Vec2 unit_vector_deg(double deg) {
  double a = std::fmod(deg, 360.0);
  if (a < 0) a += 360;
  if (a == 0) return Vec2(1, 0);
  if (a == 90) return Vec2(0, 1);
  if (a == 180) return Vec2(-1, 0);
  if (a == 270) return Vec2(0, -1);
  const double rad = deg * M_PI / 180;
  return Vec2(std::cos(rad), std::sin(rad));
}

// Chords of an arc lie inside the circle by r (1 - cos(step / 2)); this tolerance keeps a wall
// drawn as an arc within a centimetre of the circle, finer than any body radius.
constexpr double kArcTolerance = 0.01;  // m
constexpr int kArcMaxSegments = 1000;   // every segment costs a distance per agent and step

static std::vector<Vec2> parse_arc(const JsonReader& r) {
  r.require_object();
  r.allow_only({"center", "radius", "from", "to", "segments"});
  const Vec2 c = r.vec2("center", std::nullopt);
  const double radius = r.positive("radius", std::nullopt);
  const double from = r.number("from", std::nullopt), to = r.number("to", std::nullopt);
  const double sweep = std::abs(to - from);
  if (sweep == 0) r.fail_at("to", "must differ from \"from\" (" + format_number(from) + " degrees): the arc has no length");
  if (sweep > 360)
    r.fail_at("to", "must be within 360 degrees of \"from\", got a sweep of " + format_number(sweep) + " degrees");
  int n;
  if (r.has("segments")) {
    n = r.integer("segments", 1, kArcMaxSegments, std::nullopt);
  } else {
    const double step = 2 * std::acos(std::clamp(1 - kArcTolerance / radius, -1.0, 1.0));  // radians
    // At most 45 degrees a segment, so that even a small arc still looks round.
    const double fewest = std::max(std::ceil(sweep / 45), std::ceil(sweep * M_PI / 180 / step));
    n = static_cast<int>(std::min<double>(fewest, kArcMaxSegments));
  }
  if (2 * radius * std::sin(sweep * M_PI / 360 / n) < 1e-9)
    r.fail("is too small: its segments would be shorter than 1e-9 m");
  std::vector<Vec2> pts;
  // The last point is computed from "to" itself, so the arc ends exactly where it was asked to.
  for (int k = 0; k <= n; ++k) pts.push_back(c + radius * unit_vector_deg(k == n ? to : from + (to - from) * k / n));
  return pts;
}

Shape parse_wall(const JsonReader& r) {
  r.require_object();
  if (r.has("points") == r.has("arc")) r.fail("needs exactly one of \"points\" (a polyline) or \"arc\"");
  std::vector<Vec2> pts;
  if (r.has("arc")) {
    // An arc is open, or a whole circle when it sweeps 360 degrees: "closed" does not apply.
    r.allow_only({"id", "arc", "thickness"});
    pts = parse_arc(r.at("arc"));
  } else {
    r.allow_only({"id", "points", "thickness", "closed"});
    auto points = r.at("points");
    pts = points.as_points(2);
    if (r.boolean("closed", false)) pts.push_back(pts.front());
    for (size_t k = 0; k + 1 < pts.size(); ++k) {
      if ((pts[k + 1] - pts[k]).norm() >= 1e-9) continue;
      if (k + 1 == points.size())  // the point "closed" appended
        r.fail_at("closed", "the last point already equals the first (zero-length wall segment): leave it out");
      points.item(k + 1).fail("repeats the previous point (zero-length wall segment)");
    }
  }
  return Shape::polyline(pts, r.in_range("thickness", 0.01, 10, 0.2));
}

}  // namespace crowdmpm
