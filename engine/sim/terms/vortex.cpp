// "vortex": turning around a point (strength > 0 counter-clockwise), within a range. With
// r = x - center, d = |r|: a = strength (-r_y, r_x) / d for 1e-9 < d <= range (hard cutoff: the
// range is not learnable).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Vortex : public TermFormula<Vortex> {
 public:
  const char* type() const override { return "vortex"; }
  const char* summary() const override { return "a = strength (-r_y, r_x)/|r|, r = x - center, within range"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"center", 2, "m", -1e9, 1e9, kRequired, true, "the centre"},
        {"strength", 1, "m/s^2", -50, 50, kRequired, true, "> 0 counter-clockwise"},
        {"range", 1, "m", 1e-9, 1e300, 1e300, false, "no acceleration farther than this"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T a[2], T&) const {
    const T rx = x[0] - p[0], ry = x[1] - p[1];
    const T d = sqrt(rx * rx + ry * ry);
    if (value_of(d) < 1e-9 || value_of(d) > value_of(p[3])) return;
    a[0] = p[2] * (-ry / d);
    a[1] = p[2] * (rx / d);
  }
};
}  // namespace
const TermLaw* vortex_term() {
  static const Vortex law;
  return &law;
}
}  // namespace crowdmpm
