#include "engine/losses.hpp"

#include <cmath>
#include <limits>

#include "engine/error.hpp"

namespace crowdmpm {

long TrajectoryTarget::samples() const {
  long n = 0;
  for (const auto& row : targets)
    for (const Vec2& t : row) n += t.allFinite() ? 1 : 0;
  return n;
}

void trajectory_loss_at(const std::vector<Vec2>& x, const std::vector<Vec2>& target, double weight, double& loss,
                        std::vector<Vec2>* dL_dx) {
  if (x.size() != target.size())
    throw Error("trajectory loss: " + std::to_string(x.size()) + " positions against " + std::to_string(target.size()) +
                " targets");
  for (size_t p = 0; p < x.size(); ++p) {
    if (!target[p].allFinite()) continue;
    const Vec2 d = x[p] - target[p];
    loss += weight * d.squaredNorm();
    if (dL_dx) (*dL_dx)[p] += 2 * weight * d;
  }
}

double GridVelocityField::mask_sum() const {
  double s = 0;
  for (double m : mask) s += m;
  return s;
}

namespace {
// Calls fn(node, w, dw/dx) for the 9 nodes of x's stencil; nothing for a point whose stencil
// does not fit on the grid (make_stencil would clamp it, and its weights mean nothing there).
template <class F>
void for_stencil(const Vec2& origin, double dx, int nx, int ny, const Vec2& x, F&& fn) {
  const double bx = std::floor((x.x() - origin.x()) / dx - 0.5), by = std::floor((x.y() - origin.y()) / dx - 0.5);
  if (!(bx >= 0 && by >= 0 && bx <= nx - 3 && by <= ny - 3)) return;
  const Stencil s = make_stencil(origin, dx, nx, ny, x);
  double dwx[3], dwy[3];
  stencil_weight_gradients(s, dx, dwx, dwy);
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const int node = (s.by + j) * nx + (s.bx + i);
      fn(static_cast<size_t>(node), s.wx[i] * s.wy[j], Vec2(dwx[i] * s.wy[j], s.wx[i] * dwy[j]));
    }
}

void check_field(const GridVelocityField& f, const Grid& g) {
  if (f.nx != g.nx || f.ny != g.ny || std::abs(f.dx - g.dx) > 1e-12 || (f.origin - g.origin).norm() > 1e-9 ||
      f.velocity.size() != g.nodes() || f.mask.size() != g.nodes())
    throw Error("grid velocity loss: the observed field's grid (" + std::to_string(f.nx) + " x " + std::to_string(f.ny) +
                " nodes, spacing " + std::to_string(f.dx) + " m) differs from the simulation's (" + std::to_string(g.nx) +
                " x " + std::to_string(g.ny) + ", " + std::to_string(g.dx) + " m)");
}

void accumulate(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& g,
                std::vector<double>& M, std::vector<Vec2>& P) {
  M.assign(g.nodes(), 0);
  P.assign(g.nodes(), Vec2::Zero());
  for (size_t p = 0; p < x.size(); ++p)
    for_stencil(g.origin, g.dx, g.nx, g.ny, x[p], [&](size_t i, double w, const Vec2&) {
      M[i] += w * mass;
      P[i] += w * mass * v[p];
    });
}
}  // namespace

GridVelocityField grid_velocity_of(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass,
                                   const Grid& shape, double min_mass) {
  GridVelocityField f;
  f.origin = shape.origin;
  f.dx = shape.dx;
  f.nx = shape.nx;
  f.ny = shape.ny;
  std::vector<double> M;
  std::vector<Vec2> P;
  accumulate(x, v, mass, shape, M, P);
  f.velocity.assign(shape.nodes(), Vec2::Zero());
  f.mask.assign(shape.nodes(), 0);
  for (size_t i = 0; i < shape.nodes(); ++i)
    if (M[i] >= min_mass && M[i] > 0) {
      f.velocity[i] = P[i] / M[i];
      f.mask[i] = 1;
    }
  return f;
}

double grid_velocity_loss(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& shape,
                          const GridVelocityField& observed, std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv) {
  check_field(observed, shape);
  const double norm = observed.mask_sum();
  if (norm <= 0) return 0;
  std::vector<double> M;
  std::vector<Vec2> P;
  accumulate(x, v, mass, shape, M, P);
  double loss = 0;
  // dL/dP_i and dL/dM_i of f_i = M |P/M - u|^2 (times mask / norm).
  std::vector<Vec2> dP(shape.nodes(), Vec2::Zero());
  std::vector<double> dM(shape.nodes(), 0);
  for (size_t i = 0; i < shape.nodes(); ++i) {
    const double m = observed.mask[i];
    if (m <= 0 || M[i] < 1e-9) continue;
    const Vec2 vel = P[i] / M[i], r = vel - observed.velocity[i];
    loss += m * M[i] * r.squaredNorm() / norm;
    dP[i] = 2 * m * r / norm;
    dM[i] = m * (r.squaredNorm() - 2 * r.dot(vel)) / norm;
  }
  if (dL_dx || dL_dv)
    for (size_t p = 0; p < x.size(); ++p)
      for_stencil(shape.origin, shape.dx, shape.nx, shape.ny, x[p], [&](size_t i, double w, const Vec2& dw) {
        if (M[i] < 1e-9) return;
        if (dL_dv) (*dL_dv)[p] += w * mass * dP[i];
        if (dL_dx) (*dL_dx)[p] += mass * (dP[i].dot(v[p]) + dM[i]) * dw;
      });
  return loss;
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
