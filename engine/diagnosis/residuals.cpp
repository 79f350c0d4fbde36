#include "engine/diagnosis/residuals.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "engine/core/parallel.hpp"
#include "engine/predict/predict.hpp"

namespace crowdmpm {
namespace {

// Recorded positions of some people at one frame (NaN where not recorded).
std::vector<Vec2> recorded_at(const TrajectorySet& t, long frame, const std::vector<long>& ids) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::unordered_map<long, Vec2> at;
  auto [b, e] = t.frame(frame);
  for (auto p = b; p != e; ++p) at.emplace(p->id, Vec2(p->x, p->y));
  std::vector<Vec2> out;
  out.reserve(ids.size());
  for (long id : ids) {
    auto it = at.find(id);
    out.push_back(it == at.end() ? Vec2(nan, nan) : it->second);
  }
  return out;
}

// Whether x lies within the margin of a source's region (see ResidualOptions::source_margin).
bool near_source(const ScenarioDef& s, const Vec2& x, double margin) {
  for (const GroupDef& g : s.groups)
    if (g.is_source && g.region.sdf(x) < margin) return true;
  return false;
}

bool finite(const Vec2& v) { return std::isfinite(v.x()) && std::isfinite(v.y()); }

// The rollout starts between from and to, and the frames of a rollout's middle and end.
struct Rollouts {
  std::vector<long> starts;
  long mid = 0, end = 0;
};
Rollouts plan(const TrajectorySet& t, long from, long to, const ResidualOptions& o) {
  if (!(o.horizon > 0 && o.stride > 0)) throw Error("diagnosis: residual horizon and stride must be > 0 s");
  Rollouts r;
  r.end = std::max(2L, std::lround(o.horizon * t.framerate));
  r.mid = r.end / 2;
  const long stride = std::max(1L, std::lround(o.stride * t.framerate));
  const long history = std::lround(std::max(o.velocity_window, o.speed_window) * t.framerate);
  for (long f = t.skip_gap(std::max(from, t.frame_min() + history), stride); f + r.end <= to; f = t.skip_gap(f + stride, stride))
    r.starts.push_back(f);
  return r;
}

// Runs one rollout per start (in parallel over starts, each simulation on one thread) and
// merges what each returns in start order, so the result does not depend on the threads.
template <class F>
ResidualSet over_rollouts(const Rollouts& plan, int threads, F&& one) {
  std::vector<ResidualSet> parts(plan.starts.size());
  ThreadPool pool(std::max(1, threads));
  pool.parallel_for(plan.starts.size(), [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) parts[i] = one(i);
  }, 1);
  ResidualSet all;
  for (auto& p : parts) {
    all.velocity.insert(all.velocity.end(), p.velocity.begin(), p.velocity.end());
    all.positions.insert(all.positions.end(), p.positions.begin(), p.positions.end());
    all.rollouts += p.rollouts;
  }
  return all;
}

}  // namespace

ResidualSet recorded_residuals(const ScenarioDef& scenario, const Model& model, const TrajectorySet& t, long from,
                               long to, const ResidualOptions& o) {
  const Rollouts p = plan(t, from, to, o);
  const Predictor predict = simulation_predictor(scenario, model, WindowOptions{1, o.desired_speed});
  const double h = static_cast<double>(p.end) / t.framerate, hm = static_cast<double>(p.mid) / t.framerate;
  const auto history = speed_history_for(t, o.speed_window, o.desired_speed);
  return over_rollouts(p, o.threads, [&](size_t i) {
    ResidualSet out;
    const long f0 = p.starts[i];
    const ObservedState s = observe_at(t, f0, o.velocity_window, o.speed_window, history);
    if (s.ids.empty()) return out;
    const auto sim = predict(s, {h});
    const auto mid = recorded_at(t, f0 + p.mid, s.ids), end = recorded_at(t, f0 + p.end, s.ids);
    const double tm = static_cast<double>(f0) / t.framerate + hm, te = static_cast<double>(f0) / t.framerate + h;
    for (size_t k = 0; k < s.ids.size(); ++k) {
      if (!finite(end[k]) || !finite(mid[k]) || !finite(sim[0][k])) continue;
      if (near_source(scenario, mid[k], o.source_margin)) continue;
      out.velocity.push_back({mid[k], tm, (end[k] - sim[0][k]) / h, s.ids[k], (end[k] - s.x[k]) / h});
      out.positions.push_back({end[k], te, 1.0});
      out.positions.push_back({sim[0][k], te, -1.0});
    }
    out.rollouts = 1;
    return out;
  });
}

