#include "engine/sim/kernels.hpp"


#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace crowdmpm {

// ---------------------------------------------------------------------------------------------
// Grids

void Grid::init(const Geometry& geo, double cell) {
  dx = cell;
  // Two cells of padding so every particle inside the domain has its full 3x3 stencil.
  origin = geo.lo - Vec2(2 * dx, 2 * dx);
  nx = static_cast<int>(std::ceil((geo.hi.x() - geo.lo.x()) / dx)) + 5;
  ny = static_cast<int>(std::ceil((geo.hi.y() - geo.lo.y()) / dx)) + 5;
  mass.assign(nodes(), 0);
  velocity.assign(nodes(), Vec2::Zero());
  velocity_old.assign(nodes(), Vec2::Zero());
  solid.assign(nodes(), 0);
  normal.assign(nodes(), Vec2::Zero());
  bin_start.assign(nodes() + 1, 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      Vec2 p = origin + dx * Vec2(i, j);
      if (geo.sdf(p) < 0) {
        solid[node(i, j)] = 1;
        normal[node(i, j)] = geo.normal(p);
      }
    }
}

void NeighbourGrid::init(const Geometry& geo, double reach, double min_cell) {
  // Cells of half the reach and a 5x5 search scan ~30% less area than reach-sized cells and 3x3.
  range = reach;
  h = std::max({0.5 * reach, min_cell, 1e-3});
  span = static_cast<int>(std::ceil(reach / h - 1e-12));
  origin = geo.lo - Vec2(h, h);
  nx = static_cast<int>(std::ceil((geo.hi.x() - geo.lo.x()) / h)) + 3;
  ny = static_cast<int>(std::ceil((geo.hi.y() - geo.lo.y()) / h)) + 3;
  start.assign(static_cast<size_t>(nx) * ny + 1, 0);
}

// Counting sort of items by key; order lists items of key k at [start[k], start[k+1]), each
// run in increasing item index.
static void counting_sort(const std::vector<int>& key, size_t n, std::vector<int>& start,
                          std::vector<int>& order, std::vector<int>& cursor) {
  std::fill(start.begin(), start.end(), 0);
  for (size_t p = 0; p < n; ++p) ++start[key[p] + 1];
  for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
  order.resize(n);
  cursor.assign(start.begin(), start.end() - 1);
  for (size_t p = 0; p < n; ++p) order[cursor[key[p]]++] = static_cast<int>(p);
}

void NeighbourGrid::build(const World& w, ThreadPool& pool) {
  const size_t n = w.size();
  cell.resize(n);
  pool.parallel_for(n, [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) {
      int i = std::clamp(static_cast<int>(std::floor((w.x[p].x() - origin.x()) / h)), 0, nx - 1);
      int j = std::clamp(static_cast<int>(std::floor((w.x[p].y() - origin.y()) / h)), 0, ny - 1);
      cell[p] = j * nx + i;
    }
  });
  counting_sort(cell, n, start, order, cursor);
}

// ---------------------------------------------------------------------------------------------
// Material

double material_pressure(const MaterialParams& p, double J) {
  double P = p.E * (std::pow(J, -p.gamma) - 1);
  return J < 1 ? P : p.tension_scale * P;
}

Mat2 kirchhoff_stress(const Model& m, const Mat2& F, double J) {
  if (m.material != MaterialKind::Elastic) return -J * material_pressure(m.params, J) * Mat2::Identity();
  // Fixed-corotated elasticity: tau = 2 mu (F - R) F^T + lambda (J - 1) J I.
  const double E = m.params.E, nu = m.params.poisson_ratio;
  const double mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  Eigen::JacobiSVD<Mat2> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat2 U = svd.matrixU(), V = svd.matrixV();
  if (U.determinant() < 0) U.col(1) *= -1;
  if (V.determinant() < 0) V.col(1) *= -1;
  Mat2 R = U * V.transpose();
  double Jf = F.determinant();
  return 2 * mu * (F - R) * F.transpose() + lambda * (Jf - 1) * Jf * Mat2::Identity();
}

