#include "engine/predict/replay.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include "engine/observe/observe.hpp"

namespace crowdmpm {

namespace {
// Whether the step from p to q crosses the segment [a, b] (proper or touching at q's side).
bool crosses(const Vec2& p, const Vec2& q, const PassageLine& l) {
  auto side = [](const Vec2& o, const Vec2& u, const Vec2& v) { return (u.x() - o.x()) * (v.y() - o.y()) - (u.y() - o.y()) * (v.x() - o.x()); };
  const double s1 = side(l.a, l.b, p), s2 = side(l.a, l.b, q), s3 = side(p, q, l.a), s4 = side(p, q, l.b);
  return ((s1 > 0 && s2 <= 0) || (s1 < 0 && s2 >= 0)) && ((s3 > 0) != (s4 > 0));
}
}  // namespace

std::vector<double> recorded_passages(const TrajectorySet& t, const PassageLine& line) {
  std::unordered_map<long, Vec2> last;
  std::unordered_map<long, double> passed;
  for (const TrackPoint& p : t.points) {
    const Vec2 x(p.x, p.y);
    auto it = last.find(p.id);
    if (it != last.end() && !passed.count(p.id) && crosses(it->second, x, line))
      passed[p.id] = static_cast<double>(p.frame - t.frame_min()) / t.framerate;
    last[p.id] = x;
  }
  std::vector<double> out;
  for (const auto& kv : passed) out.push_back(kv.second);
  std::sort(out.begin(), out.end());
  return out;
}

double middle_flow(const std::vector<double>& times) {
  if (times.size() < 10) return 0;
  const size_t k20 = times.size() / 5, k80 = (times.size() * 4) / 5;
  return times[k80] > times[k20] ? static_cast<double>(k80 - k20) / (times[k80] - times[k20]) : 0;
}

ReplayResult replay_recording(const ScenarioDef& scenario, const Model& model, const TrajectorySet& rec,
                              const PassageLine& line, double extra, int threads, uint64_t jitter_seed) {
  ReplayResult r;
  r.recorded = recorded_passages(rec, line);
  // Each person's first appearance, and the velocity over their first half second.
  struct Arrival {
    double time;
    long frame;
    Vec2 x, v;
  };
  std::map<long, Arrival> first;  // by id
  const long half = std::max(1L, std::lround(0.5 * rec.framerate));
  for (const TrackPoint& p : rec.points) {
    const Vec2 x(p.x, p.y);
    auto [it, added] = first.try_emplace(p.id, Arrival{static_cast<double>(p.frame - rec.frame_min()) / rec.framerate, p.frame, x,
                                                       Vec2::Zero()});
    if (!added && p.frame - it->second.frame == half)
      it->second.v = (x - it->second.x) * (rec.framerate / static_cast<double>(half));
  }
  std::vector<Arrival> arrivals;
  for (const auto& kv : first) arrivals.push_back(kv.second);
  std::stable_sort(arrivals.begin(), arrivals.end(), [](const Arrival& a, const Arrival& b) { return a.time < b.time; });
  r.people = arrivals.size();
  if (jitter_seed > 0) {
    Rng rng(jitter_seed);
    for (Arrival& a : arrivals) {
      const double dx = rng.normal(), dy = rng.normal();
      a.x += kReplayJitter * Vec2(dx, dy);
    }
  }

  const ScenarioDef sc = window_scenario(scenario, true);
  Simulation sim(sc, model, threads);
  const Model& m = sim.model();
  const double clearance = m.params.wall_clearance;
  std::unordered_map<EntityId, Vec2> previous;
  std::unordered_map<EntityId, char> counted;
  size_t next = 0;
  const double end = rec.duration() + extra;
  while (sim.time() < end) {
    // Arrivals due by now: placed out of solids, bodies no wider than the room they have.
    for (; next < arrivals.size() && arrivals[next].time <= sim.time() + 1e-9; ++next) {
      Vec2 x = arrivals[next].x;
      for (int it = 0; it < 8 && sc.geo.sdf(x) < clearance; ++it) {
        const Vec2 n = sc.geo.normal(x);
        if (n.squaredNorm() == 0) break;
        x += (clearance - sc.geo.sdf(x) + 1e-6) * n;
      }
      if (!sim.geo_ok(x)) continue;
      // The model's own body size, even where the recorded crowd is denser than those bodies
      // pack: shrinking people to fit would let them through bottlenecks faster (AO_300 with
      // the headway model: 1.54x the recorded flow with bodies shrunk to half the nearest
      // distance, 1.05x at full size). The contact law separates the overlaps in the first steps.
      AgentDef a;
      a.position = x;
      a.velocity = arrivals[next].v;
      a.body_radius = m.params.body_radius;
      a.comfort_distance = m.params.comfort_distance;
      a.desired_speed = sc.groups[0].desired_speed;
      a.behaviour = sim.behaviour_of_group(0);
      a.group = 0;
      const EntityId id = sim.add_agent(a);
      previous[id] = x;
      ++r.placed;
    }
    sim.step();
    const World& w = sim.world();
    for (size_t p = 0; p < w.size(); ++p) {
      const EntityId id = w.id[p];
      auto it = previous.find(id);
      if (it != previous.end() && !counted[id] && crosses(it->second, w.x[p], line)) {
        counted[id] = 1;
        r.simulated.push_back(sim.time());
      }
      previous[id] = w.x[p];
    }
    if (next == arrivals.size() && w.size() == 0) break;
  }
  r.duration = sim.time();
  std::sort(r.simulated.begin(), r.simulated.end());
  r.recorded_flow = middle_flow(r.recorded);
  r.simulated_flow = middle_flow(r.simulated);
  return r;
}

std::vector<ReplayResult> replay_repeats(const ScenarioDef& scenario, const Model& model, const TrajectorySet& recording,
                                         const PassageLine& line, int repeats, double extra, int threads) {
  if (repeats < 1) throw Error("replay: repeats must be at least 1, got " + std::to_string(repeats));
  std::vector<ReplayResult> runs;
  for (int k = 1; k <= repeats; ++k)
    runs.push_back(replay_recording(scenario, model, recording, line, extra, threads, k == 1 ? 0 : static_cast<uint64_t>(k)));
  return runs;
}

double mean_simulated_flow(const std::vector<ReplayResult>& runs) {
  double sum = 0;
  for (const ReplayResult& r : runs) sum += r.simulated_flow;
  return runs.empty() ? 0 : sum / static_cast<double>(runs.size());
}

}  // namespace crowdmpm
