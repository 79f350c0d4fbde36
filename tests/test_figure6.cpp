// Source document Figure 6, measured on the drill scenarios: a wider door lowers the peak
// pressure at the door; a pillar in front of the door carries a pressure concentration on its
// upstream face. Whether the pillar also lowers the door's pressure is measured and printed.
#include <catch2/catch.hpp>
#include <cstdio>

#include "support.hpp"

using namespace crowdmpm;

namespace {
constexpr double kSeconds = 60;

// Per grid node: time average of the pressure field over the frames the node is occupied.
struct PressureMap {
  FieldFrame shape;
  std::vector<double> sum;
  std::vector<long> frames;
  void add(const FieldFrame& f) {
    if (sum.empty()) {
      shape = f;
      sum.assign(f.pressure.size(), 0);
      frames.assign(f.pressure.size(), 0);
    }
    for (size_t i = 0; i < f.pressure.size(); ++i)
      if (f.density[i] > 0.5) {
        sum[i] += f.pressure[i];
        ++frames[i];
      }
  }
  double mean_at(size_t i) const { return frames[i] ? sum[i] / static_cast<double>(frames[i]) : 0; }
};

MetricsRecorder run(const std::string& name, Simulation*& keep, PressureMap* map = nullptr) {
  static std::vector<std::unique_ptr<ScenarioDef>> scenarios;  // MetricsRecorder keeps a reference
  scenarios.push_back(std::make_unique<ScenarioDef>(ScenarioDef::load(test::scenario_path(name))));
  ScenarioDef& s = *scenarios.back();
  keep = new Simulation(s, test::model_of(s), 2);
  MetricsRecorder m(s);
  test::run_for(*keep, kSeconds, [&](const Simulation& sim) {
    FieldFrame f = compute_fields(sim.world(), sim.grid());
    if (map) map->add(f);
    m.record(sim, f);
  });
  for (size_t a = 0; a < s.areas.size(); ++a)
    std::printf("figure6 %-16s area %-12s mean density %6.2f /m2  mean pressure %7.3f  peak pressure %7.3f\n", name.c_str(),
                s.areas[a].id.c_str(), m.areas()[a].mean_density(), m.areas()[a].mean_pressure(), m.areas()[a].pressure_peak);
  std::printf("figure6 %-16s exited %zu in %.0f s\n", name.c_str(), keep->exit_events().size(), kSeconds);
  return m;
}
}  // namespace

TEST_CASE("Figure 6: wider exit lowers door pressure and the pillar face carries a pressure concentration", "[figure6]") {
  Simulation *a = nullptr, *b = nullptr, *c = nullptr;
  MetricsRecorder narrow = run("drill", a);
  MetricsRecorder wide = run("drill_wide_exit", b);
  PressureMap map;
  MetricsRecorder pillar = run("drill_pillar", c, &map);
  // Peak and time-averaged pressure at the door: narrow door above wide door.
  CHECK(narrow.area("door").pressure_peak > wide.area("door").pressure_peak);
  CHECK(narrow.area("door").mean_pressure() > 1.2 * wide.area("door").mean_pressure());
  // Pressure concentration on the pillar's upstream face: above the room's mean (over the
  // people in it), and among the highest of the room's time-averaged pressure map (over its
  // occupied grid nodes, each averaged over the frames it is occupied).
  double face = pillar.area("pillar_face").mean_pressure(), room = pillar.area("room").mean_pressure();
  const Shape& face_shape = c->scenario().areas[1].shape;
  const Shape& room_shape = c->scenario().areas[2].shape;
  REQUIRE(c->scenario().areas[1].id == "pillar_face");
  REQUIRE(c->scenario().areas[2].id == "room");
  std::vector<double> room_nodes;
  double face_sum = 0, room_sum = 0;
  int face_n = 0;
  for (int j = 0; j < map.shape.ny; ++j)
    for (int i = 0; i < map.shape.nx; ++i) {
      const size_t k = static_cast<size_t>(j) * map.shape.nx + i;
      const Vec2 x = map.shape.node_position(i, j);
      if (map.frames[k] == 0) continue;
      if (face_shape.contains(x)) {
        face_sum += map.mean_at(k);
        ++face_n;
      }
      if (room_shape.contains(x)) {
        room_nodes.push_back(map.mean_at(k));
        room_sum += map.mean_at(k);
      }
    }
  REQUIRE(face_n > 0);
  const double face_map = face_sum / face_n, room_map = room_sum / static_cast<double>(room_nodes.size());
  double below = 0;
  for (double v : room_nodes) below += v < face_map ? 1 : 0;
  const double percentile = 100 * below / static_cast<double>(room_nodes.size());
  std::printf("figure6 pillar face / room mean pressure = %.3f (people); map: face %.2f, room nodes mean %.2f (x%.2f), face above %.0f%% of %zu room nodes\n",
              face / room, face_map, room_map, face_map / room_map, percentile, room_nodes.size());
  // Measured x1.20 (people), x1.24 (map), above 66% of the room's nodes since bodies are held a
  // body radius off the pillar (shoulder_clearance); x1.3, x1.5 and 86% while they could overlap
  // it by 10 cm. Only the approach to the door is higher.
  CHECK(face > 1.1 * room);
  CHECK(face_map > 1.2 * room_map);
  CHECK(percentile > 60);
  // The source document claims the pillar moves the high pressure from the door to the pillar.
  double with = pillar.area("door").mean_pressure(), without = narrow.area("door").mean_pressure();
  std::printf("figure6 door time-averaged pressure without pillar %.3f, with pillar %.3f: %s\n", without, with,
              with < without ? "the pillar lowers the door pressure" : "the pillar does NOT lower the door pressure");
  delete a;
  delete b;
  delete c;
}
