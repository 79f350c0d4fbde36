#include "engine/observe/observe.hpp"

#include "engine/sim/kernels.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace crowdmpm {

namespace {
// The upper median, as elsewhere in the engine (reorders x).
double upper_median(std::vector<double>& x) {
  std::nth_element(x.begin(), x.begin() + static_cast<long>(x.size() / 2), x.end());
  return x[x.size() / 2];
}

// The median, over frames with two people or more (at most about 200 of them, evenly spread), of
// the median distance from each person to their nearest neighbour; 0 when no frame has two.
double median_neighbour_distance(const TrajectorySet& t) {
  std::vector<long> frames;
  for (long f = t.frame_min(); f <= t.frame_max(); f = t.skip_gap(f + 1, 1)) frames.push_back(f);
  const size_t step = std::max<size_t>(1, frames.size() / 200);
  std::vector<double> medians;
  for (size_t k = 0; k < frames.size(); k += step) {
    const auto [a, b] = t.frame(frames[k]);
    const long n = b - a;
    if (n < 2 || n > 2000) continue;
    std::vector<double> nearest;
    for (const TrackPoint* p = a; p != b; ++p) {
      double d2 = std::numeric_limits<double>::infinity();
      for (const TrackPoint* q = a; q != b; ++q)
        if (q != p) d2 = std::min(d2, (p->x - q->x) * (p->x - q->x) + (p->y - q->y) * (p->y - q->y));
      nearest.push_back(std::sqrt(d2));
    }
    medians.push_back(upper_median(nearest));
  }
  return medians.empty() ? 0 : upper_median(medians);
}
}  // namespace

void check_recording_scale(const TrajectorySet& t, const Geometry& geo, const std::string& venue) {
  if (t.points.empty()) return;
  // The share of the positions inside the domain with the file's numbers read `scale` times
  // larger than they were.
  auto inside_share = [&](double scale) {
    size_t in = 0;
    for (const TrackPoint& q : t.points) in += geo.in_domain(scale * Vec2(q.x, q.y)) ? 1 : 0;
    return static_cast<double>(in) / static_cast<double>(t.points.size());
  };
  const double spacing = median_neighbour_distance(t);
  // Units that would fit: most positions inside the venue and people spaced as bodies allow.
  auto hint = [&](const std::string& otherwise) {
    for (const auto& [scale, unit] : {std::pair<double, const char*>{0.01, "centimetres"}, {0.001, "millimetres"},
                                      {100, "metres (its header's unit makes them 100 times smaller)"},
                                      {1000, "metres (its header's unit makes them 1000 times smaller)"}})
      if (inside_share(scale) >= 0.9 && (spacing == 0 || scale * spacing >= kMinBodySpacing))
        return std::string("its numbers fit the venue as ") + unit + ": state the unit in its header (\"# unit: cm\", \"mm\" or \"m\")";
    return otherwise;
  };
  const double inside = inside_share(1);
  if (inside < 0.5) {
    const auto [lo, hi] = t.bounds();
    auto box = [](const Vec2& a, const Vec2& b) {
      return "[" + format_number(a.x()) + ", " + format_number(b.x()) + "] x [" + format_number(a.y()) + ", " + format_number(b.y()) + "] m";
    };
    throw Error(t.source + ": " + format_number(std::round(1000 * (1 - inside)) / 10) + "% of its positions lie outside the domain of " + venue +
                ", " + box(geo.lo, geo.hi) + " (the recording spans " + box(lo, hi) + "): " +
                hint("a recording of another venue, or in other units than its header states (\"# unit: cm\" or mm; metres when none)"));
  }
  if (spacing > 0 && spacing < kMinBodySpacing)
    throw Error(t.source + ": its people stand " + format_number(std::round(1000 * spacing) / 1000) +
                " m from their nearest neighbour (median over its frames), closer than bodies allow (" + format_number(kMinBodySpacing) +
                " m): " + hint("a recording in other units than its header states (\"# unit: cm\" or mm; metres when none), or each person tracked twice"));
}

long velocity_lag_frames(double velocity_window, double framerate) {
  return std::max(1L, std::lround(velocity_window * framerate));
}

