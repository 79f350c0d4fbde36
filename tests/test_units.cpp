// Unit tests of the engine's parts: shapes, navigation, traction network, world bookkeeping,
// thread pool, writers.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "engine/core/parallel.hpp"
#include "engine/io/trajectory.hpp"
#include "engine/sim/kernels.hpp"
#include "support.hpp"

using namespace crowdmpm;

TEST_CASE("shape signed distances", "[units]") {
  Shape sq = Shape::rect(Vec2(0, 0), Vec2(2, 2));
  CHECK(sq.sdf(Vec2(1, 1)) == Approx(-1));
  CHECK(sq.sdf(Vec2(3, 1)) == Approx(1));
  CHECK(sq.sdf(Vec2(3, 3)) == Approx(std::sqrt(2.0)));
  CHECK(sq.area() == Approx(4));
  Shape c = Shape::circle(Vec2(1, 0), 0.5);
  CHECK(c.sdf(Vec2(1, 2)) == Approx(1.5));
  Shape wall = Shape::polyline({Vec2(0, 0), Vec2(4, 0)}, 0.2);
  CHECK(wall.sdf(Vec2(2, 1)) == Approx(0.9));
  CHECK(wall.sdf(Vec2(2, 0)) == Approx(-0.1));
  CHECK(wall.sdf(Vec2(5, 0)) == Approx(0.9));
}

TEST_CASE("geometry sdf includes the domain border and normals point out of solids", "[units]") {
  Geometry g;
  g.lo = Vec2(0, 0);
  g.hi = Vec2(10, 10);
  g.solids.push_back(Shape::circle(Vec2(5, 5), 1));
  CHECK(g.sdf(Vec2(0.5, 5)) == Approx(0.5));
  CHECK(g.sdf(Vec2(5, 6.5)) == Approx(0.5));
  Vec2 n = g.normal(Vec2(5, 6.5));
  CHECK(n.y() == Approx(1).margin(1e-6));
  CHECK(g.sdf(Vec2(-1, 5)) < 0);  // outside the domain is solid
}

TEST_CASE("navigation field goes around an obstacle", "[units]") {
  Geometry g;
  g.lo = Vec2(0, 0);
  g.hi = Vec2(10, 4);
  g.solids.push_back(Shape::rect(Vec2(4, 0), Vec2(5, 3)));  // a wall with a gap at the top
  Shape target = Shape::rect(Vec2(9, 0), Vec2(10, 4));
  NavField nav(g, {&target}, 0.1, 0.1);
  // Below the wall's top, right in front of it: the way is up, not through the wall.
  Vec2 d = nav.direction(Vec2(3.5, 1));
  CHECK(d.y() > 0.7);
  // Travel distance exceeds the straight line and is close to the path over the wall.
  // Shortest path: up to the wall's corner (4, 3.1), along its top, then straight to x = 9.
  double straight = 9 - 1.0, around = std::hypot(3.0, 2.1) + 1.0 + 4.0;
  double t = nav.distance(Vec2(1, 1));
  CHECK(t > straight);
  CHECK(t == Approx(around).epsilon(0.05));
  CHECK(nav.reachable(Vec2(1, 1)));
}

TEST_CASE("traction network evaluates as its layers say", "[units]") {
  json j = {{"layers", {{{"weights", {{1, 0, 0, 0, 0, 0}, {0, 1, 0, 0, 0, 0}}}, {"biases", {0.5, 0}}, {"activation", "tanh"}},
                         {{"weights", {{2, -1}}}, {"biases", {0.1}}, {"activation", "identity"}}}}};
  TractionNet net = TractionNet::parse(JsonReader(j, "traction"));
  double in[6] = {0.3, 0.7, 0, 0, 0, 0};
  double expected = std::log1p(std::exp(2 * std::tanh(0.8) - std::tanh(0.7) + 0.1));
  CHECK(net.eval(in) == Approx(expected).epsilon(1e-12));
  CHECK(net.parameter_count() == 12 + 2 + 2 + 1);
  json bad = j;
  bad["layers"][0]["weights"][1] = {1, 2, 3};
  CHECK_THROWS_WITH(TractionNet::parse(JsonReader(bad, "traction")), Catch::Contains("traction.layers[0].weights[1]"));
}

TEST_CASE("contact potential is zero at the comfort distance and keeps growing past contact", "[units]") {
  CHECK(contact_potential(0.7, 0.4, 0.3, 0.01) == Approx(0).margin(1e-12));
  CHECK(contact_potential(0.41, 0.4, 0.3, 0.01) == Approx(std::log(30.0)));
  CHECK(contact_potential(0.40, 0.4, 0.3, 0.01) > contact_potential(0.41, 0.4, 0.3, 0.01));
  CHECK(contact_potential(0.35, 0.4, 0.3, 0.01) > contact_potential(0.40, 0.4, 0.3, 0.01) + 4);
}

