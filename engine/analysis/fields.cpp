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
    for_each_stencil_node(s, g.nx, g.dx, [&](const StencilNode& nd) {
      wsum[nd.k] += nd.w;
      f.velocity[nd.k] += nd.w * w.v[p];
      f.pressure[nd.k] += nd.w * w.pressure[p];
    });
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
