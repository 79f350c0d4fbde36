// C ABI call sequences: a structured decoder turns one input into dozens of calls on up to four
// world handles (live, destroyed, null or forged), with buffers of exactly the capacity passed
// (so that a write past it is caught by AddressSanitizer) and arguments from the input bytes.
// Every call must return one of the documented statuses.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "crowdmpm/crowdmpm.h"
#include "fuzz_common.hpp"

namespace {

class Bytes {
 public:
  Bytes(const uint8_t* d, size_t n) : d_(d), n_(n) {}
  bool done() const { return i_ >= n_; }
  uint8_t u8() { return i_ < n_ ? d_[i_++] : 0; }
  int32_t i32() {
    uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v = (v << 8) | u8();
    return static_cast<int32_t>(v);
  }
  // A double that is usually ordinary and sometimes extreme (NaN, infinities, huge, negative).
  double number() {
    const uint8_t kind = u8();
    switch (kind % 8) {
      case 0: return NAN;
      case 1: return (kind & 8) ? INFINITY : -INFINITY;
      case 2: return (kind & 8 ? -1 : 1) * std::ldexp(1.0, u8() % 64 * 16 - 500);
      default: return (static_cast<int>(u8()) - 64) / 16.0 + u8() / 4096.0;
    }
  }

 private:
  const uint8_t* d_;
  size_t n_, i_ = 0;
};

const char* kScenarios[] = {
    // A room emptying through a door, with a goal and an obstacle.
    R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [8, 6]},
        "time": {"dt": 0.01, "duration": 30}, "seed": 4,
        "geometry": {"walls": [{"points": [[6, 0], [6, 2.5]]}, {"points": [[6, 3.5], [6, 6]]}],
                     "exits": [{"id": "door", "rect": [7.5, 0, 8, 6]}], "obstacles": [{"circle": {"center": [3, 3], "radius": 0.5}}]},
        "goals": [{"id": "corner", "rect": [0, 0, 1, 1]}],
        "groups": [{"id": "g", "spawn": {"rect": [0.5, 0.5, 5.5, 5.5]}, "count": 40, "behaviour": {"type": "goal", "target": "door"}}]})",
    // A source feeding a corridor, social force.
    R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [12, 3]},
        "time": {"dt": 0.01, "duration": 30}, "model": {"format": "crowdmpm-model", "version": 1, "material": "social_force"},
        "geometry": {"exits": [{"id": "end", "rect": [11.5, 0, 12, 3]}]},
        "sources": [{"id": "s", "spawn": {"rect": [0, 0, 1, 3]}, "rate": 4, "max_count": 30, "behaviour": {"type": "goal", "target": "end"}}]})",
    // An empty venue.
    R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [-5, -5], "max": [5, 5]}, "time": {"duration": 5},
        "geometry": {"exits": [{"id": "x", "circle": {"center": [4, 4], "radius": 0.8}}]}})",
};
const char* kTargets[] = {"door", "corner", "end", "x", "nearest_exit", "", "nowhere"};
const char* kParams[] = {"E", "gamma", "tau", "v0_scale", "time_gap", "max_speed", "body_radius", "rest_density", "nonsense", ""};
const char* kTraction[] = {"{\"constant\": 0.5}", "{\"constant\": -1}", "{\"layers\": []}", "{", "[]",
                           "{\"layers\": [{\"weights\": [[1, 2]], \"biases\": [0], \"activation\": \"relu\"}]}"};