// ---------------------------------------------------------------------------------------------
// 1. Drive: a_p = (s v0 f e_p - v_p) / tau + sum of the force terms (terms.hpp).

Vec2 desired_direction(const StepInputs& in, const Behaviour& b, const Vec2& x, const Vec2& heading) {
  switch (b.kind) {
    case Behaviour::Kind::None: return Vec2::Zero();
    case Behaviour::Kind::Heading: return heading;
    case Behaviour::Kind::Goal:
      if (b.goal && b.goal->contains(x)) return Vec2::Zero();
      return in.navs[b.nav].direction(x);
    case Behaviour::Kind::Orbit: {
      if (b.nav >= 0) {
        // Around a structure: along the level sets of the travel distance to it (the tangent of
        // -grad T turned by 90 degrees), plus an inward share towards it.
        Vec2 d = in.navs[b.nav].direction(x);
        if (d.squaredNorm() == 0) return Vec2::Zero();
        Vec2 e = b.sign * Vec2(d.y(), -d.x()) + b.inward * d;
        return e.normalized();
      }
      Vec2 r = x - b.point;
      double n = r.norm();
      if (n < 1e-9) return Vec2::Zero();
      Vec2 radial = r / n;
      Vec2 e = b.sign * Vec2(-radial.y(), radial.x()) - b.inward * radial;
      return e.normalized();
    }
    case Behaviour::Kind::Attract: {
      Vec2 d = b.point - x;
      double n = d.norm();
      return n > b.arrive_radius ? Vec2(d / n) : Vec2::Zero();
    }
  }
  return Vec2::Zero();
}

TermPoint terms_point(const StepInputs& in, const World& w, size_t p, const Vec2& heading, const std::vector<double>& density,
                      const std::vector<double>& ahead) {
  TermPoint pt{w.x[p], w.v[p], heading, w.group[p], in.time};
  pt.density = density.empty() ? 0.0 : density[p];
  pt.density_ahead = ahead.empty() ? 0.0 : ahead[p];
  pt.id = w.id[p];
  return pt;
}

std::vector<double> terms_density(const StepInputs& in, const World& w) {
  return terms_need_density(in.terms) ? local_density(w, 0, kDensityRadius) : std::vector<double>();
}

std::vector<double> material_density(const StepInputs& in, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                                     const std::vector<Vec2>& v) {
  const MaterialParams& P = in.model.params;
  if (!material_density_law(P)) return {};
  std::vector<double> rho = local_density_ahead(x, heading, P.density_speed_reach, P.density_speed_focus, &v, P.density_opening_speed);
  if (in.walkable) per_walkable_area(*in.walkable, x, heading, P.density_speed_reach, P.density_speed_focus, rho);
  return rho;
}

void material_density_vjp(const StepInputs& in, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                          const std::vector<Vec2>& v, const std::vector<double>& density_bar, std::vector<Vec2>& x_bar,
                          std::vector<Vec2>& heading_bar, std::vector<Vec2>& v_bar, double* opening_bar) {
  const MaterialParams& P = in.model.params;
  if (!material_density_law(P)) return;
  const double R = P.density_speed_reach, k = P.density_speed_focus;
  if (!in.walkable) {
    local_density_ahead_vjp(x, heading, R, k, density_bar, x_bar, heading_bar, &v, P.density_opening_speed, &v_bar, opening_bar);
    return;
  }
  // rho / s' with s' = max(s, kMinWalkableShare): d = drho / s' - rho ds / s'^2 where s' = s.
  // (The share and its derivatives in one pass, only where the density matters to the loss.)
  const std::vector<double> rho = local_density_ahead(x, heading, R, k, &v, P.density_opening_speed);
  std::vector<char> need(rho.size());
  for (size_t p = 0; p < rho.size(); ++p) need[p] = density_bar[p] != 0;
  const std::vector<ShareAhead> share = walkable_share_ahead_derivatives(*in.walkable, x, heading, R, k, need);
  std::vector<double> rho_bar(rho.size()), share_bar(rho.size(), 0.0);
  for (size_t p = 0; p < rho.size(); ++p) {
    const double s = std::max(share[p].share, kMinWalkableShare);
    rho_bar[p] = density_bar[p] / s;
    if (share[p].share > kMinWalkableShare) share_bar[p] = -density_bar[p] * rho[p] / (s * s);
  }
  local_density_ahead_vjp(x, heading, R, k, rho_bar, x_bar, heading_bar, &v, P.density_opening_speed, &v_bar, opening_bar);
  walkable_share_ahead_vjp(share, share_bar, x_bar, heading_bar);
}

