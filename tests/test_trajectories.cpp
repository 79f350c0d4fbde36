// Trajectory reading (PeTrack/JuPedSim text): units, headers, errors, and every real recording
// in ../shared/data/real against its manifest (skipped, saying so, when the data is absent).
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include "engine/io/trajectory.hpp"
#include "engine/observe/measure.hpp"
#include "engine/observe/observe.hpp"
#include "engine/observe/track_smoother.hpp"
#include "support.hpp"

using namespace crowdmpm;

TEST_CASE("trajectory text: units, comments, sorting", "[trajectories]") {
  const char* text =
      "# framerate: 16\n# id frame x/cm y/cm z/cm\n"
      "2 5 100 -250 170\n1 5 50 25\n\n1 4 40 20 170\r\n";
  TrajectorySet t = TrajectorySet::parse(text, "mem.txt");
  CHECK(t.framerate == 16);
  REQUIRE(t.points.size() == 3);
  CHECK(t.points[0].frame == 4);
  CHECK(t.points[0].x == Approx(0.4));
  CHECK(t.points[2].id == 2);
  CHECK(t.points[2].y == Approx(-2.5));
  CHECK(t.person_count() == 2);
  auto [b, e] = t.frame(5);
  CHECK(e - b == 2);
  CHECK(t.duration() == Approx(1 / 16.0));
  CHECK(TrajectorySet::parse("# unit: mm\n1 0 1000 0\n", "u", 10).points[0].x == Approx(1));
}

TEST_CASE("trajectory text: errors name file and line", "[trajectories]") {
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1 0 1.0\n", "a.txt"), Catch::Contains("a.txt:2: expected \"id frame x y [z]\""));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1 0 1.0 nan\n", "a.txt"), Catch::Contains("a.txt:2: column 4 is not a finite number"));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1 0 1.0 abc\n", "a.txt"), Catch::Contains("a.txt:2: column 4 is not a number"));
  CHECK_THROWS_WITH(TrajectorySet::parse("1 0 1 2\n", "b.txt"), Catch::Contains("b.txt: no \"# framerate: N\" header"));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1 0 1 2\n1 0 3 4\n", "c.txt"), Catch::Contains("person 1 appears twice in frame 0"));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n# unit: furlong\n", "d.txt"), Catch::Contains("d.txt:2: unknown unit"));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1.5 0 1 2\n", "e.txt"), Catch::Contains("whole numbers"));
}

TEST_CASE("a recording at the wrong scale for its venue is refused with the units that fit", "[trajectories]") {
  Geometry venue;  // a 10 m x 4 m corridor
  venue.lo = Vec2(0, 0);
  venue.hi = Vec2(10, 4);
  // Six people 0.8 m apart walking along it, written in centimetres.
  std::string cm = "# framerate: 10\n";
  for (int f = 0; f < 20; ++f)
    for (int id = 1; id <= 6; ++id)
      cm += std::to_string(id) + " " + std::to_string(f) + " " + std::to_string(100 + 80 * id + 5 * f) + " " + std::to_string(100 + 40 * (id % 2)) + "\n";
  const TrajectorySet read_as_m = TrajectorySet::parse(cm, "people_cm.txt");
  CHECK_THROWS_WITH(check_recording_scale(read_as_m, venue, "corridor.json"),
                    Catch::Contains("people_cm.txt: 100% of its positions lie outside the domain of corridor.json") &&
                        Catch::Contains("fit the venue as centimetres"));
  const TrajectorySet right = TrajectorySet::parse("# unit: cm\n" + cm, "people_cm.txt");
  CHECK_NOTHROW(check_recording_scale(right, venue, "corridor.json"));
  // The same numbers divided by 100 and then said to be centimetres: inside the venue, 8 mm apart.
  std::string m = "# framerate: 10\n# unit: cm\n";
  for (const TrackPoint& p : right.points)
    m += std::to_string(p.id) + " " + std::to_string(p.frame) + " " + std::to_string(p.x) + " " + std::to_string(p.y) + "\n";
  const TrajectorySet shrunk = TrajectorySet::parse(m, "people_m.txt");
  CHECK_THROWS_WITH(check_recording_scale(shrunk, venue, "corridor.json"),
                    Catch::Contains("closer than bodies allow") && Catch::Contains("fit the venue as metres"));
  // Another venue altogether: no unit fits.
  Geometry far = venue;
  far.lo = Vec2(100, 100);
  far.hi = Vec2(110, 104);
  CHECK_THROWS_WITH(check_recording_scale(right, far, "elsewhere.json"), Catch::Contains("a recording of another venue"));
}

