// A thin C++ class over the C ABI, used only to generate the SWIG bindings: it turns status
// codes into exceptions (with the library's message) and buffers into vectors, so that every
// host language gets exceptions and bulk arrays. It calls nothing but cmpm_* functions.
#pragma once
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "crowdmpm/crowdmpm.h"

namespace crowdmpm_binding {

inline void check(cmpm_Status s) {
  if (s != CMPM_OK) throw std::runtime_error(cmpm_GetLastError());
}

inline std::string version() { return cmpm_GetVersion(); }
inline int abi_version() { return cmpm_GetAbiVersion(); }

// Learns a model from recorded trajectories (cmpm_TrainModel; request format in
// docs/learning.md) and writes it to out_model_path; raises with the library's message.
inline void train_model(const std::string& request_json, const std::string& out_model_path) {
  check(cmpm_TrainModel(request_json.c_str(), out_model_path.c_str()));
}

// Predicts a recording with constant velocity, the scenario's model and the models given
// (cmpm_PredictRecording) and writes the errors as JSON to out_json_path.
inline void predict_recording(const std::string& request_json, const std::string& out_json_path) {
  check(cmpm_PredictRecording(request_json.c_str(), out_json_path.c_str()));
}

// Diagnoses missing physics (cmpm_Diagnose; request format in docs/diagnosis.md): writes
// report.json, summary.txt, the residual pictures, scenario.json and model.json into out_dir.
inline void diagnose(const std::string& request_json, const std::string& out_dir) {
  check(cmpm_Diagnose(request_json.c_str(), out_dir.c_str()));
}

class World {
 public:
  // scenario: a file path, or JSON text if it starts with '{'. model: "" (the scenario's or the
  // default model), a path, or JSON text. threads: 1..256, results do not depend on it.
  // allow_outside_paths: let the scenario name files outside its folder; max_input_bytes: the
  // largest file read (0: 256 MiB).
  World(const std::string& scenario, const std::string& model = "", int threads = 1, bool allow_outside_paths = false,
        long long max_input_bytes = 0) {
    cmpm_WorldDef def = cmpm_DefaultWorldDef();
    def.allow_outside_paths = allow_outside_paths ? 1 : 0;
    def.max_input_bytes = max_input_bytes;
    bool scenario_text = is_json(scenario), model_text = is_json(model);
    def.scenario_json = scenario_text ? scenario.c_str() : nullptr;
    def.scenario_path = scenario_text ? nullptr : scenario.c_str();
    if (!model.empty()) {
      def.model_json = model_text ? model.c_str() : nullptr;
      def.model_path = model_text ? nullptr : model.c_str();
    }
    def.threads = threads;
    check(cmpm_CreateWorld(&def, &id_));
  }
  ~World() {
    if (id_.index1) cmpm_DestroyWorld(id_);
  }
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // A world whose id is null: every call on it raises (for tests of error handling).
  static World* null_world() { return new World(); }

  // A world restored from a snapshot file written by save_snapshot: it continues exactly as the
  // saved world would have.
  static World* from_snapshot(const std::string& path, int threads = 1) {
    cmpm_WorldDef def = cmpm_DefaultWorldDef();
    def.snapshot_path = path.c_str();
    def.threads = threads;
    World* w = new World();
    cmpm_Status s = cmpm_CreateWorld(&def, &w->id_);
    if (s != CMPM_OK) {
      delete w;
      check(s);
    }
    return w;
  }
  // Saves the world to a snapshot file (versioned, checksummed).
  void save_snapshot(const std::string& path) { check(cmpm_World_SaveSnapshot(id_, path.c_str())); }

  // Destroys the world now; later calls raise "... was destroyed".
  void destroy() {
    cmpm_WorldId id = id_;
    check(cmpm_DestroyWorld(id));
  }
  bool is_valid() const { return cmpm_World_IsValid(id_) == 1; }

