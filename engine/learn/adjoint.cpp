#include "engine/learn/adjoint.hpp"

#include <cmath>

namespace crowdmpm {

void TractionAdjoint::reset(size_t n, size_t np) {
  x.assign(n, Vec2::Zero());
  v.assign(n, Vec2::Zero());
  heading.assign(n, Vec2::Zero());
  comfort.assign(n, 0);
  network.assign(np, 0);
}

void contact_potential_grad(double d, double theta1, double c, double eps, double& dphi_dd, double& dphi_dc) {
  dphi_dc = 1 / c;  // both branches carry + log c
  dphi_dd = d >= theta1 + eps ? -1 / (d - theta1) : -1 / eps;
}

// Turning a vector by +90 degrees, perp(a) = (-a_y, a_x), is linear; its adjoint turns back.
static inline Vec2 perp(const Vec2& a) { return Vec2(-a.y(), a.x()); }
static inline Vec2 perp_adjoint(const Vec2& g) { return Vec2(g.y(), -g.x()); }

void kernel_traction_adjoint(const StepInputs& in, const NeighbourGrid& nb, const World& w,
                             const std::vector<Vec2>& force_bar, TractionAdjoint& out) {
  if (!in.model.has_traction()) return;
  const TractionNet& net = in.model.traction;
  const double eps = in.model.params.contact_epsilon;
  double inputs[TractionNet::kInputs];
  for (size_t p = 0; p < w.size(); ++p) {
    const Vec2& fb = force_bar[p];
    if (fb.squaredNorm() == 0) continue;
    const Vec2 xp = w.x[p], vp = w.v[p], hp = w.heading[p];
    const double cp = w.comfort[p];
    nb.for_each_candidate(p, [&](size_t q) {
      Vec2 r = w.x[q] - xp;
      double d = r.norm();
      const double theta1 = w.radius[p] + w.radius[q];
      if (d >= theta1 + cp || d < 1e-9) return;  // coincident centres: fixed direction, no gradient
      const Vec2 n = r / d, np = perp(n), hperp = perp(hp), dv = w.v[q] - vp;
      inputs[0] = cp;
      inputs[1] = d;
      inputs[2] = r.dot(hp);
      inputs[3] = r.dot(hperp);
      inputs[4] = -dv.dot(n);
      inputs[5] = dv.dot(np);
      const double phi = contact_potential(d, theta1, cp, eps);
      // Forward: f_p += -K phi n.
      const double s_bar = -fb.dot(n);  // adjoint of K phi
      double in_bar[TractionNet::kInputs] = {0};
      const double K = net.eval_backward(inputs, s_bar * phi, in_bar, out.network.data());
      const double phi_bar = s_bar * K;
      Vec2 n_bar = -K * phi * fb;
      double d_bar = 0;
      double dphi_dd, dphi_dc;
      contact_potential_grad(d, theta1, cp, eps, dphi_dd, dphi_dc);
      d_bar += phi_bar * dphi_dd;
      out.comfort[p] += phi_bar * dphi_dc + in_bar[0];
      d_bar += in_bar[1];
      Vec2 r_bar = in_bar[2] * hp + in_bar[3] * hperp;
      out.heading[p] += in_bar[2] * r + perp_adjoint(in_bar[3] * r);
      Vec2 dv_bar = -in_bar[4] * n + in_bar[5] * np;
      n_bar += -in_bar[4] * dv + perp_adjoint(in_bar[5] * dv);
      // n = r / d and d = |r|.
      r_bar += (n_bar - n_bar.dot(n) * n) / d + d_bar * n;
      out.x[q] += r_bar;
      out.x[p] -= r_bar;
      out.v[q] += dv_bar;
      out.v[p] -= dv_bar;
    });
  }
}

void TransferAdjoint::reset(size_t n) {
  x.assign(n, Vec2::Zero());
  v.assign(n, Vec2::Zero());
  accel.assign(n, Vec2::Zero());
  force.assign(n, Vec2::Zero());
  C.assign(n, Mat2::Zero());
  J.assign(n, 0);
  E = gamma = tension_scale = alignment_time = 0;
}

namespace {
// Quadratic B-spline weights and their derivatives with respect to the position (per axis).
struct StencilGrad {
  Stencil s;
  double dwx[3], dwy[3];  // d w / d x (1/m)
};

StencilGrad stencil_grad(const Grid& g, const Vec2& x) {
  StencilGrad r;
  r.s = make_stencil(g.origin, g.dx, g.nx, g.ny, x);
  stencil_weight_gradients(r.s, g.dx, r.dwx, r.dwy);
  return r;
}

// The grid boundary condition at a node as a linear map of the velocity, when active.
struct NodeBC {
  bool active = false;
  Vec2 n = Vec2::Zero();
  double keep = 1;  // 1 - wall_friction
  Vec2 apply(const Vec2& u) const { return active ? Vec2(keep * (u - u.dot(n) * n)) : u; }
};
}  // namespace

void kernel_transfer_adjoint(const StepInputs& in, const Grid& shape, const World& w, const std::vector<Vec2>& x_bar,
                             const std::vector<Vec2>& v_bar, const std::vector<Mat2>& C_bar,
                             const std::vector<double>& J_bar, TransferAdjoint& out, AfterHook after_hook, void* hook_ctx) {
  if (in.model.material == MaterialKind::Elastic)
    throw Error("the transfer adjoint covers the crowd and fluid materials (no deformation gradient)");
  const MaterialParams& P = in.model.params;
  const size_t n = w.size(), nodes = shape.nodes();
  const double m = P.mass, vol0 = 1.0 / P.rest_density, dt = in.dt, dx = shape.dx, inv_dx2 = 1 / (dx * dx);
  const double alpha_raw = dt / P.alignment_time, alpha = std::min(1.0, alpha_raw);
  const double j_max = P.tension_scale > 0 ? 4.0 : 1.0;
  // --- Forward recomputation: P2G sums and grid velocities before and after the boundary condition.
  std::vector<double> mass(nodes, 0), stress_s(n);
  std::vector<Vec2> MO(nodes, Vec2::Zero()), MN(nodes, Vec2::Zero());
  std::vector<StencilGrad> st(n);
  for (size_t p = 0; p < n; ++p) {
    st[p] = stencil_grad(shape, w.x[p]);
    const double J = w.J[p];
    stress_s[p] = dt * vol0 * 4 * inv_dx2 * J * material_pressure(P, J);  // S_p = s_p I
    for_each_stencil_node(st[p].s, shape.nx, dx, [&](const StencilNode& nd) {
      const Vec2 mo = nd.w * (m * w.v[p] + m * w.C[p] * nd.dpos);
      mass[nd.k] += nd.w * m;
      MO[nd.k] += mo;
      MN[nd.k] += mo + nd.w * stress_s[p] * nd.dpos;
    });
  }
  std::vector<NodeBC> bc_new(nodes), bc_old(nodes);
  std::vector<Vec2> vo(nodes, Vec2::Zero()), vn(nodes, Vec2::Zero());
  for (size_t k = 0; k < nodes; ++k) {
    if (mass[k] <= 0) continue;
    const Vec2 uo = MO[k] / mass[k], un = MN[k] / mass[k];
    if (shape.solid[k]) {
      // The forward applies the condition to each velocity on its own.
      const Vec2& nrm = shape.normal[k];
      bc_old[k] = NodeBC{uo.dot(nrm) < 0, nrm, 1 - P.wall_friction};
      bc_new[k] = NodeBC{un.dot(nrm) < 0, nrm, 1 - P.wall_friction};
    }
    vo[k] = bc_old[k].apply(uo);
    vn[k] = bc_new[k].apply(un);
  }
  // --- Backward through G2P, into the grid.
  std::vector<Vec2> vn_bar(nodes, Vec2::Zero()), vo_bar(nodes, Vec2::Zero());
  for (size_t p = 0; p < n; ++p) {
    const Stencil& s = st[p].s;
    Vec2 v_pic = Vec2::Zero(), dv = Vec2::Zero();
    Mat2 Cn = Mat2::Zero();
    for_each_stencil_node(s, shape.nx, dx, [&](const StencilNode& nd) {
      v_pic += nd.w * vn[nd.k];
      dv += nd.w * (vn[nd.k] - vo[nd.k]);
      Cn += 4 * inv_dx2 * nd.w * vn[nd.k] * nd.dpos.transpose();
    });
    const Vec2 v_new = (1 - alpha) * (w.v[p] + dv) + alpha * v_pic + dt * (w.accel[p] + w.pair_force[p] / m);
    const bool speed_clamped = v_new.norm() > P.max_speed;
    const double J_unclamped = w.J[p] * (1 + dt * Cn.trace());
    const bool J_clamped = J_unclamped < kMinJ || J_unclamped > j_max;
    Vec2 xbp = x_bar[p], vbp = v_bar[p];
    if (after_hook) {
      const Vec2 v_after = speed_clamped ? Vec2(v_new * (P.max_speed / v_new.norm())) : v_new;
      after_hook(hook_ctx, p, w.x[p] + dt * v_after, v_after, xbp, vbp);
    }
    // x' = x + dt v'; J' = J (1 + dt tr C'); C' = Cn.
    out.x[p] += xbp;
    Vec2 vb = speed_clamped ? Vec2::Zero() : Vec2(vbp + dt * xbp);
    Mat2 Cb = C_bar[p];
    if (!J_clamped) {
      out.J[p] += J_bar[p] * (1 + dt * Cn.trace());
      Cb += J_bar[p] * w.J[p] * dt * Mat2::Identity();
    }
    // v' = (1 - a)(v + dv) + a v_pic + dt (accel + f / m).
    out.accel[p] += dt * vb;
    out.force[p] += dt / m * vb;
    out.v[p] += (1 - alpha) * vb;
    const Vec2 dv_bar = (1 - alpha) * vb, vpic_bar = alpha * vb;
    const double alpha_bar = vb.dot(v_pic - w.v[p] - dv);
    if (alpha_raw < 1) out.alignment_time += alpha_bar * (-dt / (P.alignment_time * P.alignment_time));
    for_each_stencil_node(s, shape.nx, dx, [&](const StencilNode& nd) {
      const size_t k = nd.k;
      const double W = nd.w;
      vn_bar[k] += W * (vpic_bar + dv_bar) + 4 * inv_dx2 * W * Cb * nd.dpos;
      vo_bar[k] -= W * dv_bar;
      // Position dependence of the weights and of dpos (d dpos / dx = -I).
      const Vec2 dW(st[p].dwx[nd.a] * s.wy[nd.b], s.wx[nd.a] * st[p].dwy[nd.b]);
      const double g = vn[k].dot(vpic_bar + dv_bar) - vo[k].dot(dv_bar) + 4 * inv_dx2 * vn[k].dot(Cb * nd.dpos);
      out.x[p] += g * dW - 4 * inv_dx2 * W * (Cb.transpose() * vn[k]);
    });
  }
  // --- Backward through the grid update: v = BC(M / m); the projection is symmetric.
  std::vector<Vec2> MN_bar(nodes, Vec2::Zero()), MO_bar(nodes, Vec2::Zero());
  std::vector<double> mass_bar(nodes, 0);
  for (size_t k = 0; k < nodes; ++k) {
    if (mass[k] <= 0) continue;
    const Vec2 gn = bc_new[k].apply(vn_bar[k]), go = bc_old[k].apply(vo_bar[k]);
    MN_bar[k] = gn / mass[k];
    MO_bar[k] = go / mass[k];
    mass_bar[k] -= (gn.dot(MN[k]) + go.dot(MO[k])) / (mass[k] * mass[k]);  // d(M/m)/dm = -M/m^2
  }
  // --- Backward through P2G: MO = sum W (m v + m C dpos), MN = MO + sum W s dpos, mass = sum W m.
  for (size_t p = 0; p < n; ++p) {
    const Stencil& s = st[p].s;
    double s_bar = 0;
    for_each_stencil_node(s, shape.nx, dx, [&](const StencilNode& nd) {
      const size_t k = nd.k;
      const double W = nd.w;
      const Vec2 mo_bar = MO_bar[k] + MN_bar[k];  // MN contains MO
      out.v[p] += W * m * mo_bar;
      out.C[p] += W * m * mo_bar * nd.dpos.transpose();
      s_bar += W * MN_bar[k].dot(nd.dpos);
      const Vec2 dW(st[p].dwx[nd.a] * s.wy[nd.b], s.wx[nd.a] * st[p].dwy[nd.b]);
      const Vec2 mo = m * w.v[p] + m * w.C[p] * nd.dpos;
      const double g = mo_bar.dot(mo) + stress_s[p] * MN_bar[k].dot(nd.dpos) + m * mass_bar[k];
      out.x[p] += g * dW - W * m * (w.C[p].transpose() * mo_bar) - W * stress_s[p] * MN_bar[k];
    });
    // s_p = dt V0 (4/dx^2) J P(J), P = scale E (J^-gamma - 1), scale = 1 for J < 1 else s_t.
    const double J = w.J[p], c0 = dt * vol0 * 4 * inv_dx2;
    const double scale = J < 1 ? 1.0 : P.tension_scale, Jg = std::pow(J, -P.gamma);
    const double Pj = scale * P.E * (Jg - 1);
    const double dP_dJ = -scale * P.E * P.gamma * Jg / J;
    out.J[p] += s_bar * c0 * (Pj + J * dP_dJ);
    out.E += s_bar * c0 * J * scale * (Jg - 1);
    out.gamma += s_bar * c0 * J * scale * P.E * (-Jg * std::log(J));
    if (J >= 1) out.tension_scale += s_bar * c0 * J * P.E * (Jg - 1);
  }
}

}  // namespace crowdmpm