// Issue 13: a frame of 1e30 is a whole number >= 2^63; it used to be cast to long out of range
// (undefined behaviour: it came out negative, passed "frame >= 0", and duration() overflowed).
TEST_CASE("trajectory text: ids and frames beyond the range of long are refused", "[trajectories]") {
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n1 1e30 1 2\n", "f.txt"), Catch::Contains("f.txt:2: id and frame must be at most"));
  CHECK_THROWS_WITH(TrajectorySet::parse("# framerate: 10\n-1e19 0 1 2\n", "g.txt"), Catch::Contains("g.txt:2: id and frame must be at most"));
  const TrajectorySet t = TrajectorySet::parse("# framerate: 10\n1 0 1 2\n1 1000000000000 1 2\n", "h.txt");
  CHECK(t.frame_max() == 1000000000000L);
  CHECK(t.duration() == Approx(1e11));
}

// fuzz_trajectory's timeout: a recording with a gap of a trillion frames. Loops that walked every
// frame number of the gap never ended; they now step over recorded rows.
TEST_CASE("trajectory text: a gap of 1e12 frames costs nothing to observe and measure and cut into windows", "[trajectories]") {
  const TrajectorySet t = TrajectorySet::parse("# framerate: 10\n1 0 0 0\n1 1 0.1 0\n1 2 0.2 0\n1 999999999998 5 5\n1 999999999999 5.1 5\n", "gap.txt");
  const ObservedState s = observe_at(t, 999999999999L, 0.1, 1.0);
  REQUIRE(s.ids.size() == 1);
  CHECK(s.v[0].x() == Approx(1.0));
  CHECK(free_speeds(t, 0.1).at(1) == Approx(1.0));
  CHECK(classic_density_speed(t, Vec2(-1, -1), Vec2(6, 6), 0.1).size() == 4);  // the recorded frames, not 1e11 samples
  CHECK(t.skip_gap(3, 10) == 1000000000003L);  // the first frame of 3, 13, 23, ... after 999999999998
  CHECK(t.skip_gap(1000000000000L, 1) == t.frame_max() + 1);
}

// Messages never quote what a file holds (it may be a secret the scenario was made to name).
TEST_CASE("trajectory text: errors do not quote the file's contents", "[trajectories]") {
  for (const char* text : {"# framerate: 10\n1 0 1 secret\n", "# framerate: secret\n", "# unit: secret\n"}) {
    try {
      TrajectorySet::parse(text, "s.txt");
      FAIL("no error for " << text);
    } catch (const Error& e) {
      CHECK(std::string(e.what()).find("secret") == std::string::npos);
    }
  }
}

TEST_CASE("a recording sampled every few frames: its step is found and the frames between rows are interpolated", "[trajectories]") {
  // Person 1 every 4th frame at 1 m/s in x (framerate 10), then out of view from frame 8 to 40;
  // person 2 every 4th frame in y; person 3 one row only.
  TrajectorySet t = TrajectorySet::parse("# framerate: 10\n1 0 0 0\n1 4 0.4 0\n1 8 0.8 0\n1 40 4 0\n"
                                         "2 0 5 1\n2 4 5 1.2\n2 8 5 1.4\n3 4 9 9\n", "sparse");
  CHECK(t.frame_step() == 4);
  const size_t before = t.points.size();
  CHECK(t.fill_frames(t.frame_step()) == 4 * 3);  // frames 1-3 and 5-7 of persons 1 and 2
  CHECK(t.points.size() == before + 12);
  auto [b, e] = t.frame(6);
  REQUIRE(e - b == 2);
  CHECK(b[0].id == 1);
  CHECK(b[0].x == Approx(0.6));
  CHECK(b[1].y == Approx(1.3));
  CHECK(t.frame(20).first == t.frame(20).second);  // the 32-frame gap is left: person 1 out of view
  CHECK(t.frame_step() == 1);
  CHECK(t.fill_frames(4) == 0);
  CHECK(TrajectorySet::parse("# framerate: 10\n1 0 0 0\n", "one").frame_step() == 1);
}

