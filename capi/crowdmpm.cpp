// The C ABI over the engine: a registry of worlds addressed by (index, generation), a guard at
// every entry point that turns any C++ exception into a status and a thread-local message.
#include "crowdmpm/crowdmpm.h"

#include <atomic>
#include <climits>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <vector>

#include "engine/analysis/fields.hpp"
#include "engine/core/output.hpp"
#include "engine/diagnosis/diagnose.hpp"
#include "engine/sim/simulation.hpp"
#include "engine/predict/predict.hpp"
#include "engine/learn/train.hpp"
#include "engine/sim/snapshot.hpp"

using namespace crowdmpm;

namespace {

constexpr int32_t kCookie = 0x434d504d;  // "CMPM"

thread_local std::string g_last_error;

struct ApiError {
  cmpm_Status status;
  std::string message;
};

// A world and the lock every call on it holds for its whole duration: calls on one world are
// serialised, calls on different worlds run concurrently, and destroying waits for the call in
// progress (the header's thread contract).
struct Box {
  std::mutex call;
  // Set by cmpm_DestroyWorld as it invalidates the handle (before it waits for the call lock):
  // a call that was already waiting for the lock may get it first (mutexes are not fair), and
  // must then fail as stale instead of running on a world being destroyed.
  std::atomic<bool> dead{false};
  std::unique_ptr<Simulation> sim;  // null once destroyed
};

// A slot whose generation reached this is retired: a wrapped generation would let a stale
// handle address a new world.
constexpr uint32_t kRetiredGeneration = 0xffffffffu;

struct Slot {
  std::shared_ptr<Box> box;  // null: free slot
  uint32_t generation = 1;
};

std::mutex g_registry_mutex;  // guards g_slots (never held while waiting for a world)
std::vector<Slot> g_slots;

[[noreturn]] void fail(cmpm_Status s, const std::string& msg) { throw ApiError{s, msg}; }

// An output path that cannot be written is the caller's argument, found before the work that
// would fill it (core/output.hpp).
template <class Check>
void writable_output(Check check) {
  try {
    check();
  } catch (const Error& e) {
    fail(CMPM_ERROR_INVALID_ARGUMENT, e.what());
  }
}

// Sets the thread's message; never throws (out of memory while building it leaves a fixed text).
void set_error(const char* fn, const char* prefix, const char* what) noexcept {
  try {
    g_last_error = std::string(fn) + ": " + prefix + what;
  } catch (...) {
    try {
      g_last_error.assign("out of memory");
    } catch (...) {
    }
  }
}

template <class F>
cmpm_Status guard(const char* fn, cmpm_Status input_status, F&& f) noexcept {
  try {
    f();
    g_last_error.clear();
    return CMPM_OK;
  } catch (const ApiError& e) {
    set_error(fn, "", e.message.c_str());
    return e.status;
  } catch (const Error& e) {
    set_error(fn, "", e.what());
    return input_status;
  } catch (const std::bad_alloc&) {
    set_error(fn, "", "out of memory");
    return CMPM_ERROR_INTERNAL;
  } catch (const std::exception& e) {
    set_error(fn, "internal error: ", e.what());
    return CMPM_ERROR_INTERNAL;
  } catch (...) {
    set_error(fn, "internal error (unknown exception)", "");
    return CMPM_ERROR_INTERNAL;
  }
}

std::string describe(cmpm_WorldId w) {
  return "world {index1 " + std::to_string(w.index1) + ", generation " + std::to_string(w.generation) + "}";
}

// The live slot of a handle; the registry mutex must be held.
Slot& live_slot(cmpm_WorldId w) {
  if (w.index1 > g_slots.size() || !g_slots[w.index1 - 1].box || g_slots[w.index1 - 1].generation != w.generation)
    fail(CMPM_ERROR_STALE_HANDLE, describe(w) + " does not exist or was destroyed");
  return g_slots[w.index1 - 1];
}

// A world held for one call: it keeps the world's memory alive and its call lock taken until
// the call returns. Deliberately not convertible to Simulation&, so that no call site can let
// the lock go while still using the world.
class Held {
 public:
  Held(std::shared_ptr<Box> box, std::unique_lock<std::mutex> lock) : box_(std::move(box)), lock_(std::move(lock)) {}
  Simulation& sim() { return *box_->sim; }