void check_status(cmpm_Status s) {
  if (static_cast<int>(s) < CMPM_OK || static_cast<int>(s) > CMPM_ERROR_INTERNAL) __builtin_trap();
  if (s == CMPM_ERROR_INTERNAL) __builtin_trap();  // an engine fault, not the caller's
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Bytes in(data, size);
  cmpm_WorldId worlds[4] = {};
  std::vector<uint64_t> agents;
  std::vector<cmpm_WorldId> created;  // every world made, destroyed at the end (handles get overwritten)
  const std::string snap = crowdmpm::fuzz::scratch_dir() + "/crowdmpm_fuzz_capi.snap";
  for (int call = 0; call < 200 && !in.done(); ++call) {
    const uint8_t op = in.u8();
    cmpm_WorldId& w = worlds[in.u8() % 4];
    if (op % 23 == 22) w = cmpm_WorldId{static_cast<uint32_t>(in.i32()), static_cast<uint32_t>(in.i32())};  // forged
    cmpm_Status s = CMPM_OK;
    switch (op % 22) {
      case 0: {
        cmpm_WorldDef def = cmpm_DefaultWorldDef();
        const uint8_t k = in.u8();
        def.scenario_json = kScenarios[k % 3];
        def.threads = 1 + (k >> 6) % 2;
        s = cmpm_CreateWorld(&def, &w);
        break;
      }
      case 1: s = cmpm_DestroyWorld(w); break;
      case 2: s = cmpm_World_Step(w, in.u8() % 6 - 1); break;
      case 3: s = cmpm_World_SetTimeStep(w, in.number()); break;
      case 4: {
        double t;
        uint64_t h;
        int32_t n;
        check_status(cmpm_World_GetTime(w, &t));
        check_status(cmpm_World_GetTimeStep(w, &t));
        check_status(cmpm_World_GetStateHash(w, &h));
        check_status(cmpm_World_GetExitedCount(w, &n));
        s = cmpm_World_GetAgentCount(w, &n);
        break;
      }
      case 5:
      case 6:
      case 7: {
        const int32_t cap = in.u8() * 2 - 10;
        std::vector<double> buf(cap > 0 ? static_cast<size_t>(cap) : 0);
        int32_t written = -1;
        double* out = cap > 0 ? buf.data() : nullptr;
        s = op % 22 == 5 ? cmpm_World_GetPositions(w, out, cap, &written)
            : op % 22 == 6 ? cmpm_World_GetVelocities(w, out, cap, &written)
                           : cmpm_World_GetPressures(w, out, cap, &written);
        if (s == CMPM_OK && (written < 0 || written > cap)) __builtin_trap();
        break;
      }
      case 8: {
        const int32_t cap = in.u8() - 5;
        std::vector<cmpm_AgentId> ids(cap > 0 ? static_cast<size_t>(cap) : 0);
        int32_t written = -1;
        s = cmpm_World_GetAgentIds(w, cap > 0 ? ids.data() : nullptr, cap, &written);
        if (s == CMPM_OK) {
          if (written < 0 || written > cap) __builtin_trap();
          for (int32_t i = 0; i < written; ++i) agents.push_back(ids[static_cast<size_t>(i)].value);
        }
        break;
      }
      case 9: {
        int32_t nx = 0, ny = 0, written = -1;
        check_status(cmpm_World_GetFieldShape(w, &nx, &ny, nullptr, nullptr, nullptr));
        const int32_t field = static_cast<int32_t>(in.u8() % 4) - (in.u8() % 8 == 0 ? 7 : 0);
        const int32_t cap = nx * ny * (1 + in.u8() % 2) - in.u8() % 3;
        std::vector<double> buf(cap > 0 ? static_cast<size_t>(cap) : 0);
        s = cmpm_World_GetField(w, field, cap > 0 ? buf.data() : nullptr, cap, &written);
        if (s == CMPM_OK && (written < 0 || written > cap)) __builtin_trap();
        break;
      }
      case 10: {  // one agent, or a batch of 0-3 (cmpm_World_AddAgents; a negative count now and then)
        const uint8_t how = in.u8();
        const int32_t count = how % 2 ? static_cast<int32_t>(how / 2 % 5) - 1 : 1;
        std::vector<cmpm_AgentDef> defs(static_cast<size_t>(std::max(count, 1)));
        for (cmpm_AgentDef& a : defs) {
          a = cmpm_DefaultAgentDef();
          a.x = in.number();
          a.y = in.number();
          a.vx = in.u8() % 4 == 0 ? in.number() : 0;
          const uint8_t k = in.u8();
          a.target = k % 8 == 7 ? nullptr : kTargets[k % 7];
          a.group = static_cast<int32_t>(in.u8() % 4) - 1;
          if (k & 0x80) a.desired_speed = in.number();
          if (k & 0x40) a.body_radius = in.number();
        }
        std::vector<cmpm_AgentId> ids(defs.size(), cmpm_AgentId{0});
        s = how % 2 ? cmpm_World_AddAgents(w, defs.data(), count, ids.data()) : cmpm_World_AddAgent(w, defs.data(), ids.data());
        if (s == CMPM_OK)
          for (int32_t k = 0; k < count; ++k) agents.push_back(ids[static_cast<size_t>(k)].value);
        break;
      }
      case 11:
      case 12:
      case 13: {
        const uint8_t k = in.u8();
        const cmpm_AgentId id{agents.empty() || k % 5 == 0 ? k : agents[k % agents.size()]};
        double x, y, vx, vy;
        s = op % 22 == 11 ? cmpm_World_RemoveAgent(w, id)
            : op % 22 == 12 ? cmpm_World_SetAgentTarget(w, id, kTargets[in.u8() % 7])
                            : cmpm_World_GetAgentState(w, id, &x, &y, &vx, &vy);
        break;
      }
      case 14: {
        double v;
        s = cmpm_World_GetParameter(w, kParams[in.u8() % 10], &v);
        break;
      }
      case 15: s = cmpm_World_SetParameter(w, kParams[in.u8() % 10], in.number()); break;
      case 16: s = cmpm_World_LoadTraction(w, kTraction[in.u8() % 6]); break;
      case 17: s = cmpm_World_SaveSnapshot(w, snap.c_str()); break;
      case 18: {
        cmpm_WorldDef def = cmpm_DefaultWorldDef();
        def.snapshot_path = snap.c_str();
        def.threads = 1 + in.u8() % 2;
        s = cmpm_CreateWorld(&def, &w);
        break;
      }
      case 19: (void)cmpm_World_IsValid(w); break;
      case 20: {  // misuse: null outputs, uninitialised defs
        cmpm_WorldDef def;
        std::memset(&def, 0, sizeof def);
        check_status(cmpm_CreateWorld(&def, &w));
        check_status(cmpm_World_GetTime(w, nullptr));
        s = cmpm_World_AddAgent(w, nullptr, nullptr);
        break;
      }
      default: w = cmpm_WorldId{0, 0}; break;  // forget the handle (destroyed at the end)
    }
    check_status(s);
    if (s == CMPM_OK && (op % 22 == 0 || op % 22 == 18)) created.push_back(w);
    (void)cmpm_GetLastError();
  }
  for (const cmpm_WorldId& w : created) cmpm_DestroyWorld(w);  // the stale ones fail harmlessly
  return 0;
}