ObservedState observe_at(const TrajectorySet& t, long frame, double velocity_window, double speed_window,
                         std::shared_ptr<const SpeedHistory> history) {
  ObservedState s;
  s.frame = frame;
  s.history = std::move(history);
  const long back = velocity_lag_frames(velocity_window, t.framerate);
  const long back_s = std::max(back, std::lround(speed_window * t.framerate));
  // Each person's latest recorded position at or before `target` frames, searching no further
  // back than `limit` (recordings sampled every few frames, such as ETH/UCY's every 10th,
  // have no row exactly `back` frames earlier).
  // Over the recorded rows, latest first (not over frame numbers: a recording may leave gaps
  // of any length between frames).
  auto recorded_before = [&](long target, long limit) {
    std::unordered_map<long, std::pair<long, Vec2>> at;  // id -> (frame, position)
    const TrackPoint* first = t.frame(limit).first;
    if (limit > target) return at;
    for (const TrackPoint* p = t.frame(target).second; p != first;) {
      --p;
      at.emplace(p->id, std::make_pair(p->frame, Vec2(p->x, p->y)));
    }
    return at;
  };
  const auto before = recorded_before(frame - back, frame - 2 * back);
  const auto long_before = recorded_before(frame - back_s, frame - 2 * back_s);
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

namespace {
// Calls visit(id, i, j, speed) for every recorded point i (an index into t.points) of frame at
// most `last` whose track has a point j at least speed_window earlier (the latest such), with the
// speed between them; each track in frame order.
template <class Visit>
void for_each_track_speed(const TrajectorySet& t, double speed_window, long last, Visit&& visit) {
  const long lag = std::max(1L, std::lround(speed_window * t.framerate));
  std::unordered_map<long, std::vector<size_t>> tracks;
  for (size_t k = 0; k < t.points.size(); ++k) {  // sorted by frame: each track in time order
    if (t.points[k].frame > last) break;
    tracks[t.points[k].id].push_back(k);
  }
  for (auto& [id, track] : tracks) {
    size_t j = 0;
    for (size_t i = 0; i < track.size(); ++i) {
      const TrackPoint& a = t.points[track[i]];
      while (j < i && a.frame - t.points[track[j + 1]].frame >= lag) ++j;  // latest sample at least lag frames back
      const TrackPoint& b = t.points[track[j]];
      if (a.frame - b.frame < lag) continue;
      visit(id, track[i], track[j], (Vec2(a.x, a.y) - Vec2(b.x, b.y)).norm() * t.framerate / static_cast<double>(a.frame - b.frame));
    }
  }
}

// The 90th percentile of speeds (reordered).
double percentile90(std::vector<double>& speeds) {
  const size_t k = std::min(speeds.size() - 1, static_cast<size_t>(0.9 * static_cast<double>(speeds.size())));
  std::nth_element(speeds.begin(), speeds.begin() + static_cast<long>(k), speeds.end());
  return speeds[k];
}
}  // namespace

std::unordered_map<long, double> free_speeds(const TrajectorySet& t, double speed_window, long last) {
  std::unordered_map<long, std::vector<double>> speeds;
  for_each_track_speed(t, speed_window, last, [&](long id, size_t, size_t, double v) { speeds[id].push_back(v); });
  std::unordered_map<long, double> out;
  for (auto& [id, v] : speeds) out[id] = percentile90(v);
  return out;
}

std::unordered_map<long, double> free_speeds_by_law(const SpeedHistory& h, long last, const MaterialParams& P,
                                                    const WalkableLattice* walk) {
  std::unordered_map<long, double> out;
  const std::vector<float>& rho = h.density_ahead(P.density_speed_reach, P.density_speed_focus, walk);
  std::vector<double> v;
  TermPoint pt;
  for (const auto& [id, samples] : h.by_id) {
    v.clear();
    for (const SpeedSample& x : samples) {
      if (x.frame > last) break;
      pt.density_ahead = rho[x.point];
      v.push_back(x.speed / std::max(material_density_factor(P, pt), kLawFactorFloor));
    }
    if (!v.empty()) out[id] = std::min(percentile90(v), kLawFreeSpeedCap);
  }
  return out;
}

SpeedDistribution free_speed_distribution(const TrajectorySet& t, double speed_window, long last, const MaterialParams* law) {
  std::unordered_map<long, double> by_id;
  if (law && material_density_law(*law)) by_id = free_speeds_by_law(*speed_history(t, speed_window), last, *law, nullptr);
  else by_id = free_speeds(t, speed_window, last);
  std::vector<double> v;
  for (const auto& [id, speed] : by_id)
    if (std::isfinite(speed)) v.push_back(speed);
  if (v.empty())
    throw Error(t.source + ": nobody is seen walking for " + format_number(speed_window) + " s up to frame " + std::to_string(last) +
                ": no free speed to read");
  SpeedDistribution d;
  d.median = upper_median(v);
  for (double& x : v) x = std::abs(x - d.median);
  d.sd = 1.4826 * upper_median(v);
  d.people = static_cast<long>(v.size());
  return d;
}

const std::vector<float>& SpeedHistory::density_ahead(double reach, double focus, const WalkableLattice* walk) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::unique_ptr<std::vector<float>>& rho = cache_[{reach, focus, walk ? walk->fingerprint : 0}];
  if (rho) return *rho;
  auto d = std::make_unique<std::vector<float>>(at.size(), 0.0f);
  std::vector<Vec2> xs, hs;
  for (size_t i = 0; i + 1 < frame_start.size(); ++i) {
    const size_t b = frame_start[i], e = frame_start[i + 1];
    xs.assign(at.begin() + static_cast<long>(b), at.begin() + static_cast<long>(e));
    hs.assign(dir.begin() + static_cast<long>(b), dir.begin() + static_cast<long>(e));
    std::vector<double> r = local_density_ahead(xs, hs, reach, focus);
    if (walk) per_walkable_area(*walk, xs, hs, reach, focus, r);
    for (size_t k = b; k < e; ++k) (*d)[k] = static_cast<float>(r[k - b]);
  }
  rho = std::move(d);
  return *rho;
}