TEST_CASE("world ids stay valid through swap-removal", "[units]") {
  World w;
  EntityId a = w.add(AgentDef{}), b = w.add(AgentDef{}), c = w.add(AgentDef{});
  w.x[w.index_of(c)] = Vec2(3, 3);
  w.remove_at(static_cast<size_t>(w.index_of(a)));
  CHECK(w.size() == 2);
  CHECK(w.index_of(a) == -1);
  CHECK(w.x[w.index_of(c)] == Vec2(3, 3));
  CHECK(w.index_of(b) >= 0);
  CHECK(w.index_of(0) == -1);
  CHECK(w.index_of(99) == -1);
}

TEST_CASE("thread pool covers every index once and rethrows", "[units]") {
  ThreadPool pool(2);
  std::vector<int> hits(1000, 0);
  pool.parallel_for(hits.size(), [&](size_t b, size_t e) { for (size_t i = b; i < e; ++i) ++hits[i]; });
  for (int h : hits) CHECK(h == 1);
  CHECK_THROWS_WITH(pool.parallel_for(1000, [](size_t b, size_t) { if (b > 0) throw Error("boom"); }), "boom");
  CHECK_THROWS(ThreadPool(0));
}

TEST_CASE("trajectory and npy writers produce readable files", "[units]") {
  auto dir = std::filesystem::temp_directory_path() / "crowdmpm_units";
  std::filesystem::create_directories(dir);
  World w;
  AgentDef d;
  d.position = Vec2(1.5, -2.25);
  w.add(d);
  {
    TrajectoryWriter t((dir / "t.txt").string(), 16, "unit test");
    t.write_frame(w, 7);
    t.close();
  }
  std::ifstream in(dir / "t.txt");
  std::string line, last;
  std::getline(in, line);
  CHECK(line == "# framerate: 16");
  while (std::getline(in, line)) last = line;
  CHECK(last == "1 7 1.50000 -2.25000 0");
  {
    NpyWriter n((dir / "a.npy").string(), 2, 3, 1);
    n.write_frame(std::vector<float>(6, 1.0f));
    n.write_frame(std::vector<float>(6, 2.0f));
    n.close();
  }
  CHECK(std::filesystem::file_size(dir / "a.npy") == 128 + 12 * 4);
  std::ifstream npy(dir / "a.npy", std::ios::binary);
  std::string header(128, '\0');
  npy.read(&header[0], 128);
  CHECK(header.find("'shape': (2, 2, 3)") != std::string::npos);
  CHECK_THROWS_WITH(TrajectoryWriter("/nonexistent/dir/t.txt", 10, ""), Catch::Contains("/nonexistent/dir/t.txt"));
}

TEST_CASE("groups are placed at the density asked, without overlap, outside solids", "[units]") {
  const char* text = R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [0, 0], "max": [10, 10]}, "time": {"duration": 1},
    "geometry": {"obstacles": [{"circle": {"center": [5, 5], "radius": 1}}]},
    "groups": [{"spawn": {"rect": [1, 1, 9, 9]}, "density": 5, "behaviour": {"type": "none"}}]})";
  ScenarioDef s = ScenarioDef::parse_text(text);
  Simulation sim(s, Model::default_model(), 1);
  const World& w = sim.world();
  double free_area = 64 - M_PI * 1.1 * 1.1;  // minus the obstacle and its clearance
  CHECK(static_cast<double>(w.size()) == Approx(5 * free_area).epsilon(0.03));
  double closest = 1e300;
  for (size_t p = 0; p < w.size(); ++p) {
    CHECK(s.geo.sdf(w.x[p]) >= 0.1 - 1e-9);
    for (size_t q = p + 1; q < w.size(); ++q) closest = std::min(closest, (w.x[p] - w.x[q]).norm());
  }
  CHECK(closest >= 0.4 - 1e-9);
}

TEST_CASE("orbit around a structure follows its contour counter-clockwise", "[units]") {
  const char* text = R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [-10, -10], "max": [10, 10]}, "time": {"duration": 1},
    "geometry": {"obstacles": [{"id": "block", "rect": [-2, -2, 2, 2]}]},
    "goals": [{"id": "block", "rect": [-2, -2, 2, 2]}],
    "groups": [{"spawn": {"rect": [3, -1, 4, 1]}, "count": 1, "behaviour": {"type": "orbit", "around": "block", "direction": "ccw"}}]})";
  ScenarioDef s = ScenarioDef::parse_text(text);
  Simulation sim(s, Model::default_model(), 1);
  Vec2 e = sim.world().heading[0];  // desired direction, computed at construction
  CHECK(e.y() > 0.95);              // east of the block, counter-clockwise is +y
  const char* both = R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [0, 0], "max": [5, 5]}, "time": {"duration": 1},
    "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 1, "behaviour": {"type": "orbit", "around": "x", "center": [1, 1]}}]})";
  CHECK_THROWS_WITH(ScenarioDef::parse_text(both), Catch::Contains("groups[0].behaviour: orbit needs exactly one of"));
}

