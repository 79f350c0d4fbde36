#include "engine/observe/measure.hpp"

#include <cmath>
#include <limits>
#include <unordered_map>

#include "engine/core/error.hpp"

namespace crowdmpm {

std::vector<DensitySpeed> classic_density_speed(const TrajectorySet& t, const Vec2& lo, const Vec2& hi, double every) {
  if (!(hi.x() > lo.x() && hi.y() > lo.y())) throw Error("measurement area: max must lie above and right of min");
  if (!(every > 0) || !(t.framerate > 0)) throw Error("measurement interval and frame rate must be > 0");
  const double area = (hi.x() - lo.x()) * (hi.y() - lo.y());
  const long step = std::max(1L, std::lround(every * t.framerate));
  std::vector<DensitySpeed> out;
  for (long f = t.frame_min(); f < t.frame_max(); f = t.skip_gap(f + step, step)) {
    auto [b, e] = t.frame(f);
    auto [nb, ne] = t.frame(f + 1);
    std::unordered_map<long, Vec2> next;
    for (auto p = nb; p != ne; ++p) next.emplace(p->id, Vec2(p->x, p->y));
    DensitySpeed s;
    s.time = static_cast<double>(f - t.frame_min()) / t.framerate;
    long inside = 0, moving = 0;
    double speed_sum = 0;
    for (auto p = b; p != e; ++p) {
      if (p->x < lo.x() || p->x > hi.x() || p->y < lo.y() || p->y > hi.y()) continue;
      ++inside;
      auto it = next.find(p->id);
      if (it == next.end()) continue;
      speed_sum += (it->second - Vec2(p->x, p->y)).norm() * t.framerate;
      ++moving;
    }
    s.density = static_cast<double>(inside) / area;
    s.speed = moving ? speed_sum / static_cast<double>(moving) : std::numeric_limits<double>::quiet_NaN();
    out.push_back(s);
  }
  return out;
}

}  // namespace crowdmpm
