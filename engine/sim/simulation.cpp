#include "engine/sim/simulation.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <unordered_map>

namespace crowdmpm {

uint64_t Rng::next() {
  uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

double Rng::uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

double Rng::normal() {
  const double u1 = uniform();  // separate statements: the order of the draws is fixed
  const double u2 = uniform();
  return std::sqrt(-2 * std::log(1 - u1)) * std::cos(2 * M_PI * u2);
}

static void check_time_step(const ScenarioDef& s, const Model& m, double dt) {
  if (!(dt > 0 && dt <= 0.1)) throw Error(s.source + ": time.dt: must be in (0, 0.1] s, got " + format_number(dt));
  if (dt * m.params.max_speed > 0.25 * s.cell_size)
    throw Error(s.source + ": time.dt: " + format_number(dt) + " s is too large for domain.cell_size " +
                format_number(s.cell_size) + " m: dt * max_speed (" + format_number(m.params.max_speed) +
                " m/s) must be <= cell_size / 4");
}

void Simulation::set_duration(double seconds) {
  if (!(seconds > 0 && seconds <= 1e9)) throw Error("duration must be in (0, 1e9] s, got " + format_number(seconds));
  scenario_.duration = seconds;
}

void Simulation::set_time_step(double dt) {
  check_time_step(scenario_, model_, dt);
  time_at_dt_change_ = time();
  steps_at_dt_change_ = steps_;
  scenario_.dt = dt;
  // The social force keeps a step's neighbour lists through its substeps, widened by the most
  // two people close in one step: a longer step needs wider lists.
  if (!model_.is_continuum()) init_neighbours(neighbour_reach());
}

Simulation::Simulation(const ScenarioDef& scenario, const Model& model, int threads)
    : scenario_(scenario), model_(model), pool_(threads), rng_(scenario.seed) {
  const MaterialParams& P = model_.params;
  check_time_step(scenario_, model_, scenario_.dt);
  grid_.init(scenario_.geo, scenario_.cell_size);
  try {
    build_behaviours();
  } catch (const Error& e) {
    throw Error(scenario_.source + ": " + e.what());
  }
  // A pair interacts up to r_p + r_q + c_p: the cell lists must cover the largest such reach.
  double max_r = P.body_radius, max_c = P.comfort_distance;
  for (const auto& g : scenario_.groups) {
    max_r = std::max(max_r, g.body_radius.value_or(P.body_radius));
    max_c = std::max(max_c, g.comfort_distance.value_or(P.comfort_distance));
  }
  double min_c = P.comfort_distance;
  for (const auto& g : scenario_.groups) min_c = std::min(min_c, g.comfort_distance.value_or(P.comfort_distance));
  if (model_.has_traction() && P.contact_epsilon >= min_c)
    throw Error(scenario_.source + ": model contact_epsilon " + format_number(P.contact_epsilon) +
                " m must be smaller than every comfort distance (smallest: " + format_number(min_c) + " m)");
  max_radius_ = max_r;
  max_comfort_ = max_c;
  for (const auto& g : scenario_.groups) max_v0_ = std::max(max_v0_, g.speed_max);
  init_neighbours(neighbour_reach());
  size_t capacity = 0;
  source_accum_.assign(scenario_.groups.size(), 0);
  source_spawned_.assign(scenario_.groups.size(), 0);
  for (size_t gi = 0; gi < scenario_.groups.size(); ++gi)
    if (scenario_.groups[gi].is_source) capacity += scenario_.groups[gi].max_count;
  world_.reserve(capacity + 1024);
  try {
    for (size_t gi = 0; gi < scenario_.groups.size(); ++gi)
      if (!scenario_.groups[gi].is_source) place_group(gi);
  } catch (const Error& e) {
    throw Error(scenario_.source + ": " + e.what());
  }
  spawn_sources();
  if (model_.density_referenced()) reference_volumes(world_, 0, model_.params.rest_density);
  batch_start_ = world_.size();
  update_walkable();
  prepare_derived();
}

void Simulation::update_walkable() {
  if (!material_density_law(model_.params)) {
    walkable_ = WalkableLattice();
    return;
  }
  const double h = model_.params.density_speed_reach / 8;
  if (walkable_.empty() || walkable_.h != h) walkable_ = walkable_lattice(scenario_.geo, h);
}

void Simulation::set_model(const Model& m) {
  if (m.material != model_.material)
    throw Error(std::string("the material of a world is fixed (") + material_name(model_.material) + ")");
  for (const auto& info : param_table())
    if (info.sets_up_world && m.params.*info.field != model_.params.*info.field)
      throw Error(std::string(info.name) + " is fixed once a world exists (it sizes and places agents, or shapes navigation)");
  check_time_step(scenario_, m, scenario_.dt);
  if (m.has_traction())
    for (const auto& g : scenario_.groups)  // sources still to spawn with these comfort distances
      if (m.params.contact_epsilon >= g.comfort_distance.value_or(m.params.comfort_distance))
        throw Error("contact_epsilon " + format_number(m.params.contact_epsilon) + " m must be smaller than the comfort distance of " +
                    g.path + " (" + format_number(g.comfort_distance.value_or(m.params.comfort_distance)) + " m)");
  if (m.has_traction())
    for (size_t p = 0; p < world_.size(); ++p)
      if (m.params.contact_epsilon >= world_.comfort[p])
        throw Error("contact_epsilon " + format_number(m.params.contact_epsilon) +
                    " m must be smaller than every agent's comfort distance (agent " + std::to_string(world_.id[p]) +
                    ": " + format_number(world_.comfort[p]) + " m)");
  model_ = m;
  init_neighbours(neighbour_reach());
  update_walkable();
  prepare_derived();
}

int Simulation::nav_for(const std::string& target) {
  for (size_t i = 0; i < nav_targets_.size(); ++i)
    if (nav_targets_[i] == target) return static_cast<int>(i);
  std::vector<const Shape*> shapes;
  if (target == "nearest_exit") {
    for (const auto& e : scenario_.geo.exits) shapes.push_back(&e.shape);
  } else {
    const NamedShape* t = scenario_.geo.find_target(target);
    if (!t) throw Error("no exit or goal with id \"" + target + "\"");
    shapes.push_back(&t->shape);
  }
  NavField field(scenario_.geo, shapes, scenario_.nav_cell, model_.params.wall_clearance);
  if (!field.has_target())
    throw Error("target \"" + target + "\" has no walkable cell in or next to it (it lies inside solids or outside the domain)");
  navs_.push_back(std::move(field));
  nav_targets_.push_back(target);
  nav_goal_.push_back(0);
  return static_cast<int>(navs_.size() - 1);
}

// A goal behaviour towards an exit, a goal region or "nearest_exit". Agents stop inside a goal
// region; exits retire them instead.
Behaviour Simulation::goal_behaviour(const std::string& target) {
  Behaviour b;
  b.kind = Behaviour::Kind::Goal;
  b.target = target;
  resolve(b);
  return b;
}

// Navigation field and goal region of a behaviour.
void Simulation::resolve(Behaviour& b) {
  if (b.kind == Behaviour::Kind::Goal) {
    b.nav = nav_for(b.target);
    if (!nav_goal_[static_cast<size_t>(b.nav)]) {
      nav_goal_[static_cast<size_t>(b.nav)] = 1;
      if (!route_pace_.empty()) navs_[static_cast<size_t>(b.nav)].set_cost(route_costs());
    }
    const NamedShape* t = b.target == "nearest_exit" ? nullptr : scenario_.geo.find_target(b.target);
    bool is_exit = false;
    for (const auto& e : scenario_.geo.exits) is_exit = is_exit || &e == t;
    b.goal = (t && !is_exit) ? &t->shape : nullptr;
  } else if (b.kind == Behaviour::Kind::Orbit && !b.target.empty()) {
    b.nav = nav_for(b.target);
  }
}

// Behaviour 0 is "none"; then each group's (groups, then sources: behaviour_of_group). Behaviours
// refer to navigation fields by index, so adding fields later (behaviour_for_target) is safe.
void Simulation::build_behaviours() {
  behaviours_.push_back(Behaviour{});
  for (const auto& g : scenario_.groups) {
    Behaviour b = g.behaviour;
    try {
      resolve(b);
    } catch (const Error& e) {
      throw Error(b.path + (b.kind == Behaviour::Kind::Orbit ? ".around: " : ".target: ") + e.what());
    }
    group_behaviour_.push_back(static_cast<int>(behaviours_.size()));
    behaviours_.push_back(b);
  }
}

int Simulation::behaviour_for_target(const std::string& target) {
  if (!scenario_.geo.find_target(target) && target != "nearest_exit")
    throw Error("no exit or goal with id \"" + target + "\"");
  for (size_t i = 0; i < nav_targets_.size(); ++i)
    if (nav_targets_[i] == target)
      for (size_t b = 0; b < behaviours_.size(); ++b)
        if (behaviours_[b].kind == Behaviour::Kind::Goal && behaviours_[b].nav == static_cast<int>(i))
          return static_cast<int>(b);
  behaviours_.push_back(goal_behaviour(target));
  added_targets_.push_back(target);
  return static_cast<int>(behaviours_.size() - 1);
}

AgentDef Simulation::agent_template(const GroupDef& g, int gi) const {
  AgentDef d;
  d.velocity = g.velocity;
  d.body_radius = g.body_radius.value_or(model_.params.body_radius);
  d.comfort_distance = g.comfort_distance.value_or(model_.params.comfort_distance);
  d.desired_speed = g.desired_speed;
  d.behaviour = behaviour_of_group(gi);
  d.group = gi;
  return d;
}

AgentDef Simulation::with_entry_heading(AgentDef d) const {
  // The heading behaviour walks on the way the person moved at entry (no drive if standing).
  if (behaviours_[static_cast<size_t>(d.behaviour)].kind == Behaviour::Kind::Heading)
    d.heading = d.velocity.norm() > 1e-9 ? Vec2(d.velocity.normalized()) : Vec2::Zero();
  return d;
}

void Simulation::check_agent(const AgentDef& def) const {
  if (def.behaviour < 0 || def.behaviour >= static_cast<int>(behaviours_.size()))
    throw Error("agent behaviour index " + std::to_string(def.behaviour) + " out of range");
  if (!def.position.allFinite() || !def.velocity.allFinite())
    throw Error("agent position and velocity must be finite numbers");
  if (scenario_.geo.sdf(def.position) < 0) throw Error("agent position is inside a wall, an obstacle or outside the domain");
  if (!(def.body_radius >= 0.05 && def.body_radius <= 0.5)) throw Error("agent body_radius must be in [0.05, 0.5] m, got " + format_number(def.body_radius));
  if (!(def.comfort_distance >= 0.01 && def.comfort_distance <= 2)) throw Error("agent comfort_distance must be in [0.01, 2] m, got " + format_number(def.comfort_distance));
  if (!(def.desired_speed >= 0 && def.desired_speed <= 12)) throw Error("agent desired_speed must be in [0, 12] m/s, got " + format_number(def.desired_speed));
  if (def.group < -1 || def.group >= static_cast<int>(scenario_.groups.size()))
    throw Error("agent group " + std::to_string(def.group) + " out of range (-1 for none, or a group index)");
  if (model_.has_traction() && def.comfort_distance <= model_.params.contact_epsilon)
    throw Error("agent comfort_distance must be larger than the model's contact_epsilon (" +
                format_number(model_.params.contact_epsilon) + " m)");
}

EntityId Simulation::add_agent(const AgentDef& def) { return add_agents({def}).front(); }

std::vector<EntityId> Simulation::add_agents(const std::vector<AgentDef>& defs) {
  for (size_t k = 0; k < defs.size(); ++k) {
    try {
      check_agent(defs[k]);
    } catch (const Error& e) {
      if (defs.size() == 1) throw;
      throw Error("agent " + std::to_string(k) + " of " + std::to_string(defs.size()) + ": " + e.what());
    }
  }
  // Keep the cell lists wide enough for the new agents' reach.
  for (const AgentDef& def : defs) {
    max_radius_ = std::max(max_radius_, def.body_radius);
    max_comfort_ = std::max(max_comfort_, def.comfort_distance);
    max_v0_ = std::max(max_v0_, def.desired_speed);
  }
  if (neighbour_reach() > neighbours_.range) init_neighbours(neighbour_reach());
  std::vector<EntityId> ids;
  ids.reserve(defs.size());
  for (const AgentDef& def : defs) ids.push_back(world_.add(with_entry_heading(def)));
  // People added before a step (a recorded state, a replay's arrivals, one by one or together)
  // are one batch: J is recomputed over the whole batch, so it does not depend on the order of
  // adding nor on how the batch was split into calls.
  if (model_.density_referenced() && !defs.empty()) reference_volumes(world_, batch_start_, model_.params.rest_density);
  return ids;
}

// Hexagonal lattice at the density asked for, jittered without overlap, inside the region and
// outside solids and other agents. Sparser than asked if it does not fit at first; an error if
// even the densest packing of the bodies cannot hold the count.
void Simulation::place_group(size_t gi) {
  const GroupDef& g = scenario_.groups[gi];
  AgentDef tmpl = agent_template(g, static_cast<int>(gi));
  const double r = tmpl.body_radius, clearance = std::max(model_.params.wall_clearance, 0.0);
  const Geometry& geo = scenario_.geo;
  auto free_at = [&](const Vec2& p) { return g.region.contains(p) && geo.sdf(p) >= clearance; };
  const Vec2 lo = g.region.lo.cwiseMax(geo.lo), hi = g.region.hi.cwiseMin(geo.hi);  // the region within the domain
  const double area = geo.free_area(g.region, clearance);
  if (g.count == 0) return;
  if (area <= 0) throw Error(g.path + ".spawn: the region has no walkable area (it lies inside walls, obstacles or outside the domain)");
  const long count = g.count >= 0 ? g.count : std::lround(g.density * area);
  if (count == 0) return;
  const double densest = 2 / (std::sqrt(3.0) * 4 * r * r);
  const double want = static_cast<double>(count) / area;
  if (want > densest)
    throw Error(g.path + (g.count >= 0 ? ".count" : ".density") + ": " + format_number(want) +
                " persons/m^2 on " + format_number(area) + " m^2 of walkable area cannot hold bodies of radius " +
                format_number(r) + " m (hexagonal packing allows at most " + format_number(densest) + ")");
  // Existing agents (earlier groups) in a coarse hash for overlap checks.
  std::unordered_map<uint64_t, std::vector<Vec2>> occupied;
  auto key = [](const Vec2& p) {
    // 1 m cells; offset so that coordinates down to -2^30 m stay non-negative before packing.
    auto cell = [](double c) { return static_cast<uint64_t>(static_cast<int64_t>(std::floor(c)) + (int64_t{1} << 30)); };
    return (cell(p.x()) << 32) ^ cell(p.y());
  };
  for (size_t p = 0; p < world_.size(); ++p) occupied[key(world_.x[p])].push_back(world_.x[p]);
  auto overlaps = [&](const Vec2& p, double rr) {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        auto it = occupied.find(key(p + Vec2(dx, dy)));
        if (it == occupied.end()) continue;
        for (const auto& q : it->second)
          if ((q - p).norm() < rr) return true;
      }
    return false;
  };
  double a = hexagonal_spacing(want);
  for (int attempt = 0; attempt < 200; ++attempt, a *= 0.98) {
    if (a < 2 * r) break;
    std::vector<Vec2> pts;
    const double row = a * std::sqrt(3.0) / 2;
    // Draws in separate statements: the order of evaluation of function arguments is
    // unspecified (GCC and Clang differ), and the stream must be consumed in one order.
    const double off_x = rng_.uniform() * a;
    const double off_y = rng_.uniform() * row;
    const Vec2 off(off_x, off_y);
    // Counted as well as compared, as the area sampling (Geometry::free_area).
    const long rows = static_cast<long>(std::ceil((hi.y() - lo.y()) / row)) + 3, cols = static_cast<long>(std::ceil((hi.x() - lo.x()) / a)) + 3;
    int k = 0;
    for (double y = lo.y() + off.y() - row; k < rows && y <= hi.y(); y += row, ++k) {
      long i = 0;
      for (double x = lo.x() + off.x() - a + (k % 2) * a / 2; i < cols && x <= hi.x(); x += a, ++i) {
        Vec2 p(x, y);
        if (free_at(p) && !overlaps(p, 2 * r)) pts.push_back(p);
      }
    }
    if (static_cast<long>(pts.size()) < count) continue;
    // Choose count of them at random (Fisher-Yates on our own generator), keep lattice order.
    std::vector<size_t> idx(pts.size());
    for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
    for (size_t i = idx.size() - 1; i > 0; --i) std::swap(idx[i], idx[static_cast<size_t>(rng_.uniform() * static_cast<double>(i + 1))]);
    idx.resize(static_cast<size_t>(count));
    std::sort(idx.begin(), idx.end());
    const double jitter = 0.45 * (a - 2 * r);
    for (size_t i : idx) {
      AgentDef d = tmpl;
      d.desired_speed = draw_speed(g);
      d.position = pts[i];
      double ang = 2 * M_PI * rng_.uniform(), rad = jitter * std::sqrt(rng_.uniform());
      Vec2 q = pts[i] + rad * Vec2(std::cos(ang), std::sin(ang));
      if (free_at(q) && !overlaps(q, 2 * r)) d.position = q;
      world_.add(with_entry_heading(d));
      ++spawned_;
      occupied[key(d.position)].push_back(d.position);
    }
    return;
  }
  throw Error(g.path + ".spawn: cannot place " + std::to_string(count) + " agents of radius " + format_number(r) +
              " m without overlap in the walkable part of the region (" + format_number(area) + " m^2)");
}

// A person's free speed: the group's, or drawn from its truncated normal distribution (no
// draw when it has none, so that fixed speeds leave the random stream as it was).
double Simulation::draw_speed(const GroupDef& g) {
  if (!(g.speed_sd > 0)) return g.desired_speed;
  for (int tries = 0; tries < 100; ++tries) {
    const double v = g.desired_speed + g.speed_sd * rng_.normal();
    if (v >= g.speed_min && v <= g.speed_max) return v;
  }
  return g.desired_speed;
}

long Simulation::pending_spawns() const {
  long n = 0;
  for (size_t gi = 0; gi < scenario_.groups.size(); ++gi) {
    const auto& g = scenario_.groups[gi];
    if (g.is_source && time() < std::min(g.end, scenario_.duration)) n += g.max_count - source_spawned_[gi];
  }
  return n;
}

void Simulation::spawn_sources() {
  const double t = time();
  const size_t first_new = world_.size();
  for (size_t gi = 0; gi < scenario_.groups.size(); ++gi) {
    const GroupDef& g = scenario_.groups[gi];
    if (!g.is_source || t < g.start || t >= g.end) continue;
    source_accum_[gi] += g.rate * scenario_.dt;
    AgentDef tmpl = agent_template(g, static_cast<int>(gi));
    while (source_accum_[gi] >= 1 && source_spawned_[gi] < g.max_count) {
      bool placed = false;
      for (int tries = 0; tries < 30 && !placed; ++tries) {
        const double ux = rng_.uniform();  // separate statements: see place_group
        const double uy = rng_.uniform();
        Vec2 p(g.region.lo.x() + ux * (g.region.hi.x() - g.region.lo.x()), g.region.lo.y() + uy * (g.region.hi.y() - g.region.lo.y()));
        if (!g.region.contains(p) || scenario_.geo.sdf(p) < model_.params.wall_clearance) continue;
        bool clear = true;
        for (size_t q = 0; q < world_.size() && clear; ++q)
          clear = (world_.x[q] - p).norm() >= world_.radius[q] + tmpl.body_radius;
        if (!clear) continue;
        AgentDef d = tmpl;
        d.desired_speed = draw_speed(g);
        d.position = p;
        world_.add(with_entry_heading(d));
        placed = true;
      }
      if (!placed) break;  // region full: try again next step
      source_accum_[gi] -= 1;
      ++source_spawned_[gi];
      ++spawned_;
    }
  }  if (world_.size() > first_new && model_.density_referenced())
    reference_volumes(world_, first_new, model_.params.rest_density);
}

// A pair interacts up to r_p + r_q + c_p (or the social force's margin) over the agents added so
// far: the cells are sized for it. The headway looks further ahead along its lane only
// (NeighbourGrid::for_each_candidate_ahead).
double Simulation::neighbour_reach() const { return 2 * max_radius_ + interaction_margin(model_, max_comfort_); }

void Simulation::init_neighbours(double reach) {
  // The social force keeps a step's neighbour lists through its substeps: pairs may close by
  // up to 2 max_speed dt meanwhile, so the lists reach that much further.
  if (!model_.is_continuum()) reach += 2 * model_.params.max_speed * scenario_.dt;
  size_neighbour_cells(reach);
}

void Simulation::size_neighbour_cells(double cell_reach) {
  neighbour_reach_ = cell_reach;
  // Bound the number of cells (huge venues): larger cells cost time, not correctness.
  const Vec2 ext = scenario_.geo.hi - scenario_.geo.lo;
  neighbours_.init(scenario_.geo, cell_reach, std::sqrt(ext.x() * ext.y() / 2e7));
  neighbours_.max_radius = max_radius_;  // a larger body widens the reach, so it passes here
}

void Simulation::prepare_derived() {
  StepInputs in = step_inputs();
  kernel_drive(in, world_, pool_);
  neighbours_.build(world_, pool_);
  if (!model_.is_continuum()) {
    kernel_social_force(in, neighbours_, world_, pool_);
    return;
  }
  kernel_headway(in, neighbours_, world_, pool_);
  kernel_traction(in, neighbours_, world_, pool_);
  kernel_p2g(in, world_, grid_, pool_);  // reported pressure of the initial state
}

const char* const StepProfile::kNames[StepProfile::kParts] = {"drive", "neighbours", "headway", "traction", "p2g", "grid_update",
                                                               "g2p", "project", "exits", "sources"};

// Route choice under congestion (after Hughes 2002: the route minimises the travel time at the
// speeds the crowd walks): a goal's route minimises the integral of c ds with the cost per metre
// c = 1 + w (1 / max(s, 1/20) - 1), w = route_congestion, s the crowd's pace there: how much of
// their free speed the people around walk, s = (sum K |v_p| / u_p + rho_b) / (sum K + rho_b), K a
// Gaussian of kRouteSmoothing over each person's quadratic B-spline deposit on the grid's free
// nodes (per m^2), rho_b = kRouteBackground persons/m^2 of free walkers (so that a lone slow
// person is not a jam). Where the crowd walks at its free speed the routes are the shortest
// paths; a queue (s small) costs up to 1 + 19 w times its length and the routes bend round it.
void Simulation::update_routes() {
  const MaterialParams& P = model_.params;
  if (!(P.route_congestion > 0)) {
    if (!route_pace_.empty()) {
      route_pace_.clear();
      apply_route_pace();
    }
    return;
  }
  const long every = std::max(1L, std::lround(kRouteInterval / scenario_.dt));
  if (!route_pace_.empty() && (routes_held_ || steps_ % every != 0)) return;  // most steps end here
  if (std::find(nav_goal_.begin(), nav_goal_.end(), 1) == nav_goal_.end()) return;  // no goal routes to bend
  const Grid& g = grid_;
  // Deposits per node: persons (each renormalised over the free nodes of their stencil, so walls
  // do not thin the crowd beside them) and their paces |v| / u (1 for people without a drive).
  RouteScratch& r = route_scratch_;
  std::vector<double>&mass = r.mass, &pace = r.pace, &weight = r.weight, &t0 = r.t0, &t1 = r.t1, &t2 = r.t2;
  mass.assign(g.nodes(), 0.0);
  pace.assign(g.nodes(), 0.0);
  weight.resize(g.nodes());
  t0.resize(g.nodes());
  t1.resize(g.nodes());
  t2.resize(g.nodes());
  for (size_t p = 0; p < world_.size(); ++p) {
    const Stencil st = make_stencil(g.origin, g.dx, g.nx, g.ny, world_.x[p]);
    double free_weight = 0;
    for_each_stencil_node(st, g.nx, g.dx, [&](const StencilNode& n) {
      if (!g.solid[n.k]) free_weight += n.w;
    });
    if (!(free_weight > 0)) continue;
    const double u = world_.free_speed[p];
    const double s = u > 0 ? std::min(1.0, world_.v[p].norm() / u) : 1.0;
    for_each_stencil_node(st, g.nx, g.dx, [&](const StencilNode& n) {
      if (g.solid[n.k]) return;
      mass[n.k] += n.w / free_weight;
      pace[n.k] += s * n.w / free_weight;
    });
  }
  for (size_t k = 0; k < g.nodes(); ++k) weight[k] = g.solid[k] ? 0.0 : 1.0;
  // Gaussian smoothing, separable, renormalised over the free nodes (the sums become per m^2).
  const int reach = std::max(1, static_cast<int>(std::ceil(3 * kRouteSmoothing / g.dx)));
  std::vector<double>& kernel = r.kernel;
  kernel.resize(static_cast<size_t>(2 * reach + 1));
  for (int k = -reach; k <= reach; ++k) kernel[static_cast<size_t>(k + reach)] = std::exp(-0.5 * std::pow(k * g.dx / kRouteSmoothing, 2));
  for (bool along_x : {true, false}) {
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        double m = 0, q = 0, wsum = 0;
        for (int k = -reach; k <= reach; ++k) {
          const int a = along_x ? i + k : i, b = along_x ? j : j + k;
          if (a < 0 || b < 0 || a >= g.nx || b >= g.ny) continue;
          const double c = kernel[static_cast<size_t>(k + reach)];
          const size_t n = static_cast<size_t>(g.node(a, b));
          m += c * mass[n];
          q += c * pace[n];
          wsum += c * weight[n];
        }
        const size_t n = static_cast<size_t>(g.node(i, j));
        t0[n] = m;
        t1[n] = q;
        t2[n] = wsum;
      }
    mass.swap(t0);
    pace.swap(t1);
    weight.swap(t2);
  }
  const double area = g.dx * g.dx;
  for (size_t k = 0; k < g.nodes(); ++k) {
    const bool ok = !g.solid[k] && weight[k] > 1e-12;
    const double rho = ok ? mass[k] / (weight[k] * area) : 0.0, flux = ok ? pace[k] / (weight[k] * area) : 0.0;
    pace[k] = (flux + kRouteBackground) / (rho + kRouteBackground);
  }
  route_pace_.assign(pace.begin(), pace.end());  // a copy: both buffers keep their capacity
  apply_route_pace();
}