 private:
  std::shared_ptr<Box> box_;
  std::unique_lock<std::mutex> lock_;
};

Held lookup(cmpm_WorldId w) {
  if (w.index1 == 0) fail(CMPM_ERROR_NULL_HANDLE, "null world id (zeroed cmpm_WorldId)");
  std::shared_ptr<Box> box;
  {
    std::lock_guard<std::mutex> registry(g_registry_mutex);
    box = live_slot(w).box;
  }
  std::unique_lock<std::mutex> lock(box->call);
  // Destroyed while this call waited for another call on the same world to finish.
  if (box->dead || !box->sim) fail(CMPM_ERROR_STALE_HANDLE, describe(w) + " was destroyed");
  return Held(std::move(box), std::move(lock));
}

int32_t as_count(size_t n, const char* what) {
  if (n > static_cast<size_t>(INT32_MAX))
    fail(CMPM_ERROR_INTERNAL, std::string(what) + ": " + std::to_string(n) + " is more than an int32_t count can report");
  return static_cast<int32_t>(n);
}

template <class T>
void require(const T* p, const char* name) {
  if (!p) fail(CMPM_ERROR_INVALID_ARGUMENT, std::string(name) + " is NULL");
}

void check_capacity(int32_t capacity, size_t needed, int32_t* out_written, const char* what) {
  require(out_written, "out_written");
  *out_written = 0;
  if (capacity < 0) fail(CMPM_ERROR_INVALID_ARGUMENT, std::string("capacity must be >= 0, got ") + std::to_string(capacity));
  as_count(needed, what);  // reportable through *out_written
  if (static_cast<size_t>(capacity) < needed)
    fail(CMPM_ERROR_BUFFER_TOO_SMALL, std::string(what) + ": buffer holds " + std::to_string(capacity) + " but " +
                                          std::to_string(needed) + " are needed");
}

long agent_index(const Simulation& sim, cmpm_AgentId a) {
  if (a.value == 0) fail(CMPM_ERROR_NULL_HANDLE, "null agent id (0)");
  long i = sim.world().index_of(a.value);
  if (i < 0)
    fail(a.value < sim.world().next_id() ? CMPM_ERROR_STALE_HANDLE : CMPM_ERROR_INVALID_ARGUMENT,
         "agent " + std::to_string(a.value) + (a.value < sim.world().next_id() ? " was removed or has left through an exit" : " does not exist"));
  return i;
}

int behaviour_for(Simulation& sim, const char* target, int32_t group) {
  if (target) return sim.behaviour_for_target(target);
  if (group == -1) fail(CMPM_ERROR_INVALID_ARGUMENT, "an agent needs a target or a group (to take its behaviour from)");
  const auto& groups = sim.scenario().groups;
  if (group < 0 || group >= static_cast<int32_t>(groups.size()))
    fail(CMPM_ERROR_INVALID_ARGUMENT, "agent group " + std::to_string(group) + " out of range (the scenario has " +
                                          std::to_string(groups.size()) + " groups and sources); or give a target");
  return sim.behaviour_of_group(group);
}

// The request of a job and the file it writes: both given, the path not empty.
json job_request(const char* request_json, const char* out_path, const char* out_name, const char* source) {
  require(request_json, "request_json");
  require(out_path, out_name);
  if (!*out_path) fail(CMPM_ERROR_INVALID_ARGUMENT, std::string(out_name) + " is empty");
  return parse_json_text(request_json, source);
}

}  // namespace