namespace {
// Weidmann's factor f of the material's law at the density ahead, before the floor.
double weidmann_factor(const MaterialParams& P, const TermPoint& pt) {
  double f = 1;
  const double law[2] = {P.density_speed_gamma, P.density_speed_max};
  Vec2 unused = Vec2::Zero();
  TermPoint at = pt;
  at.density = pt.density_ahead;
  density_speed_term()->eval(law, at, unused, f);
  return f;
}

// The floored factor F = (1 - m)(phi + (1 - phi) f) + m M, M = f + softplus(b (phi - f)) / b a
// smooth max(f, phi), with its slopes in phi and f (optional). No floor: f itself.
double floored_factor(double f, double phi, double m, double* d_phi, double* d_f) {
  if (!(phi > 0)) {
    if (d_phi) *d_phi = 0;
    if (d_f) *d_f = 1;
    return f;
  }
  const double added = phi + (1 - phi) * f;
  if (!(m > 0)) {  // the added floor alone (the default): no smooth max to evaluate
    if (d_phi) *d_phi = 1 - f;
    if (d_f) *d_f = 1 - phi;
    return added;
  }
  const double z = kFloorSharpness * (phi - f);
  const double smooth_max = f + (z > 30 ? z : std::log1p(std::exp(z))) / kFloorSharpness;
  if (d_phi || d_f) {
    const double sigma = 1 / (1 + std::exp(-z));
    if (d_phi) *d_phi = (1 - m) * (1 - f) + m * sigma;
    if (d_f) *d_f = (1 - m) * (1 - phi) + m * (1 - sigma);
  }
  return (1 - m) * added + m * smooth_max;
}
}  // namespace

double material_density_factor(const MaterialParams& P, const TermPoint& pt) {
  if (!material_density_law(P)) return 1;
  return floored_factor(weidmann_factor(P, pt), P.density_speed_floor, P.density_speed_floor_max, nullptr, nullptr);
}

double material_density_factor_vjp(const MaterialParams& P, const TermPoint& pt, double f_bar, MaterialParams& grad) {
  if (!material_density_law(P) || f_bar == 0) return 0;
  const double law[2] = {P.density_speed_gamma, P.density_speed_max};
  double law_bar[2] = {0, 0};
  Vec2 x_bar = Vec2::Zero(), v_bar = Vec2::Zero();  // the law reads neither
  TermPoint at = pt;
  at.density = pt.density_ahead;
  double dF_dphi = 0, dF_df = 1;
  floored_factor(weidmann_factor(P, pt), P.density_speed_floor, P.density_speed_floor_max, &dF_dphi, &dF_df);
  density_speed_term()->vjp(law, at, Vec2::Zero(), f_bar * dF_df, x_bar, v_bar, law_bar);
  grad.density_speed_gamma += law_bar[0];
  grad.density_speed_max += law_bar[1];
  grad.density_speed_floor += f_bar * dF_dphi;
  // df/drho of the same law, a smooth function of one variable: central differences (DESIGN.md
  // section 4 allows local derivatives of pointwise functions).
  const double h = 1e-6 * std::max(pt.density_ahead, 1.0);
  TermPoint up = pt, down = pt;
  up.density_ahead += h;
  down.density_ahead -= h;
  return f_bar * (material_density_factor(P, up) - material_density_factor(P, down)) / (2 * h);
}

