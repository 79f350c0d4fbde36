#pragma once
// A running scenario: the world, its grid, navigation fields and behaviours, and one step of
// the crowd material (drive, traction, P2G, grid update, G2P, projection, exits, sources).
#include <memory>
#include <string>
#include <vector>

#include "engine/sim/kernels.hpp"
#include "engine/sim/scenario.hpp"

namespace crowdmpm {

// Wall-clock seconds spent in each part of the step, accumulated while profiling is on.
struct StepProfile {
  static constexpr int kParts = 10;
  static const char* const kNames[kParts];  // drive, neighbours, headway, traction, p2g, grid, g2p, project, exits, sources
  double seconds[kParts] = {0};
  long steps = 0;
};

// Neighbour statistics of the current state, for cost models.
struct PairStats {
  long candidates = 0;  // particle pairs examined in the cell lists
  long pairs = 0;       // of which within the interaction reach (pair traction evaluated)
  long ahead = 0;       // particle pairs the headway examines (its longer reach)
};

struct ExitEvent {
  EntityId id;
  int exit;    // index into geometry.exits
  double time; // s
};

// Deterministic random numbers (SplitMix64): the same seed gives the same stream everywhere.
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t next();
  double uniform();  // [0, 1)
  double normal();   // standard normal (Box-Muller from two uniforms, drawn in that order)
  uint64_t state() const { return state_; }
  void set_state(uint64_t s) { state_ = s; }
 private:
  uint64_t state_;
};

class Simulation {
 public:
  // model: the material to use (the scenario's own model is ignored when it is given).
  Simulation(const ScenarioDef& scenario, const Model& model, int threads = 1);

  void step();  // advance by dt
  // Changes dt; checks (0, 0.1] and dt * max_speed <= cell_size / 4. Throws Error otherwise.
  void set_time_step(double dt);
  void run_steps(long n);
  bool finished() const;
  // The state became non-finite (a step threw UnstableError): no further steps, fields or snapshots.
  bool failed() const { return failed_; }

  // Simulated time: steps since the last change of dt times dt, plus the time reached then
  // (so that changing dt never rewrites the past, and without a change time = steps * dt exactly).
  double time() const { return time_at_dt_change_ + static_cast<double>(steps_ - steps_at_dt_change_) * scenario_.dt; }
  long steps() const { return steps_; }
  // The step counter and clock, to put back after running steps again (gradient checkpoints).
  struct Clock {
    long steps, steps_at_dt_change;
    double time_at_dt_change;
  };
  Clock clock() const { return Clock{steps_, steps_at_dt_change_, time_at_dt_change_}; }
  void set_clock(const Clock& c) {
    steps_ = c.steps;
    steps_at_dt_change_ = c.steps_at_dt_change;
    time_at_dt_change_ = c.time_at_dt_change;
  }
  const ScenarioDef& scenario() const { return scenario_; }
  const Model& model() const { return model_; }
  // Replaces the model of a running world as if the world had been built with it: the material
  // kind and the parameters that set up the world (ParamInfo::sets_up_world) must stay as they
  // are; the time step, the contact epsilon against the agents' comfort distances, the
  // neighbour reach and the reported pressure are checked and derived again. Throws Error.
  void set_model(const Model& m);
  World& world() { return world_; }
  const World& world() const { return world_; }
  const Grid& grid() const { return grid_; }
  const std::vector<ExitEvent>& exit_events() const { return exit_events_; }
  long spawned() const { return spawned_; }
  long pending_spawns() const;  // sources still to spawn (within their windows)
  int threads() const { return pool_.threads(); }
  void set_profiling(bool on) { profiling_ = on; }
  const StepProfile& profile() const { return profile_; }
  PairStats pair_stats();

