// "vortex": turning around a point (strength > 0 counter-clockwise), within a range:
// a = strength w (-r_y, r_x) / d, r = x - center, d = |r|, w = 1 within range (or a smooth edge
// there: centred_offset).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Vortex : public TermFormula<Vortex> {
 public:
  const char* type() const override { return "vortex"; }
  const char* summary() const override { return "a = strength (-r_y, r_x)/|r|, r = x - center, within range"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = centred_fields("> 0 counter-clockwise");
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T a[2], T&) const {
    T rx, ry, d, w;
    if (!centred_offset(p, x, rx, ry, d, w)) return;
    a[0] = p[2] * w * (-ry / d);
    a[1] = p[2] * w * (rx / d);
  }
};
}  // namespace
const TermLaw* vortex_term() {
  static const Vortex law;
  return &law;
}
}  // namespace crowdmpm