void drive_point(const StepInputs& in, const Behaviour& beh, const TermPoint& pt, double v0, Vec2& accel, Vec2& heading,
                 double& free_speed) {
  const MaterialParams& P = in.model.params;
  const Vec2& x = pt.x;
  const Vec2& v = pt.v;
  const Vec2& prev_heading = pt.heading;
  Vec2 a = Vec2::Zero();
  double factor = material_density_factor(P, pt);
  apply_terms(in.terms, pt, a, factor);
  Vec2 dir = desired_direction(in, beh, x, prev_heading);
  const double u = P.v0_scale * v0 * factor;  // the free speed
  if (beh.kind != Behaviour::Kind::None) a = (u * dir - v) / P.tau + a;
  accel = a;
  free_speed = beh.kind != Behaviour::Kind::None && dir.squaredNorm() > 0 ? u : 0;
  if (beh.kind == Behaviour::Kind::Heading) heading = prev_heading;  // kept from entry (zero: no drive)
  else if (dir.squaredNorm() > 0) heading = dir;
  else if (v.squaredNorm() > 1e-8) heading = v.normalized();
  else heading = prev_heading;
}

void kernel_drive(const StepInputs& in, World& w, ThreadPool& pool) {
  const std::vector<double> density = terms_density(in, w);
  const std::vector<double> ahead = material_density(in, w.x, w.heading, w.v);  // before the headings change
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p)
      drive_point(in, in.behaviours[w.behaviour[p]], terms_point(in, w, p, w.heading[p], density, ahead), w.v0[p], w.accel[p],
                  w.heading[p], w.free_speed[p]);
  });
}

// ---------------------------------------------------------------------------------------------
// 1b. Headway speed adaptation: a_p += (min(u_p, max(0, (s_p - s0) / T)) - u_p) e_p / tau (kernels.hpp).

Headway headway_point(const NeighbourGrid& nb, const World& w, size_t p, const Vec2& e, double width, double look) {
  Headway h;
  const Vec2 xp = w.x[p];
  // Nobody further along than T u_p + r_p + r_q limits p: the search ends there.
  nb.for_each_candidate_ahead(p, xp, w.radius[p], e, look, width, [&](size_t q) {
    const Vec2 r = w.x[q] - xp;
    const double along = r.dot(e), side = r.x() * e.y() - r.y() * e.x();
    const double bodies = w.radius[p] + w.radius[q];
    if (along <= 0 || std::abs(side) >= width * bodies) return;
    // Converging walkers (two people funnelling into a door) each have the other ahead in their
    // lane; counting both would stop both. The one further ahead in the other's lane goes first
    // (ties: the lower id) and does not count the other.
    if (w.free_speed[q] > 0) {
      const Vec2 eq = w.heading[q];
      const double along_q = -r.dot(eq), side_q = r.y() * eq.x() - r.x() * eq.y();
      if (along_q > 0 && std::abs(side_q) < width * bodies &&
          (along_q > along || (along_q == along && w.id[p] < w.id[q])))
        return;
    }
    const double gap = along - bodies;
    if (gap < h.gap) {
      h.gap = gap;
      h.q = q;
    }
  });
  return h;
}

void kernel_headway(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool) {
  const MaterialParams& P = in.model.params;
  if (!(P.time_gap > 0)) return;
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) {
      const double u = w.free_speed[p];
      if (!(u > 0)) continue;
      const Headway h = headway_point(nb, w, p, w.heading[p], P.headway_width, headway_look(P, u));
      const double V = headway_speed(P, h.gap);
      if (V < u) w.accel[p] += (V - u) / P.tau * w.heading[p];
    }
  });
}

// ---------------------------------------------------------------------------------------------
// 2. Pair traction: f_p = sum_q K_pq phi(d) (x_p - x_q)/d for d < theta2 = r_p + r_q + c_p.