extern "C" {

#define CMPM_STR2(x) #x
#define CMPM_STR(x) CMPM_STR2(x)

const char* cmpm_GetVersion(void) {
  return CMPM_STR(CMPM_VERSION_MAJOR) "." CMPM_STR(CMPM_VERSION_MINOR) "." CMPM_STR(CMPM_VERSION_PATCH);
}

int32_t cmpm_GetAbiVersion(void) { return CMPM_ABI_VERSION; }

const char* cmpm_GetLastError(void) { return g_last_error.c_str(); }

cmpm_WorldDef cmpm_DefaultWorldDef(void) {
  cmpm_WorldDef d;
  std::memset(&d, 0, sizeof d);
  d.threads = 1;
  d.internal_cookie = kCookie;
  return d;
}

cmpm_AgentDef cmpm_DefaultAgentDef(void) {
  cmpm_AgentDef d;
  std::memset(&d, 0, sizeof d);
  d.body_radius = -1;  // the model's
  d.comfort_distance = -1;
  d.desired_speed = 1.3;
  d.group = -1;  // none
  d.internal_cookie = kCookie;
  return d;
}

cmpm_Status cmpm_CreateWorld(const cmpm_WorldDef* def, cmpm_WorldId* out_world) {
  return guard("cmpm_CreateWorld", CMPM_ERROR_INVALID_INPUT, [&] {
    require(def, "def");
    require(out_world, "out_world");
    *out_world = cmpm_WorldId{0, 0};
    if (def->internal_cookie != kCookie)
      fail(CMPM_ERROR_UNINITIALIZED_DEF, "the cmpm_WorldDef was not made by cmpm_DefaultWorldDef()");
    const int sources = (def->scenario_json != nullptr) + (def->scenario_path != nullptr) + (def->snapshot_path != nullptr);
    if (sources != 1) fail(CMPM_ERROR_INVALID_ARGUMENT, "give exactly one of scenario_json, scenario_path or snapshot_path");
    if (def->model_json && def->model_path) fail(CMPM_ERROR_INVALID_ARGUMENT, "give at most one of model_json or model_path");
    if (def->snapshot_path && (def->model_json || def->model_path))
      fail(CMPM_ERROR_INVALID_ARGUMENT, "a snapshot holds its model: give no model_json or model_path with snapshot_path");
    if (def->threads < 1 || def->threads > 256)
      fail(CMPM_ERROR_INVALID_ARGUMENT, "threads must be in [1, 256], got " + std::to_string(def->threads));
    if (def->max_input_bytes < 0)
      fail(CMPM_ERROR_INVALID_ARGUMENT, "max_input_bytes must be >= 0 (0: the default), got " + std::to_string(def->max_input_bytes));
    if (def->allow_outside_paths != 0 && def->allow_outside_paths != 1)
      fail(CMPM_ERROR_INVALID_ARGUMENT, "allow_outside_paths must be 0 or 1, got " + std::to_string(def->allow_outside_paths));
    InputPolicy policy;
    if (def->max_input_bytes > 0) policy.max_bytes = static_cast<uint64_t>(def->max_input_bytes);
    policy.allow_outside_paths = def->allow_outside_paths == 1;
    std::unique_ptr<Simulation> sim;
    if (def->snapshot_path) {
      sim = load_snapshot_file(def->snapshot_path, def->threads, policy);
    } else {
      ScenarioDef s = def->scenario_path ? ScenarioDef::load(def->scenario_path, policy)
                                         : ScenarioDef::parse_text(def->scenario_json, ".", policy);
      Model m = def->model_path ? Model::load(def->model_path, policy)
                : def->model_json ? Model::parse(JsonReader(parse_json_text(def->model_json, "<model>"), ""), "<model>")
                : s.model_or_default();
      sim = std::make_unique<Simulation>(s, m, def->threads);
    }
    auto box = std::make_shared<Box>();
    box->sim = std::move(sim);
    std::lock_guard<std::mutex> lock(g_registry_mutex);
    size_t i = 0;
    while (i < g_slots.size() && (g_slots[i].box || g_slots[i].generation == kRetiredGeneration)) ++i;
    if (i == g_slots.size()) {
      if (g_slots.size() >= 0xffffffffu) fail(CMPM_ERROR_INTERNAL, "too many worlds");
      g_slots.emplace_back();
    }
    g_slots[i].box = std::move(box);
    *out_world = cmpm_WorldId{static_cast<uint32_t>(i + 1), g_slots[i].generation};
  });
}

cmpm_Status cmpm_DestroyWorld(cmpm_WorldId world) {
  return guard("cmpm_DestroyWorld", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    if (world.index1 == 0) fail(CMPM_ERROR_NULL_HANDLE, "null world id (zeroed cmpm_WorldId)");
    std::shared_ptr<Box> box;
    {
      // Checking the handle and invalidating it are one step: of two threads destroying the
      // same world, exactly one succeeds.
      std::lock_guard<std::mutex> registry(g_registry_mutex);
      Slot& slot = live_slot(world);
      box = std::move(slot.box);
      box->dead = true;
      ++slot.generation;  // reaching kRetiredGeneration retires the slot
    }
    // Wait for a call in progress on the world (it holds the call lock), then free it; calls
    // that were waiting find it destroyed.
    std::lock_guard<std::mutex> call(box->call);
    box->sim.reset();
  });
}

int32_t cmpm_World_IsValid(cmpm_WorldId world) {
  if (world.index1 == 0) return 0;
  try {
    std::lock_guard<std::mutex> lock(g_registry_mutex);
    return world.index1 <= g_slots.size() && g_slots[world.index1 - 1].box &&
           g_slots[world.index1 - 1].generation == world.generation;
  } catch (...) {  // a mutex that cannot be locked (std::system_error): report "not valid"
    return 0;
  }
}

