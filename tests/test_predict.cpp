// Prediction: windows, masks and errors on synthetic recordings with known answers, and the
// predict pipeline on a real Hermes corridor run (skipped, saying so, without ../shared/data).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "engine/predict/predict.hpp"
#include "support.hpp"

using namespace crowdmpm;

namespace {
// People walking in +x at 1 m/s from x = 1, 10 fps, 12 s; person 3 leaves the view after 5 s.
TrajectorySet straight_walkers() {
  std::ostringstream s;
  s << "# framerate: 10\n";
  for (int id = 1; id <= 3; ++id)
    for (int f = 0; f <= 120; ++f) {
      if (id == 3 && f > 50) break;
      s << id << " " << f << " " << 1 + 0.1 * f << " " << 2.0 * id << "\n";
    }
  return TrajectorySet::parse(s.str(), "synthetic");
}
}  // namespace

TEST_CASE("constant velocity is exact on straight walkers, and masks people who leave the view", "[predict]") {
  TrajectorySet t = straight_walkers();
  PredictOptions o;
  o.observe = 1;
  o.horizon = 4;
  o.stride = 2;
  PredictionReport r = evaluate_predictor("cv", t, o, constant_velocity_predictor());
  REQUIRE(r.horizons.size() == 4);
  CHECK(r.windows == 4);  // starts at 1, 3, 5, 7 s; 9 s + 4 s would pass the end (12 s)
  for (const auto& h : r.horizons) {
    CHECK(h.ade < 1e-9);
    CHECK(h.fde < 1e-9);
  }
  // Person 3 is recorded until 5 s and masked after: at 4 s ahead only the window starting at
  // 1 s still has them (3 + 2 + 2 + 2); at 1 s ahead the windows at 1 s and 3 s do.
  CHECK(r.horizons[3].samples == 3 + 2 + 2 + 2);
  CHECK(r.horizons[0].samples == 3 + 3 + 2 + 2);
}

TEST_CASE("velocities and walking speeds from a recording sampled every third frame", "[predict]") {
  // As ETH/UCY's files, which keep every 10th frame: no row lies exactly 0.5 s or 1 s back.
  std::ostringstream text;
  text << "# framerate: 10\n";
  for (int f = 0; f <= 60; f += 3) text << "1 " << f << " " << 1 + 0.1 * f << " 2\n";
  TrajectorySet t = TrajectorySet::parse(text.str(), "sparse");
  ObservedState s = observe_at(t, 30, 0.5, 1.0);
  REQUIRE(s.ids.size() == 1);
  CHECK(s.v[0].x() == Approx(1.0));
  CHECK(s.v[0].y() == Approx(0.0).margin(1e-12));
  CHECK(s.speed[0] == Approx(1.0));
  CHECK(observe_at(t, 31, 0.5, 1.0).ids.empty());  // nobody recorded at frame 31
}