double contact_potential(double d, double theta1, double c, double eps) {
  // phi(d) = -log((d - theta1)/c): zero at theta2 = theta1 + c, unbounded towards contact. Below
  // theta1 + eps it continues along its tangent, so it keeps growing through and past contact
  // instead of saturating (a saturated barrier lets fast bodies pass through each other).
  if (d >= theta1 + eps) return -std::log((d - theta1) / c);
  return -std::log(eps / c) + (theta1 + eps - d) / eps;
}

void kernel_traction(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool) {
  const TractionNet& net = in.model.traction;
  const bool active = in.model.has_traction();
  const double eps = in.model.params.contact_epsilon;
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    double inputs[TractionNet::kInputs];
    for (size_t p = b; p < e; ++p) {
      Vec2 force = Vec2::Zero();
      double virial = 0;
      if (active) {
        const Vec2 xp = w.x[p], vp = w.v[p], hp = w.heading[p];
        const double cp = w.comfort[p];
        nb.for_each_candidate(p, [&](size_t q) {
          Vec2 r = w.x[q] - xp;
          double d = r.norm();
          double theta1 = w.radius[p] + w.radius[q];
          if (d >= theta1 + cp) return;
          if (d < 1e-9) {
            // Coincident centres: separate them along x, the lower id to the left, so that
            // two agents placed on the same spot do not stay fused.
            r = Vec2(w.id[q] > w.id[p] ? 1e-9 : -1e-9, 0);
            d = 1e-9;
          }
          Vec2 n = r / d, np(-n.y(), n.x());
          Vec2 dv = w.v[q] - vp;
          inputs[0] = cp;
          inputs[1] = d;
          inputs[2] = r.dot(hp);
          inputs[3] = r.dot(Vec2(-hp.y(), hp.x()));
          inputs[4] = -dv.dot(n);
          inputs[5] = dv.dot(np);
          double K = net.eval(inputs);
          double phi = contact_potential(d, theta1, cp, eps);
          force -= K * phi * n;
          virial += K * phi * d;
        });
      }
      w.pair_force[p] = force;
      w.pair_virial[p] = virial;
    }
  });
}

// ---------------------------------------------------------------------------------------------
// 3. P2G, scattering particles sorted by stencil base in row blocks (see below):
//      (mv)_i = sum_p w_ip [m v_p + m C_p (x_i - x_p)]                 -> v_old
//      (mv)_i += sum_p w_ip [-dt V0 (4/dx^2) tau_p (x_i - x_p)]         -> v_new (after the grid update)
//    The drive and the pair traction act on the particles themselves (G2P), not through the grid:
//    spread over a 3x3 stencil, equal and opposite pair forces of two close neighbours cancel.

static inline Stencil stencil(const Grid& g, const Vec2& x) { return make_stencil(g.origin, g.dx, g.nx, g.ny, x); }