cmpm_Status cmpm_World_SaveSnapshot(cmpm_WorldId world, const char* path) {
  return guard("cmpm_World_SaveSnapshot", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    require(path, "path");
    if (!*path) fail(CMPM_ERROR_INVALID_ARGUMENT, "path is empty");
    save_snapshot_file(held.sim(), path);
  });
}

cmpm_Status cmpm_World_Step(cmpm_WorldId world, int32_t steps) {
  return guard("cmpm_World_Step", CMPM_ERROR_SIMULATION, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    if (steps < 0 || steps > 10000000)
      fail(CMPM_ERROR_INVALID_ARGUMENT, "steps must be in [0, 10000000], got " + std::to_string(steps));
    sim.run_steps(steps);
  });
}

cmpm_Status cmpm_World_SetTimeStep(cmpm_WorldId world, double dt) {
  return guard("cmpm_World_SetTimeStep", CMPM_ERROR_INVALID_ARGUMENT, [&] { lookup(world).sim().set_time_step(dt); });
}

cmpm_Status cmpm_World_GetTimeStep(cmpm_WorldId world, double* out_dt) {
  return guard("cmpm_World_GetTimeStep", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    require(out_dt, "out_dt");
    *out_dt = lookup(world).sim().scenario().dt;
  });
}

cmpm_Status cmpm_World_GetTime(cmpm_WorldId world, double* out_seconds) {
  return guard("cmpm_World_GetTime", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    require(out_seconds, "out_seconds");
    *out_seconds = lookup(world).sim().time();
  });
}

cmpm_Status cmpm_World_GetStateHash(cmpm_WorldId world, uint64_t* out_hash) {
  return guard("cmpm_World_GetStateHash", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    require(out_hash, "out_hash");
    *out_hash = lookup(world).sim().world().state_hash();
  });
}

cmpm_Status cmpm_World_GetAgentCount(cmpm_WorldId world, int32_t* out_count) {
  return guard("cmpm_World_GetAgentCount", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    require(out_count, "out_count");
    *out_count = as_count(lookup(world).sim().world().size(), "agents");
  });
}

cmpm_Status cmpm_World_GetExitedCount(cmpm_WorldId world, int32_t* out_count) {
  return guard("cmpm_World_GetExitedCount", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    require(out_count, "out_count");
    *out_count = as_count(lookup(world).sim().exit_events().size(), "exited agents");
  });
}

cmpm_Status cmpm_World_GetAgentIds(cmpm_WorldId world, cmpm_AgentId* out, int32_t capacity, int32_t* out_written) {
  return guard("cmpm_World_GetAgentIds", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const World& w = held.sim().world();
    check_capacity(capacity, w.size(), out_written, "agent ids");
    if (w.size()) require(out, "out");
    for (size_t p = 0; p < w.size(); ++p) out[p].value = w.id[p];
    *out_written = static_cast<int32_t>(w.size());
  });
}

static cmpm_Status read_vec2(const char* fn, cmpm_WorldId world, double* out, int32_t capacity, int32_t* out_written,
                             bool velocity) {
  return guard(fn, CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const World& w = held.sim().world();
    check_capacity(capacity, 2 * w.size(), out_written, velocity ? "velocities (doubles)" : "positions (doubles)");
    if (w.size()) require(out, "out");
    const std::vector<Vec2>& src = velocity ? w.v : w.x;
    for (size_t p = 0; p < w.size(); ++p) {
      out[2 * p] = src[p].x();
      out[2 * p + 1] = src[p].y();
    }
    *out_written = static_cast<int32_t>(2 * w.size());
  });
}

cmpm_Status cmpm_World_GetPositions(cmpm_WorldId world, double* out_xy, int32_t capacity, int32_t* out_written) {
  return read_vec2("cmpm_World_GetPositions", world, out_xy, capacity, out_written, false);
}

cmpm_Status cmpm_World_GetVelocities(cmpm_WorldId world, double* out_vxy, int32_t capacity, int32_t* out_written) {
  return read_vec2("cmpm_World_GetVelocities", world, out_vxy, capacity, out_written, true);
}

cmpm_Status cmpm_World_GetPressures(cmpm_WorldId world, double* out, int32_t capacity, int32_t* out_written) {
  return guard("cmpm_World_GetPressures", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const World& w = held.sim().world();
    check_capacity(capacity, w.size(), out_written, "pressures");
    if (w.size()) require(out, "out");
    for (size_t p = 0; p < w.size(); ++p) out[p] = w.pressure[p];
    *out_written = static_cast<int32_t>(w.size());
  });
}

