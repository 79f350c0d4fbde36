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
  // Over the recorded rows, latest first (not over frame numbers: a recording may leave gaps
  // of any length between frames).
  auto history = [&](long target, long limit) {
    std::unordered_map<long, std::pair<long, Vec2>> at;  // id -> (frame, position)
    const TrackPoint* first = t.frame(limit).first;
    if (limit > target) return at;
    for (const TrackPoint* p = t.frame(target).second; p != first;) {
      --p;
      at.emplace(p->id, std::make_pair(p->frame, Vec2(p->x, p->y)));
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
  const std::unordered_map<long, double> free = free_speeds(t, speed_window, frame);
  for (size_t i = 0; i < s.ids.size(); ++i) {
    auto it = free.find(s.ids[i]);
    s.free_speed.push_back(it != free.end() ? std::max(it->second, s.speed[i]) : s.speed[i]);
  }
  return s;
}

const char* desired_speed_name(DesiredSpeed d) {
  return d == DesiredSpeed::Scenario ? "scenario" : d == DesiredSpeed::Free ? "free" : "observed";
}

std::unordered_map<long, double> free_speeds(const TrajectorySet& t, double speed_window, long last) {
  const long lag = std::max(1L, std::lround(speed_window * t.framerate));
  std::unordered_map<long, std::vector<std::pair<long, Vec2>>> tracks;
  for (const TrackPoint& p : t.points) {  // sorted by frame: each track in time order
    if (p.frame > last) break;
    tracks[p.id].emplace_back(p.frame, Vec2(p.x, p.y));
  }
  std::unordered_map<long, double> out;
  for (auto& [id, track] : tracks) {
    std::vector<double> speeds;
    size_t j = 0;
    for (size_t i = 0; i < track.size(); ++i) {
      while (j < i && track[i].first - track[j + 1].first >= lag) ++j;  // latest sample at least lag frames back
      if (track[i].first - track[j].first < lag) continue;
      speeds.push_back((track[i].second - track[j].second).norm() * t.framerate / static_cast<double>(track[i].first - track[j].first));
    }
    if (speeds.empty()) continue;
    const size_t k = std::min(speeds.size() - 1, static_cast<size_t>(0.9 * static_cast<double>(speeds.size())));
    std::nth_element(speeds.begin(), speeds.begin() + static_cast<long>(k), speeds.end());
    out[id] = speeds[k];
  }
  return out;
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
  std::vector<AgentDef> defs;
  std::vector<size_t> placed;  // index in s of each def
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
    const std::vector<double>& own = o.desired_speed == DesiredSpeed::Free ? s.free_speed : s.speed;
    a.desired_speed = o.desired_speed != DesiredSpeed::Scenario && i < own.size()
                          ? std::clamp(own[i], 0.0, std::min(12.0, model.params.max_speed))
                          : sim.draw_speed(sc.groups[0]);
    if (!std::isfinite(a.desired_speed)) a.desired_speed = 0;
    a.behaviour = sim.behaviour_of_group(0);
    a.group = 0;
    ws.ids.push_back(0);
    if (sim.geo_ok(x)) {
      placed.push_back(i);
      defs.push_back(a);
    }
  }
  const std::vector<EntityId> ids = sim.add_agents(defs);
  for (size_t k = 0; k < placed.size(); ++k) ws.ids[placed[k]] = ids[k];
  return ws;
}

InflowRun::InflowRun(const EdgeInflow& inflow, DesiredSpeed desired_speed)
    : inflow_(inflow), desired_speed_(desired_speed), due_(inflow.points.size(), 0.0) {
  if (!inflow.points.empty() && !(inflow.density > 0)) throw Error("inflow: density must be > 0 persons/m2");
}

void InflowRun::after_step(Simulation& sim) {
  if (inflow_.points.empty()) return;
  const Model& m = sim.model();
  const double dt = sim.scenario().dt;
  const double spacing = hexagonal_spacing(inflow_.density);
  const double walk_in = desired_speed_ == DesiredSpeed::Observed ? m.params.v0_scale : 1.0;
  for (size_t k = 0; k < inflow_.points.size(); ++k) {
    const EdgeInflow::Point& in = inflow_.points[k];
    due_[k] = std::min(2.0, due_[k] + walk_in * in.rate * dt);
    if (due_[k] < 1) continue;
    const World& w = sim.world();
    bool free = true;
    for (size_t p = 0; p < w.size() && free; ++p) free = (w.x[p] - in.x).squaredNorm() >= 0.25 * spacing * spacing;
    if (!free) continue;  // stays due until the spot clears
    due_[k] -= 1;
    AgentDef a;
    a.position = in.x;
    a.velocity = in.v;
    a.body_radius = std::clamp(0.5 * spacing, 0.05, m.params.body_radius);
    a.comfort_distance = m.params.comfort_distance;
    a.desired_speed = desired_speed_ == DesiredSpeed::Scenario ? sim.draw_speed(sim.scenario().groups[0])
                                                               : std::clamp(in.v.norm(), 0.0, std::min(12.0, m.params.max_speed));
    a.behaviour = sim.behaviour_of_group(0);
    a.group = 0;
    sim.add_agent(a);
  }
}

}  // namespace crowdmpm