TEST_CASE("an exit nobody can reach is refused and one with a clear point is not", "[units]") {
  auto scenario = [](const std::string& exit_rect) {
    return R"({"format": "crowdmpm-scenario", "version": 1, "domain": {"min": [0, 0], "max": [10, 4]}, "time": {"duration": 1},
      "geometry": {"obstacles": [{"id": "block", "rect": [6, 0, 6.5, 4]}], "exits": [{"id": "out", "rect": )" + exit_rect + R"(}]},
      "groups": [{"spawn": {"rect": [1, 1, 3, 3]}, "count": 4, "behaviour": {"type": "goal", "target": "out"}}]})";
  };
  CHECK_THROWS_WITH(ScenarioDef::parse_text(scenario("[6.1, 1, 6.4, 2]")),
                    Catch::Contains("geometry.exits[0]: lies wholly inside walls or obstacles") && Catch::Contains("\"out\""));
  CHECK_NOTHROW(ScenarioDef::parse_text(scenario("[6.1, 1, 6.7, 2]")));  // its right edge sticks out of the block
  CHECK_NOTHROW(ScenarioDef::parse_text(scenario("[9.8, 0, 10, 4]")));   // a strip along the domain's edge
}

TEST_CASE("agents placed on the same spot separate", "[units]") {
  const char* text = R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [0, 0], "max": [10, 6]}, "time": {"duration": 5},
    "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "behaviour": {"type": "none"}}]})";
  ScenarioDef s = ScenarioDef::parse_text(text);
  Simulation sim(s, Model::default_model(), 1);
  AgentDef a;
  a.position = Vec2(5, 3);
  a.behaviour = 1;
  EntityId first = sim.add_agent(a), second = sim.add_agent(a);
  sim.run_steps(200);
  const World& w = sim.world();
  double gap = (w.x[static_cast<size_t>(w.index_of(first))] - w.x[static_cast<size_t>(w.index_of(second))]).norm();
  CHECK(gap > 0.3);
}

TEST_CASE("changing dt keeps the elapsed time", "[units]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation sim(s, test::model_of(s), 1);
  sim.run_steps(100);
  CHECK(sim.time() == Approx(1.0));
  sim.set_time_step(0.005);
  CHECK(sim.time() == Approx(1.0));
  sim.run_steps(100);
  CHECK(sim.time() == Approx(1.5));
  CHECK_THROWS_WITH(sim.set_time_step(0.2), Catch::Contains("time.dt"));
}

TEST_CASE("contact_epsilon must stay below every comfort distance", "[units]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Model m = Model::default_model();
  m.set("contact_epsilon", 0.1);
  m.set("comfort_distance", 0.05);
  CHECK_THROWS_WITH(Simulation(s, m, 1), Catch::Contains("contact_epsilon 0.1 m must be smaller than every comfort distance"));
}

TEST_CASE("a run ending between frames does not repeat a frame number", "[units]") {
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  s.duration = 1.03;
  s.outputs.fields = s.outputs.pictures = s.outputs.video = false;
  auto dir = (std::filesystem::temp_directory_path() / "crowdmpm_partial_frame").string();
  run_scenario(s, test::model_of(s), RunOptions{dir, 1, nullptr});
  TrajectorySet t = TrajectorySet::read(dir + "/trajectories.txt");  // rejects repeated (id, frame)
  CHECK(t.frame_max() == 10);
}