void kernel_p2g(const StepInputs& in, World& w, Grid& g, ThreadPool& pool) {
  const size_t n = w.size();
  const double m = in.model.params.mass, vol0 = 1.0 / in.model.params.rest_density;
  const double dt = in.dt, inv_dx2 = 1.0 / (g.dx * g.dx);
  g.base.resize(n);
  g.momentum.resize(n);
  g.affine.resize(n);
  g.stress.resize(n);
  g.stencils.resize(n);
  pool.parallel_for(n, [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) {
      const Stencil& s = g.stencils[p] = stencil(g, w.x[p]);
      g.base[p] = g.node(s.bx, s.by);
      g.affine[p] = m * w.C[p];
      const Mat2 tau = kirchhoff_stress(in.model, w.F[p], w.J[p]);
      g.stress[p] = -dt * vol0 * 4 * inv_dx2 * tau;
      g.momentum[p] = m * w.v[p];
      // Reported pressure: the continuum part plus the pair virial of kernel_traction.
      const double J = std::max(w.J[p], 1e-6);
      w.pressure[p] = -0.5 * tau.trace() / J + w.pair_virial[p] / (4 * vol0 * J);
    }
  });
  counting_sort(g.base, n, g.bin_start, g.order, g.cursor);
  pool.parallel_for(g.nodes(), [&](size_t b, size_t e) {
    std::fill(g.mass.begin() + static_cast<long>(b), g.mass.begin() + static_cast<long>(e), 0.0);
    std::fill(g.velocity.begin() + static_cast<long>(b), g.velocity.begin() + static_cast<long>(e), Vec2::Zero());
    std::fill(g.velocity_old.begin() + static_cast<long>(b), g.velocity_old.begin() + static_cast<long>(e), Vec2::Zero());
  });
  // Scatter in row blocks: particles whose stencil base lies in rows [4k, 4k + 4) touch node rows
  // [4k, 4k + 6), so even blocks never share a node, nor do odd blocks. Even blocks go first,
  // then odd ones, each block in sorted particle order: every node sums its contributions in
  // the same order whatever the thread count, and no atomics are needed.
  constexpr int kBlockRows = 4;
  const int blocks = (g.ny + kBlockRows - 1) / kBlockRows;
  for (int parity = 0; parity < 2; ++parity) {
    const size_t count = static_cast<size_t>((blocks - parity + 1) / 2);
    pool.parallel_for(count, [&](size_t kb, size_t ke) {
      for (size_t kk = kb; kk < ke; ++kk) {
        const int row0 = (2 * static_cast<int>(kk) + parity) * kBlockRows;
        const int row1 = std::min(row0 + kBlockRows, g.ny);
        for (int s = g.bin_start[g.node(0, row0)]; s < g.bin_start[static_cast<size_t>(row1) * g.nx]; ++s) {
          const size_t p = static_cast<size_t>(g.order[s]);
          const Stencil& st = g.stencils[p];
          for_each_stencil_node(st, g.nx, g.dx, [&](const StencilNode& nd) {
            const Vec2 mv = nd.w * (g.momentum[p] + g.affine[p] * nd.dpos);
            g.mass[nd.k] += nd.w * m;
            g.velocity_old[nd.k] += mv;
            g.velocity[nd.k] += mv + nd.w * (g.stress[p] * nd.dpos);
          });
        }
      }
    }, 1);
  }
}

// ---------------------------------------------------------------------------------------------
// 5. Grid update: v_i = (mv)_i / m_i; no flow into solids (slip, optional friction).

void kernel_grid_update(const StepInputs& in, Grid& g, ThreadPool& pool) {
  const double friction = in.model.params.wall_friction;
  pool.parallel_for(g.nodes(), [&](size_t b, size_t e) {
    for (size_t k = b; k < e; ++k) {
      if (g.mass[k] <= 0) {
        g.velocity[k] = g.velocity_old[k] = Vec2::Zero();
        continue;
      }
      // The boundary condition goes on both velocities: the FLIP increment v_new - v_old then
      // carries only the stress impulse, and walls act on a particle through the PIC share and
      // its own projection. A boundary jump inside the increment would be re-applied every step
      // and damp motion along walls at a rate set by dt rather than by physics.
      auto constrain = [&](Vec2 v) {
        if (g.solid[k]) {
          const Vec2& nrm = g.normal[k];
          double vn = v.dot(nrm);
          if (vn < 0) {
            v -= vn * nrm;
            v *= (1 - friction);
          }
        }
        return v;
      };
      g.velocity_old[k] = constrain(g.velocity_old[k] / g.mass[k]);
      g.velocity[k] = constrain(g.velocity[k] / g.mass[k]);
    }
  });
}

// ---------------------------------------------------------------------------------------------
// 6. G2P. Each particle keeps its own velocity and receives the grid's change (FLIP), blended
//    with the grid velocity (PIC) at the rate dt / alignment_time, so that the blend is a
//    physical relaxation towards the local flow rather than a per-step smoothing whose strength
//    depends on dt. Then the particle's own forces:
//      v_p = (1 - a) (v_p + sum w (v_new - v_old)) + a sum w v_new + dt (a_p + f_p / m)
//      C_p = 4/dx^2 sum w v_new (x_i - x_p)^T;  J *= 1 + dt tr C;  F = (I + dt C) F;  x += dt v_p