TEST_CASE("a prediction job on a recording sampled every 4th frame compares at every whole second", "[predict]") {
  // Rows every 0.4 s (framerate 10): 1 s after a window's start has no row of its own.
  const auto dir = std::filesystem::temp_directory_path() / "crowdmpm_sparse_predict";
  std::filesystem::remove_all(dir);  // left by an earlier failed run
  std::filesystem::create_directories(dir);
  {
    std::ofstream rec(dir / "sparse.txt");
    rec << "# framerate: 10\n";
    for (int id = 1; id <= 2; ++id)
      for (int f = 0; f <= 120; f += 4) rec << id << " " << f << " " << 1 + 0.1 * f << " " << 3.0 * id << "\n";
    std::ofstream(dir / "open.json") << R"({"format": "crowdmpm-scenario", "version": 1,
      "domain": {"min": [0, 0], "max": [20, 8]}, "time": {"duration": 10},
      "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "desired_speed": 1.0, "behaviour": {"type": "heading"}}]})";
  }
  PredictOptions o;
  o.observe = 1.2;
  o.horizon = 3;
  o.grid_min_mass = 0.05;  // two people: the grid velocity error compares the nodes each covers
  const PredictJob job = make_predict_job((dir / "open.json").string(), (dir / "sparse.txt").string(), {}, o, DesiredSpeed::Observed);
  CHECK(job.frame_step == 4);
  CHECK(job.interpolated_rows == 2 * 30 * 3);
  const std::vector<PredictionReport> reports = run_prediction(job);
  REQUIRE(reports.size() == 2);
  // Windows start on recorded rows only (nothing read from after a start): 1.2 s and 7.2 s; the
  // start 4.2 s has no row of its own and moves on to the next start that has one.
  CHECK(reports[0].windows == 2);
  for (const PredictionReport& r : reports) {
    INFO(r.method);
    REQUIRE(r.horizons.size() == 3);
    for (const auto& h : r.horizons) {
      CHECK(h.samples > 0);
      CHECK(std::isfinite(h.grid_velocity_rms));
    }
  }
  // Straight walkers at 1 m/s: constant velocity is exact at every second.
  for (const auto& h : reports[0].horizons) CHECK(h.fde == Approx(0).margin(1e-9));
  CHECK(prediction_json(job, reports)["recording_frame_step"] == 4);
  CHECK(prediction_json(job, reports)["interpolated_rows"] == 2 * 30 * 3);
  // Rows 2 s apart (the same rows at 2 frames a second) are not filled in.
  {
    std::ifstream in(dir / "sparse.txt");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(dir / "slow.txt") << "# framerate: 2\n" << text.substr(text.find('\n') + 1);
  }
  o.observe = 4;
  const PredictJob slow = make_predict_job((dir / "open.json").string(), (dir / "slow.txt").string(), {}, o, DesiredSpeed::Observed);
  CHECK(slow.frame_step == 4);
  CHECK(slow.interpolated_rows == 0);
  std::filesystem::remove_all(dir);
}

TEST_CASE("free speeds: the 90th percentile of a person's walking speed along the whole track", "[predict]") {
  // Person 1 walks 1.5 m/s for 2 s, then queues at 0.2 m/s for 8 s; person 2 stands still;
  // person 3 is seen for 0.5 s only (shorter than the 1 s speed window).
  std::ostringstream text;
  text << "# framerate: 10\n";
  double x = 0;
  for (int f = 0; f <= 100; ++f) {
    text << "1 " << f << " " << x << " 0\n";
    x += f < 20 ? 0.15 : 0.02;
    text << "2 " << f << " 5 5\n";
    if (f <= 5) text << "3 " << f << " " << 0.1 * f << " 9\n";
  }
  const TrajectorySet t = TrajectorySet::parse(text.str(), "queue");
  const auto v = free_speeds(t, 1.0);
  REQUIRE(v.count(1) == 1);
  CHECK(v.at(1) > 1.0);  // the unhindered start, not the queue's 0.2 m/s (the median)
  CHECK(v.at(1) <= 1.5 + 1e-9);
  REQUIRE(v.count(2) == 1);
  CHECK(v.at(2) == Approx(0).margin(1e-12));
  CHECK(v.count(3) == 0);
  // Up to a frame only (what a prediction may know): in the queue at frame 60, person 1's free
  // speed is still that of the start; observe_at carries it as free_speed.
  CHECK(free_speeds(t, 1.0, 60).at(1) == Approx(1.5));
  const ObservedState s = observe_at(t, 60, 0.5, 1.0);
  REQUIRE(s.ids.size() == 2);  // person 3 has left
  REQUIRE(s.ids[0] == 1);
  CHECK(s.speed[0] == Approx(0.2));
  CHECK(s.free_speed[0] == Approx(1.5));
}

