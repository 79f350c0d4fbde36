// Malformed scenario and model files (tests/bad/, listed in tests/bad/expected.json with the
// words their error must contain): each must give a crowdmpm::Error naming the JSON path or
// file position, never a crash or another exception type.
#include <catch2/catch.hpp>
#include <filesystem>

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
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.path().filename() != "expected.json") ++files;
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