TEST_CASE("local density counts a uniform crowd at its density, a person alone at 2/(pi R^2), however far apart", "[units]") {
  // A hexagonal lattice at 5 persons/m^2, 20 m x 20 m.
  World w;
  const double rho = 5, a = std::sqrt(2 / (std::sqrt(3.0) * rho));
  for (int j = 0; j * a * std::sqrt(3.0) / 2 < 20; ++j)
    for (int i = 0; i * a < 20; ++i) {
      AgentDef d;
      d.position = Vec2(i * a + 0.5 * a * (j & 1), j * a * std::sqrt(3.0) / 2);
      w.add(d);
    }
  const std::vector<double> all = local_density(w, 0, 1.0);
  REQUIRE(all.size() == w.size());
  for (size_t p = 0; p < w.size(); ++p)
    if ((w.x[p] - Vec2(10, 10)).norm() < 5) CHECK(all[p] == Approx(rho).epsilon(0.05));
  // Version 2's reference volumes at a rest density of 4: J = 4/5 inside, 1 where sparser.
  reference_volumes(w, 0, 4);
  for (size_t p = 0; p < w.size(); ++p) {
    if ((w.x[p] - Vec2(10, 10)).norm() < 5) CHECK(w.J[p] == Approx(0.8).epsilon(0.05));
    CHECK(w.J[p] <= 1);
  }
  // People far apart (a line 1e12 m long): each alone, and the cell lists stay small.
  World far;
  for (int k = 0; k < 3; ++k) {
    AgentDef d;
    d.position = Vec2(1e12 * k, 5);
    far.add(d);
  }
  for (double r : local_density(far, 0, 1.0)) CHECK(r == Approx(2 / M_PI));
  CHECK(local_density(far, 3, 1.0).empty());
}

TEST_CASE("density ahead: a uniform crowd at its density whichever way people face, the queue behind counts for nothing", "[units]") {
  // The hexagonal lattice at 5 persons/m^2 of the test above, everyone facing a different way.
  const double rho = 5, a = std::sqrt(2 / (std::sqrt(3.0) * rho));
  std::vector<Vec2> x, heading;
  for (int j = 0; j * a * std::sqrt(3.0) / 2 < 20; ++j)
    for (int i = 0; i * a < 20; ++i) {
      x.emplace_back(i * a + 0.5 * a * (j & 1), j * a * std::sqrt(3.0) / 2);
      const double angle = 0.7 * static_cast<double>(x.size());
      heading.emplace_back(std::cos(angle), std::sin(angle));
    }
  const std::vector<double> ahead = local_density_ahead(x, heading, 1.0, 1.0);
  const std::vector<double> around = local_density(x, 0, 1.0);
  for (size_t p = 0; p < x.size(); ++p)
    if ((x[p] - Vec2(10, 10)).norm() < 5) CHECK(ahead[p] == Approx(around[p]).epsilon(0.1));
  // At the front of the crowd, facing out: the people behind count for nothing (only those
  // beside and the person themselves); facing back, the crowd counts about twice.
  std::vector<Vec2> out(x.size(), Vec2(1, 0)), back(x.size(), Vec2(-1, 0));
  const std::vector<double> front_out = local_density_ahead(x, out, 1.0, 1.0), front_back = local_density_ahead(x, back, 1.0, 1.0);
  size_t front = 0;
  for (size_t p = 0; p < x.size(); ++p)
    if (std::abs(x[p].y() - 10) < 1 && x[p].x() > x[front].x()) front = p;
  CHECK(front_out[front] < 0.6 * around[front]);  // 1.6 against 3.0 around (half a disc of the crowd)
  CHECK(front_back[front] > 1.4 * around[front]);  // 4.4
  // No heading: every neighbour weighs 1, as local_density.
  const std::vector<double> none = local_density_ahead(x, std::vector<Vec2>(x.size(), Vec2::Zero()), 1.0, 1.0);
  for (size_t p = 0; p < x.size(); ++p) CHECK(none[p] == Approx(around[p]));
  // The opening discount (density_opening_speed): a crowd walking as one parts from nobody and
  // counts in full; the people ahead walking away at 0.3 m/s count with exp(-0.3 / 0.1) = 0.05.
  const std::vector<Vec2> together(x.size(), Vec2(1.2, 0));
  const std::vector<double> uniform = local_density_ahead(x, out, 1.0, 1.0, &together, 0.1);
  for (size_t p = 0; p < x.size(); ++p) CHECK(uniform[p] == Approx(front_out[p]));
  std::vector<Vec2> parting(x.size(), Vec2(1.0, 0));
  for (size_t p = 0; p < x.size(); ++p)
    if (x[p].x() > x[front].x() - 0.3) parting[p] = Vec2(1.3, 0);  // the front row walks away
  const std::vector<double> opened = local_density_ahead(x, out, 1.0, 1.0, &parting, 0.1);
  size_t behind = 0;  // the person nearest 0.6 m behind the front one
  for (size_t p = 0; p < x.size(); ++p)
    if ((x[p] - x[front] + Vec2(0.6, 0)).norm() < (x[behind] - x[front] + Vec2(0.6, 0)).norm()) behind = p;
  CHECK(opened[behind] < 0.8 * front_out[behind]);
  CHECK(opened[front] == Approx(front_out[front]));  // nobody ahead of the front row parts from it
  // Reach and focus (density_speed_reach, density_speed_focus): inside a uniform crowd any
  // kernel reads its density; a person 1.5 m in front of the crowd, facing it, sees it only
  // with a reach beyond 1.5 m, and a focused kernel sees less of the people beside them: at the
  // crowd's side edge facing along it, half the disc is empty either way, but at its front
  // facing out, the front row beside the person weighs (1 + cos 90)^4 / 4.375 = 0.23 instead of 1.
  for (double focus : {1.0, 2.5, 4.0}) {
    const std::vector<double> wide = local_density_ahead(x, heading, 3.0, focus);
    const std::vector<double> around3 = local_density(x, 0, 3.0);
    for (size_t p = 0; p < x.size(); ++p)
      if ((x[p] - Vec2(10, 10)).norm() < 3) CHECK(wide[p] == Approx(around3[p]).epsilon(0.05));
  }
  std::vector<Vec2> ahead_of = x;
  ahead_of.emplace_back(x[front].x() + 1.5, x[front].y());
  std::vector<Vec2> facing(ahead_of.size(), Vec2(1, 0));
  facing.back() = Vec2(-1, 0);
  const double alone = 2 / M_PI;  // itself only, reach 1 m
  CHECK(local_density_ahead(ahead_of, facing, 1.0, 1.0).back() == Approx(alone));
  CHECK(local_density_ahead(ahead_of, facing, 3.0, 4.0).back() > 1.0);
  const double out1 = local_density_ahead(x, out, 1.0, 1.0)[front], out4 = local_density_ahead(x, out, 1.0, 4.0)[front];
  CHECK(out4 < 0.6 * out1);
  // A focus below 1 is not a kernel the model accepts (docs/model-format.md: [1, 8]).
  Model m = Model::default_model();
  CHECK_THROWS_WITH(m.set("density_speed_focus", 0.5), Catch::Contains("density_speed_focus must be in [1, 8]"));
  CHECK_THROWS_WITH(m.set("density_speed_reach", 0.1), Catch::Contains("density_speed_reach must be in [0.5, 5] m"));
}