const std::vector<double>& Simulation::route_costs() {
  const double w = model_.params.route_congestion;
  const Grid& g = grid_;
  const NavField& f = navs_.front();
  std::vector<double>& cost = route_scratch_.cost;
  cost.assign(static_cast<size_t>(f.nx()) * f.ny(), 1.0);
  for (int j = 0; j < f.ny(); ++j)
    for (int i = 0; i < f.nx(); ++i) {
      // Bilinear over the four surrounding grid nodes, renormalised over the free ones.
      const Vec2 c = f.cell_centre(i, j);
      const double gx = (c.x() - g.origin.x()) / g.dx, gy = (c.y() - g.origin.y()) / g.dx;
      const int i0 = std::clamp(static_cast<int>(std::floor(gx)), 0, g.nx - 2);
      const int j0 = std::clamp(static_cast<int>(std::floor(gy)), 0, g.ny - 2);
      const double tx = std::clamp(gx - i0, 0.0, 1.0), ty = std::clamp(gy - j0, 0.0, 1.0);
      double s = 0, wsum = 0;
      for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a) {
          const int k = g.node(i0 + a, j0 + b);
          if (g.solid[static_cast<size_t>(k)]) continue;
          const double wt = (a ? tx : 1 - tx) * (b ? ty : 1 - ty);
          s += wt * route_pace_[static_cast<size_t>(k)];
          wsum += wt;
        }
      if (wsum > 1e-12) cost[static_cast<size_t>(j) * f.nx() + i] = 1 + w * (1 / std::max(s / wsum, 0.05) - 1);
    }
  return cost;
}

