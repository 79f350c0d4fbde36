#include "engine/analysis/grid_velocity.hpp"

#include <cmath>
#include <limits>

#include "engine/core/error.hpp"

namespace crowdmpm {

double GridVelocityField::mask_sum() const {
  double s = 0;
  for (double m : mask) s += m;
  return s;
}

void grid_mass_momentum(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& g,
                std::vector<double>& M, std::vector<Vec2>& P) {
  M.assign(g.nodes(), 0);
  P.assign(g.nodes(), Vec2::Zero());
  for (size_t p = 0; p < x.size(); ++p)
    for_stencil_on_grid(g.origin, g.dx, g.nx, g.ny, x[p], [&](size_t i, double w, const Vec2&) {
      M[i] += w * mass;
      P[i] += w * mass * v[p];
    });
}

GridVelocityField grid_velocity_of(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass,
                                   const Grid& shape, double min_mass) {
  GridVelocityField f;
  f.origin = shape.origin;
  f.dx = shape.dx;
  f.nx = shape.nx;
  f.ny = shape.ny;
  std::vector<double> M;
  std::vector<Vec2> P;
  grid_mass_momentum(x, v, mass, shape, M, P);
  f.velocity.assign(shape.nodes(), Vec2::Zero());
  f.mask.assign(shape.nodes(), 0);
  for (size_t i = 0; i < shape.nodes(); ++i)
    if (M[i] >= min_mass && M[i] > 0) {
      f.velocity[i] = P[i] / M[i];
      f.mask[i] = 1;
    }
  return f;
}

double grid_velocity_rms(const GridVelocityField& a, const GridVelocityField& b) {
  if (a.velocity.size() != b.velocity.size()) throw Error("grid_velocity_rms: fields on different grids");
  double s = 0;
  long n = 0;
  for (size_t i = 0; i < a.velocity.size(); ++i)
    if (a.mask[i] > 0 && b.mask[i] > 0) {
      s += (a.velocity[i] - b.velocity[i]).squaredNorm();
      ++n;
    }
  return n ? std::sqrt(s / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace crowdmpm