void kernel_g2p(const StepInputs& in, const Grid& g, World& w, ThreadPool& pool) {
  const double dt = in.dt, inv_dx2 = 1.0 / (g.dx * g.dx);
  const MaterialParams& P = in.model.params;
  const bool elastic = in.model.material == MaterialKind::Elastic;
  const double alpha = std::min(1.0, dt / P.alignment_time);
  // With no tension (s_t = 0) nothing resists expansion: J is capped at 1 (DESIGN.md section 2).
  const double j_max = P.tension_scale > 0 || elastic ? 4.0 : 1.0;
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) {
      Stencil s = stencil(g, w.x[p]);
      Vec2 v_pic = Vec2::Zero(), dv = Vec2::Zero();
      Mat2 C = Mat2::Zero();
      for_each_stencil_node(s, g.nx, g.dx, [&](const StencilNode& nd) {
        const Vec2& vi = g.velocity[nd.k];
        v_pic += nd.w * vi;
        dv += nd.w * (vi - g.velocity_old[nd.k]);
        C += 4 * inv_dx2 * nd.w * vi * nd.dpos.transpose();
      });
      Vec2 v = (1 - alpha) * (w.v[p] + dv) + alpha * v_pic + dt * (w.accel[p] + w.pair_force[p] / P.mass);
      double speed = v.norm();
      if (speed > P.max_speed) v *= P.max_speed / speed;
      w.v[p] = v;
      w.C[p] = C;
      if (elastic) {
        w.F[p] = (Mat2::Identity() + dt * C) * w.F[p];
        w.J[p] = w.F[p].determinant();
      } else {
        w.J[p] = std::clamp(w.J[p] * (1 + dt * C.trace()), kMinJ, j_max);
      }
      w.x[p] += dt * v;
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Projection out of solids: centres are kept a clearance away from every solid, and the
// velocity component into the solid is removed.

namespace {
// Half the width of the opening a person at x stands in, capped at h_max: half the distance from
// the nearest solid (s behind, against n) to the first solid that a ray from x meets within 100
// degrees of n (sphere-traced; a door's far post, a corridor's far wall; up to 2 h_max - s away).
double opening_half_width(const Geometry& geo, const Vec2& x, const Vec2& n, double s, double h_max) {
  // (cos, sin) of 0, +-25, +-50, +-75 and +-100 degrees, computed once.
  static const std::vector<Vec2> kRays = [] {
    std::vector<Vec2> r;
    for (double deg : {0, 25, -25, 50, -50, 75, -75, 100, -100}) r.emplace_back(std::cos(deg * (M_PI / 180)), std::sin(deg * (M_PI / 180)));
    return r;
  }();
  double hit = 2 * h_max - s;
  for (const Vec2& cs : kRays) {
    const double c = cs.x(), sn = cs.y();
    const Vec2 d(c * n.x() - sn * n.y(), sn * n.x() + c * n.y());
    double t = 0;
    for (int k = 0; k < 24 && t < hit; ++k) {
      const double st = geo.sdf(x + t * d);
      if (st < 2e-3) {
        hit = t;
        break;
      }
      t += st;
    }
  }
  return std::min(h_max, 0.5 * (s + hit));
}

// projection_clearance with s = geo.sdf(x) already at hand.
double clearance_at(const MaterialParams& P, const Geometry& geo, const Vec2& x, double s) {
  const double c_min = P.wall_clearance, c_sh = P.shoulder_clearance;
  if (!(c_sh > c_min)) return c_min;
  if (s >= c_sh) return c_sh;
  // In an opening of half-width h the clearance is h - r (r the model's body_radius) between
  // wall_clearance and shoulder_clearance: the lane left to the centres, 2 (h - clearance), is
  // one body wide until the shoulders have their full clearance, and people squeeze towards the
  // walls only in openings narrower than 2 (wall_clearance + r) (single file). On the medial axis
  // (equally near two solids, as on a door's centre line) the distance's gradient is shorter
  // than 1 and s is the half-width itself.
  const Vec2 g = geo.sdf_gradient(x);
  const double gn = g.norm();
  if (!(gn > 1e-12)) return c_min;
  const double h = gn < 0.95 ? s : opening_half_width(geo, x, g / gn, s, c_sh + P.body_radius);
  return std::clamp(h - P.body_radius, c_min, c_sh);
}
}  // namespace

double projection_clearance(const MaterialParams& P, const Geometry& geo, const Vec2& x) {
  return clearance_at(P, geo, x, geo.sdf(x));
}

void project_point(const StepInputs& in, Vec2& x, Vec2& v, double clearance) {
  const double friction = in.model.params.wall_friction;
  for (int iter = 0; iter < 4; ++iter) {
    double s = in.geo.sdf(x);
    if (s >= clearance) break;
    Vec2 n = in.geo.normal(x);
    if (n.squaredNorm() == 0) break;
    x += (clearance - s) * n;
    double vn = v.dot(n);
    if (vn < 0) {
      v -= vn * n;
      v *= (1 - friction);
    }
  }
}

void project_point(const StepInputs& in, Vec2& x, Vec2& v) {
  const MaterialParams& P = in.model.params;
  const double s = in.geo.sdf(x);
  if (s >= std::max(P.wall_clearance, P.shoulder_clearance)) return;
  project_point(in, x, v, clearance_at(P, in.geo, x, s));
}

double interaction_margin(const Model& m, double comfort) {
  return m.material == MaterialKind::SocialForce ? std::min(8 * m.params.sf_B, 3.0) : comfort;
}

void kernel_social_force(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool) {
  const MaterialParams& P = in.model.params;
  const double reach_extra = interaction_margin(in.model, 0), area = 1.0 / P.rest_density;
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) {
      const Vec2 xp = w.x[p], vp = w.v[p];
      Vec2 force = Vec2::Zero();
      double virial = 0;
      nb.for_each_candidate(p, [&](size_t q) {
        Vec2 r = xp - w.x[q];
        double d = r.norm();
        const double rpq = w.radius[p] + w.radius[q];
        if (d >= rpq + reach_extra) return;
        if (d < 1e-9) {  // coincident centres: apart along x, the lower id to the left
          r = Vec2(w.id[q] > w.id[p] ? -1e-9 : 1e-9, 0);
          d = 1e-9;
        }
        const Vec2 n = r / d, t(-n.y(), n.x());
        const double overlap = std::max(rpq - d, 0.0);
        Vec2 f = (P.sf_A * std::exp((rpq - d) / P.sf_B) + P.sf_k * overlap) * n;
        f += P.sf_kappa * overlap * (w.v[q] - vp).dot(t) * t;
        force += f;
        virial += f.dot(r);
      });
      const double dw = in.geo.sdf(xp);
      if (dw < w.radius[p] + reach_extra) {
        const Vec2 nw = in.geo.normal(xp);
        if (nw.squaredNorm() > 0) {
          const Vec2 tw(-nw.y(), nw.x());
          const double overlap = std::max(w.radius[p] - dw, 0.0);
          force += (P.sf_A * std::exp((w.radius[p] - dw) / P.sf_B) + P.sf_k * overlap) * nw;
          force -= P.sf_kappa * overlap * vp.dot(tw) * tw;
        }
      }
      w.pair_force[p] = force;
      w.pair_virial[p] = virial;
      w.pressure[p] = virial / (2 * area);
    }
  });
}

void kernel_project(const StepInputs& in, World& w, ThreadPool& pool) {
  pool.parallel_for(w.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) project_point(in, w.x[p], w.v[p]);
  });
}

}  // namespace crowdmpm