void Simulation::apply_route_pace() {
  if (navs_.empty()) return;
  static const std::vector<double> shortest;
  const std::vector<double>& cost = route_pace_.empty() ? shortest : route_costs();
  for (size_t i = 0; i < navs_.size(); ++i)
    if (nav_goal_[i]) navs_[i].set_cost(cost);
}

void Simulation::step() {
  if (failed_)
    throw UnstableError("the simulation became unstable at t = " + format_number(time()) + " s and cannot be stepped further");
  update_routes();
  StepInputs in = step_inputs();
  using clock = std::chrono::steady_clock;
  auto t = profiling_ ? clock::now() : clock::time_point();
  int part = 0;
  auto mark = [&]() {
    if (!profiling_) return;
    auto now = clock::now();
    profile_.seconds[part++] += std::chrono::duration<double>(now - t).count();
    t = now;
  };
  if (model_.is_continuum()) {
    kernel_drive(in, world_, pool_);
    mark();
    neighbours_.build(world_, pool_);
    mark();
    kernel_headway(in, neighbours_, world_, pool_);
    mark();
    kernel_traction(in, neighbours_, world_, pool_);
    mark();
    kernel_p2g(in, world_, grid_, pool_);
    mark();
    kernel_grid_update(in, grid_, pool_);
    mark();
    kernel_g2p(in, grid_, world_, pool_);
    mark();
  } else {
    step_social_force(in);
    mark();    // profiled as drive; the neighbour, headway, traction and grid parts stay empty
    part = 7;
  }
  kernel_project(in, world_, pool_);
  mark();
  ++steps_;
  check_finite();
  retire_at_exits();
  mark();
  spawn_sources();
  mark();
  batch_start_ = world_.size();
  if (profiling_) ++profile_.steps;
}