TEST_CASE("density per walkable area: a corridor narrower than the kernel reads its density, its share's adjoint is exact", "[units]") {
  // A corridor 2.5 m wide (the domain's border is its wall) filled with the hexagonal lattice at
  // 2.5 persons/m^2, everyone walking along it; the law's kernel reaches 2 m, past both walls.
  Geometry geo;
  geo.lo = Vec2(0, 0);
  geo.hi = Vec2(30, 2.5);
  const double rho = 2.5, a = hexagonal_spacing(rho);
  std::vector<Vec2> x, heading;
  for (int j = 0; (j + 0.5) * a * std::sqrt(3.0) / 2 < 2.5; ++j)
    for (int i = 0; (i + 0.5) * a < 30; ++i) {
      x.emplace_back((i + 0.25 + 0.5 * (j & 1)) * a, (j + 0.5) * a * std::sqrt(3.0) / 2);
      heading.emplace_back(1, 0);
    }
  const double density = static_cast<double>(x.size()) / (30 * 2.5);  // the corridor's own
  const WalkableLattice walk = walkable_lattice(geo, 0.25);
  REQUIRE_FALSE(walk.empty());
  const std::vector<double> plain = local_density_ahead(x, heading, 2.0, 1.0);
  std::vector<double> per_area = plain;
  per_walkable_area(walk, x, heading, 2.0, 1.0, per_area);
  const std::vector<double> share = walkable_share_ahead(walk, x, heading, 2.0, 1.0);
  int middle = 0;
  for (size_t p = 0; p < x.size(); ++p) {
    CHECK(share[p] > 0);
    CHECK(share[p] < 1);  // everyone is within 2 m of a wall
    if (std::abs(x[p].x() - 15) > 5) continue;
    ++middle;
    CHECK(share[p] > 0.55);  // a 2.5 m band of a 4 m disc, the kernel heaviest near its centre
    CHECK(share[p] < 0.9);
    CHECK(plain[p] < 0.9 * density);  // the area behind the walls taken for empty
    CHECK(per_area[p] == Approx(density).epsilon(0.1));  // the corridor's density (plain: 1.56-2.05 of 2.35)
  }
  REQUIRE(middle > 20);
  // In the open, far from any wall, the share is exactly 1 and the density unchanged.
  Geometry open;
  open.lo = Vec2(-50, -50);
  open.hi = Vec2(50, 50);
  const WalkableLattice wide = walkable_lattice(open, 0.25);
  const std::vector<Vec2> y = {Vec2(0.3, 0.1), Vec2(-1.2, 0.7)}, e = {Vec2(0.6, 0.8), Vec2(0, 0)};
  for (double s : walkable_share_ahead(wide, y, e, 2.0, 2.5)) CHECK(s == 1.0);
  // The share's adjoint against central differences near a corner (positions and headings), at
  // a point with no heading, for a focus that is not whole (pow) and whole ones (1 and 3: the
  // weights written out for the loop). The share the adjoint's pass gives is the same number as
  // walkable_share_ahead's.
  geo.solids.push_back(Shape::circle(Vec2(4, 1.2), 0.5));
  const WalkableLattice corner = walkable_lattice(geo, 0.25);
  const std::vector<Vec2> q = {Vec2(2.9, 0.9), Vec2(0.8, 2.0), Vec2(3.3, 1.9)};
  const std::vector<Vec2> eq = {Vec2(0.8, 0.6), Vec2(-0.6, 0.8), Vec2(0, 0)};
  const std::vector<double> weights = {1.0, -0.7, 0.4};
  for (double focus : {2.5, 1.0, 3.0}) {
    INFO("focus " << focus);
    auto loss = [&](const std::vector<Vec2>& at, const std::vector<Vec2>& he) {
      const std::vector<double> s = walkable_share_ahead(corner, at, he, 2.0, focus);
      return weights[0] * s[0] + weights[1] * s[1] + weights[2] * s[2];
    };
    const std::vector<double> plain_share = walkable_share_ahead(corner, q, eq, 2.0, focus);
    const std::vector<ShareAhead> with_derivatives = walkable_share_ahead_derivatives(corner, q, eq, 2.0, focus);
    for (size_t p = 0; p < q.size(); ++p) {
      CHECK(plain_share[p] < 1);
      CHECK(with_derivatives[p].share == plain_share[p]);
      // Against its definition summed another way: the kernel's weights of the lattice centres
      // within 2 m as neighbours in local_density_ahead (every centre, then the walkable ones;
      // each sum also holds the point itself, weight 1).
      std::vector<Vec2> all = {q[p]}, walkable = {q[p]};
      for (long j = -12; j < corner.ny + 12; ++j)
        for (long i = -12; i < corner.nx + 12; ++i) {
          const Vec2 y = corner.lo + corner.h * Vec2(static_cast<double>(i) + 0.5, static_cast<double>(j) + 0.5);
          if ((y - q[p]).norm() >= 2.0) continue;
          all.push_back(y);
          if (i >= 0 && i < corner.nx && j >= 0 && j < corner.ny && corner.clearance[static_cast<size_t>(j * corner.nx + i)] > 0)
            walkable.push_back(y);
        }
      const auto weight_sum = [&](const std::vector<Vec2>& at) {
        std::vector<Vec2> heading_of(at.size(), Vec2::Zero());
        heading_of[0] = eq[p];
        return local_density_ahead(at, heading_of, 2.0, focus)[0] * M_PI * 4 / 2 - 1;
      };
      REQUIRE(walkable.size() < all.size());
      CHECK(plain_share[p] == Approx(weight_sum(walkable) / weight_sum(all)).epsilon(1e-9));
    }
    std::vector<Vec2> xb(q.size(), Vec2::Zero()), eb(q.size(), Vec2::Zero());
    walkable_share_ahead_vjp(corner, q, eq, 2.0, focus, weights, xb, eb);
    const double h = 1e-6;
    for (size_t p = 0; p < q.size(); ++p)
      for (int c = 0; c < 2; ++c) {
        std::vector<Vec2> up = q, down = q;
        up[p][c] += h;
        down[p][c] -= h;
        CHECK(xb[p][c] == Approx((loss(up, eq) - loss(down, eq)) / (2 * h)).margin(1e-6));
        std::vector<Vec2> eu = eq, ed = eq;
        eu[p][c] += h;
        ed[p][c] -= h;
        if (eq[p].squaredNorm() > 0) CHECK(eb[p][c] == Approx((loss(q, eu) - loss(q, ed)) / (2 * h)).margin(1e-6));
      }
    CHECK(xb[0].norm() > 0.01);  // near the post and the wall the share moves with the position
  }
}