cmpm_Status cmpm_World_GetFieldShape(cmpm_WorldId world, int32_t* out_nx, int32_t* out_ny, double* out_origin_x,
                                     double* out_origin_y, double* out_cell) {
  return guard("cmpm_World_GetFieldShape", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const Grid& g = held.sim().grid();
    require(out_nx, "out_nx");
    require(out_ny, "out_ny");
    *out_nx = g.nx;
    *out_ny = g.ny;
    if (out_origin_x) *out_origin_x = g.origin.x();
    if (out_origin_y) *out_origin_y = g.origin.y();
    if (out_cell) *out_cell = g.dx;
  });
}

cmpm_Status cmpm_World_GetField(cmpm_WorldId world, int32_t field, double* out, int32_t capacity, int32_t* out_written) {
  return guard("cmpm_World_GetField", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const Simulation& sim = held.sim();
    if (sim.failed()) fail(CMPM_ERROR_SIMULATION, "the world became unstable (non-finite state): it has no fields");
    if (field != CMPM_FIELD_DENSITY && field != CMPM_FIELD_PRESSURE && field != CMPM_FIELD_VELOCITY)
      fail(CMPM_ERROR_INVALID_ARGUMENT, "unknown field " + std::to_string(field) + " (0 density, 1 pressure, 2 velocity)");
    const size_t n = sim.grid().nodes() * (field == CMPM_FIELD_VELOCITY ? 2 : 1);
    check_capacity(capacity, n, out_written, "field (doubles)");
    require(out, "out");
    FieldFrame f = compute_fields(sim.world(), sim.grid());
    for (size_t k = 0; k < sim.grid().nodes(); ++k) {
      if (field == CMPM_FIELD_DENSITY) out[k] = f.density[k];
      else if (field == CMPM_FIELD_PRESSURE) out[k] = f.pressure[k];
      else {
        out[2 * k] = f.velocity[k].x();
        out[2 * k + 1] = f.velocity[k].y();
      }
    }
    *out_written = static_cast<int32_t>(n);
  });
}

namespace {

// The engine's agent of a cmpm_AgentDef (throws ApiError or Error naming what is wrong).
AgentDef agent_of(Simulation& sim, const cmpm_AgentDef& def) {
  if (def.internal_cookie != kCookie) fail(CMPM_ERROR_UNINITIALIZED_DEF, "the cmpm_AgentDef was not made by cmpm_DefaultAgentDef()");
  AgentDef a;
  a.position = Vec2(def.x, def.y);
  a.velocity = Vec2(def.vx, def.vy);
  a.body_radius = def.body_radius < 0 ? sim.model().params.body_radius : def.body_radius;
  a.comfort_distance = def.comfort_distance < 0 ? sim.model().params.comfort_distance : def.comfort_distance;
  a.desired_speed = def.desired_speed;
  a.behaviour = behaviour_for(sim, def.target, def.group);
  a.group = def.group;
  return a;
}

}  // namespace

cmpm_Status cmpm_World_AddAgent(cmpm_WorldId world, const cmpm_AgentDef* def, cmpm_AgentId* out_agent) {
  return guard("cmpm_World_AddAgent", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    require(def, "def");
    require(out_agent, "out_agent");
    out_agent->value = 0;
    out_agent->value = sim.add_agent(agent_of(sim, *def));
  });
}

cmpm_Status cmpm_World_AddAgents(cmpm_WorldId world, const cmpm_AgentDef* defs, int32_t count, cmpm_AgentId* out_agents) {
  return guard("cmpm_World_AddAgents", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    if (count < 0) fail(CMPM_ERROR_INVALID_ARGUMENT, "count must be >= 0, got " + std::to_string(count));
    if (count == 0) return;
    require(defs, "defs");
    require(out_agents, "out_agents");
    const size_t n = static_cast<size_t>(count);
    for (size_t k = 0; k < n; ++k) out_agents[k].value = 0;
    std::vector<AgentDef> agents;
    agents.reserve(n);
    for (size_t k = 0; k < n; ++k) {
      const std::string which = "agent " + std::to_string(k) + " of " + std::to_string(n) + ": ";
      try {
        agents.push_back(agent_of(sim, defs[k]));
      } catch (const ApiError& e) {
        fail(e.status, which + e.message);
      } catch (const Error& e) {
        fail(CMPM_ERROR_INVALID_ARGUMENT, which + e.what());
      }
    }
    // Simulation::add_agents checks every agent before adding any, and names the first it refuses.
    const std::vector<EntityId> ids = sim.add_agents(agents);
    for (size_t k = 0; k < n; ++k) out_agents[k].value = ids[k];
  });
}

