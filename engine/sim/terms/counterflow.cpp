// "counterflow": a share of the people inside a rectangle walk another way (a group heading
// back against the crowd, people crossing it). Person i is picked by a stable draw u_i in [0, 1)
// from their id, smoothly: w_i = 1 / (1 + exp((u_i - share) / 0.02)). Inside the rectangle
// (smooth edges as slow_zone, r(x)), a picked person's own drive is switched off and replaced
// by a push along the direction d = (cos direction, sin direction):
//   f = 1 - w_i r(x),   a = w_i r(x) push d.
// A person pushed with `push` under the model's relaxation time tau walks at about push tau.
// With by_motion 1 the people are picked by how they move instead (share is not read):
// w_i = 1 / (1 + exp(-(v_i . d - along) / 0.1)), the people moving along d faster than `along`
// m/s (along -0.3: everyone not walking against d at 0.3 m/s or more, those heading d and those
// held up on their way). An id draw picks other people than a recording's in a window started
// from the recorded state (its ids are not the recording's); the motion picks the people seen
// doing it.
#include "engine/sim/terms.hpp"

namespace crowdmpm {
namespace {
double draw(uint64_t id) {  // splitmix64 of the id, as a number in [0, 1)
  uint64_t z = id + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
}

class Counterflow : public TermFormula<Counterflow> {
 public:
  const char* type() const override { return "counterflow"; }
  const char* summary() const override { return "a share of the people in [xmin, xmax] x [ymin, ymax] pushed along direction instead of their own way"; }
  const std::vector<TermField>& fields() const override {
    static const std::vector<TermField> f = {
        {"min", 2, "m", -1e9, 1e9, kRequired, true, "lower left corner (xmin, ymin)"},
        {"max", 2, "m", -1e9, 1e9, kRequired, true, "upper right corner (xmax, ymax)"},
        {"direction", 1, "degrees", -720, 720, kRequired, true, "where the picked people head, from +x counter-clockwise"},
        {"share", 1, "1", 0, 1, kRequired, true, "share of the people picked"},
        {"push", 1, "m/s^2", 0, 20, 2.6, true, "their drive along the direction"},
        {"edge", 1, "m", 0.01, 10, 0.5, true, "width of the rectangle's smooth edge"},
        {"by_motion", 1, "1", 0, 1, 0, false, "1: pick the people moving along direction faster than `along` (share not read); 0: by the id draw and share"},
        {"along", 1, "m/s", -5, 5, -0.3, true, "with by_motion 1, the speed along direction above which a person is picked"}};
    return f;
  }
  std::string check(const double* p) const override {
    if (!(p[0] < p[2] && p[1] < p[3])) return "max: must lie above and right of min";
    if (p[8] != 0 && p[8] != 1) return "by_motion: must be 0 or 1";
    return {};
  }
  template <class T>
  void formula(const T* p, const T x[2], const T v[2], const TermPoint& pt, T a[2], T& f) const {
    const T r = smooth_box(p, x, p[7]);
    const T angle = p[4] * T(M_PI / 180);
    const T dx = cos(angle), dy = sin(angle);
    const T w = value_of(p[8]) == 1 ? T(1) / (T(1) + exp(-(v[0] * dx + v[1] * dy - p[9]) / T(0.1)))
                                    : T(1) / (T(1) + exp((T(draw(pt.id)) - p[5]) / T(0.02)));
    const T wr = w * r;
    f = T(1) - wr;
    a[0] = wr * p[6] * dx;
    a[1] = wr * p[6] * dy;
  }
};
}  // namespace
const TermLaw* counterflow_term() {
  static const Counterflow law;
  return &law;
}
}  // namespace crowdmpm
