#include "engine/learn/losses.hpp"

#include <cmath>
#include <limits>

#include "engine/core/error.hpp"

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

namespace {
void check_field(const GridVelocityField& f, const Grid& g) {
  if (f.nx != g.nx || f.ny != g.ny || std::abs(f.dx - g.dx) > 1e-12 || (f.origin - g.origin).norm() > 1e-9 ||
      f.velocity.size() != g.nodes() || f.mask.size() != g.nodes())
    throw Error("grid velocity loss: the observed field's grid (" + std::to_string(f.nx) + " x " + std::to_string(f.ny) +
                " nodes, spacing " + std::to_string(f.dx) + " m) differs from the simulation's (" + std::to_string(g.nx) +
                " x " + std::to_string(g.ny) + ", " + std::to_string(g.dx) + " m)");
}

}  // namespace

double grid_velocity_loss(const std::vector<Vec2>& x, const std::vector<Vec2>& v, double mass, const Grid& shape,
                          const GridVelocityField& observed, std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv,
                          double empty_mass) {
  check_field(observed, shape);
  const double norm = observed.mask_sum();
  if (norm <= 0) return 0;
  std::vector<double> M;
  std::vector<Vec2> P;
  grid_mass_momentum(x, v, mass, shape, M, P);
  double loss = 0;
  // dL/dP_i and dL/dM_i of f_i = M |P/M - u|^2 (times mask / norm).
  std::vector<Vec2> dP(shape.nodes(), Vec2::Zero());
  std::vector<double> dM(shape.nodes(), 0);
  for (size_t i = 0; i < shape.nodes(); ++i) {
    const double m = observed.mask[i];
    if (m <= 0) continue;
    if (empty_mass > 0) {
      // f_i = |P / max(M, m0) - u|^2: dP = 2 r / max(M, m0); dM = -2 r . vel / M above m0, 0 below.
      const double D = std::max(M[i], empty_mass);
      const Vec2 vel = P[i] / D, r = vel - observed.velocity[i];
      loss += m * r.squaredNorm() / norm;
      dP[i] = 2 * m * r / (D * norm);
      dM[i] = M[i] >= empty_mass ? -2 * m * r.dot(vel) / (M[i] * norm) : 0.0;
      continue;
    }
    if (M[i] < 1e-9) continue;
    const Vec2 vel = P[i] / M[i], r = vel - observed.velocity[i];
    loss += m * M[i] * r.squaredNorm() / norm;
    dP[i] = 2 * m * r / norm;
    dM[i] = m * (r.squaredNorm() - 2 * r.dot(vel)) / norm;
  }
  if (dL_dx || dL_dv)
    for (size_t p = 0; p < x.size(); ++p)
      for_stencil_on_grid(shape.origin, shape.dx, shape.nx, shape.ny, x[p], [&](size_t i, double w, const Vec2& dw) {
        if (M[i] < 1e-9) return;
        if (dL_dv) (*dL_dv)[p] += w * mass * dP[i];
        if (dL_dx) (*dL_dx)[p] += mass * (dP[i].dot(v[p]) + dM[i]) * dw;
      });
  return loss;
}

namespace {
// chi(x) = 1 / (1 + exp(sdf / edge)) and its gradient (central differences of the sdf).
double soft_inside(const Shape& a, const Vec2& p, Vec2* grad) {
  const double z = a.sdf(p) / kAreaEdge;
  const double chi = z > 0 ? std::exp(-z) / (1 + std::exp(-z)) : 1 / (1 + std::exp(z));
  if (grad) {
    const double h = 1e-6;
    const Vec2 g((a.sdf(p + Vec2(h, 0)) - a.sdf(p - Vec2(h, 0))) / (2 * h), (a.sdf(p + Vec2(0, h)) - a.sdf(p - Vec2(0, h))) / (2 * h));
    *grad = -chi * (1 - chi) / kAreaEdge * g;
  }
  return chi;
}
}  // namespace

double area_loss_at(const std::vector<Shape>& areas, const std::vector<Vec2>& x, const std::vector<Vec2>& v,
                    const std::vector<Vec2>& seen_x, const std::vector<Vec2>& seen_v, double weight,
                    std::vector<Vec2>* dL_dx, std::vector<Vec2>* dL_dv) {
  const size_t n = x.size();
  if (v.size() != n || seen_x.size() != n || seen_v.size() != n)
    throw Error("area loss: " + std::to_string(n) + " positions, " + std::to_string(v.size()) + " velocities against " +
                std::to_string(seen_x.size()) + " recorded positions and " + std::to_string(seen_v.size()) + " velocities");
  double loss = 0;
  for (const Shape& a : areas) {
    const double A = a.area();
    if (!(A > 0)) throw Error("area loss: a measurement area has no area");
    double rho = 0, rho_seen = 0;
    Vec2 q = Vec2::Zero(), q_seen = Vec2::Zero();
    for (size_t p = 0; p < n; ++p) {
      if (!seen_x[p].allFinite()) continue;
      const double c = soft_inside(a, x[p], nullptr), c_seen = soft_inside(a, seen_x[p], nullptr);
      rho += c;
      rho_seen += c_seen;
      if (!seen_v[p].allFinite()) continue;
      q += c * v[p];
      q_seen += c_seen * seen_v[p];
    }
    const double d_rho = (rho - rho_seen) / A;
    const Vec2 d_q = (q - q_seen) / A;
    loss += d_rho * d_rho + d_q.squaredNorm();
    if (!dL_dx && !dL_dv) continue;
    for (size_t p = 0; p < n; ++p) {
      if (!seen_x[p].allFinite()) continue;
      Vec2 g;
      const double c = soft_inside(a, x[p], &g);
      const bool moving = seen_v[p].allFinite();
      if (dL_dx) (*dL_dx)[p] += weight * 2 / A * (d_rho + (moving ? d_q.dot(v[p]) : 0.0)) * g;
      if (moving && dL_dv) (*dL_dv)[p] += weight * 2 / A * c * d_q;
    }
  }
  return weight * loss;
}

}  // namespace crowdmpm
