#include "engine/observe/observe.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace crowdmpm {

ObservedState observe_at(const TrajectorySet& t, long frame, double velocity_window, double speed_window) {
  ObservedState s;
  s.frame = frame;
  const long back = std::max(1L, std::lround(velocity_window * t.framerate));
  const long back_s = std::max(back, std::lround(speed_window * t.framerate));
  // Each person's latest recorded position at or before `target` frames, searching no further
  // back than `limit` (recordings sampled every few frames, such as ETH/UCY's every 10th,
  // have no row exactly `back` frames earlier).
  auto history = [&](long target, long limit) {
    std::unordered_map<long, std::pair<long, Vec2>> at;  // id -> (frame, position)
    for (long f = target; f >= limit; --f) {
      auto [b, e] = t.frame(f);
      for (auto p = b; p != e; ++p) at.emplace(p->id, std::make_pair(f, Vec2(p->x, p->y)));
    }
    return at;
  };
  const auto before = history(frame - back, frame - 2 * back);
  const auto long_before = history(frame - back_s, frame - 2 * back_s);
  auto [b, e] = t.frame(frame);
  for (auto p = b; p != e; ++p) {
    auto it = before.find(p->id);
    if (it == before.end()) continue;  // too little history for a velocity
    Vec2 x(p->x, p->y);
    s.ids.push_back(p->id);
    s.x.push_back(x);
    s.v.push_back((x - it->second.second) * (t.framerate / static_cast<double>(frame - it->second.first)));
    auto il = long_before.find(p->id);
    s.speed.push_back(il != long_before.end()
                          ? (x - il->second.second).norm() * (t.framerate / static_cast<double>(frame - il->second.first))
                          : s.v.back().norm());
  }
  return s;
}

ScenarioDef window_scenario(const ScenarioDef& scenario, bool keep_exits) {
  if (scenario.groups.empty()) throw Error(scenario.source + ": prediction needs a group whose behaviour the observed people follow");
  ScenarioDef base = scenario;
  for (auto& g : base.groups) {
    if (g.is_source) g.max_count = 0;
    else g.count = 0;
  }
  base.duration = 1e6;
  base.stop_when_empty = false;
  if (!keep_exits) {
    for (auto& e : base.geo.exits) base.geo.goals.push_back(e);
    base.geo.exits.clear();
  }
  return base;
}

WindowSim start_window(const ScenarioDef& sc, const Model& model, const ObservedState& s, const WindowOptions& o) {
  WindowSim ws;
  ws.sim = std::make_unique<Simulation>(sc, model, o.threads);
  Simulation& sim = *ws.sim;
  const double clearance = model.params.wall_clearance;
  // Bodies must fit the observed crowd: recorded crowds reach 9-11 persons/m², closer than
  // the model's default bodies allow, and starting them overlapped would throw them apart.
  // Each agent's radius is at most half its nearest observed neighbour's distance.
  std::vector<double> nearest(s.x.size(), 1e300);
  for (size_t i = 0; i < s.x.size(); ++i)
    for (size_t j = i + 1; j < s.x.size(); ++j) {
      double d = (s.x[i] - s.x[j]).norm();
      nearest[i] = std::min(nearest[i], d);
      nearest[j] = std::min(nearest[j], d);
    }
  for (size_t i = 0; i < s.x.size(); ++i) {
    AgentDef a;
    Vec2 x = s.x[i];
    for (int it = 0; it < 8 && sc.geo.sdf(x) < clearance; ++it) {
      Vec2 n = sc.geo.normal(x);
      if (n.squaredNorm() == 0) break;
      x += (clearance - sc.geo.sdf(x) + 1e-6) * n;
    }
    a.position = x;
    a.velocity = s.v[i];
    a.body_radius = std::clamp(0.5 * nearest[i], 0.05, model.params.body_radius);
    a.comfort_distance = model.params.comfort_distance;
    // An observed speed beyond what the model allows (a tracking glitch) is clamped.
    a.desired_speed = o.desired_speed == DesiredSpeed::Observed && i < s.speed.size()
                          ? std::clamp(s.speed[i], 0.0, std::min(12.0, model.params.max_speed))
                          : sc.groups[0].desired_speed;
    if (!std::isfinite(a.desired_speed)) a.desired_speed = 0;
    a.behaviour = sim.behaviour_of_group(0);
    a.group = 0;
    ws.ids.push_back(sim.geo_ok(x) ? sim.add_agent(a) : 0);
  }
  return ws;
}

}  // namespace crowdmpm
