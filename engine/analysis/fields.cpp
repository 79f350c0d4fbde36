#include "engine/analysis/fields.hpp"

#include <algorithm>
#include <cmath>

namespace crowdmpm {

FieldFrame compute_fields(const World& w, const Grid& g, double min_density) {
  FieldFrame f;
  f.origin = g.origin;
  f.dx = g.dx;
  f.nx = g.nx;
  f.ny = g.ny;
  const size_t n = g.nodes();
  std::vector<double> wsum(n, 0);
  f.density.assign(n, 0);
  f.pressure.assign(n, 0);
  f.velocity.assign(n, Vec2::Zero());
  const double inv_area = 1.0 / (g.dx * g.dx);
  for (size_t p = 0; p < w.size(); ++p) {
    Stencil s = make_stencil(g.origin, g.dx, g.nx, g.ny, w.x[p]);
    for (int b = 0; b < 3; ++b)
      for (int a = 0; a < 3; ++a) {
        size_t k = static_cast<size_t>(g.node(s.bx + a, s.by + b));
        double weight = s.wx[a] * s.wy[b];
        wsum[k] += weight;
        f.velocity[k] += weight * w.v[p];
        f.pressure[k] += weight * w.pressure[p];
      }
  }
  for (size_t k = 0; k < n; ++k) {
    f.density[k] = wsum[k] * inv_area;
    if (wsum[k] > 0) {
      f.velocity[k] /= wsum[k];
      f.pressure[k] /= wsum[k];
    }
    if (f.density[k] < min_density) f.pressure[k] = 0;
  }
  return f;
}

}  // namespace crowdmpm
