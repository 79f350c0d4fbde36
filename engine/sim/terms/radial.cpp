// "radial" (alias "attractor"): towards (strength > 0) or away from (< 0) a point, within a range:
// a = -strength w r / d, r = x - center, d = |r|, w = 1 within range (or a smooth edge there:
// centred_offset).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Radial : public TermFormula<Radial> {
 public:
  const char* type() const override { return "radial"; }
  const char* alias() const override { return "attractor"; }
  const char* summary() const override { return "a = -strength (x - center)/|x - center| within range"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = centred_fields("> 0 pulls in, < 0 pushes out");
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint&, T a[2], T&) const {
    T rx, ry, d, w;
    if (!centred_offset(p, x, rx, ry, d, w)) return;
    a[0] = -p[2] * w * (rx / d);
    a[1] = -p[2] * w * (ry / d);
  }
};
}  // namespace
const TermLaw* radial_term() {
  static const Radial law;
  return &law;
}
}  // namespace crowdmpm
