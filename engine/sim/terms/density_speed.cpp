// "density_speed": the desired speed falls with the local density, after Weidmann (1993),
//   f = 1 - exp(-gamma s(1/rho - 1/max_density)),   s(u) = ln(1 + e^(10 u)) / 10,
// rho the persons/m^2 within 1 m of the person (TermPoint::density, read as it is), s a smooth
// max(u, 0) so that f reaches ~0 at max_density and every parameter has a gradient. Weidmann's
// values are gamma = 1.913 persons/m^2, max_density = 5.4 persons/m^2.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class DensitySpeed : public TermFormula<DensitySpeed> {
 public:
  const char* type() const override { return "density_speed"; }
  const char* summary() const override { return "desired speed times 1 - exp(-gamma (1/rho - 1/max_density)) (smoothly 0 beyond max_density)"; }
  bool needs_density() const override { return true; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"gamma", 1, "persons/m^2", 0.01, 50, 1.913, true, "how fast the speed falls with density"},
        {"max_density", 1, "persons/m^2", 0.5, 12, 5.4, true, "density at which people stop"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T*, const T*, const TermPoint& pt, T*, T& f) const {
    const double rho = std::max(pt.density, 0.05);
    const T u = T(1.0 / rho) - T(1) / p[1];
    // s(u) = ln(1 + e^(10 u)) / 10, written so that it neither overflows nor loses u for u >> 0.
    const T s = value_of(u) > 0 ? u + log(T(1) + exp(T(-10) * u)) / T(10) : log(T(1) + exp(T(10) * u)) / T(10);
    f = T(1) - exp(-(p[0] * s));
  }
};
}  // namespace
const TermLaw* density_speed_term() {
  static const DensitySpeed law;
  return &law;
}
}  // namespace crowdmpm
