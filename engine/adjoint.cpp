#include "engine/adjoint.hpp"

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
    const int c = nb.cell[p], ci = c % nb.nx, cj = c / nb.nx;
    for (int dj = -nb.span; dj <= nb.span; ++dj)
      for (int di = -nb.span; di <= nb.span; ++di) {
        int i = ci + di, j = cj + dj;
        if (i < 0 || j < 0 || i >= nb.nx || j >= nb.ny) continue;
        int k = j * nb.nx + i;
        for (int s = nb.start[k]; s < nb.start[k + 1]; ++s) {
          const size_t q = static_cast<size_t>(nb.order[s]);
          if (q == p) continue;
          Vec2 r = w.x[q] - xp;
          double d = r.norm();
          const double theta1 = w.radius[p] + w.radius[q];
          if (d >= theta1 + cp || d < 1e-9) continue;  // coincident centres: fixed direction, no gradient
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
        }
      }
  }
}

}  // namespace crowdmpm
