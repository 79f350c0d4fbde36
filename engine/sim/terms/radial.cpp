// "radial" (alias "attractor"): towards (strength > 0) or away from (< 0) a point, within a range.
// With r = x - center, d = |r|: a = -strength r / d for 1e-9 < d <= range. The cutoff at the
// range is hard, so the range is not learnable.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Radial : public TermFormula<Radial> {
 public:
  const char* type() const override { return "radial"; }
  const char* alias() const override { return "attractor"; }
  const char* summary() const override { return "a = -strength (x - center)/|x - center| within range"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"center", 2, "m", -1e9, 1e9, kRequired, true, "the point"},
        {"strength", 1, "m/s^2", -50, 50, kRequired, true, "> 0 pulls in, < 0 pushes out"},
        {"range", 1, "m", 1e-9, 1e300, 1e300, false, "no acceleration farther than this"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T a[2], T&) const {
    const T rx = x[0] - p[0], ry = x[1] - p[1];
    const T d = sqrt(rx * rx + ry * ry);
    if (value_of(d) < 1e-9 || value_of(d) > value_of(p[3])) return;
    a[0] = -p[2] * (rx / d);
    a[1] = -p[2] * (ry / d);
  }
};
}  // namespace
const TermLaw* radial_term() {
  static const Radial law;
  return &law;
}
}  // namespace crowdmpm
