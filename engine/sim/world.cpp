#include "engine/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <string>

#include "engine/core/binary.hpp"
#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"

namespace crowdmpm {

void World::reserve(size_t n) {
  x.reserve(n); v.reserve(n); C.reserve(n); F.reserve(n); J.reserve(n);
  id.reserve(n); radius.reserve(n); comfort.reserve(n); v0.reserve(n);
  behaviour.reserve(n); group.reserve(n);
  accel.reserve(n); heading.reserve(n); free_speed.reserve(n); pair_force.reserve(n); pair_virial.reserve(n); pressure.reserve(n);
}

EntityId World::add(const AgentDef& d) {
  EntityId e = next_id_++;
  if (slot_.size() <= e) slot_.resize(e + 1, -1);
  slot_[e] = static_cast<long>(size());
  x.push_back(d.position);
  v.push_back(d.velocity);
  C.push_back(Mat2::Zero());
  F.push_back(Mat2::Identity());
  J.push_back(1.0);
  id.push_back(e);
  radius.push_back(d.body_radius);
  comfort.push_back(d.comfort_distance);
  v0.push_back(d.desired_speed);
  behaviour.push_back(d.behaviour);
  group.push_back(d.group);
  accel.push_back(Vec2::Zero());
  heading.push_back(d.heading);
  free_speed.push_back(0);
  pair_force.push_back(Vec2::Zero());
  pair_virial.push_back(0);
  pressure.push_back(0);
  return e;
}

template <class T>
static void swap_pop(std::vector<T>& a, size_t i) {
  a[i] = a.back();
  a.pop_back();
}

void World::remove_at(size_t i) {
  slot_[id[i]] = -1;
  if (i + 1 != size()) slot_[id.back()] = static_cast<long>(i);
  swap_pop(x, i); swap_pop(v, i); swap_pop(C, i); swap_pop(F, i); swap_pop(J, i);
  swap_pop(id, i); swap_pop(radius, i); swap_pop(comfort, i); swap_pop(v0, i);
  swap_pop(behaviour, i); swap_pop(group, i);
  swap_pop(accel, i); swap_pop(heading, i); swap_pop(free_speed, i); swap_pop(pair_force, i); swap_pop(pair_virial, i);
  swap_pop(pressure, i);
}

namespace {
// Calls visit(p, q, r2) for every agent p of [first, n) and every agent q (p itself included)
// with r2 = |x_q - x_p|^2 / R^2 < 1, p in increasing order (local_density, local_density_ahead and its adjoint).
template <class Visit>
void for_each_within(const std::vector<Vec2>& xs, size_t first, double R, Visit&& visit) {
  const size_t n = xs.size();
  if (first >= n) return;
  // Cell lists of size R over the bounding box of every agent.
  Vec2 lo = xs[0], hi = xs[0];
  for (const Vec2& x : xs) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  // Cells of at least R, and O(n) of them however far apart people are: at most ~4 n + 1 cells
  // of area and 4 n + 1 along either side (people along one line far apart).
  const Vec2 ext = hi - lo;
  const double cells = 4.0 * static_cast<double>(n) + 1;
  const double h = std::max({R, std::sqrt(ext.x() * ext.y() / cells), ext.x() / cells, ext.y() / cells});
  const long nx = static_cast<long>(ext.x() / h) + 1, ny = static_cast<long>(ext.y() / h) + 1;
  auto cell_of = [&](const Vec2& x, long& i, long& j) {
    i = std::clamp(static_cast<long>((x.x() - lo.x()) / h), 0L, nx - 1);
    j = std::clamp(static_cast<long>((x.y() - lo.y()) / h), 0L, ny - 1);
  };
  std::vector<long> start(static_cast<size_t>(nx * ny) + 1, 0), order(n), key(n);
  for (size_t p = 0; p < n; ++p) {
    long i, j;
    cell_of(xs[p], i, j);
    key[p] = j * nx + i;
    ++start[static_cast<size_t>(key[p]) + 1];
  }
  for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
  std::vector<long> cursor(start.begin(), start.end() - 1);
  for (size_t p = 0; p < n; ++p) order[static_cast<size_t>(cursor[static_cast<size_t>(key[p])]++)] = static_cast<long>(p);
  const double inv_r2 = 1 / (R * R);
  for (size_t p = first; p < n; ++p) {
    long ci, cj;
    cell_of(xs[p], ci, cj);
    for (long j = std::max(0L, cj - 1); j <= std::min(ny - 1, cj + 1); ++j)
      for (long i = std::max(0L, ci - 1); i <= std::min(nx - 1, ci + 1); ++i)
        for (long s = start[static_cast<size_t>(j * nx + i)]; s < start[static_cast<size_t>(j * nx + i) + 1]; ++s) {
          const size_t q = static_cast<size_t>(order[static_cast<size_t>(s)]);
          const double r2 = (xs[q] - xs[p]).squaredNorm() * inv_r2;
          if (r2 < 1) visit(p, q, r2);
        }
  }
}
}  // namespace

std::vector<double> local_density(const std::vector<Vec2>& x, size_t first, double R) {
  std::vector<double> rho(first < x.size() ? x.size() - first : 0, 0.0);
  const double norm = 2 / (M_PI * R * R);
  for_each_within(x, first, R, [&](size_t p, size_t, double r2) { rho[p - first] += 1 - r2; });
  for (double& r : rho) r *= norm;
  return rho;
}

std::vector<double> local_density(const World& w, size_t first, double R) { return local_density(w.x, first, R); }

namespace {
// b^k for the focus k >= 1: by multiplication when k is whole (the common foci 1, 2, 4; pow
// is many times slower in the kernels' inner loops), else pow.
double focus_power(double b, double k) {
  if (k != std::floor(k) || k > 16) return std::pow(b, k);
  double r = 1;
  for (int i = 0; i < static_cast<int>(k); ++i) r *= b;
  return r;
}

// The weight of neighbour q at r = x_q - x_p (0 < |r| < R) seen with heading e, and its
// derivatives along r and e: W = (1 - |r|^2/R^2)(1 + r.e/|r|)^k / N_k (N_k: focus_norm).
double ahead_weight(const Vec2& r, const Vec2& e, double R, double k, double Nk, Vec2* dr, Vec2* de) {
  const double n = r.norm(), a = 1 - r.squaredNorm() / (R * R);
  if (!(n > 0)) return a;  // the agent itself
  const double c = r.dot(e) / n;
  const double g = focus_power(1 + c, k);  // (1 + c)^k
  const double N = e.squaredNorm() > 0 ? Nk : 1;              // no heading: every neighbour weighs 1 (c = 0)
  if (dr || de) {
    const double dg = k * focus_power(1 + c, k - 1);  // d(1 + c)^k / dc, only for the adjoint
    if (dr) *dr = (g * (-2 / (R * R)) * r + a * dg * (e - c * r / n) / n) / N;
    if (de) *de = a * dg * r / n / N;
  }
  return a * g / N;
}

// N_k, the mean of (1 + cos a)^k over the circle: Gamma(2k + 1) / (Gamma(k + 1)^2 2^k); 1 for k = 1.
double focus_norm(double k) { return std::exp(std::lgamma(2 * k + 1) - 2 * std::lgamma(k + 1) - k * std::log(2.0)); }

// The opening discount of neighbour q seen by p: D = exp(-s / u) for s = dv.e > 0 (dv = v_q - v_p),
// else 1; with dD/ds, ds/d(dv) = e, ds/de = dv and dD/du.
double opening_discount(const Vec2& dv, const Vec2& e, double u, double* dD_ds, double* dD_du) {
  const double s = dv.dot(e);
  if (!(s > 0)) {
    if (dD_ds) *dD_ds = 0;
    if (dD_du) *dD_du = 0;
    return 1;
  }
  const double D = std::exp(-s / u);
  if (dD_ds) *dD_ds = -D / u;
  if (dD_du) *dD_du = D * s / (u * u);
  return D;
}
}  // namespace

std::vector<double> local_density_ahead(const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R, double focus,
                                        const std::vector<Vec2>* v, double opening) {
  std::vector<double> rho(x.size(), 0.0);
  const double norm = 2 / (M_PI * R * R), Nk = focus_norm(focus);
  const bool discount = v && opening > 0;
  for_each_within(x, 0, R, [&](size_t p, size_t q, double) {
    const double W = ahead_weight(x[q] - x[p], heading[p], R, focus, Nk, nullptr, nullptr);
    rho[p] += discount && p != q ? W * opening_discount((*v)[q] - (*v)[p], heading[p], opening, nullptr, nullptr) : W;
  });
  for (double& r : rho) r *= norm;
  return rho;
}

void local_density_ahead_vjp(const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R, double focus,
                             const std::vector<double>& rho_bar, std::vector<Vec2>& x_bar, std::vector<Vec2>& heading_bar,
                             const std::vector<Vec2>* v, double opening, std::vector<Vec2>* v_bar, double* opening_bar) {
  const double norm = 2 / (M_PI * R * R), Nk = focus_norm(focus);
  const bool discount = v && opening > 0;
  for_each_within(x, 0, R, [&](size_t p, size_t q, double) {
    if (p == q || rho_bar[p] == 0) return;
    Vec2 dr = Vec2::Zero(), de = Vec2::Zero();
    const double W = ahead_weight(x[q] - x[p], heading[p], R, focus, Nk, &dr, &de);
    const double g = rho_bar[p] * norm;
    if (!discount) {
      x_bar[q] += g * dr;
      x_bar[p] -= g * dr;
      heading_bar[p] += g * de;
      return;
    }
    // rho_p gets W D: d(W D) = D dW + W dD.
    const Vec2 dv = (*v)[q] - (*v)[p];
    double dD_ds = 0, dD_du = 0;
    const double D = opening_discount(dv, heading[p], opening, &dD_ds, &dD_du);
    x_bar[q] += g * D * dr;
    x_bar[p] -= g * D * dr;
    heading_bar[p] += g * (D * de + W * dD_ds * dv);
    if (v_bar) {
      (*v_bar)[q] += g * W * dD_ds * heading[p];
      (*v_bar)[p] -= g * W * dD_ds * heading[p];
    }
    if (opening_bar) *opening_bar += g * W * dD_du;
  });
}

WalkableLattice walkable_lattice(const Geometry& geo, double h) {
  if (!(h > 0) || !std::isfinite(h)) throw Error("walkable lattice spacing must be positive and finite, got " + format_number(h) + " m");
  WalkableLattice walk;
  const Vec2 ext = geo.hi - geo.lo;
  if (!(ext.x() > 0 && ext.y() > 0)) return walk;
  walk.lo = geo.lo;
  walk.h = h;
  walk.nx = static_cast<long>(std::ceil(ext.x() / h));
  walk.ny = static_cast<long>(std::ceil(ext.y() / h));
  walk.clearance.resize(static_cast<size_t>(walk.nx * walk.ny));
  for (long j = 0; j < walk.ny; ++j)
    for (long i = 0; i < walk.nx; ++i)
      walk.clearance[static_cast<size_t>(j * walk.nx + i)] =
          static_cast<float>(geo.sdf(walk.lo + h * Vec2(static_cast<double>(i) + 0.5, static_cast<double>(j) + 0.5)));
  const double head[5] = {walk.lo.x(), walk.lo.y(), h, static_cast<double>(walk.nx), static_cast<double>(walk.ny)};
  walk.fingerprint = fnv1a64(reinterpret_cast<const char*>(head), sizeof(head)) ^
                     fnv1a64(reinterpret_cast<const char*>(walk.clearance.data()), walk.clearance.size() * sizeof(float));
  return walk;
}

namespace {
// Calls run(i, m, rx, r2, ry, row) over runs of up to kRun consecutive lattice centres of a row
// (the lattice extended beyond its cells, where nothing is walkable) that hold every centre
// within R of x, and a few just beyond (r2 >= R^2, for the caller to skip): centre i + t at
// y = (x + rx[t], x + ry), r2[t] = |y - x|^2; row: the row's clearances, null outside the
// lattice. Returns false without a run when the whole disc is walkable (the centre nearest x is
// clear by more than R plus a cell's diagonal).
constexpr long kRun = 32;
template <class Run>
bool for_each_run(const WalkableLattice& walk, const Vec2& x, double R, Run&& run) {
  const double h = walk.h;
  const Vec2 u = (x - walk.lo) / h;
  const long ci = static_cast<long>(std::floor(u.x())), cj = static_cast<long>(std::floor(u.y()));
  if (ci >= 0 && ci < walk.nx && cj >= 0 && cj < walk.ny && walk.clearance[static_cast<size_t>(cj * walk.nx + ci)] > R + 1.5 * h)
    return false;
  const double r = R / h, R2 = R * R;
  const long i0 = static_cast<long>(std::ceil(u.x() - r - 0.5)), i1 = static_cast<long>(std::floor(u.x() + r - 0.5));
  const long j0 = static_cast<long>(std::ceil(u.y() - r - 0.5)), j1 = static_cast<long>(std::floor(u.y() + r - 0.5));
  double rx[kRun], r2[kRun];
  for (long j = j0; j <= j1; ++j) {
    const double ry = (walk.lo.y() + h * (static_cast<double>(j) + 0.5)) - x.y();
    if (ry * ry >= R2) continue;
    // The row's half chord, in spacings, a centre either side to spare.
    const double chord = std::sqrt(R2 - ry * ry) / h;
    const long a = std::max(i0, static_cast<long>(std::ceil(u.x() - chord - 0.5)) - 1);
    const long b = std::min(i1, static_cast<long>(std::floor(u.x() + chord - 0.5)) + 1);
    const float* row = j >= 0 && j < walk.ny ? walk.clearance.data() + j * walk.nx : nullptr;
    for (long first = a; first <= b; first += kRun) {
      const long m = std::min(kRun, b - first + 1);
      const double f = static_cast<double>(first);  // (whole numbers: f + t is exact)
      for (long t = 0; t < m; ++t) {
        rx[t] = (walk.lo.x() + h * ((f + static_cast<double>(static_cast<int>(t))) + 0.5)) - x.x();
        r2[t] = rx[t] * rx[t] + ry * ry;
      }
      run(first, m, rx, r2, ry, row);
    }
  }
  return true;
}

// The kernel's weights over the lattice centres within R of x: S0 over every centre, S1 over the
// walkable ones, and with derivatives, their gradients along x and the heading e.
struct ShareSums {
  double s0 = 0, s1 = 0;
  Vec2 dx0 = Vec2::Zero(), dx1 = Vec2::Zero(), de0 = Vec2::Zero(), de1 = Vec2::Zero();
};
// False (sums untouched) when the whole disc is walkable. Half of a diagnosis is spent here
// (benchmarks/results/diagnosis_timing.md): each run's weights (and derivatives) are ahead_weight's written out branch-free, so that the
// compiler computes several at once, with the same operations in the same order (the same
// numbers), then summed in the lattice's order; a focus that is not whole (pow) calls ahead_weight.
bool share_sums(const WalkableLattice& walk, const Vec2& x, const Vec2& e, double R, double focus, double Nk, bool derivatives,
                ShareSums& out) {
  const double R2 = R * R, N = e.squaredNorm() > 0 ? Nk : 1, ex = e.x(), ey = e.y(), m2 = -2 / (R * R);
  const bool whole = focus == std::floor(focus) && focus >= 1 && focus <= 16;
  const int k = whole ? static_cast<int>(focus) : 0;
  double w[kRun], drx[kRun], dry[kRun], dex[kRun], dey[kRun];
  return for_each_run(walk, x, R, [&](long first, long m, const double* rx, const double* r2, double ry, const float* row) {
    if (!whole) {
      for (long t = 0; t < m; ++t) {
        if (r2[t] >= R2) continue;
        Vec2 dr = Vec2::Zero(), de = Vec2::Zero();
        w[t] = ahead_weight(Vec2(rx[t], ry), e, R, focus, Nk, derivatives ? &dr : nullptr, derivatives ? &de : nullptr);
        drx[t] = dr.x(), dry[t] = dr.y(), dex[t] = de.x(), dey[t] = de.y();
      }
    } else if (!derivatives && k == 1) {  // (1 * b is b: focus_power(b, 1))
      for (long t = 0; t < m; ++t) w[t] = (1 - r2[t] / R2) * (1 + (rx[t] * ex + ry * ey) / std::sqrt(r2[t])) / N;
    } else if (!derivatives) {
      for (long t = 0; t < m; ++t) {
        const double b = 1 + (rx[t] * ex + ry * ey) / std::sqrt(r2[t]);
        double g = 1;
        for (int q = 0; q < k; ++q) g *= b;
        w[t] = (1 - r2[t] / R2) * g / N;
      }
    } else {
      // b^k and b^(k-1) for the weight and its derivative (k >= 1; for k = 1, b and 1, and the
      // loop free of inner loops).
      const auto derivatives_at = [&](long t, double g, double gk, double n, double a, double c) {
        const double ad = a * (focus * gk);
        w[t] = a * g / N;
        drx[t] = ((g * m2) * rx[t] + ad * (ex - c * rx[t] / n) / n) / N;
        dry[t] = ((g * m2) * ry + ad * (ey - c * ry / n) / n) / N;
        dex[t] = ad * rx[t] / n / N;
        dey[t] = ad * ry / n / N;
      };
      if (k == 1) {
        for (long t = 0; t < m; ++t) {
          const double n = std::sqrt(r2[t]), c = (rx[t] * ex + ry * ey) / n;
          derivatives_at(t, 1 + c, 1, n, 1 - r2[t] / R2, c);
        }
      } else {
        for (long t = 0; t < m; ++t) {
          const double n = std::sqrt(r2[t]), c = (rx[t] * ex + ry * ey) / n, b = 1 + c;
          double g = 1, gk = 1;
          for (int q = 0; q < k; ++q) g *= b;
          for (int q = 1; q < k; ++q) gk *= b;
          derivatives_at(t, g, gk, n, 1 - r2[t] / R2, c);
        }
      }
    }
    for (long t = 0; t < m; ++t) {
      if (r2[t] >= R2) continue;
      double W = w[t];
      if (!(r2[t] > 0)) {  // the centre at x itself: weight 1 - 0, no derivatives
        W = 1 - r2[t] / R2;
        drx[t] = dry[t] = dex[t] = dey[t] = 0;
      }
      const long i = first + t;
      const bool in = row && i >= 0 && i < walk.nx && row[i] > 0;
      out.s0 += W;
      if (in) out.s1 += W;
      if (!derivatives) continue;
      const Vec2 dr(drx[t], dry[t]), de(dex[t], dey[t]);
      out.dx0 -= dr;  // r = y - x
      out.de0 += de;
      if (!in) continue;
      out.dx1 -= dr;
      out.de1 += de;
    }
  });
}
// The walkable share at x (heading e) from its sums: 1 where the disc is whole.
double share_of(bool partial, const ShareSums& S) { return partial && S.s0 > 0 ? S.s1 / S.s0 : 1.0; }
}  // namespace

std::vector<double> walkable_share_ahead(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                                         double R, double focus) {
  std::vector<double> share(x.size(), 1.0);
  if (walk.empty()) return share;
  const double Nk = focus_norm(focus);
  for (size_t p = 0; p < x.size(); ++p) {
    ShareSums S;
    share[p] = share_of(share_sums(walk, x[p], heading[p], R, focus, Nk, false, S), S);
  }
  return share;
}

void per_walkable_area(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R,
                       double focus, std::vector<double>& rho) {
  const std::vector<double> share = walkable_share_ahead(walk, x, heading, R, focus);
  for (size_t p = 0; p < rho.size(); ++p) rho[p] /= std::max(share[p], kMinWalkableShare);
}

std::vector<ShareAhead> walkable_share_ahead_derivatives(const WalkableLattice& walk, const std::vector<Vec2>& x,
                                                         const std::vector<Vec2>& heading, double R, double focus,
                                                         const std::vector<char>& need) {
  std::vector<ShareAhead> out(x.size());
  if (walk.empty()) return out;
  const double Nk = focus_norm(focus);
  for (size_t p = 0; p < x.size(); ++p) {
    if (!need.empty() && !need[p]) continue;
    ShareSums S;
    ShareAhead& d = out[p];
    d.share = share_of(share_sums(walk, x[p], heading[p], R, focus, Nk, true, S), S);
    if (!(S.s0 > 0)) continue;  // the whole disc walkable: no derivatives
    // s = S1 / S0: ds = (dS1 - s dS0) / S0.
    d.s0 = S.s0;
    d.dx = S.dx1 - d.share * S.dx0;
    d.de = S.de1 - d.share * S.de0;
  }
  return out;
}

void walkable_share_ahead_vjp(const std::vector<ShareAhead>& d, const std::vector<double>& share_bar, std::vector<Vec2>& x_bar,
                              std::vector<Vec2>& heading_bar) {
  for (size_t p = 0; p < d.size(); ++p) {
    if (share_bar[p] == 0 || !(d[p].s0 > 0)) continue;
    const double g = share_bar[p] / d[p].s0;
    x_bar[p] += g * d[p].dx;
    heading_bar[p] += g * d[p].de;
  }
}

void walkable_share_ahead_vjp(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                              double R, double focus, const std::vector<double>& share_bar, std::vector<Vec2>& x_bar,
                              std::vector<Vec2>& heading_bar) {
  std::vector<char> need(x.size());
  for (size_t p = 0; p < x.size(); ++p) need[p] = share_bar[p] != 0;
  walkable_share_ahead_vjp(walkable_share_ahead_derivatives(walk, x, heading, R, focus, need), share_bar, x_bar, heading_bar);
}

void reference_volumes(World& w, size_t first, double rest_density) {
  const std::vector<double> rho = local_density(w, first, kDensityRadius);
  for (size_t p = first; p < w.size(); ++p) w.J[p] = std::clamp(rest_density / rho[p - first], kMinJ, 1.0);
}

long World::index_of(EntityId e) const {
  if (e == 0 || e >= slot_.size()) return -1;
  return slot_[e];
}

uint64_t World::state_hash() const {
  std::vector<size_t> order(size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return id[a] < id[b]; });
  uint64_t h = 14695981039346656037ull;
  auto mix = [&](const void* data, size_t n) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (size_t k = 0; k < n; ++k) {
      h ^= p[k];
      h *= 1099511628211ull;
    }
  };
  for (size_t i : order) {
    double buf[4] = {x[i].x(), x[i].y(), v[i].x(), v[i].y()};
    mix(&id[i], sizeof(EntityId));
    mix(buf, sizeof(buf));
  }
  return h;
}

}  // namespace crowdmpm