ResidualSet null_residuals(const ScenarioDef& scenario, const Model& model, const TrajectorySet& t, long from, long to,
                           const ResidualOptions& o, const TrackError& error, uint64_t seed) {
  const Rollouts p = plan(t, from, to, o);
  const Predictor predict = simulation_predictor(scenario, model, WindowOptions{1, o.desired_speed});
  const double h = static_cast<double>(p.end) / t.framerate, hm = static_cast<double>(p.mid) / t.framerate;
  const double noise = error.position, v_noise = error.velocity;
  const auto history = speed_history_for(t, o.speed_window, o.desired_speed);
  return over_rollouts(p, o.threads, [&](size_t i) {
    ResidualSet out;
    const long f0 = p.starts[i];
    const ObservedState s = observe_at(t, f0, o.velocity_window, o.speed_window, history);
    if (s.ids.empty()) return out;
    Rng rng(seed * 0x9E3779B97F4A7C15ULL + static_cast<uint64_t>(f0) * 7919 + 1);
    auto normal2 = [&rng]() {  // separate statements: the order of the draws is fixed
      const double a = rng.normal();
      const double b = rng.normal();
      return Vec2(a, b);
    };
    const auto truth = predict(s, {hm, h});
    ObservedState seen = s;
    for (size_t k = 0; k < seen.ids.size(); ++k) {
      seen.x[k] += noise * normal2();
      seen.v[k] += v_noise * normal2();
    }
    const auto sim = predict(seen, {h});
    const double tm = static_cast<double>(f0) / t.framerate + hm, te = static_cast<double>(f0) / t.framerate + h;
    for (size_t k = 0; k < s.ids.size(); ++k) {
      if (!finite(truth[1][k]) || !finite(truth[0][k]) || !finite(sim[0][k])) continue;
      if (near_source(scenario, truth[0][k], o.source_margin)) continue;
      const Vec2 end = truth[1][k] + noise * normal2();
      out.velocity.push_back({truth[0][k], tm, (end - sim[0][k]) / h, s.ids[k], (end - seen.x[k]) / h});
      out.positions.push_back({end, te, 1.0});
      out.positions.push_back({sim[0][k], te, -1.0});
    }
    out.rollouts = 1;
    return out;
  });
}

TrackError white_track_error(double noise, double velocity_window, double framerate) {
  const double span = static_cast<double>(velocity_lag_frames(velocity_window, framerate)) / framerate;
  return {noise, std::sqrt(2.0) * noise / span};
}

double tracking_noise(const TrajectorySet& t) {
  // Consecutive rows of one person three frames in a row.
  std::vector<double> d2;
  for (const auto& tr : t.tracks())
    for (size_t k = 1; k + 1 < tr.size(); ++k) {
      const TrackPoint &a = t.points[tr[k - 1]], &b = t.points[tr[k]], &c = t.points[tr[k + 1]];
      if (a.frame + 1 == b.frame && b.frame + 1 == c.frame)
        d2.push_back((Vec2(c.x, c.y) - 2 * Vec2(b.x, b.y) + Vec2(a.x, a.y)).squaredNorm());
    }
  if (d2.empty()) return 0;
  std::nth_element(d2.begin(), d2.begin() + static_cast<long>(d2.size() / 2), d2.end());
  // |d2|^2 of white noise of sd s per component is 6 s^2 times a chi-square with 2 degrees of
  // freedom, whose median is 2 ln 2.
  return std::sqrt(d2[d2.size() / 2] / (6 * 2 * std::log(2.0)));
}

double ResidualMap::rms(int min_people) const {
  double s = 0;
  long n = 0;
  for (size_t c = 0; c < mean.size(); ++c)
    if (people[c] >= min_people) {
      s += mean[c].squaredNorm();
      ++n;
    }
  return n ? std::sqrt(s / static_cast<double>(n)) : 0;
}

