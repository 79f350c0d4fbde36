// "wall_friction": drag along one wall (a rough or crowded wall, people touching it, a queue
// along a barrier). With d the distance from the wall's segment [from, to] and t its unit
// direction,
//   a = -coefficient exp(-d / range) (v . t) t,
// so motion along the wall is slowed near it and motion across it is not. Every parameter is
// smooth (the distance to a segment is, except on its end normals), so where the wall is, how
// strongly and how far out it drags can all be fitted.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class WallFriction : public TermFormula<WallFriction> {
 public:
  const char* type() const override { return "wall_friction"; }
  const char* summary() const override { return "a = -coefficient exp(-d/range) (v.t) t near the segment [from, to]"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"from", 2, "m", -1e9, 1e9, kRequired, true, "one end of the wall"},
        {"to", 2, "m", -1e9, 1e9, kRequired, true, "its other end"},
        {"coefficient", 1, "1/s", 0, 50, kRequired, true, "drag rate at the wall"},
        {"range", 1, "m", 0.01, 10, 0.5, true, "decay length of the drag away from the wall"}};
    return f;
  }
  std::string check(const double* p) const override {
    if (std::hypot(p[2] - p[0], p[3] - p[1]) < 1e-6) return "to: must differ from from (a wall has a length)";
    return {};
  }
  template <class T>
  void formula(const T* p, const T x[2], const T v[2], const TermPoint&, T a[2], T&) const {
    const T sx = p[2] - p[0], sy = p[3] - p[1];
    const T len = sqrt(sx * sx + sy * sy);
    const T tx = sx / len, ty = sy / len;
    // The nearest point of the segment: along = clamp((x - from) . t, 0, len).
    T along = (x[0] - p[0]) * tx + (x[1] - p[1]) * ty;
    if (value_of(along) < 0) along = T(0);
    if (value_of(along) > value_of(len)) along = len;
    const T dx = x[0] - (p[0] + along * tx), dy = x[1] - (p[1] + along * ty);
    const T d = sqrt(dx * dx + dy * dy + T(1e-12));
    const T g = p[4] * exp(-(d / p[5])) * (v[0] * tx + v[1] * ty);
    a[0] = -(g * tx);
    a[1] = -(g * ty);
  }
};
}  // namespace
const TermLaw* wall_friction_term() {
  static const WallFriction law;
  return &law;
}
}  // namespace crowdmpm