TEST_CASE("the density-speed law's floor: added to Weidmann's factor, or its smooth max with it, and the adjoint", "[units]") {
  Model m = Model::default_model();
  m.set("density_speed_gamma", 1.913);
  m.set("density_speed_max", 5.4);
  auto weidmann = [&](double rho) { return 1 - std::exp(-1.913 * std::log1p(std::exp(10 * (1 / rho - 1 / 5.4))) / 10); };
  auto factor = [&](const MaterialParams& P, double rho) {
    TermPoint pt;
    pt.density_ahead = rho;
    return material_density_factor(P, pt);
  };
  for (double rho : {0.5, 2.0, 3.5, 8.0}) CHECK(factor(m.params, rho) == Approx(weidmann(rho)).epsilon(1e-9));  // no floor
  m.set("density_speed_floor", 0.45);
  // density_speed_floor_max 0 (the default): phi + (1 - phi) f everywhere.
  for (double rho : {0.5, 2.0, 8.0}) CHECK(factor(m.params, rho) == Approx(0.45 + 0.55 * weidmann(rho)).epsilon(1e-12));
  // 1: a smooth max(f, phi), Weidmann's law where it asks for more than the floor.
  m.set("density_speed_floor_max", 1);
  CHECK(factor(m.params, 0.5) == Approx(weidmann(0.5)).epsilon(1e-5));  // far above the floor: the law itself
  CHECK(factor(m.params, 1.5) - weidmann(1.5) > 0);  // 0.15 above it: within 0.003 (softplus(-3) / 20)
  CHECK(factor(m.params, 1.5) - weidmann(1.5) < 0.003);
  CHECK(factor(m.params, 8.0) == Approx(0.45).epsilon(1e-3));  // beyond rho_max: the floor
  for (double rho : {2.0, 2.5, 3.0}) {  // around the crossing: a smooth max, at most ln 2 / 20 above both
    const double f = factor(m.params, rho), w = weidmann(rho);
    CHECK(f >= std::max(w, 0.45));
    CHECK(f <= std::max(w, 0.45) + std::log(2.0) / kFloorSharpness + 1e-12);
  }
  // Between: the mix. The adjoint: dF/dphi, dF/dgamma, dF/drho_max and dF/drho against central
  // differences, for each form.
  Model mixed = m;
  mixed.set("density_speed_floor_max", 0.5);
  CHECK(factor(mixed.params, 2.5) == Approx(0.5 * (0.45 + 0.55 * weidmann(2.5)) + 0.5 * factor(m.params, 2.5)).epsilon(1e-12));
  for (double form : {0.0, 0.5, 1.0}) {
    m.set("density_speed_floor_max", form);
    for (double rho : {1.0, 2.3, 2.6, 4.0, 7.0}) {
      MaterialParams grad = zero_params();
      TermPoint pt;
      pt.density_ahead = rho;
      const double d_rho = material_density_factor_vjp(m.params, pt, 1.0, grad);
      auto diff = [&](const char* name, double value) {
        const double h = 1e-6;
        Model up = m, down = m;
        up.set(name, value + h);
        down.set(name, value - h);
        return (factor(up.params, rho) - factor(down.params, rho)) / (2 * h);
      };
      CHECK(grad.density_speed_floor == Approx(diff("density_speed_floor", 0.45)).margin(1e-6));
      CHECK(grad.density_speed_gamma == Approx(diff("density_speed_gamma", 1.913)).margin(1e-6));
      CHECK(grad.density_speed_max == Approx(diff("density_speed_max", 5.4)).margin(1e-6));
      CHECK(d_rho == Approx((factor(m.params, rho + 1e-6) - factor(m.params, rho - 1e-6)) / 2e-6).margin(1e-6));
    }
  }
}