ResidualMap bin_residuals(const ResidualSet& s, const Geometry& geo, const ResidualOptions& o) {
  if (!(o.cell > 0 && o.time_bin > 0)) throw Error("diagnosis: residual cell and time bin must be > 0");
  ResidualMap m;
  m.cell = o.cell;
  m.time_bin = o.time_bin;
  m.origin = geo.lo;
  m.nx = std::max(1, static_cast<int>(std::ceil((geo.hi.x() - geo.lo.x()) / o.cell)));
  m.ny = std::max(1, static_cast<int>(std::ceil((geo.hi.y() - geo.lo.y()) / o.cell)));
  double t_lo = std::numeric_limits<double>::infinity(), t_hi = -t_lo;
  for (const auto& r : s.velocity) {
    t_lo = std::min(t_lo, r.t);
    t_hi = std::max(t_hi, r.t);
  }
  if (s.velocity.empty()) t_lo = t_hi = 0;
  m.t0 = t_lo;
  m.nt = std::max(1, static_cast<int>(std::floor((t_hi - t_lo) / o.time_bin)) + 1);
  const size_t cells = static_cast<size_t>(m.nx) * static_cast<size_t>(m.ny);
  auto cell_of = [&](const Vec2& x, int& ix, int& iy) {
    ix = static_cast<int>(std::floor((x.x() - m.origin.x()) / m.cell));
    iy = static_cast<int>(std::floor((x.y() - m.origin.y()) / m.cell));
    return ix >= 0 && iy >= 0 && ix < m.nx && iy < m.ny;
  };
  // The robust spread of one component.
  std::vector<double> comp;
  comp.reserve(2 * s.velocity.size());
  for (const auto& r : s.velocity) {
    comp.push_back(r.r.x());
    comp.push_back(r.r.y());
  }
  if (!comp.empty()) {
    auto mid = comp.begin() + static_cast<long>(comp.size() / 2);
    std::nth_element(comp.begin(), mid, comp.end());
    const double med = *mid;
    for (double& c : comp) c = std::abs(c - med);
    std::nth_element(comp.begin(), mid, comp.end());
    m.sigma = std::max(1.4826 * *mid, 1e-6);
  }
  std::vector<Vec2> sum(cells, Vec2::Zero());
  std::vector<double> count(cells, 0);
  std::vector<std::vector<long>> ids(cells);
  m.sum_t.assign(cells * static_cast<size_t>(m.nt), Vec2::Zero());
  m.count_t.assign(cells * static_cast<size_t>(m.nt), 0);
  for (const auto& r : s.velocity) {
    int ix, iy;
    if (!cell_of(r.x, ix, iy)) continue;
    const size_t c = m.index(ix, iy);
    sum[c] += r.r;
    count[c] += 1;
    ids[c].push_back(r.id);
    const int it = std::clamp(static_cast<int>(std::floor((r.t - m.t0) / m.time_bin)), 0, m.nt - 1);
    m.sum_t[static_cast<size_t>(it) * cells + c] += r.r;
    m.count_t[static_cast<size_t>(it) * cells + c] += 1;
  }
  std::vector<double> dens(cells, 0);
  for (const auto& p : s.positions) {
    int ix, iy;
    if (cell_of(p.x, ix, iy)) dens[m.index(ix, iy)] += p.weight;
  }
  m.mean.assign(cells, Vec2::Zero());
  m.people.assign(cells, 0);
  m.z.assign(cells, 0);
  m.density.assign(cells, 0);
  const double per_rollout = 1.0 / (static_cast<double>(std::max<long>(1, s.rollouts)) * 9 * m.cell * m.cell);
  std::vector<long> pooled;
  for (int iy = 0; iy < m.ny; ++iy)
    for (int ix = 0; ix < m.nx; ++ix) {
      const size_t c = m.index(ix, iy);
      if (count[c] > 0) m.mean[c] = sum[c] / count[c];
      Vec2 ps = Vec2::Zero();
      double pn = 0, pd = 0;
      pooled.clear();
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int jx = ix + dx, jy = iy + dy;
          if (jx < 0 || jy < 0 || jx >= m.nx || jy >= m.ny) continue;
          const size_t q = m.index(jx, jy);
          ps += sum[q];
          pn += count[q];
          pd += dens[q];
          pooled.insert(pooled.end(), ids[q].begin(), ids[q].end());
        }
      std::sort(pooled.begin(), pooled.end());
      m.people[c] = static_cast<double>(std::unique(pooled.begin(), pooled.end()) - pooled.begin());
      m.density[c] = pd * per_rollout;
      if (pn > 0 && m.people[c] >= o.min_people) m.z[c] = (ps / pn).norm() * std::sqrt(m.people[c]) / m.sigma;
    }
  return m;
}

