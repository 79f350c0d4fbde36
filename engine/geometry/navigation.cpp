#include "engine/geometry/navigation.hpp"

#include <cmath>
#include <limits>
#include <algorithm>
#include <functional>
#include <string>

#include "engine/core/error.hpp"

namespace crowdmpm {

static constexpr double kInf = std::numeric_limits<double>::infinity();

NavField::NavField(const Geometry& geo, const std::vector<const Shape*>& targets, double cell, double clearance)
    : lo_(geo.lo), h_(cell) {
  nx_ = std::max(1, static_cast<int>(std::ceil((geo.hi.x() - geo.lo.x()) / h_)));
  ny_ = std::max(1, static_cast<int>(std::ceil((geo.hi.y() - geo.lo.y()) / h_)));
  const size_t n = static_cast<size_t>(nx_) * ny_;
  free_.assign(n, 0);
  for (int j = 0; j < ny_; ++j)
    for (int i = 0; i < nx_; ++i) {
      const Vec2 c = cell_centre(i, j);
      const int k = index(i, j);
      free_[k] = geo.sdf(c) >= clearance;
      bool in_target = false;
      for (const Shape* t : targets) in_target = in_target || t->contains(c);
      if (free_[k] && in_target) seeds_.push_back(k);
    }
  if (seeds_.empty()) {
    // Targets thinner than a cell: seed the walkable cells within two cells of them.
    for (int k = 0; k < static_cast<int>(n); ++k) {
      if (!free_[k]) continue;
      const Vec2 q = cell_centre(k % nx_, k / nx_);
      for (const Shape* t : targets)
        if (t->sdf(q) < 2 * h_) {
          seeds_.push_back(k);
          break;
        }
    }
  }
  seeded_ = !seeds_.empty();
  // The heap holds the marching front (a few times the cells along it, far below n).
  heap_.reserve(n / 4 + seeds_.size() + 64);
  march({});
}

void NavField::set_cost(const std::vector<double>& cost) {
  if (!cost.empty() && cost.size() != free_.size())
    throw Error("navigation cost: " + std::to_string(cost.size()) + " values for " + std::to_string(free_.size()) + " cells");
  march(cost);
}

void NavField::march(const std::vector<double>& cost) {
  const size_t n = free_.size();
  T_.assign(n, kInf);
  dir_.assign(n, Vec2::Zero());
  done_.assign(n, 0);
  // A binary min-heap on heap_ (std::push_heap with greater: the smallest T on top).
  heap_.clear();
  const auto later = std::greater<std::pair<double, int>>();
  auto push = [&](double t, int k) {
    heap_.emplace_back(t, k);
    std::push_heap(heap_.begin(), heap_.end(), later);
  };
  for (int k : seeds_) {
    T_[k] = 0;
    push(0.0, k);
  }
  auto value = [&](int i, int j) { return (i < 0 || j < 0 || i >= nx_ || j >= ny_) ? kInf : T_[index(i, j)]; };
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    const int k = heap_.back().second;
    heap_.pop_back();
    if (done_[k]) continue;
    done_[k] = 1;
    int i = k % nx_, j = k / nx_;
    const int di[4] = {1, -1, 0, 0}, dj[4] = {0, 0, 1, -1};
    for (int d = 0; d < 4; ++d) {
      int a = i + di[d], b = j + dj[d];
      if (a < 0 || b < 0 || a >= nx_ || b >= ny_) continue;
      int q = index(a, b);
      if (!free_[q] || done_[q]) continue;
      const double hc = cost.empty() ? h_ : h_ * cost[q];  // |grad T| = c: a step of h costs h c
      double tx = std::min(value(a - 1, b), value(a + 1, b));
      double ty = std::min(value(a, b - 1), value(a, b + 1));
      double lo = std::min(tx, ty), hi = std::max(tx, ty);
      double tn = (hi - lo >= hc || hi == kInf) ? lo + hc
                                                 : 0.5 * (lo + hi + std::sqrt(2 * hc * hc - (hi - lo) * (hi - lo)));
      if (tn < T_[q]) {
        T_[q] = tn;
        push(tn, q);
      }
    }
  }
  // Upwind gradient: along each axis, the difference towards the smaller neighbour.
  for (int j = 0; j < ny_; ++j)
    for (int i = 0; i < nx_; ++i) {
      int k = index(i, j);
      if (T_[k] == kInf) continue;
      Vec2 g = Vec2::Zero();
      double l = value(i - 1, j), r = value(i + 1, j), dn = value(i, j - 1), up = value(i, j + 1);
      if (std::min(l, r) < T_[k]) g.x() = l < r ? (T_[k] - l) / h_ : (r - T_[k]) / h_;
      if (std::min(dn, up) < T_[k]) g.y() = dn < up ? (T_[k] - dn) / h_ : (up - T_[k]) / h_;
      double gn = g.norm();
      if (gn > 0) dir_[k] = -g / gn;
      else if (T_[k] > 0) {
        // A local minimum away from the target (diagonal-only neighbours): step to the best diagonal.
        double best = T_[k];
        for (int b = -1; b <= 1; ++b)
          for (int a = -1; a <= 1; ++a)
            if (value(i + a, j + b) < best) { best = value(i + a, j + b); dir_[k] = Vec2(a, b).normalized(); }
      }
    }
}

