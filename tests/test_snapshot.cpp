// World snapshots (engine/sim/snapshot.hpp): save at step 200, restore, run to step 400, and the
// world equals the uninterrupted run's, byte for byte; damaged snapshots give clear errors.
#include <catch2/catch.hpp>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "engine/sim/snapshot.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {

std::string error_of(const std::string& bytes) {
  try {
    restore_snapshot(bytes, "s.snap", 1);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// Steps `a` and a copy restored from its snapshot at `at` side by side to `to`: every state
// byte (the snapshot of each) must agree at the end.
void check_continues(Simulation& a, long at, long to, int threads_after) {
  a.run_steps(at);
  const std::string snap = save_snapshot(a);
  std::unique_ptr<Simulation> b = restore_snapshot(snap, "s.snap", threads_after);
  CHECK(save_snapshot(*b) == snap);  // restored exactly
  a.run_steps(to - at);
  b->run_steps(to - at);
  CHECK(b->steps() == a.steps());
  CHECK(b->time() == a.time());
  CHECK(b->world().state_hash() == a.world().state_hash());
  CHECK(save_snapshot(*b) == save_snapshot(a));
}

}  // namespace

TEST_CASE("snapshot: every shipped kind of world continues bit-identically after a restore", "[snapshot]") {
  // Crowd material with an exit (drill), sources and orbiting (corridor), the elastic material,
  // the social force model, a learned traction network (hajj).
  for (const char* name : {"drill", "corridor", "compression_elastic_soft", "hajj", "rimea_09"}) {
    INFO(name);
    ScenarioDef s = ScenarioDef::load(test::scenario_path(name));
    Simulation a(s, test::model_of(s), 2);
    check_continues(a, 200, 400, 1);
  }
  ScenarioDef s = ScenarioDef::load(test::scenario_path("bottleneck"));
  Simulation sf(s, Model::default_of("social_force"), 1);
  check_continues(sf, 200, 400, 2);
}

TEST_CASE("snapshot: changes made through the API travel with it", "[snapshot]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation a(s, test::model_of(s), 1);
  a.run_steps(50);
  // A behaviour added after construction (a new navigation target), an agent added by hand, a
  // removed agent, a changed parameter and a changed time step.
  AgentDef d;
  d.position = Vec2(3, 3);
  d.behaviour = a.behaviour_for_target("nearest_exit");
  a.add_agent(d);
  a.world().remove_at(0);
  Model m = a.model();
  m.set("tau", 0.7);
  a.set_model(m);
  a.set_time_step(0.005);
  check_continues(a, 100, 300, 2);
}

TEST_CASE("snapshot: a social force world whose time step changed continues identically", "[snapshot]") {
  // The social force widens its neighbour cells by 2 max_speed dt: a restore must size them as
  // they were, not from the current dt.
  ScenarioDef s = ScenarioDef::load(test::scenario_path("bottleneck"));
  Simulation a(s, Model::default_of("social_force"), 1);
  a.run_steps(30);
  a.set_time_step(0.005);
  check_continues(a, 30, 120, 2);
}

TEST_CASE("snapshot: a world saved with a time step its scenario file would refuse restores", "[snapshot]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation a(s, test::model_of(s), 1);
  a.set_time_step(0.005);
  Model m = a.model();
  m.set("max_speed", 18);  // dt max_speed <= cell / 4: valid for dt 0.005, too fast for the file's 0.01
  a.set_model(m);
  check_continues(a, 20, 60, 1);
}

TEST_CASE("snapshot: mutated state with a valid checksum is refused or restores, never crashes", "[snapshot]") {
  // A deterministic miniature of tests/fuzz/fuzz_snapshot.cpp: every 5th byte of the state after
  // the JSON strings, flipped three ways, with length and checksum fixed up.
  ScenarioDef s = ScenarioDef::parse_text(R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [6, 4]},
    "time": {"dt": 0.01, "duration": 10}, "geometry": {"exits": [{"id": "door", "rect": [5.5, 1, 6, 3]}]},
    "groups": [{"id": "g", "spawn": {"rect": [0.5, 0.5, 3, 3.5]}, "count": 6, "behaviour": {"type": "goal", "target": "door"}}]})");
  Simulation a(s, test::model_of(s), 1);
  a.run_steps(5);
  const std::string snap = save_snapshot(a);
  const size_t header = kSnapshotHeaderBytes, length = snap.size() - header - 8;
  // Skip the three JSON strings (scenario, name, model): their damage is JSON errors.
  size_t at = header;
  for (int k = 0; k < 3; ++k) {
    uint64_t n;
    std::memcpy(&n, snap.data() + at, 8);
    at += 8 + n;
  }
  int refused = 0, restored = 0;
  for (size_t i = at; i < header + length; i += 5)
    for (unsigned char x : {0x01, 0x80, 0xff}) {
      std::string bad = snap;
      bad[i] = static_cast<char>(bad[i] ^ x);
      reseal_snapshot(bad);
      try {
        auto b = restore_snapshot(bad, "m.snap", 1);
        b->run_steps(2);
        ++restored;
      } catch (const Error&) {
        ++refused;
      }
    }
  INFO("refused " << refused << ", restored " << restored);
  CHECK(refused > 0);
  CHECK(refused + restored > 1000);
}