void Simulation::step_social_force(const StepInputs& in) {
  // Contacts are stiff (k, kappa): semi-implicit Euler in substeps of at most 2.5 ms, with the
  // neighbour lists of the step start (init_neighbours widened them by 2 max_speed dt, the
  // most two people can close in one step).
  const MaterialParams& P = model_.params;
  const int sub = std::max(1, static_cast<int>(std::ceil(scenario_.dt / 0.0025 - 1e-9)));
  const double h = scenario_.dt / sub;
  neighbours_.build(world_, pool_);
  for (int k = 0; k < sub; ++k) {
    kernel_drive(in, world_, pool_);
    kernel_social_force(in, neighbours_, world_, pool_);
    World& w = world_;
    pool_.parallel_for(w.size(), [&](size_t b, size_t e) {
      for (size_t p = b; p < e; ++p) {
        Vec2 v = w.v[p] + h * (w.accel[p] + w.pair_force[p]);
        const double speed = v.norm();
        if (speed > P.max_speed) v *= P.max_speed / speed;
        w.v[p] = v;
        w.x[p] += h * v;
      }
    });
  }
}

PairStats Simulation::pair_stats() {
  PairStats st;
  neighbours_.build(world_, pool_);  // the lists of the last step may name retired agents
  const NeighbourGrid& nb = neighbours_;
  const World& w = world_;
  for (size_t p = 0; p < w.size(); ++p) {
    nb.for_each_candidate(p, [&](size_t q) {
      ++st.candidates;
      if ((w.x[q] - w.x[p]).norm() < w.radius[p] + w.radius[q] + w.comfort[p]) ++st.pairs;
    });
    if (model_.is_continuum() && model_.params.time_gap > 0 && w.free_speed[p] > 0)
      nb.for_each_candidate_ahead(p, w.x[p], w.radius[p], w.heading[p], headway_look(model_.params, w.free_speed[p]),
                                  model_.params.headway_width, [&](size_t) { ++st.ahead; });
  }
  return st;
}

