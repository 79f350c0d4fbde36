// Malformed scenario and model files (tests/bad/, listed in tests/bad/expected.json with the
// words their error must contain): each must give a crowdmpm::Error naming the JSON path or
// file position, never a crash or another exception type.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>

#include "support.hpp"

using namespace crowdmpm;

namespace {
// Loads a scenario or a model the way the CLI does, including placing the groups.
void load_like_cli(const std::string& kind, const std::string& path) {
  if (kind == "model") {
    Model m = Model::load(path);
    ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
    Simulation sim(s, m, 1);
  } else {
    ScenarioDef s = ScenarioDef::load(path);
    Simulation sim(s, test::model_of(s), 1);
  }
}
}  // namespace

TEST_CASE("every malformed file in tests/bad gives a clear error naming where", "[validation]") {
  const std::string dir = test::repo_path("tests/bad");
  json expected = load_json_file(dir + "/expected.json");
  REQUIRE(expected.size() >= 15);
  size_t files = 0;
  // Folders (bases/: the files some bad files extend) are not bad files themselves.
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.is_regular_file() && entry.path().filename() != "expected.json") ++files;
  CHECK(files == expected.size());  // every bad file has an expectation and vice versa
  for (auto it = expected.begin(); it != expected.end(); ++it) {
    const std::string name = it.key();
    const std::string path = dir + "/" + name;
    INFO("file: " << name);
    REQUIRE(std::filesystem::exists(path));
    std::string message;
    bool other_exception = false;
    try {
      load_like_cli(it.value().at("kind").get<std::string>(), path);
    } catch (const Error& e) {
      message = e.what();
    } catch (const std::exception& e) {
      other_exception = true;
      message = e.what();
    }
    INFO("message: " << message);
    CHECK_FALSE(other_exception);
    REQUIRE_FALSE(message.empty());
    for (const auto& s : it.value().at("error_contains")) CHECK(message.find(s.get<std::string>()) != std::string::npos);
  }
}

namespace {
// The .json files directly in a folder of the repository.
std::vector<std::string> json_files_in(const std::string& folder) {
  std::vector<std::string> out;
  for (const auto& entry : std::filesystem::directory_iterator(test::repo_path(folder)))
    if (entry.path().extension() == ".json") out.push_back(entry.path().string());
  return out;
}
}  // namespace

TEST_CASE("every shipped scenario is valid", "[validation]") {
  const auto files = json_files_in("scenarios");
  for (const auto& f : files) {
    INFO("scenario: " << f);
    CHECK_NOTHROW(ScenarioDef::load(f));
  }
  CHECK(files.size() >= 12);
}

TEST_CASE("model JSON round-trips through to_json and parse", "[validation]") {
  Model m = Model::default_model();
  m.set("E", 33);
  Model back = Model::parse(JsonReader(m.to_json(), ""), "roundtrip");
  CHECK(back.get("E") == 33);
  CHECK(back.traction.parameter_count() == m.traction.parameter_count());
  double in[TractionNet::kInputs] = {0.3, 0.5, 0.2, -0.1, 0.4, 0.1};
  CHECK(back.traction.eval(in) == m.traction.eval(in));
  CHECK_THROWS_WITH(m.set("E", -1), Catch::Contains("E must be in"));
  CHECK_THROWS_WITH(m.set("stiffness", 1), Catch::Contains("unknown material parameter \"stiffness\""));
}

TEST_CASE("every shipped model is valid", "[validation]") {
  const auto files = json_files_in("scenarios/models");
  for (const auto& f : files) {
    INFO("model: " << f);
    CHECK_NOTHROW(Model::load(f));
  }
  CHECK(files.size() >= 1);
}

namespace {
// A fresh folder for one test's scenario files.
std::filesystem::path scratch_folder(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("crowdmpm_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

uint64_t hash_after(const ScenarioDef& s, long steps) {
  Simulation sim(s, test::model_of(s), 1);
  sim.run_steps(steps);
  return sim.world().state_hash();
}

const char* kBase = R"({
  "format": "crowdmpm-scenario", "version": 1, "name": "room",
  "domain": {"min": [0, 0], "max": [10, 6]},
  "navigation": {"cell_size": 0.2},
  "time": {"dt": 0.01, "duration": 30},
  "geometry": {
    "walls": [{"id": "partition", "points": [[7, 0], [7, 2.5]]}],
    "exits": [{"id": "door", "rect": [9, 2, 10, 4]}]
  },
  "groups": [{"id": "crowd", "spawn": {"rect": [1, 1, 4, 5]}, "density": 2, "behaviour": {"type": "goal", "target": "door"}}],
  "outputs": {"pixels_per_metre": 50, "video": false}
})";
}  // namespace