std::vector<Cluster> find_clusters(const ResidualMap& m, const ResidualSet& s, const ResidualOptions& o) {
  const size_t cells = m.z.size();
  std::vector<int> label(cells, -1);
  std::vector<Cluster> out;
  for (size_t c0 = 0; c0 < cells; ++c0) {
    if (label[c0] >= 0 || !(m.z[c0] > o.z_threshold)) continue;
    Cluster cl;
    std::vector<size_t> stack = {c0};
    label[c0] = static_cast<int>(out.size());
    while (!stack.empty()) {
      const size_t c = stack.back();
      stack.pop_back();
      cl.cells.push_back(c);
      const int ix = static_cast<int>(c % static_cast<size_t>(m.nx)), iy = static_cast<int>(c / static_cast<size_t>(m.nx));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int jx = ix + dx, jy = iy + dy;
          if (jx < 0 || jy < 0 || jx >= m.nx || jy >= m.ny) continue;
          const size_t q = m.index(jx, jy);
          if (label[q] < 0 && m.z[q] > o.z_threshold) {
            label[q] = static_cast<int>(out.size());
            stack.push_back(q);
          }
        }
    }
    double wsum = 0;
    cl.lo = Vec2(1e300, 1e300);
    cl.hi = -cl.lo;
    for (size_t c : cl.cells) {
      const int ix = static_cast<int>(c % static_cast<size_t>(m.nx)), iy = static_cast<int>(c / static_cast<size_t>(m.nx));
      const double w = m.z[c] * m.z[c];
      cl.statistic += w;
      cl.center += w * m.centre(ix, iy);
      wsum += w;
      cl.lo = cl.lo.cwiseMin(m.origin + Vec2(ix * m.cell, iy * m.cell));
      cl.hi = cl.hi.cwiseMax(m.origin + Vec2((ix + 1) * m.cell, (iy + 1) * m.cell));
    }
    cl.center /= wsum;
    cl.radius = std::max(m.cell, std::sqrt(static_cast<double>(cl.cells.size()) / M_PI) * m.cell);
    out.push_back(std::move(cl));
  }
  // What each cluster's samples say: mean residual, radial and tangential parts about its
  // centre (within its radius plus a cell), the time bins where its own z passes the threshold.
  const size_t ncells = static_cast<size_t>(m.nx) * static_cast<size_t>(m.ny);
  for (Cluster& cl : out) {
    const double reach = cl.radius + m.cell;
    Vec2 sum = Vec2::Zero(), flow = Vec2::Zero();
    double n = 0, rad = 0, tan = 0, nrt = 0;
    for (const auto& r : s.velocity) {
      const Vec2 d = r.x - cl.center;
      const double dist = d.norm();
      if (dist > reach) continue;
      sum += r.r;
      flow += r.moved;
      n += 1;
      if (dist > 1e-6) {
        rad += r.r.dot(d / dist);
        tan += (d.x() * r.r.y() - d.y() * r.r.x()) / dist;
        nrt += 1;
      }
    }
    if (n > 0) {
      cl.mean_residual = sum / n;
      cl.flow = flow / n;
    }
    if (nrt > 0) {
      cl.radial = rad / nrt;
      cl.tangential = tan / nrt;
    }
    int first = -1, last = -1;
    for (int it = 0; it < m.nt; ++it) {
      Vec2 ts = Vec2::Zero();
      double tn = 0;
      for (size_t c : cl.cells) {
        ts += m.sum_t[static_cast<size_t>(it) * ncells + c];
        tn += m.count_t[static_cast<size_t>(it) * ncells + c];
      }
      // Within one time bin the samples of a person are few: count them as independent / 3.
      const double zt = tn > 0 ? (ts / tn).norm() * std::sqrt(tn / 3) / m.sigma : 0;
      if (zt > o.z_threshold) {
        if (first < 0) first = it;
        last = it;
      }
    }
    if (first < 0) {
      first = 0;
      last = m.nt - 1;
    }
    cl.t_start = m.t0 + first * m.time_bin;
    cl.t_end = m.t0 + (last + 1) * m.time_bin;
    // The hole: the cell near the cluster where the model has the most people the recording lacks.
    double best = 0;
    cl.hole = cl.center;
    for (int iy = 0; iy < m.ny; ++iy)
      for (int ix = 0; ix < m.nx; ++ix) {
        const Vec2 c = m.centre(ix, iy);
        if ((c - cl.center).norm() > cl.radius + 2 * m.cell) continue;
        const double lack = -m.density[m.index(ix, iy)];
        if (lack > best) {
          best = lack;
          cl.hole = c;
        }
      }
  }
  std::sort(out.begin(), out.end(), [](const Cluster& a, const Cluster& b) { return a.statistic > b.statistic; });
  return out;
}

void assess_clusters(std::vector<Cluster>& clusters, const std::vector<double>& null_maxima, const ResidualOptions& o) {
  double mean = 0, var = 0;
  for (double v : null_maxima) mean += v;
  if (!null_maxima.empty()) mean /= static_cast<double>(null_maxima.size());
  for (double v : null_maxima) var += (v - mean) * (v - mean);
  if (null_maxima.size() > 1) var /= static_cast<double>(null_maxima.size() - 1);
  // A floor on the spread: a null with few or no clusters still varies by about one cell's worth.
  const double sd = std::max(std::sqrt(var), o.z_threshold * o.z_threshold);
  for (Cluster& c : clusters) c.significance = 0.5 * std::erfc((c.statistic - mean) / (sd * std::sqrt(2.0)));
}

}  // namespace crowdmpm