  void step(int steps = 1) { check(cmpm_World_Step(id_, steps)); }
  double time() const { double t; check(cmpm_World_GetTime(id_, &t)); return t; }
  double time_step() const { double t; check(cmpm_World_GetTimeStep(id_, &t)); return t; }
  void set_time_step(double dt) { check(cmpm_World_SetTimeStep(id_, dt)); }
  uint64_t state_hash() const { uint64_t h; check(cmpm_World_GetStateHash(id_, &h)); return h; }
  // The state hash as 16 lower-case hex digits (for hosts without unsigned 64-bit integers).
  std::string state_hash_hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(state_hash()));
    return buf;
  }
  int agent_count() const { int32_t n; check(cmpm_World_GetAgentCount(id_, &n)); return n; }
  int exited_count() const { int32_t n; check(cmpm_World_GetExitedCount(id_, &n)); return n; }

  // Bulk reads: x0, y0, x1, y1, ... (m); vx0, vy0, ... (m/s); pressures; ids. Same agent order.
  std::vector<double> positions() const { return read_all<double>(&cmpm_World_GetPositions, 2); }
  std::vector<double> velocities() const { return read_all<double>(&cmpm_World_GetVelocities, 2); }
  std::vector<double> pressures() const { return read_all<double>(&cmpm_World_GetPressures, 1); }
  std::vector<long long> agent_ids() const {
    const std::vector<cmpm_AgentId> ids = read_all<cmpm_AgentId>(&cmpm_World_GetAgentIds, 1);
    std::vector<long long> out;
    for (const cmpm_AgentId& a : ids) out.push_back(static_cast<long long>(a.value));
    return out;
  }

  // Grid field "density", "pressure" or "velocity" (2 values per node), row-major, ny rows of nx.
  std::vector<double> field(const std::string& name) const {
    int32_t f = name == "density" ? CMPM_FIELD_DENSITY : name == "pressure" ? CMPM_FIELD_PRESSURE
                : name == "velocity" ? CMPM_FIELD_VELOCITY : -1;
    if (f < 0) throw std::runtime_error("unknown field \"" + name + "\" (density, pressure or velocity)");
    std::vector<double> out(static_cast<size_t>(field_nx()) * static_cast<size_t>(field_ny()) * (f == CMPM_FIELD_VELOCITY ? 2 : 1));
    int32_t n;
    check(cmpm_World_GetField(id_, f, out.data(), static_cast<int32_t>(out.size()), &n));
    return out;
  }
  int field_nx() const { int32_t nx, ny; check(cmpm_World_GetFieldShape(id_, &nx, &ny, nullptr, nullptr, nullptr)); return nx; }
  int field_ny() const { int32_t nx, ny; check(cmpm_World_GetFieldShape(id_, &nx, &ny, nullptr, nullptr, nullptr)); return ny; }

  // Adds an agent walking to `target` (an exit or goal id, or "nearest_exit"); returns its id.
  long long add_agent(double x, double y, const std::string& target, double vx = 0, double vy = 0, double desired_speed = 1.3) {
    const cmpm_AgentDef d = agent_def(x, y, target, vx, vy, desired_speed);
    cmpm_AgentId a;
    check(cmpm_World_AddAgent(id_, &d, &a));
    return static_cast<long long>(a.value);
  }
  // Adds agents walking to `target` in one call (cmpm_World_AddAgents: all or none): xy holds
  // x0, y0, x1, y1, ...; vxy the velocities the same way, or is empty for people at rest.
  // Returns their ids in order.
  std::vector<long long> add_agents_xy(const std::vector<double>& xy, const std::string& target,
                                       const std::vector<double>& vxy = {}, double desired_speed = 1.3) {
    if (xy.size() % 2) throw std::invalid_argument("add_agents: positions must hold x, y pairs, got " + std::to_string(xy.size()) + " numbers");
    if (!vxy.empty() && vxy.size() != xy.size())
      throw std::invalid_argument("add_agents: velocities must hold as many numbers as positions (" + std::to_string(xy.size()) +
                                  "), got " + std::to_string(vxy.size()));
    const size_t n = xy.size() / 2;
    if (n > static_cast<size_t>(INT32_MAX)) throw std::invalid_argument("add_agents: too many agents in one call");
    std::vector<cmpm_AgentDef> defs;
    defs.reserve(n);
    for (size_t k = 0; k < n; ++k)
      defs.push_back(agent_def(xy[2 * k], xy[2 * k + 1], target, vxy.empty() ? 0 : vxy[2 * k], vxy.empty() ? 0 : vxy[2 * k + 1],
                               desired_speed));
    std::vector<cmpm_AgentId> ids(n);
    check(cmpm_World_AddAgents(id_, defs.data(), static_cast<int32_t>(n), ids.data()));
    std::vector<long long> out(n);
    for (size_t k = 0; k < n; ++k) out[k] = static_cast<long long>(ids[k].value);
    return out;
  }
  void remove_agent(long long agent) { check(cmpm_World_RemoveAgent(id_, cmpm_AgentId{static_cast<uint64_t>(agent)})); }
  void set_agent_target(long long agent, const std::string& target) {
    check(cmpm_World_SetAgentTarget(id_, cmpm_AgentId{static_cast<uint64_t>(agent)}, target.c_str()));
  }
  // x, y, vx, vy of one agent.
  std::vector<double> agent_state(long long agent) const {
    std::vector<double> s(4);
    check(cmpm_World_GetAgentState(id_, cmpm_AgentId{static_cast<uint64_t>(agent)}, &s[0], &s[1], &s[2], &s[3]));
    return s;
  }

  double parameter(const std::string& name) const { double v; check(cmpm_World_GetParameter(id_, name.c_str(), &v)); return v; }
  void set_parameter(const std::string& name, double value) { check(cmpm_World_SetParameter(id_, name.c_str(), value)); }
  void load_traction(const std::string& json) { check(cmpm_World_LoadTraction(id_, json.c_str())); }

 private:
  World() : id_{0, 0} {}
  static bool is_json(const std::string& s) {
    for (char c : s)
      if (c != ' ' && c != '\n' && c != '\t' && c != '\r') return c == '{';
    return false;
  }
  // The definition of an agent walking to `target` (its c_str stays owned by the caller).
  static cmpm_AgentDef agent_def(double x, double y, const std::string& target, double vx, double vy, double desired_speed) {
    cmpm_AgentDef d = cmpm_DefaultAgentDef();
    d.x = x;
    d.y = y;
    d.vx = vx;
    d.vy = vy;
    d.desired_speed = desired_speed;
    d.target = target.c_str();
    return d;
  }
  // A bulk read sized from the agent count. Another thread may step the world between the count
  // and the read (the C ABI serialises calls, not pairs of calls): on "buffer too small" it
  // counts again and retries.
  template <class T>
  std::vector<T> read_all(cmpm_Status (*fn)(cmpm_WorldId, T*, int32_t, int32_t*), size_t per_agent) const {
    for (int attempt = 0;; ++attempt) {
      std::vector<T> out(per_agent * static_cast<size_t>(agent_count()) + (attempt > 0 ? 64 : 0));
      int32_t n = 0;
      cmpm_Status s = fn(id_, out.data(), static_cast<int32_t>(out.size()), &n);
      if (s == CMPM_ERROR_BUFFER_TOO_SMALL && attempt < 8) continue;
      check(s);
      out.resize(static_cast<size_t>(n));
      return out;
    }
  }
  cmpm_WorldId id_;
};

}  // namespace crowdmpm_binding
