#include "engine/geometry/geometry.hpp"

#include <algorithm>
#include <cmath>

namespace crowdmpm {

double Geometry::free_area(const Shape& region, double clearance) const {
  const Vec2 a = region.lo.cwiseMax(lo), b = region.hi.cwiseMin(hi);
  if (!(b.x() > a.x() && b.y() > a.y())) return 0;
  const double h = std::max(0.05, std::sqrt((b.x() - a.x()) * (b.y() - a.y()) / 4e6));
  // Counted as well as compared: a step below the spacing of doubles there would never end.
  const long nx = static_cast<long>(std::ceil((b.x() - a.x()) / h)) + 1, ny = static_cast<long>(std::ceil((b.y() - a.y()) / h)) + 1;
  long free_cells = 0;
  double y = a.y() + h / 2;
  for (long j = 0; j < ny && y < b.y(); ++j, y += h) {
    double x = a.x() + h / 2;
    for (long i = 0; i < nx && x < b.x(); ++i, x += h) free_cells += region.contains(Vec2(x, y)) && sdf(Vec2(x, y)) >= clearance;
  }
  return static_cast<double>(free_cells) * h * h;
}

double Geometry::sdf(const Vec2& p) const {
  double d = std::min(std::min(p.x() - lo.x(), hi.x() - p.x()), std::min(p.y() - lo.y(), hi.y() - p.y()));
  for (const auto& s : solids) {
    // Bounding-box distance is a lower bound of the shape distance: skip far shapes.
    Vec2 q = p.cwiseMax(s.lo).cwiseMin(s.hi);
    if ((q - p).norm() >= d) continue;
    d = std::min(d, s.sdf(p));
  }
  return d;
}

Vec2 Geometry::sdf_gradient(const Vec2& p) const {
  const double h = 1e-5;
  return Vec2((sdf(p + Vec2(h, 0)) - sdf(p - Vec2(h, 0))) / (2 * h), (sdf(p + Vec2(0, h)) - sdf(p - Vec2(0, h))) / (2 * h));
}

Vec2 Geometry::normal(const Vec2& p) const {
  const Vec2 g = sdf_gradient(p);
  double n = g.norm();
  return n > 1e-12 ? Vec2(g / n) : Vec2(0, 0);
}

int Geometry::exit_at(const Vec2& p) const {
  for (size_t i = 0; i < exits.size(); ++i)
    if (exits[i].shape.contains(p)) return static_cast<int>(i);
  return -1;
}

const NamedShape* Geometry::find_target(const std::string& id) const {
  for (const auto& e : exits)
    if (e.id == id) return &e;
  for (const auto& g : goals)
    if (g.id == id) return &g;
  return nullptr;
}

}  // namespace crowdmpm