TEST_CASE("written trajectories read back", "[trajectories]") {
  auto path = (std::filesystem::temp_directory_path() / "crowdmpm_traj_roundtrip.txt").string();
  ScenarioDef s = ScenarioDef::load(test::scenario_path("drill"));
  Simulation sim(s, test::model_of(s), 1);
  {
    TrajectoryWriter w(path, s.output_rate, "round trip");
    w.write_frame(sim.world(), 0);
    sim.run_steps(10);
    w.write_frame(sim.world(), 1);
    w.close();
  }
  TrajectorySet t = TrajectorySet::read(path);
  CHECK(t.framerate == s.output_rate);
  CHECK(t.person_count() == sim.world().size());
  auto [b, e] = t.frame(1);
  REQUIRE(e - b == static_cast<long>(sim.world().size()));
  long i = sim.world().index_of(static_cast<EntityId>(b->id));
  REQUIRE(i >= 0);
  CHECK(b->x == Approx(sim.world().x[static_cast<size_t>(i)].x()).margin(1e-5));
}

namespace {
std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    char c = line[i];
    if (c == '"') {
      if (quoted && i + 1 < line.size() && line[i + 1] == '"') { out.back() += '"'; ++i; }
      else quoted = !quoted;
    } else if (c == ',' && !quoted) out.emplace_back();
    else out.back() += c;
  }
  return out;
}
}  // namespace

TEST_CASE("every real recording reads with the counts its manifest states", "[trajectories][data]") {
  const std::string data = test::shared_data_dir();
  if (data.empty()) {
    WARN("skipped: ../shared/data is absent, no real recordings to read");
    return;
  }
  std::ifstream manifest(data + "/real/manifest.csv");
  REQUIRE(manifest);
  std::string line;
  std::getline(manifest, line);
  auto header = split_csv(line);
  auto col = [&](const std::string& name) {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return i;
    FAIL("manifest has no column " << name);
    return size_t{0};
  };
  const size_t c_dataset = col("dataset"), c_file = col("file"), c_kind = col("kind"), c_fps = col("fps"),
               c_people = col("pedestrians"), c_rows = col("rows"), c_fmin = col("frame_min"), c_fmax = col("frame_max");
  int files = 0;
  while (std::getline(manifest, line)) {
    auto f = split_csv(line);
    if (f.size() <= c_fmax || f[c_kind] != "trajectory") continue;
    const std::string path = data + "/real/" + f[c_dataset] + "/" + f[c_file];
    INFO(path);
    TrajectorySet t = TrajectorySet::read(path);
    CHECK(t.framerate == std::stod(f[c_fps]));
    CHECK(t.person_count() == std::stoul(f[c_people]));
    CHECK(t.points.size() == std::stoul(f[c_rows]));
    CHECK(t.frame_min() == std::stol(f[c_fmin]));
    CHECK(t.frame_max() == std::stol(f[c_fmax]));
    std::printf("trajectories %-32s %4zu people %7zu rows %6.1f s at %g fps\n", f[c_file].c_str(), t.person_count(),
                t.points.size(), t.duration(), t.framerate);
    ++files;
  }
  CHECK(files >= 12);
}

TEST_CASE("classic density and speed in a measurement area count the people inside and their frame-to-frame speed", "[trajectories]") {
  // Four people walking in +y at 1 m/s and one outside the area, at 10 frames/s for 3 s.
  std::string text = "# framerate: 10\n";
  for (int f = 0; f <= 30; ++f)
    for (int id = 1; id <= 5; ++id) {
      const double x = id == 5 ? 9.0 : 0.5 + 0.5 * (id - 1), y = -1.5 + 0.1 * f + 0.05 * (id % 2);
      text += std::to_string(id) + " " + std::to_string(f) + " " + std::to_string(x) + " " + std::to_string(y) + "\n";
    }
  const TrajectorySet t = TrajectorySet::parse(text, "<test>");
  const auto s = classic_density_speed(t, Vec2(0, -2), Vec2(2, 2), 1);
  REQUIRE(s.size() == 3);  // frames 0, 10, 20 (30 has no next frame)
  for (const auto& d : s) {
    CHECK(d.density == Approx(4.0 / 8));
    CHECK(d.speed == Approx(1.0).epsilon(1e-6));
  }
  CHECK(s[1].time == Approx(1.0));
  CHECK_THROWS_AS(classic_density_speed(t, Vec2(2, 2), Vec2(0, -2), 1), Error);
}

