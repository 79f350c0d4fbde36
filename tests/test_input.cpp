// Bounded, confined input (engine/core/input.hpp): issue 13's reproducers and the rules that
// keep them fixed. Every case here failed (or hung) before the readers were bounded.
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>

#include "engine/io/trajectory.hpp"
#include "engine/sim/scenario.hpp"
#include "support.hpp"

using namespace crowdmpm;
namespace fs = std::filesystem;

namespace {

// A fresh folder under the system's temporary folder, removed at the end of the test case.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name) : path(fs::temp_directory_path() / ("crowdmpm_input_" + name)) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    fs::create_directories((path / name).parent_path());
    std::ofstream(path / name) << text;
    return (path / name).string();
  }
};

std::string room_with_model(const std::string& model) {
  return R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [10, 10]},
             "time": {"dt": 0.01, "duration": 1}, "model": ")" + model + R"(",
             "geometry": {"exits": [{"id": "out", "rect": [9, 4, 10, 6]}]},
             "groups": [{"id": "g", "spawn": {"rect": [1, 1, 5, 5]}, "count": 4,
                         "behaviour": {"type": "goal", "target": "out"}}]})";
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("input: devices and other special files are refused before reading", "[input]") {
  // Issue 13: "model": "/dev/zero" was read without bound (4.2 GB resident after 20 s).
  CHECK_THROWS_WITH(read_input_file("/dev/zero"), Catch::Contains("/dev/zero: is not a regular file"));
  InputPolicy outside;
  outside.allow_outside_paths = true;
  TempDir d("devices");
  const std::string scenario = d.write("room.json", room_with_model("/dev/zero"));
  CHECK_THROWS_WITH(ScenarioDef::load(scenario, outside), Catch::Contains("/dev/zero: is not a regular file"));
  // A named pipe would block an open() for ever: it is refused from its type alone.
  const std::string fifo = (d.path / "pipe").string();
  REQUIRE(mkfifo(fifo.c_str(), 0600) == 0);
  CHECK_THROWS_WITH(TrajectorySet::read(fifo), Catch::Contains("is not a regular file"));
  CHECK_THROWS_WITH(read_input_file(d.path.string()), Catch::Contains("is a folder"));
  CHECK_THROWS_WITH(read_input_file((d.path / "missing.json").string()), Catch::Contains("no such file"));
}

TEST_CASE("input: files above the size limit are refused, and the limit is settable", "[input]") {
  TempDir d("size");
  const std::string big = d.write("big.txt", "# framerate: 10\n" + std::string(5000, '#') + "\n1 0 1 2\n");
  InputPolicy small;
  small.max_bytes = 1000;
  CHECK_THROWS_WITH(TrajectorySet::read(big, 0, small), Catch::Contains("above the input limit of"));
  CHECK(TrajectorySet::read(big).points.size() == 1);  // the default limit is 256 MiB
  const std::string scenario = d.write("room.json", room_with_model("default") + std::string(2000, ' '));
  CHECK_THROWS_WITH(ScenarioDef::load(scenario, small), Catch::Contains("above the input limit"));
  CHECK_NOTHROW(ScenarioDef::load(scenario));
}

TEST_CASE("input: a scenario's model and extends stay inside its folder unless allowed", "[input]") {
  TempDir d("confined");
  const std::string model_text = read_input_file(test::repo_path("scenarios/models/v1.json"));
  d.write("models/m.json", model_text);
  d.write("outside_model.json", model_text);
  const std::string inside = d.write("venue/inside.json", room_with_model("../models/m.json"));
  CHECK_THROWS_WITH(ScenarioDef::load(inside), Catch::Contains("lies outside the folder"));
  InputPolicy allow;
  allow.allow_outside_paths = true;
  CHECK(ScenarioDef::load(inside, allow).model.has_value());
  const std::string ok = d.write("ok.json", room_with_model("models/m.json"));
  CHECK(ScenarioDef::load(ok).model.has_value());
  // A symbolic link inside the folder that points out of it is followed, then refused.
  fs::create_directories(d.path / "venue2");
  fs::create_symlink(d.path / "outside_model.json", d.path / "venue2" / "link.json");
  const std::string linked = d.write("venue2/s.json", room_with_model("link.json"));
  CHECK_THROWS_WITH(ScenarioDef::load(linked), Catch::Contains("lies outside the folder"));
  // Absolute paths are confined too.
  const std::string abs = d.write("venue3/s.json", room_with_model((d.path / "outside_model.json").string()));
  CHECK_THROWS_WITH(ScenarioDef::load(abs), Catch::Contains("lies outside the folder"));
  // "extends" of a file outside the folder.
  const std::string ext = d.write("venue4/s.json", R"({"extends": "../ok.json"})");
  CHECK_THROWS_WITH(ScenarioDef::load(ext), Catch::Contains("lies outside the folder"));
  CHECK_NOTHROW(ScenarioDef::load(ext, allow));
}

TEST_CASE("input: errors never quote the contents of the file read", "[input]") {
  // Issue 13: the error for "model": "/etc/passwd" echoed the file's first character.
  TempDir d("echo");
  d.write("secret.json", "root:x:0:0:root:/root:/bin/bash\n");
  d.write("secret2.json", "{\"format\": \"crowdmpm-model\", \"version\": 1, \"material\": rootpass}");
  InputPolicy allow;
  allow.allow_outside_paths = true;
  for (const char* name : {"secret.json", "secret2.json", "/etc/passwd"}) {
    const std::string scenario = d.write("s.json", room_with_model(name));
    const std::string msg = message_of([&] { ScenarioDef::load(scenario, allow); });
    INFO(msg);
    CHECK(msg.find("cannot load model") != std::string::npos);
    CHECK(msg.find("root") == std::string::npos);
    CHECK(msg.find("last read") == std::string::npos);
  }
}
