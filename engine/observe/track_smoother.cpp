#include "engine/observe/track_smoother.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Dense>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"

namespace crowdmpm {

namespace {

// One track, one axis: the time (s) since the previous position (the first unused) and positions.
struct Series {
  std::vector<double> dt;
  std::vector<double> z;
};

// One person's series along one axis (0: x, 1: y); idx: their points in frame order.
Series series_of(const TrajectorySet& t, const std::vector<size_t>& idx, int axis) {
  Series s;
  for (size_t k = 0; k < idx.size(); ++k) {
    const TrackPoint& p = t.points[idx[k]];
    s.dt.push_back(k ? static_cast<double>(p.frame - t.points[idx[k - 1]].frame) / t.framerate : 0.0);
    s.z.push_back(axis ? p.y : p.x);
  }
  return s;
}

// The filter's state: position, velocity and their covariance (p_pp, p_pv, p_vv).
struct State {
  double p = 0, v = 0, cpp = 0, cpv = 0, cvv = 0;
};

constexpr double kVelocityPrior = 3;  // m/s: sd of a track's velocity before its second position
constexpr double kGate = 25;          // an innovation counts at most 5 standard deviations

State predicted(const State& s, double dt, double q) {
  State o;
  o.p = s.p + dt * s.v;
  o.v = s.v;
  o.cpp = s.cpp + 2 * dt * s.cpv + dt * dt * s.cvv + q * dt * dt * dt / 3;
  o.cpv = s.cpv + dt * s.cvv + q * dt * dt / 2;
  o.cvv = s.cvv + q * dt;
  return o;
}

State updated(const State& s, double z, double r2) {
  const double S = s.cpp + r2, kp = s.cpp / S, kv = s.cpv / S, e = z - s.p;
  State o;
  o.p = s.p + kp * e;
  o.v = s.v + kv * e;
  o.cpp = s.cpp - kp * s.cpp;
  o.cpv = s.cpv - kp * s.cpv;
  o.cvv = s.cvv - kv * s.cpv;
  return o;
}

// The state after a track's first position (seen with variance r2), velocity not yet known.
State initial(double z, double r2) { return State{z, 0, r2, 0, kVelocityPrior * kVelocityPrior}; }

// The smoother's backward gain C = P_k F^T (P'_k+1)^-1 from a filtered state f and the next
// predicted state p, dt apart (F = [[1, dt], [0, 1]]): the correction of f's position and velocity
// per unit of the next smoothed-minus-predicted position and velocity. Empty when p's covariance
// has collapsed (a vanishing acceleration), where the filter's estimate stands.
struct Gain {
  double pp, pv, vp, vv;  // [[pp, pv], [vp, vv]]
};
std::optional<Gain> backward_gain(const State& f, const State& p, double dt) {
  const double a = f.cpp + dt * f.cpv, b = f.cpv, c = f.cpv + dt * f.cvv, d = f.cvv;  // P_k F^T = [[a, b], [c, d]]
  const double det = p.cpp * p.cvv - p.cpv * p.cpv;
  if (!(det > 0)) return std::nullopt;
  const double i00 = p.cvv / det, i01 = -p.cpv / det, i11 = p.cpp / det;
  return Gain{a * i00 + b * i01, a * i01 + b * i11, c * i00 + d * i01, c * i01 + d * i11};
}

// Negative log likelihood per innovation (from each series' third position on, where the
// velocity is known from the data), with outlying innovations capped at kGate.
double innovation_nll(const std::vector<Series>& all, double q, double r2) {
  double sum = 0;
  long n = 0;
  for (const Series& s : all) {
    if (s.z.size() < 3) continue;
    State x = initial(s.z[0], r2);
    for (size_t k = 1; k < s.z.size(); ++k) {
      const State pr = predicted(x, s.dt[k], q);
      if (k >= 2) {
        const double S = pr.cpp + r2, e = s.z[k] - pr.p;
        sum += std::log(S) + std::min(e * e / S, kGate);
        ++n;
      }
      x = updated(pr, s.z[k], r2);
    }
  }
  return n ? sum / static_cast<double>(n) : 0;
}

}  // namespace

TrackNoise estimate_track_noise(const TrajectorySet& t) {
  TrackNoise out;
  if (!(t.framerate > 0) || t.points.empty()) return out;
  std::vector<Series> all;
  for (const auto& idx : t.tracks())
    for (int axis = 0; axis < 2; ++axis) all.push_back(series_of(t, idx, axis));
  const double dt = 1.0 / t.framerate;
  // Moments of second differences at consecutive frames: with white position noise of variance
  // R and white acceleration of density q, var(d2) = 6R + 2/3 q dt^3 and
  // cov(d2_k, d2_k+1) = -4R + 1/6 q dt^3.
  double c0 = 0, c1 = 0;
  long n0 = 0, n1 = 0;
  const double tol = 1e-6 * dt;
  for (const Series& s : all)
    for (size_t k = 2; k < s.z.size(); ++k) {
      if (std::abs(s.dt[k] - dt) > tol || std::abs(s.dt[k - 1] - dt) > tol) continue;
      const double d = s.z[k] - 2 * s.z[k - 1] + s.z[k - 2];
      c0 += d * d;
      ++n0;
      if (k + 1 < s.z.size() && std::abs(s.dt[k + 1] - dt) <= tol) {
        c1 += d * (s.z[k + 1] - 2 * s.z[k] + s.z[k - 1]);
        ++n1;
      }
    }
  long n = 0;
  for (const Series& s : all) n += std::max(0L, static_cast<long>(s.z.size()) - 2);
  if (n < 20 || n0 == 0 || n1 == 0) return out;
  c0 /= static_cast<double>(n0);
  c1 /= static_cast<double>(n1);
  const double r2_floor = 1e-12, q_floor = 1e-6;
  double lr = std::log(std::max((c0 - 4 * c1) / 22, std::max(r2_floor, 1e-4 * c0)));
  double lq = std::log(std::max(6 * (c1 + 4 * std::exp(lr)) / (dt * dt * dt), std::max(q_floor, 1e-2 * c0 / (dt * dt * dt))));
  const double lr_lo = std::log(r2_floor), lr_hi = std::log(1.0), lq_lo = std::log(q_floor), lq_hi = std::log(1e4);
  const auto nll = [&](double a, double b) { return innovation_nll(all, std::exp(a), std::exp(b)); };
  double best = nll(lq, lr);
  // Compass search: steps of e^1 down to e^0.01 on each axis.
  for (double step = 1; step >= 0.01;) {
    bool moved = false;
    for (int axis = 0; axis < 2; ++axis)
      for (int sign = -1; sign <= 1; sign += 2) {
        const double a = axis == 0 ? std::clamp(lq + sign * step, lq_lo, lq_hi) : lq;
        const double b = axis == 1 ? std::clamp(lr + sign * step, lr_lo, lr_hi) : lr;
        const double v = nll(a, b);
        if (v < best) best = v, lq = a, lr = b, moved = true;
      }
    if (!moved) step /= 2;
  }
  out.position = std::exp(lr / 2);
  out.acceleration = std::exp(lq);
  out.samples = n;
  return out;
}

namespace {
void check_levels(const TrackNoise& noise) {
  if (!(std::isfinite(noise.position) && noise.position >= 0 && std::isfinite(noise.acceleration) && noise.acceleration >= 0))
    throw Error("track smoother: noise levels must be finite and >= 0, got position " + format_number(noise.position) +
                " m, acceleration " + format_number(noise.acceleration) + " m^2/s^3");
}
constexpr double kMinAcceleration = 1e-9;  // m^2/s^3: the smoother's least acceleration density
}  // namespace

SmoothedError smoothed_error(const TrackNoise& noise, double dt, long lag) {
  check_levels(noise);
  if (!(std::isfinite(dt) && dt > 0)) throw Error("track smoother: the time between frames must be > 0 s, got " + format_number(dt));
  if (lag < 1) throw Error("track smoother: a velocity's lag must be at least 1 frame, got " + std::to_string(lag));
  if (noise.position == 0) return {};
  const double r2 = noise.position * noise.position, q = std::max(noise.acceleration, kMinAcceleration);
  // The filter's steady state, iterated from the state after a first position (the Riccati
  // recursion converges geometrically): its covariance after an update and predicted.
  State f = initial(0, r2);
  for (int k = 0; k < 1000000; ++k) {
    const State next = updated(predicted(f, dt, q), 0, r2);
    const double change = std::max({std::abs(next.cpp - f.cpp), std::abs(next.cpv - f.cpv), std::abs(next.cvv - f.cvv)});
    const bool still = change <= 1e-15 * std::max({std::abs(f.cpp), std::abs(f.cpv), std::abs(f.cvv)});
    f = next;
    if (still && k > 10) break;
  }
  const State p = predicted(f, dt, q);
  const std::optional<Gain> c = backward_gain(f, p, dt);
  if (!c) return {std::sqrt(f.cpp), 0};
  // The smoother's steady state: Ps = P + G (Ps - Pp) G^T.
  using M = Eigen::Matrix2d;
  M P, Pp, G;
  P << f.cpp, f.cpv, f.cpv, f.cvv;
  Pp << p.cpp, p.cpv, p.cpv, p.cvv;
  G << c->pp, c->pv, c->vp, c->vv;
  M Ps = P;
  for (int k = 0; k < 1000000; ++k) {
    const M next = P + G * (Ps - Pp) * G.transpose();
    const bool still = (next - Ps).cwiseAbs().maxCoeff() <= 1e-15 * Ps.cwiseAbs().maxCoeff();
    Ps = next;
    if (still && k > 10) break;
  }
  M Gm = M::Identity();
  for (long k = 0; k < lag; ++k) Gm = Gm * G;
  const double var = Ps(0, 0), cov = (Gm * Ps)(0, 0), span = static_cast<double>(lag) * dt;
  return {std::sqrt(var), std::sqrt(std::max(0.0, 2 * (var - cov))) / span};
}

TrajectorySet smoothed_tracks(const TrajectorySet& t, const TrackNoise& noise) {
  check_levels(noise);
  TrajectorySet out = t;
  if (noise.position == 0 || !(t.framerate > 0)) return out;
  const double r2 = noise.position * noise.position, q = std::max(noise.acceleration, kMinAcceleration);
  for (const auto& idx : t.tracks()) {
    const size_t n = idx.size();
    if (n < 2) continue;
    for (int axis = 0; axis < 2; ++axis) {
      const Series track = series_of(t, idx, axis);
      std::vector<State> filt(n), pred(n);
      filt[0] = initial(track.z[0], r2);
      pred[0] = filt[0];
      for (size_t k = 1; k < n; ++k) {
        pred[k] = predicted(filt[k - 1], track.dt[k], q);
        filt[k] = updated(pred[k], track.z[k], r2);
      }
      // Backward: x_k += C (x_k+1 smoothed - x_k+1 predicted), C the backward gain.
      State sm = filt[n - 1];
      std::vector<double> pos(n);
      pos[n - 1] = sm.p;
      for (size_t k = n - 1; k-- > 0;) {
        const State& f = filt[k];
        const State& p = pred[k + 1];
        const std::optional<Gain> c = backward_gain(f, p, track.dt[k + 1]);
        if (!c) {
          sm = f;
          pos[k] = f.p;
          continue;
        }
        const double dp = sm.p - p.p, dv = sm.v - p.v;
        State s;
        s.p = f.p + c->pp * dp + c->pv * dv;
        s.v = f.v + c->vp * dp + c->vv * dv;
        sm = s;  // (only the means are needed backward)
        pos[k] = sm.p;
      }
      for (size_t k = 0; k < n; ++k) (axis ? out.points[idx[k]].y : out.points[idx[k]].x) = pos[k];
    }
  }
  return out;
}

TrackNoise smooth_under_own_noise(TrajectorySet& t) {
  const TrackNoise levels = estimate_track_noise(t);
  if (levels.position > 0) t = smoothed_tracks(t, levels);
  return levels;
}

}  // namespace crowdmpm