TEST_CASE("free speed distribution: the median and robust spread of the people's free speeds up to a frame", "[predict]") {
  // Five people at 1.0, 1.2, 1.3, 1.4 and 3.0 m/s (the last a tracking glitch the median and
  // the absolute deviations ignore), each seen for 3 s; a sixth seen only after frame 40.
  std::ostringstream text;
  text << "# framerate: 10\n";
  const double speeds[] = {1.0, 1.2, 1.3, 1.4, 3.0};
  for (int f = 0; f <= 60; ++f) {
    for (int p = 0; p < 5; ++p)
      if (f <= 30) text << p + 1 << " " << f << " " << speeds[p] * 0.1 * f << " " << p << "\n";
    if (f > 40) text << "6 " << f << " " << 0.5 * 0.1 * f << " 9\n";
  }
  const TrajectorySet t = TrajectorySet::parse(text.str(), "five");
  const SpeedDistribution d = free_speed_distribution(t, 1.0, 30);
  CHECK(d.people == 5);
  CHECK(d.median == Approx(1.3));
  CHECK(d.sd == Approx(1.4826 * 0.1));  // deviations 0.3 0.1 0 0.1 1.7: their median 0.1
  const SpeedDistribution all = free_speed_distribution(t, 1.0, 60);
  CHECK(all.people == 6);
  CHECK(all.median == Approx(1.3));  // the upper median of 0.5 1.0 1.2 1.3 1.4 3.0
  CHECK_THROWS_WITH(free_speed_distribution(t, 1.0, 5), Catch::Matchers::Contains("nobody is seen walking for 1 s"));
}