  // Add one agent (C API, tests); returns its id. Behaviour: index into behaviours().
  // Each call recomputes the reference volumes of everyone added since the last step (O(n)):
  // add many people with add_agents.
  EntityId add_agent(const AgentDef& def);
  // Add agents together (all are checked before any is added; an Error names the first bad
  // one), one reference-volume pass for them all; returns their ids in order. The same state as
  // adding them one by one.
  std::vector<EntityId> add_agents(const std::vector<AgentDef>& defs);
  // Whether an agent may stand at p: inside the domain and outside every solid.
  bool geo_ok(const Vec2& p) const { return scenario_.geo.sdf(p) >= 0; }
  const std::vector<Behaviour>& behaviours() const { return behaviours_; }
  // The behaviour of the scenario's group (or source) g, by index into groups.
  int behaviour_of_group(int g) const { return group_behaviour_.at(static_cast<size_t>(g)); }
  // The inputs the kernels see (for the adjoint passes); valid while the simulation lives.
  StepInputs step_inputs() const {
    return StepInputs{model_, scenario_.geo, navs_, behaviours_, scenario_.terms, scenario_.dt, time(), walkable()};
  }
  // The venue's walkable lattice through which the model's density-speed law reads its density
  // (spacing: the law's reach / 8), or null when the model has no such law.
  const WalkableLattice* walkable() const { return walkable_.empty() ? nullptr : &walkable_; }
  const NeighbourGrid& neighbour_grid() const { return neighbours_; }
  int behaviour_for_target(const std::string& target);  // goal behaviour to an exit/goal id
  // Changes the simulated time at which finished() holds (the scenario's time.duration), s > 0.
  void set_duration(double seconds);
  // Route choice under congestion (MaterialParams::route_congestion): goal routes are recomputed
  // from the crowd's pace (the share of their free speed people walk, smoothed) at the start of
  // every step that begins a second (kRouteInterval).
  // Held, no recomputation happens (a gradient window: the routes of its start stay fixed).
  void hold_routes(bool held) { routes_held_ = held; }
  bool routes_held() const { return routes_held_; }
  // The pace (0..1) per grid node the routes were last computed from; empty: shortest paths.
  const std::vector<double>& route_pace() const { return route_pace_; }
  static constexpr double kRouteInterval = 1.0;   // s
  static constexpr double kRouteSmoothing = 2.0;   // m: standard deviation of the pace's smoothing
  static constexpr double kRouteBackground = 1.0;  // persons/m^2 of free walkers mixed into the pace
  // A person's free speed for group g: the group's, or drawn from its truncated normal
  // distribution with the simulation's random stream (no draw when it has none).
  double draw_speed(const GroupDef& g);

 private:
  friend struct SnapshotCodec;  // engine/sim/snapshot.cpp: save and restore every member below
  void build_behaviours();
  Behaviour goal_behaviour(const std::string& target);
  void resolve(Behaviour& b);
  int nav_for(const std::string& target);
  void place_group(size_t gi);
  void spawn_sources();
  void retire_at_exits();
  void check_finite();
  void prepare_derived();  // drive, traction and P2G on the current state, so pressure is defined
  void step_social_force(const StepInputs& in);  // the social_force model's motion (no grid)
  void init_neighbours(double reach);
  void size_neighbour_cells(double cell_reach);  // the cell lists for exactly this reach
  double neighbour_reach() const;
  AgentDef agent_template(const GroupDef& g, int group_index) const;
  AgentDef with_entry_heading(AgentDef d) const;  // the heading behaviour's direction at entry
  void check_agent(const AgentDef& def) const;     // throws Error naming what add_agent refuses
  void update_walkable();     // (re)builds walkable_ for the model's density-speed law, or clears it
  void update_routes();       // at a step's start: recompute route_pace_ when due, then the routes
  void apply_route_pace(); // the goal navigation fields' costs from route_pace_
  const std::vector<double>& route_costs();  // the cost per navigation cell from route_pace_

  ScenarioDef scenario_;
  Model model_;
  ThreadPool pool_;
  World world_;
  Grid grid_;
  NeighbourGrid neighbours_;
  std::vector<NavField> navs_;
  WalkableLattice walkable_;  // see walkable(); update_walkable keeps it to the model
  std::vector<std::string> nav_targets_;
  std::vector<char> nav_goal_;          // per navigation field: a goal's (route choice bends it)
  std::vector<double> route_pace_;   // per grid node, 0..1, at the last route update
  bool routes_held_ = false;
  struct RouteScratch {  // update_routes' buffers, kept so that a route update allocates nothing
    std::vector<double> mass, pace, weight, t0, t1, t2, kernel, cost;
  } route_scratch_;
  std::vector<Behaviour> behaviours_;
  std::vector<int> group_behaviour_;
  std::vector<std::string> added_targets_;  // behaviour_for_target's new behaviours, in order
  std::vector<ExitEvent> exit_events_;
  std::vector<double> source_accum_;
  std::vector<long> source_spawned_;
  Rng rng_;
  long steps_ = 0;
  long steps_at_dt_change_ = 0;
  double time_at_dt_change_ = 0;
  bool failed_ = false;  // the state became non-finite: no further steps
  long spawned_ = 0;
  // First agent added through add_agent since the last step (or construction): the batch whose
  // reference volumes each add recomputes, so that all of them see the whole batch.
  size_t batch_start_ = 0;
  double max_radius_ = 0, max_comfort_ = 0, max_v0_ = 0;  // over agents added so far (for the cell lists)
  double neighbour_reach_ = 0;      // the reach the cell lists were last sized for (size_neighbour_cells)
  std::vector<int> exit_of_;        // scratch of retire_at_exits
  std::vector<size_t> first_bad_;   // scratch of check_finite
  bool profiling_ = false;
  StepProfile profile_;
};

}  // namespace crowdmpm
