// "obstacle": an unmodelled round solid the crowd walks around, as a soft repulsion from its
// rim: with r = x - center, d = |r|, a = strength exp((radius - d) / softness) r / d.
// Every parameter is smooth, so position, size and stiffness can all be fitted.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Obstacle : public TermFormula<Obstacle> {
 public:
  const char* type() const override { return "obstacle"; }
  const char* summary() const override { return "a = strength exp((radius - |r|)/softness) r/|r|, r = x - center"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"center", 2, "m", -1e9, 1e9, kRequired, true, "centre of the solid"},
        {"radius", 1, "m", 0, 50, kRequired, true, "its radius"},
        {"strength", 1, "m/s^2", 0, 200, 10, true, "repulsion at the rim"},
        {"softness", 1, "m", 0.01, 5, 0.15, true, "decay length of the repulsion outside the rim"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T a[2], T&) const {
    const T rx = x[0] - p[0], ry = x[1] - p[1];
    const T d = sqrt(rx * rx + ry * ry);
    if (value_of(d) < 1e-9) return;
    // Beyond 40 decay lengths the push is below e^-40 of its strength: skip it.
    if (value_of(d) - value_of(p[2]) > 40 * value_of(p[4])) return;
    const T s = p[3] * exp((p[2] - d) / p[4]);
    a[0] = s * (rx / d);
    a[1] = s * (ry / d);
  }
};
}  // namespace
const TermLaw* obstacle_term() {
  static const Obstacle law;
  return &law;
}
}  // namespace crowdmpm