TEST_CASE("free speeds under a density-speed law: speeds divided by the law's factor at the density walked at", "[predict]") {
  // Person 1 walks 0.5 m/s in +x through a block of 12 people standing 0.5 m apart (about 4
  // persons/m^2 around them); person 20 walks 1.2 m/s alone, 30 m away.
  std::ostringstream text;
  text << "# framerate: 10\n";
  for (int f = 0; f <= 40; ++f) {
    text << "1 " << f << " " << 0.05 * f << " 1\n";
    for (int k = 0; k < 12; ++k) text << 2 + k << " " << f << " " << 0.5 * (k % 4) << " " << 0.5 * (k / 4) << "\n";
    text << "20 " << f << " " << 30 + 0.12 * f << " 30\n";
  }
  const TrajectorySet t = TrajectorySet::parse(text.str(), "block");
  const auto h = speed_history(t, 1.0);
  REQUIRE(h->by_id.count(1) == 1);
  REQUIRE(h->by_id.count(20) == 1);
  const std::vector<SpeedSample>& one = h->by_id.at(1);
  REQUIRE(one.size() == 41 - 10);  // every frame with a point 1 s back
  // Each sample's density is local_density_ahead where it ends, person 1 heading the way they
  // walked (+x), the people standing without a heading.
  std::vector<Vec2> xs, heading;
  size_t me = 0;
  auto scene_at = [&](long f) {
    xs.clear();
    heading.clear();
    for (auto [b, e] = t.frame(f); b != e; ++b) {
      if (b->id == 1) me = xs.size();
      xs.emplace_back(b->x, b->y);
      heading.push_back(b->id == 1 || b->id == 20 ? Vec2(1, 0) : Vec2::Zero());
    }
  };
  scene_at(one[5].frame);  // in the middle of the block (x = 0.75)
  CHECK(one[5].speed == Approx(0.5).epsilon(1e-6));
  const std::vector<float>& rho = h->density_ahead(kDensityRadius, 1);
  CHECK(rho[one[5].point] == Approx(local_density_ahead(xs, heading, kDensityRadius, 1)[me]).epsilon(1e-6));
  CHECK(rho[one[5].point] > 2.5);
  // Leaving the block (x = 2, the block behind them): little ahead, and looking back the other
  // way they would see the block.
  scene_at(one.back().frame);
  CHECK(rho[one.back().point] == Approx(local_density_ahead(xs, heading, kDensityRadius, 1)[me]).epsilon(1e-6));
  heading[me] = Vec2(-1, 0);
  CHECK(local_density_ahead(xs, heading, kDensityRadius, 1)[me] > rho[one.back().point] + 0.5);
  CHECK(rho[h->by_id.at(20)[0].point] == Approx(2 / M_PI).epsilon(1e-6));  // alone: only themselves
  // Under Weidmann's law the walker in the block is freer than they walked; the lone walker is
  // not slowed by anyone and keeps their speed (f = 1 - exp(-1.913 (pi/2 - 1/5.4)) = 0.93).
  Model m = Model::default_model();
  m.set("density_speed_gamma", 1.913);
  m.set("density_speed_max", 5.4);
  const auto free = free_speeds_by_law(*h, 40, m.params);
  std::vector<double> expected;
  for (const SpeedSample& x : one) {
    TermPoint pt;
    pt.density_ahead = rho[x.point];
    expected.push_back(x.speed / std::max(material_density_factor(m.params, pt), kLawFactorFloor));
  }
  std::sort(expected.begin(), expected.end());
  CHECK(free.at(1) == Approx(expected[static_cast<size_t>(0.9 * static_cast<double>(expected.size()))]));
  CHECK(free.at(1) > 0.5 / 0.8);
  CHECK(free.at(20) == Approx(1.2 / (1 - std::exp(-1.913 * (M_PI / 2 - 1 / 5.4)))).epsilon(1e-4));
  // A model whose law reads further ahead reads the recording with its own kernel: the lone
  // walker (reach 3 m: 2 / (9 pi) persons/m^2, themselves) is freer still than under reach 1 m.
  Model far = m;
  far.set("density_speed_reach", 3);
  CHECK(free_speeds_by_law(*h, 40, far.params).at(20) == Approx(1.2 / (1 - std::exp(-1.913 * (9 * M_PI / 2 - 1 / 5.4)))).epsilon(1e-4));
  CHECK(&h->density_ahead(3, 1) == &h->density_ahead(3, 1));  // computed once, kept
  // Only samples up to the frame asked for; a free speed beyond the cap is cut to it.
  CHECK(free_speeds_by_law(*h, 10, m.params).count(1) == 1);
  CHECK(free_speeds_by_law(*h, 9, m.params).count(1) == 0);
  m.set("density_speed_max", 2.5);  // the block is at the law's standstill: the factor's floor
  CHECK(free_speeds_by_law(*h, 40, m.params).at(1) == Approx(std::min(0.5 / kLawFactorFloor, kLawFreeSpeedCap)));

  // A window's agents take these free speeds as desired speeds with --desired-speed free when
  // the model has the law, and the plain 90th percentile without it.
  const ScenarioDef sc = window_scenario(ScenarioDef::parse_text(R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [-5, -5], "max": [40, 35], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 10},
    "groups": [{"count": 0, "spawn": {"rect": [0, 0, 1, 1]}, "behaviour": {"type": "heading"}}]})"), false);
  const ObservedState s = observe_at(t, 40, 0.5, 1.0, h);
  REQUIRE(s.ids.size() == 14);
  auto desired_of = [&](const Model& model, long id) {
    WindowSim ws = start_window(sc, model, s, WindowOptions{1, DesiredSpeed::Free});
    for (size_t i = 0; i < s.ids.size(); ++i)
      if (s.ids[i] == id) return ws.sim->world().v0[static_cast<size_t>(ws.sim->world().index_of(ws.ids[i]))];
    return -1.0;
  };
  m.set("density_speed_max", 5.4);
  CHECK(desired_of(m, 1) == Approx(free.at(1)));
  CHECK(desired_of(m, 20) == Approx(free.at(20)));
  CHECK(desired_of(Model::default_model(), 1) == Approx(0.5));
  CHECK(desired_of(Model::default_model(), 20) == Approx(1.2));
}

TEST_CASE("a predictor that is off by a fixed offset reports that offset", "[predict]") {
  TrajectorySet t = straight_walkers();
  PredictOptions o;
  o.observe = 1;
  o.horizon = 2;
  Predictor shifted = [](const ObservedState& s, const std::vector<double>& times) {
    auto out = constant_velocity_predictor()(s, times);
    for (auto& row : out)
      for (auto& x : row) x += Vec2(0.3, 0.4);
    return out;
  };
  PredictionReport r = evaluate_predictor("shifted", t, o, shifted);
  CHECK(r.horizons[1].ade == Approx(0.5));
  CHECK(r.horizons[1].fde == Approx(0.5));
}