namespace {
// People walking at about 1.3 m/s whose velocity changes by a white acceleration of density
// `q` (m^2/s^3), 40 s at 10 frames/s; `seen` is the same with white position noise of sd `r`.
struct Walkers {
  TrajectorySet truth, seen;
};
Walkers walkers(double q, double r, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0, 1);
  Walkers w;
  w.truth.framerate = w.seen.framerate = 10;
  const double dt = 0.1;
  for (long id = 1; id <= 60; ++id) {
    Vec2 x(0, 0.5 * static_cast<double>(id)), v(1.3, 0);
    for (long f = 0; f < 400; ++f) {
      w.truth.points.push_back({id, f, x.x(), x.y()});
      w.seen.points.push_back({id, f, x.x() + r * gauss(rng), x.y() + r * gauss(rng)});
      // Exact discretisation of the constant-velocity model's white acceleration.
      for (int a = 0; a < 2; ++a) {
        const double g1 = gauss(rng), g2 = gauss(rng);
        const double dv = std::sqrt(q * dt) * g1, dx = std::sqrt(q * dt * dt * dt) * (0.5 * g1 + g2 / std::sqrt(12.0));
        x[a] += v[a] * dt + dx;
        v[a] += dv;
      }
    }
  }
  w.truth.sort_checked();
  w.seen.sort_checked();
  return w;
}
// RMS over all points of position (m) and of the velocity from one frame to the next (m/s),
// of `t` against `truth` (the same points in the same order).
std::pair<double, double> track_errors(const TrajectorySet& t, const TrajectorySet& truth) {
  std::map<std::pair<long, long>, Vec2> err;
  double p = 0;
  for (size_t i = 0; i < t.points.size(); ++i) {
    const Vec2 e(t.points[i].x - truth.points[i].x, t.points[i].y - truth.points[i].y);
    err[{t.points[i].id, t.points[i].frame}] = e;
    p += e.squaredNorm();
  }
  double v = 0;
  long n = 0;
  for (const auto& [key, e] : err) {
    const auto next = err.find({key.first, key.second + 1});
    if (next == err.end()) continue;
    v += ((next->second - e) * t.framerate).squaredNorm();
    ++n;
  }
  return {std::sqrt(p / static_cast<double>(t.points.size())), std::sqrt(v / static_cast<double>(n))};
}
}  // namespace

TEST_CASE("tracks are smoothed under the noise levels they show: jitter is read back and taken out", "[trajectories]") {
  const Walkers w = walkers(0.1, 0.02, 7);
  const TrackNoise n = estimate_track_noise(w.seen);
  std::printf("track noise read back: position %.4f m (0.02), acceleration %.3f m2/s3 (0.1), %ld innovations\n", n.position,
              n.acceleration, n.samples);
  CHECK(n.samples > 40000);
  CHECK(n.position == Approx(0.02).epsilon(0.1));
  CHECK(n.acceleration > 0.05);
  CHECK(n.acceleration < 0.2);
  const TrajectorySet s = smoothed_tracks(w.seen, n);
  REQUIRE(s.points.size() == w.seen.points.size());
  const auto [raw_pos, raw_vel] = track_errors(w.seen, w.truth);
  const auto [pos, vel] = track_errors(s, w.truth);
  std::printf("smoothed: position error %.4f -> %.4f m, frame-to-frame velocity error %.3f -> %.3f m/s\n", raw_pos, pos, raw_vel, vel);
  CHECK(pos < 0.6 * raw_pos);
  CHECK(vel < 0.25 * raw_vel);
  for (size_t i = 0; i < s.points.size(); ++i) {
    REQUIRE(s.points[i].id == w.seen.points[i].id);
    REQUIRE(s.points[i].frame == w.seen.points[i].frame);
  }
}