Vec2 NavField::direction(const Vec2& p) const {
  double fx = (p.x() - lo_.x()) / h_ - 0.5, fy = (p.y() - lo_.y()) / h_ - 0.5;
  int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
  double tx = fx - i0, ty = fy - j0;
  Vec2 d = Vec2::Zero();
  for (int b = 0; b < 2; ++b)
    for (int a = 0; a < 2; ++a) {
      int i = i0 + a, j = j0 + b;
      if (i < 0 || j < 0 || i >= nx_ || j >= ny_) continue;
      int k = index(i, j);
      if (T_[k] == kInf) continue;
      double w = (a ? tx : 1 - tx) * (b ? ty : 1 - ty);
      d += w * dir_[k];
    }
  double n = d.norm();
  if (n > 1e-12) return d / n;
  // In the clearance band next to a wall: use the nearest walkable cell in a 5x5 neighbourhood.
  int ic = static_cast<int>(std::floor(fx + 0.5)), jc = static_cast<int>(std::floor(fy + 0.5));
  double best = kInf;
  Vec2 out = Vec2::Zero();
  for (int b = -2; b <= 2; ++b)
    for (int a = -2; a <= 2; ++a) {
      int i = ic + a, j = jc + b;
      if (i < 0 || j < 0 || i >= nx_ || j >= ny_) continue;
      int k = index(i, j);
      if (T_[k] == kInf) continue;
      Vec2 c = lo_ + h_ * Vec2(i + 0.5, j + 0.5);
      double score = T_[k] + (c - p).norm();
      if (score < best) { best = score; out = c - p; }
    }
  n = out.norm();
  return n > 1e-12 ? Vec2(out / n) : Vec2::Zero();
}

double NavField::distance(const Vec2& p) const {
  int i = static_cast<int>(std::floor((p.x() - lo_.x()) / h_));
  int j = static_cast<int>(std::floor((p.y() - lo_.y()) / h_));
  if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return kInf;
  double t = T_[index(i, j)];
  if (t < kInf) return t;
  double best = kInf;
  for (int b = -2; b <= 2; ++b)
    for (int a = -2; a <= 2; ++a) {
      int u = i + a, v = j + b;
      if (u < 0 || v < 0 || u >= nx_ || v >= ny_) continue;
      best = std::min(best, T_[index(u, v)] + h_ * std::hypot(a, b));
    }
  return best;
}

}  // namespace crowdmpm