TEST_CASE("grid velocity error: zero for an exact predictor, the speed difference for a slower one", "[predict]") {
  TrajectorySet t = straight_walkers();
  const Grid grid = test::box_grid(20, 8, 0.5);
  PredictOptions o;
  o.observe = 1;
  o.horizon = 2;
  o.grid_min_mass = 0.05;  // a person 0.5 m (one cell) off puts 0.094 on the nodes both cover
  PredictionReport exact = evaluate_predictor("cv", t, o, constant_velocity_predictor(), &grid);
  CHECK(exact.horizons[1].grid_velocity_rms == Approx(0).margin(1e-9));
  // Walking at 0.5 m/s instead of 1: the fields differ by 0.5 m/s where both cover a node.
  Predictor slow = [](const ObservedState& s, const std::vector<double>& times) {
    std::vector<std::vector<Vec2>> out(times.size());
    for (size_t k = 0; k < times.size(); ++k)
      for (size_t i = 0; i < s.x.size(); ++i) out[k].push_back(s.x[i] + 0.5 * times[k] * s.v[i]);
    return out;
  };
  PredictionReport r = evaluate_predictor("slow", t, o, slow, &grid);
  CHECK(r.horizons[0].grid_velocity_rms == Approx(0.5).epsilon(1e-6));
  // Without a grid there is no grid error.
  CHECK(std::isnan(evaluate_predictor("cv", t, o, constant_velocity_predictor()).horizons[0].grid_velocity_rms));
}

TEST_CASE("the crowd model predicts free walkers heading for an exit", "[predict]") {
  const char* text = R"({"format": "crowdmpm-scenario", "version": 1,
    "domain": {"min": [0, 0], "max": [20, 8]}, "time": {"duration": 10},
    "geometry": {"exits": [{"id": "east", "rect": [19, 0, 20, 8]}]},
    "groups": [{"spawn": {"rect": [1, 1, 2, 2]}, "count": 0, "desired_speed": 1.0,
                "behaviour": {"type": "goal", "target": "east"}}]})";
  ScenarioDef s = ScenarioDef::parse_text(text);
  TrajectorySet t = straight_walkers();  // 4 m apart: no interactions; 1 m/s = their desired speed
  PredictOptions o;
  o.observe = 1;
  o.horizon = 3;
  PredictionReport r = evaluate_predictor("model", t, o, simulation_predictor(s, Model::default_model(), WindowOptions{1, DesiredSpeed::Scenario}));
  for (const auto& h : r.horizons) CHECK(h.fde < 0.05);
}

TEST_CASE("predict on a real corridor run: finite errors, constant velocity sane", "[predict][data]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("skipped: ../shared/data is absent, no real recording to predict");
    return;
  }
  TrajectorySet t = TrajectorySet::read(data + "/real/fzj_hermes_2009_corridor_uo/uo-180-180-180.txt");
  ScenarioDef s = ScenarioDef::load(test::scenario_path("corridor"));
  PredictOptions o;
  o.observe = 10;
  o.horizon = 4;
  o.stride = 10;
  o.max_windows = 4;
  PredictionReport cv = evaluate_predictor("cv", t, o, constant_velocity_predictor());
  PredictionReport model = evaluate_predictor("model", t, o, simulation_predictor(s, test::model_of(s), WindowOptions{2, DesiredSpeed::Scenario}));
  for (const auto* r : {&cv, &model}) {
    REQUIRE(r->windows == 4);
    std::printf("predict corridor %-6s", r->method.c_str());
    for (const auto& h : r->horizons) {
      CHECK(std::isfinite(h.ade));
      CHECK(h.samples > 20);
      std::printf("  ADE@%gs %.3f FDE %.3f", h.horizon, h.ade, h.fde);
    }
    std::printf("\n");
  }
  CHECK(cv.horizons[0].ade < 0.3);   // people walk ~1 m/s: 1 s of constant velocity is close
  CHECK(cv.horizons[3].fde > cv.horizons[0].fde);
}
