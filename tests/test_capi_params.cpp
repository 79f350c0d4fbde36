// Setting a parameter through the C ABI is the same as loading it from the model file: the same
// state hash after 100 steps, for every parameter of the parameter table, with the crowd
// material and the social force model. Parameters that set up a world are refused once it exists.
#include <catch2/catch.hpp>
#include <cstdio>
#include <string>

#include "crowdmpm/crowdmpm.h"
#include "engine/sim/model.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
uint64_t hash_after(const Model& loaded, const char* set_name, double set_value, int steps, cmpm_Status* set_status,
                    std::string* set_error = nullptr) {
  const std::string scenario = test::scenario_path("drill");
  const std::string model_json = loaded.to_json().dump();
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  def.scenario_path = scenario.c_str();
  def.model_json = model_json.c_str();
  cmpm_WorldId w;
  REQUIRE(cmpm_CreateWorld(&def, &w) == CMPM_OK);
  if (set_name) {
    *set_status = cmpm_World_SetParameter(w, set_name, set_value);
    if (set_error) *set_error = cmpm_GetLastError();
  }
  REQUIRE(cmpm_World_Step(w, steps) == CMPM_OK);
  uint64_t h = 0;
  REQUIRE(cmpm_World_GetStateHash(w, &h) == CMPM_OK);
  cmpm_DestroyWorld(w);
  return h;
}

// A value inside the parameter's range, away from the current one.
double other_value(const ParamInfo& info, double now) {
  double v = now == 0 ? 0.1 * (info.hi - info.lo) + info.lo : now * 1.15;
  if (v > info.hi) v = now * 0.85;
  return v;
}
}  // namespace

TEST_CASE("a parameter set through the C ABI gives the same run as the same value loaded from JSON", "[capi][parameters]") {
  int compared = 0, refused = 0;
  for (const char* kind : {"crowd", "social_force"}) {
    const Model base = Model::default_of(kind);
    for (const auto& info : param_table()) {
      INFO(kind << " model, parameter " << info.name);
      const double v = other_value(info, base.params.*info.field);
      Model changed = base;
      changed.set(info.name, v);
      cmpm_Status status = CMPM_OK;
      std::string error;
      const uint64_t via_api = hash_after(base, info.name, v, 100, &status, &error);
      if (info.sets_up_world) {
        CHECK(status == CMPM_ERROR_INVALID_ARGUMENT);
        CHECK(error.find("fixed once a world exists") != std::string::npos);
        ++refused;
        continue;
      }
      REQUIRE(status == CMPM_OK);
      CHECK(via_api == hash_after(changed, nullptr, 0, 100, nullptr));
      ++compared;
    }
  }
  std::printf("C ABI parameters: %d set and compared, %d refused once a world exists\n", compared, refused);
  CHECK(compared >= 25);
  CHECK(refused == 10);
}