std::shared_ptr<const SpeedHistory> speed_history(const TrajectorySet& t, double speed_window) {
  auto h = std::make_shared<SpeedHistory>();
  // One walk over the tracks: each speed sample, and its point's walking direction (zero where
  // the track is shorter than the speed window or the person stands).
  h->at.reserve(t.points.size());
  for (const TrackPoint& p : t.points) h->at.emplace_back(p.x, p.y);
  h->dir.assign(t.points.size(), Vec2::Zero());
  for_each_track_speed(t, speed_window, std::numeric_limits<long>::max(), [&](long id, size_t i, size_t j, double v) {
    h->by_id[id].push_back({t.points[i].frame, static_cast<float>(v), i});
    const Vec2 d(t.points[i].x - t.points[j].x, t.points[i].y - t.points[j].y);
    if (d.squaredNorm() > 0) h->dir[i] = d.normalized();
  });
  for (size_t b = 0; b < t.points.size();) {
    h->frame_start.push_back(b);
    size_t e = b;
    while (e < t.points.size() && t.points[e].frame == t.points[b].frame) ++e;
    b = e;
  }
  h->frame_start.push_back(t.points.size());
  return h;
}

std::shared_ptr<const SpeedHistory> speed_history_for(const TrajectorySet& t, double speed_window, DesiredSpeed d) {
  return d == DesiredSpeed::Free ? speed_history(t, speed_window) : nullptr;
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
  // A model with a density-speed law reads each person's free speed under its own law.
  const std::unordered_map<long, double> law_free =
      o.desired_speed == DesiredSpeed::Free && material_density_law(model.params) && s.history
          ? free_speeds_by_law(*s.history, s.frame, model.params, sim.walkable())
          : std::unordered_map<long, double>();
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
    const auto law = law_free.find(s.ids[i]);
    const double observed = law != law_free.end() ? std::max(law->second, s.speed[i]) : i < own.size() ? own[i] : 0.0;
    a.desired_speed = o.desired_speed != DesiredSpeed::Scenario && i < own.size()
                          ? std::clamp(observed, 0.0, std::min(12.0, model.params.max_speed))
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
