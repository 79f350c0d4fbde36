// "constriction": an unmodelled wall across the flow with one opening (a gate, a bottleneck's
// walls, a narrowed exit). With n = (cos angle, sin angle) the direction through the opening,
// t = (-sin angle, cos angle) along the wall, and for a person at x
//   u = (x - center) . n   (signed distance from the wall's line),
//   s = (x - center) . t   (along it; the opening is |s| < width / 2),
// each side's solid (k s >= width / 2, k = +-1) is nearest at (0, s) beside the opening and at its
// edge (0, k width / 2) inside the opening's band; with d_k the distance to it and e_k the unit
// vector from it to the person:
//   a = sum_k strength exp((thickness / 2 - d_k) / softness) e_k                (the wall's rim)
//     + steer exp(-|u| / reach) (g - h)   for people walking towards the wall's line
// where g is the unit vector from the person to the opening's centre and h their walking
// direction (TermPoint::heading): people turn towards the opening as they near the wall, as a
// crowd whose route knows the gate does. The wall is a straight line through the whole venue;
// the venue's own walls bound it. Every parameter is smooth (the rim's push is continuous across the
// opening's edges), so where the wall is, its opening, its direction and how early people turn
// can all be fitted (the heading is read as it is, without its own derivative).
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
class Constriction : public TermFormula<Constriction> {
 public:
  const char* type() const override { return "constriction"; }
  const char* summary() const override {
    return "a wall across direction `angle` through center with an opening of `width`: a = strength exp((thickness/2 - d)/softness) e "
           "+ steer exp(-|u|/reach) (g - h)";
  }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"center", 2, "m", -1e9, 1e9, kRequired, true, "centre of the opening, on the wall's line"},
        {"width", 1, "m", 0.05, 100, kRequired, true, "width of the opening"},
        {"angle", 1, "degrees", -720, 720, kRequired, true, "direction through the opening (normal to the wall), from +x counter-clockwise"},
        {"thickness", 1, "m", 0, 5, 0.2, true, "the wall's thickness"},
        {"strength", 1, "m/s^2", 0, 200, 10, true, "repulsion at the rim"},
        {"softness", 1, "m", 0.01, 5, 0.15, true, "decay length of the repulsion outside the rim"},
        {"steer", 1, "m/s^2", 0, 50, 0, true, "turning towards the opening"},
        {"reach", 1, "m", 0.05, 50, 2, true, "decay length of the turning away from the wall"}};
    return f;
  }
  template <class T>
  void formula(const T* p, const T x[2], const T*, const TermPoint& pt, T a[2], T&) const {
    const T angle = p[3] * T(M_PI / 180);
    const T nx = cos(angle), ny = sin(angle);
    const T dx = x[0] - p[0], dy = x[1] - p[1];
    const T u = dx * nx + dy * ny, s = dy * nx - dx * ny;
    const T half = T(0.5) * p[2];
    // Each side's solid (k s >= width / 2, k = +-1) pushes from its nearest point: (0, s) beside
    // the opening, its edge (0, k width / 2) inside the opening's band; the vector from there to
    // the person is (u, vs) in (n, t) components. Both sides together keep the push continuous.
    for (const double k : {1.0, -1.0}) {
      const T vs = k * value_of(s) >= value_of(half) ? T(0) : s - T(k) * half;
      const T d = sqrt(u * u + vs * vs);
      if (value_of(d) < 1e-9 || value_of(d) - 0.5 * value_of(p[4]) > 40 * value_of(p[6])) continue;
      const T push = p[5] * exp((T(0.5) * p[4] - d) / p[6]) / d;
      a[0] = a[0] + push * (u * nx - vs * ny);  // push d e, e = (u n + vs t) / d
      a[1] = a[1] + push * (u * ny + vs * nx);
    }
    const double hx = pt.heading.x(), hy = pt.heading.y();
    const double hn = hx * value_of(nx) + hy * value_of(ny);
    // Walking towards the line: heading along +n from u < 0, or along -n from u > 0.
    if (hx * hx + hy * hy > 0 && hn * value_of(u) < 0) {
      const T gx = -dx, gy = -dy;
      const T g = sqrt(gx * gx + gy * gy);
      if (value_of(g) > 1e-9) {
        const T q = p[7] * exp(-(abs_of(u) / p[8]));
        a[0] = a[0] + q * (gx / g - hx);
        a[1] = a[1] + q * (gy / g - hy);
      }
    }
  }

 private:
  template <class T>
  static T abs_of(const T& v) {
    return value_of(v) < 0 ? -v : v;
  }
};
}  // namespace
const TermLaw* constriction_term() {
  static const Constriction law;
  return &law;
}
}  // namespace crowdmpm