TEST_CASE("a scenario that extends a base equals the hand-merged scenario", "[validation]") {
  const auto dir = scratch_folder("extends_merge");
  write_text(dir / "room.json", kBase);
  // Objects merge key by key (time, geometry, outputs); arrays (groups, walls) replace whole.
  const std::string variant = R"({
    "extends": "room.json", "name": "room_pillar",
    "time": {"duration": 12},
    "geometry": {"obstacles": [{"circle": {"center": [5, 3], "radius": 0.5}}]},
    "groups": [{"id": "crowd", "spawn": {"rect": [1, 1, 3, 5]}, "count": 20}],
    "outputs": {"video": true}
  })";
  write_text(dir / "room_pillar.json", variant);
  const char* by_hand = R"({
    "format": "crowdmpm-scenario", "version": 1, "name": "room_pillar",
    "domain": {"min": [0, 0], "max": [10, 6]},
    "navigation": {"cell_size": 0.2},
    "time": {"dt": 0.01, "duration": 12},
    "geometry": {
      "walls": [{"id": "partition", "points": [[7, 0], [7, 2.5]]}],
      "obstacles": [{"circle": {"center": [5, 3], "radius": 0.5}}],
      "exits": [{"id": "door", "rect": [9, 2, 10, 4]}]
    },
    "groups": [{"id": "crowd", "spawn": {"rect": [1, 1, 3, 5]}, "count": 20}],
    "outputs": {"pixels_per_metre": 50, "video": true}
  })";
  CHECK(ScenarioDef::load_json((dir / "room_pillar.json").string()) == json::parse(by_hand));
  const ScenarioDef merged = ScenarioDef::load((dir / "room_pillar.json").string());
  const ScenarioDef hand = ScenarioDef::parse_text(by_hand);
  CHECK(merged.duration == 12);
  CHECK(merged.geo.solids.size() == 2);
  CHECK(merged.outputs.video);
  CHECK(hash_after(merged, 100) == hash_after(hand, 100));
  // From text, the base is found from base_dir, as the C ABI's scenario_json is.
  CHECK(hash_after(ScenarioDef::parse_text(variant, dir.string()), 100) == hash_after(hand, 100));
}

TEST_CASE("null in an extending scenario deletes the key so the default applies", "[validation]") {
  const auto dir = scratch_folder("extends_null");
  write_text(dir / "room.json", kBase);
  write_text(dir / "plain.json", R"({"extends": "room.json", "navigation": null, "outputs": {"pixels_per_metre": null}})");
  const ScenarioDef base = ScenarioDef::load((dir / "room.json").string());
  const ScenarioDef plain = ScenarioDef::load((dir / "plain.json").string());
  CHECK(base.nav_cell == 0.2);
  CHECK(plain.nav_cell == 0.1);
  CHECK(base.outputs.pixels_per_metre == 50);
  CHECK(plain.outputs.pixels_per_metre == 0);
  CHECK_FALSE(plain.outputs.video);  // the rest of outputs is kept
  json j = ScenarioDef::load_json((dir / "plain.json").string());
  CHECK_FALSE(j.contains("navigation"));
  CHECK_FALSE(j.contains("extends"));
}

TEST_CASE("extends chains in scenario files apply in order and resolve paths from the file that names them", "[validation]") {
  const auto dir = scratch_folder("extends_chain");
  write_text(dir / "room.json", kBase);
  // The base names a model beside it; a variant in a subfolder still finds it.
  Model soft = Model::default_model();
  soft.set("E", 33);
  std::filesystem::create_directories(dir / "models");
  save_json_file(soft.to_json(), (dir / "models" / "soft.json").string());
  write_text(dir / "room_soft.json", R"({"extends": "room.json", "model": "models/soft.json", "seed": 5})");
  write_text(dir / "variants" / "long.json", R"({"extends": "../room_soft.json", "time": {"duration": 50}})");
  // The base lies outside the variant's folder: refused unless the caller allows it.
  CHECK_THROWS_WITH(ScenarioDef::load((dir / "variants" / "long.json").string()), Catch::Contains("lies outside the folder"));
  InputPolicy outside;
  outside.allow_outside_paths = true;
  const ScenarioDef s = ScenarioDef::load((dir / "variants" / "long.json").string(), outside);
  CHECK(s.duration == 50);
  CHECK(s.dt == 0.01);
  CHECK(s.seed == 5);
  REQUIRE(s.model);
  CHECK(s.model->get("E") == 33);
  CHECK(s.name == "room");
}

TEST_CASE("scenario extends errors name the file and the chain: missing base and cycle and too long a chain", "[validation]") {
  const auto dir = scratch_folder("extends_errors");
  write_text(dir / "a.json", R"({"extends": "b.json"})");
  write_text(dir / "b.json", R"({"extends": "./a.json"})");
  const std::string a = (dir / "a.json").string(), b = (dir / "b.json").string();
  CHECK_THROWS_WITH(ScenarioDef::load(a), Catch::Contains(b + ": extends: cycle " + a + " -> " + b + " -> " + a));
  write_text(dir / "lost.json", R"({"extends": "nope.json"})");
  CHECK_THROWS_WITH(ScenarioDef::load((dir / "lost.json").string()),
                    Catch::Contains("lost.json: extends: cannot read 'nope.json'") && Catch::Contains("cannot open file"));
  CHECK_THROWS_WITH(ScenarioDef::parse_text(R"({"extends": "nope.json"})", dir.string()),
                    Catch::Contains("<scenario>: extends: cannot read 'nope.json'"));
  write_text(dir / "chain0.json", kBase);
  for (int i = 1; i <= 20; ++i)
    write_text(dir / ("chain" + std::to_string(i) + ".json"), "{\"extends\": \"chain" + std::to_string(i - 1) + ".json\"}");
  CHECK_NOTHROW(ScenarioDef::load((dir / "chain15.json").string()));  // 16 files
  CHECK_THROWS_WITH(ScenarioDef::load((dir / "chain16.json").string()),
                    Catch::Contains("extends: more than 16 files extend one another"));
  // Errors in the merged scenario name the files it came from.
  write_text(dir / "bad_density.json", R"({"extends": "chain0.json", "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "density": -2}]})");
  CHECK_THROWS_WITH(ScenarioDef::load((dir / "bad_density.json").string()),
                    Catch::Contains("bad_density.json (extends " + (dir / "chain0.json").string() + "): groups[0].density: must be in"));
}