cmpm_Status cmpm_World_RemoveAgent(cmpm_WorldId world, cmpm_AgentId agent) {
  return guard("cmpm_World_RemoveAgent", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    sim.world().remove_at(static_cast<size_t>(agent_index(sim, agent)));
  });
}

cmpm_Status cmpm_World_SetAgentTarget(cmpm_WorldId world, cmpm_AgentId agent, const char* target) {
  return guard("cmpm_World_SetAgentTarget", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    long i = agent_index(sim, agent);
    require(target, "target");
    sim.world().behaviour[static_cast<size_t>(i)] = sim.behaviour_for_target(target);
  });
}

cmpm_Status cmpm_World_GetAgentState(cmpm_WorldId world, cmpm_AgentId agent, double* out_x, double* out_y, double* out_vx,
                                     double* out_vy) {
  return guard("cmpm_World_GetAgentState", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const Simulation& sim = held.sim();
    size_t i = static_cast<size_t>(agent_index(sim, agent));
    if (out_x) *out_x = sim.world().x[i].x();
    if (out_y) *out_y = sim.world().x[i].y();
    if (out_vx) *out_vx = sim.world().v[i].x();
    if (out_vy) *out_vy = sim.world().v[i].y();
  });
}

cmpm_Status cmpm_World_GetParameter(cmpm_WorldId world, const char* name, double* out_value) {
  return guard("cmpm_World_GetParameter", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    const Simulation& sim = held.sim();
    require(name, "name");
    require(out_value, "out_value");
    *out_value = sim.model().get(name);
  });
}

cmpm_Status cmpm_World_SetParameter(cmpm_WorldId world, const char* name, double value) {
  return guard("cmpm_World_SetParameter", CMPM_ERROR_INVALID_ARGUMENT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    require(name, "name");
    Model m = sim.model();
    m.set(name, value);
    sim.set_model(m);
  });
}

cmpm_Status cmpm_World_LoadTraction(cmpm_WorldId world, const char* traction_json) {
  return guard("cmpm_World_LoadTraction", CMPM_ERROR_INVALID_INPUT, [&] {
    Held held = lookup(world);
    Simulation& sim = held.sim();
    require(traction_json, "traction_json");
    if (!sim.model().has_traction())
      fail(CMPM_ERROR_INVALID_ARGUMENT, std::string("the ") + material_name(sim.model().material) + " material has no traction network");
    json j = parse_json_text(traction_json, "<traction>");
    Model m = sim.model();
    m.traction = TractionNet::parse(JsonReader(j, "traction"));
    sim.set_model(m);
  });
}

cmpm_Status cmpm_TrainModel(const char* request_json, const char* out_model_path) {
  return guard("cmpm_TrainModel", CMPM_ERROR_INVALID_INPUT, [&] {
    const json j = job_request(request_json, out_model_path, "out_model_path", "<train request>");
    const TrainJob job = parse_train_job(j);
    writable_output([&] { check_output_file(out_model_path, "model file"); });
    const TrainResult r = train_model(job.data, job.start, job.options);
    save_model(describe_learned(job, r), out_model_path);
  });
}

cmpm_Status cmpm_PredictRecording(const char* request_json, const char* out_json_path) {
  return guard("cmpm_PredictRecording", CMPM_ERROR_INVALID_INPUT, [&] {
    const json j = job_request(request_json, out_json_path, "out_json_path", "<predict request>");
    const PredictJob job = parse_predict_job(j);
    writable_output([&] { check_output_file(out_json_path, "prediction file"); });
    save_json_file(prediction_json(job, run_prediction(job)), out_json_path);
  });
}

cmpm_Status cmpm_Diagnose(const char* request_json, const char* out_dir) {
  return guard("cmpm_Diagnose", CMPM_ERROR_INVALID_INPUT, [&] {
    const json j = job_request(request_json, out_dir, "out_dir", "<diagnose request>");
    const DiagnoseJob job = parse_diagnose_job(j);
    writable_output([&] { prepare_output_folder(out_dir, "output folder"); });
    write_diagnosis(job, run_diagnosis(job), out_dir);
  });
}

}  // extern "C"
