// "uniform" (alias "drift"): the same acceleration everywhere: a slope, wind, a push.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Uniform : public TermFormula<Uniform> {
 public:
  const char* type() const override { return "uniform"; }
  const char* alias() const override { return "drift"; }
  const char* summary() const override { return "a = acceleration everywhere"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"acceleration", 2, "m/s^2", -50, 50, kRequired, true, "the acceleration"}};
    return f;
  }
  std::string check(const double* p) const override {
    if (std::hypot(p[0], p[1]) > 50) return "acceleration: is above 50 m/s^2; check the units (m/s^2)";
    return {};
  }
  template <class T>
  void formula(const T* p, const T*, const T*, const TermPoint&, T a[2], T&) const {
    a[0] = p[0];
    a[1] = p[1];
  }
};
}  // namespace
const TermLaw* uniform_term() {
  static const Uniform law;
  return &law;
}
}  // namespace crowdmpm