TEST_CASE("model version 2 starts a dense crowd compressed, version 1 at J = 1", "[units]") {
  const char* scene = R"({"format": "crowdmpm-scenario", "version": 1, "name": "dense",
    "domain": {"min": [0, 0], "max": [12, 12], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 1},
    "groups": [{"spawn": {"rect": [1, 1, 11, 11]}, "density": 5, "desired_speed": 1, "behaviour": {"type": "none"}}]})";
  const ScenarioDef s = ScenarioDef::parse_text(scene);
  Model m2 = Model::default_model();
  m2.set("rest_density", 4);  // below the crowd's 5 /m^2 (the default's 6 would leave it at rest)
  Simulation v2(s, m2, 1);
  Simulation v1(s, Model::load(test::repo_path("scenarios/models/v1.json")), 1);
  REQUIRE(Model::default_model().version == 2);
  double inside = 0;
  int n = 0;
  for (size_t p = 0; p < v2.world().size(); ++p)
    if ((v2.world().x[p] - Vec2(6, 6)).norm() < 3) {
      inside += v2.world().J[p];
      ++n;
    }
  REQUIRE(n > 50);
  CHECK(inside / n == Approx(4.0 / 5).epsilon(0.08));  // rest density 4 over the placed ~5 /m^2
  for (double J : v1.world().J) CHECK(J == 1.0);
}

