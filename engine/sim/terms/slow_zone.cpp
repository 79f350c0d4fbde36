// "slow_zone": desired speed multiplied by `factor` inside a rectangle (stairs, a bar, a
// viewing point), with smooth edges so that every parameter has a gradient:
//   f = 1 + (factor - 1) s(x - xmin) s(xmax - x) s(y - ymin) s(ymax - y),
//   s(u) = 1 / (1 + exp(-4 u / edge)) (from 12% to 88% over one edge width).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class SlowZone : public TermFormula<SlowZone> {
 public:
  const char* type() const override { return "slow_zone"; }
  const char* summary() const override { return "desired speed times factor inside [xmin, xmax] x [ymin, ymax], smooth edges"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"min", 2, "m", -1e9, 1e9, kRequired, true, "lower left corner (xmin, ymin)"},
        {"max", 2, "m", -1e9, 1e9, kRequired, true, "upper right corner (xmax, ymax)"},
        {"factor", 1, "1", 0, 5, kRequired, true, "desired speed factor inside"},
        {"edge", 1, "m", 0.01, 10, 0.2, true, "width of the smooth edge"}};
    return f;
  }
  std::string check(const double* p) const override {
    if (!(p[0] < p[2] && p[1] < p[3])) return "max: must lie above and right of min";
    return {};
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T*, T& f) const {
    f = T(1) + (p[4] - T(1)) * smooth_box(p, x, p[5]);
  }
};
}  // namespace
const TermLaw* slow_zone_term() {
  static const SlowZone law;
  return &law;
}
}  // namespace crowdmpm
