// "obstacle": an unmodelled round solid the crowd walks around. Two parts, with r = x - center,
// d = |r|, e = r / d and h the person's walking direction (TermPoint::heading):
//   a = strength exp((radius - d) / softness) e                        (a soft rim)
//     + steer q (h - 2 (h . e) e),   q = 1.25 radius^2 / (d^2 + 0.25 radius^2)
// The second part is the doublet of potential flow past a cylinder (uniform flow h plus
// radius^2 / d^2 (h - 2 (h . e) e) is tangent to the rim): people turn aside well before the
// solid and close in behind it, as a crowd whose route knows the solid does; q is the doublet's
// 1 / d^2 decay, equal to it at the rim and finite at the centre. steer 0 (default) is a pure
// repulsion. Every parameter is smooth, so position, size, stiffness and steering can all be
// fitted (the heading is read as it is, without its own derivative).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Obstacle : public TermFormula<Obstacle> {
 public:
  const char* type() const override { return "obstacle"; }
  const char* summary() const override { return "a = strength exp((radius - |r|)/softness) e + steer q (h - 2 (h.e) e): a soft rim and potential-flow turning"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"center", 2, "m", -1e9, 1e9, kRequired, true, "centre of the solid"},
        {"radius", 1, "m", 0, 50, kRequired, true, "its radius"},
        {"strength", 1, "m/s^2", 0, 200, 10, true, "repulsion at the rim"},
        {"softness", 1, "m", 0.01, 5, 0.15, true, "decay length of the repulsion outside the rim"},
        {"steer", 1, "m/s^2", 0, 50, 0, true, "turning around the solid along potential flow"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint& pt, T a[2], T&) const {
    const T rx = x[0] - p[0], ry = x[1] - p[1];
    const T d = sqrt(rx * rx + ry * ry);
    if (value_of(d) < 1e-9) return;
    const T ex = rx / d, ey = ry / d;
    // Beyond 40 decay lengths the rim's push is below e^-40 of its strength: skip it.
    if (value_of(d) - value_of(p[2]) <= 40 * value_of(p[4])) {
      const T s = p[3] * exp((p[2] - d) / p[4]);
      a[0] = s * ex;
      a[1] = s * ey;
    }
    const double hx = pt.heading.x(), hy = pt.heading.y();
    if (hx * hx + hy * hy > 0) {
      const T r2 = p[2] * p[2];
      const T q = p[5] * T(1.25) * r2 / (d * d + T(0.25) * r2);
      const T he = hx * ex + hy * ey;
      a[0] = a[0] + q * (hx - T(2) * he * ex);
      a[1] = a[1] + q * (hy - T(2) * he * ey);
    }
  }
};
}  // namespace
const TermLaw* obstacle_term() {
  static const Obstacle law;
  return &law;
}
}  // namespace crowdmpm