void Simulation::run_steps(long n) {
  for (long i = 0; i < n; ++i) step();
}

bool Simulation::finished() const {
  if (time() >= scenario_.duration - 1e-9) return true;
  return scenario_.stop_when_empty && world_.size() == 0 && pending_spawns() == 0 && steps_ > 0;
}

void Simulation::check_finite() {
  // In parallel: find the first agent (lowest index) with a non-finite state, if any.
  std::vector<size_t>& first = first_bad_;
  first.assign(static_cast<size_t>(pool_.threads()) + 1, world_.size());
  std::atomic<int> chunk{0};
  pool_.parallel_for(world_.size(), [&](size_t b, size_t e) {
    size_t bad = world_.size();
    for (size_t p = b; p < e && bad == world_.size(); ++p)
      if (!world_.x[p].allFinite() || !world_.v[p].allFinite()) bad = p;
    first[static_cast<size_t>(chunk++)] = bad;
  });
  size_t p = *std::min_element(first.begin(), first.end());
  if (p < world_.size()) {
    failed_ = true;
    throw UnstableError("simulation became unstable at t = " + format_number(time()) + " s: agent " +
                std::to_string(world_.id[p]) + " has a non-finite position or velocity (reduce time.dt or the material stiffness E)");
  }
}

void Simulation::retire_at_exits() {
  if (scenario_.geo.exits.empty()) return;
  // Which exit each agent stands in (in parallel), then removal from the back (serial, so the
  // order of swaps, and thus of the arrays, is the same for any thread count).
  exit_of_.resize(world_.size());
  pool_.parallel_for(world_.size(), [&](size_t b, size_t e) {
    for (size_t p = b; p < e; ++p) exit_of_[p] = scenario_.geo.exit_at(world_.x[p]);
  });
  for (size_t p = world_.size(); p-- > 0;) {
    if (exit_of_[p] < 0) continue;
    exit_events_.push_back({world_.id[p], exit_of_[p], time()});
    world_.remove_at(p);
  }
}

}  // namespace crowdmpm