TEST_CASE("agents added one by one before a step get the same reference volumes in any order", "[units]") {
  const char* scene = R"({"format": "crowdmpm-scenario", "version": 1, "name": "empty",
    "domain": {"min": [0, 0], "max": [12, 12], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 1},
    "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "desired_speed": 1, "behaviour": {"type": "none"}}]})";
  const ScenarioDef s = ScenarioDef::parse_text(scene);
  std::vector<Vec2> spots;  // a square lattice at 1 / 0.45^2 = 4.9 persons/m^2
  for (int j = 0; j < 12; ++j)
    for (int i = 0; i < 12; ++i) spots.emplace_back(3 + 0.45 * i, 3 + 0.45 * j);
  Model m = Model::default_model();
  m.set("rest_density", 4);  // below the lattice's 4.9 /m^2
  auto volumes = [&](bool reversed, bool together = false) {
    Simulation sim(s, m, 1);
    std::vector<AgentDef> defs;
    for (size_t k = 0; k < spots.size(); ++k) {
      AgentDef a;
      a.position = spots[reversed ? spots.size() - 1 - k : k];
      a.behaviour = sim.behaviour_of_group(0);
      if (together) defs.push_back(a);
      else sim.add_agent(a);
    }
    if (together) CHECK(sim.add_agents(defs).size() == spots.size());
    std::vector<double> J(spots.size());
    for (size_t p = 0; p < sim.world().size(); ++p)
      for (size_t k = 0; k < spots.size(); ++k)
        if ((sim.world().x[p] - spots[k]).norm() < 1e-12) J[k] = sim.world().J[p];
    return J;
  };
  const std::vector<double> forward = volumes(false), backward = volumes(true), together = volumes(false, true);
  for (size_t k = 0; k < spots.size(); ++k) {
    CHECK(forward[k] == Approx(backward[k]));
    CHECK(forward[k] == together[k]);  // add_agents: one pass, the same volumes
  }
  CHECK(forward[spots.size() / 2 + 6] < 0.9);  // inside the lattice: compressed (4 / ~4.9)
  // A batch with a bad agent is refused whole, naming it.
  Simulation sim(s, Model::default_model(), 1);
  std::vector<AgentDef> defs(3);
  for (size_t k = 0; k < defs.size(); ++k) {
    defs[k].position = spots[k];
    defs[k].behaviour = sim.behaviour_of_group(0);
  }
  defs[2].position = Vec2(-1, 5);
  CHECK_THROWS_WITH(sim.add_agents(defs), Catch::Contains("agent 2 of 3") && Catch::Contains("outside the domain"));
  CHECK(sim.world().size() == 0);
}

TEST_CASE("the headway's lane search finds the same person ahead as a search over everyone", "[units]") {
  // The headway visits only the cells its lane crosses (NeighbourGrid::for_each_candidate_ahead):
  // against the rule applied to every pair, in an evacuation, two crowds charging each other and
  // a queue at a gate, at every person whose speed the one ahead limits.
  for (const char* name : {"drill", "hellfest_crush", "bottleneck"}) {
    ScenarioDef s = ScenarioDef::load(test::scenario_path(name));
    Simulation sim(s, test::model_of(s), 1);
    sim.run_steps(150);
    const World& w = sim.world();
    const MaterialParams& P = sim.model().params;
    REQUIRE(P.time_gap > 0);
    NeighbourGrid nb = sim.neighbour_grid();
    ThreadPool pool(1);
    nb.build(w, pool);
    long limited = 0;
    for (size_t p = 0; p < w.size(); ++p) {
      const double u = w.free_speed[p];
      if (!(u > 0)) continue;
      const Vec2 e = w.heading[p];
      double best = 1e300;
      for (size_t q = 0; q < w.size(); ++q) {
        if (q == p) continue;
        const Vec2 r = w.x[q] - w.x[p];
        const double along = r.dot(e), side = r.x() * e.y() - r.y() * e.x(), bodies = w.radius[p] + w.radius[q];
        if (along <= 0 || std::abs(side) >= P.headway_width * bodies) continue;
        if (w.free_speed[q] > 0) {
          const Vec2 eq = w.heading[q];
          const double along_q = -r.dot(eq), side_q = r.y() * eq.x() - r.x() * eq.y();
          if (along_q > 0 && std::abs(side_q) < P.headway_width * bodies && (along_q > along || (along_q == along && w.id[p] < w.id[q])))
            continue;
        }
        best = std::min(best, along - bodies);
      }
      const Headway h = headway_point(nb, w, p, e, P.headway_width, P.time_gap * u);
      if (best < P.time_gap * u) {
        ++limited;
        CHECK(h.gap == best);
      } else {
        CHECK(h.gap >= P.time_gap * u);
      }
    }
    INFO(name << ": " << limited << " of " << w.size() << " people limited by the one ahead");
    CHECK(limited > 10);
  }
}