TEST_CASE("snapshot: files are written whole and read back", "[snapshot]") {
  const std::string path = (std::filesystem::temp_directory_path() / "crowdmpm_test.snap").string();
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation a(s, test::model_of(s), 1);
  a.run_steps(20);
  save_snapshot_file(a, path);
  CHECK(!std::filesystem::exists(path + ".partial"));
  std::unique_ptr<Simulation> b = load_snapshot_file(path, 1);
  CHECK(b->world().state_hash() == a.world().state_hash());
  InputPolicy small;
  small.max_bytes = 100;
  CHECK_THROWS_WITH(load_snapshot_file(path, 1, small), Catch::Contains("above the input limit"));
  std::remove(path.c_str());
  CHECK_THROWS_WITH(save_snapshot_file(a, "/nonexistent-folder/x.snap"), Catch::Contains("/nonexistent-folder/x.snap: cannot open for writing"));
}

TEST_CASE("snapshot: truncated, corrupted, foreign and newer snapshots give clear errors", "[snapshot]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation a(s, test::model_of(s), 1);
  a.run_steps(10);
  const std::string snap = save_snapshot(a);
  CHECK_THROWS_WITH(restore_snapshot("", "s.snap", 1), Catch::Contains("s.snap: not a CrowdMPM snapshot"));
  CHECK_THROWS_WITH(restore_snapshot("{\"format\": \"crowdmpm-scenario\"}", "s.snap", 1), Catch::Contains("not a CrowdMPM snapshot"));
  // Truncated anywhere: at the header, in the state, in the checksum.
  for (size_t cut : {size_t{10}, size_t{23}, snap.size() / 2, snap.size() - 1})
    CHECK_THROWS_WITH(restore_snapshot(snap.substr(0, cut), "s.snap", 1), Catch::Contains("s.snap") && Catch::Contains("truncated"));
  CHECK_THROWS_WITH(restore_snapshot(snap + "x", "s.snap", 1), Catch::Contains("unexpected bytes after the snapshot"));
  // One flipped bit anywhere in the state.
  for (size_t at : {size_t{30}, snap.size() / 3, snap.size() - 20}) {
    std::string bad = snap;
    bad[at] = static_cast<char>(bad[at] ^ 0x10);
    CHECK_THROWS_WITH(restore_snapshot(bad, "s.snap", 1), Catch::Contains("corrupted snapshot: the checksum does not match"));
  }
  std::string newer = snap;
  newer[8] = 3;  // version
  CHECK_THROWS_WITH(restore_snapshot(newer, "s.snap", 1), Catch::Contains("snapshot format version 3; this engine reads versions 1 to 2"));
}