TEST_CASE("the smoother's steady-state error is what smoothed tracks show: positions and velocities over a lag", "[trajectories]") {
  const TrackNoise levels{0.05, 0.1, 0};
  const Walkers w = walkers(levels.acceleration, levels.position, 9);
  const TrajectorySet s = smoothed_tracks(w.seen, levels);
  // Errors per axis away from the tracks' ends (frames 40-359 of 400), and of the velocity taken
  // over 5 frames (0.5 s), as a diagnosis observes a person's velocity.
  const long lag = 5;
  std::map<std::pair<long, long>, Vec2> err;  // (id, frame) -> smoothed minus true position
  for (size_t i = 0; i < s.points.size(); ++i)
    err[{s.points[i].id, s.points[i].frame}] = Vec2(s.points[i].x - w.truth.points[i].x, s.points[i].y - w.truth.points[i].y);
  double p2 = 0, v2 = 0;
  long np = 0, nv = 0;
  for (const auto& [key, e] : err) {
    if (key.second < 40 || key.second >= 360) continue;
    p2 += e.squaredNorm();
    np += 2;
    const Vec2& before = err.at({key.first, key.second - lag});
    v2 += ((e - before) * (s.framerate / static_cast<double>(lag))).squaredNorm();
    nv += 2;
  }
  const double pos = std::sqrt(p2 / static_cast<double>(np)), vel = std::sqrt(v2 / static_cast<double>(nv));
  const SmoothedError e = smoothed_error(levels, 0.1, lag);
  const double white = std::sqrt(2.0) * e.position / 0.5;  // the same errors taken as independent
  std::printf("smoothed error: position %.4f m (steady state %.4f), velocity over 0.5 s %.4f m/s (steady state %.4f; %.4f if independent)\n",
              pos, e.position, vel, e.velocity, white);
  CHECK(e.position == Approx(pos).epsilon(0.08));
  CHECK(e.velocity == Approx(vel).epsilon(0.1));
  CHECK(e.position < 0.6 * levels.position);
  CHECK(e.velocity < 0.95 * white);
  // Over one frame the smoothed errors are strongly correlated: the velocity errs far less than
  // independent errors would make it, and more than over 5 frames.
  const SmoothedError one = smoothed_error(levels, 0.1, 1);
  std::printf("over one frame: velocity %.4f m/s (%.4f if independent)\n", one.velocity, std::sqrt(2.0) * one.position / 0.1);
  CHECK(one.velocity < 0.5 * std::sqrt(2.0) * one.position / 0.1);
  CHECK(one.velocity > e.velocity);
  CHECK(smoothed_error(TrackNoise{0, 0.1, 0}, 0.1, lag).position == 0);
  CHECK_THROWS_WITH(smoothed_error(levels, 0, lag), Catch::Contains("time between frames"));
  CHECK_THROWS_WITH(smoothed_error(levels, 0.1, 0), Catch::Contains("lag"));
  CHECK_THROWS_WITH(smoothed_error(TrackNoise{0.05, -1, 0}, 0.1, lag), Catch::Contains("acceleration -1"));
}

TEST_CASE("clean tracks are left as they are by the smoother and too few frames give no noise levels", "[trajectories]") {
  const Walkers w = walkers(0.1, 0, 8);
  const TrackNoise n = estimate_track_noise(w.truth);
  CHECK(n.position < 0.002);
  const TrajectorySet s = smoothed_tracks(w.truth, n);
  CHECK(track_errors(s, w.truth).first < 0.002);
  // Two frames per person: no innovation to read noise from; nothing is changed.
  TrajectorySet few;
  few.framerate = 10;
  for (long id = 1; id <= 30; ++id)
    for (long f = 0; f < 2; ++f) few.points.push_back({id, f, 0.1 * static_cast<double>(f), static_cast<double>(id)});
  few.sort_checked();
  const TrackNoise none = estimate_track_noise(few);
  CHECK(none.samples == 0);
  CHECK(none.position == 0);
  const TrajectorySet same = smoothed_tracks(few, none);
  for (size_t i = 0; i < few.points.size(); ++i) CHECK(same.points[i].x == few.points[i].x);
  // Levels that are no noise levels are refused, naming them.
  CHECK_THROWS_WITH(smoothed_tracks(few, TrackNoise{-0.01, 0.1, 0}), Catch::Contains("position -0.01"));
  CHECK_THROWS_WITH(smoothed_tracks(few, TrackNoise{0.01, std::nan(""), 0}), Catch::Contains("acceleration"));
}
