#include "engine/sim/snapshot.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "engine/core/binary.hpp"
#include "engine/core/json_reader.hpp"

namespace crowdmpm {

namespace {

constexpr char kMagic[8] = {'C', 'M', 'P', 'M', 'S', 'N', 'A', 'P'};
constexpr uint32_t kEndianMark = 0x01020304;
constexpr size_t kHeaderBytes = kSnapshotHeaderBytes;

}  // namespace

// Every member of World and Simulation that a step reads or that outputs report, in one place:
// a member added to either class without a line here is a snapshot that does not continue
// bit-identically (tests/test_snapshot.cpp compares hashes after restoring).
struct SnapshotCodec {
  static void write(BinaryWriter& b, const Simulation& s) {
    json doc = s.scenario_.document;
    doc.erase("model");  // the model travels whole, below (it may differ from the file's)
    b.str(doc.dump());
    b.str(s.scenario_.source);
    b.str(s.model_.to_json().dump());
    b.f64(s.scenario_.dt);
    b.f64(s.scenario_.duration);
    b.i64(s.steps_);
    b.i64(s.steps_at_dt_change_);
    b.f64(s.time_at_dt_change_);
    b.u64(s.rng_.state());
    b.u32(s.failed_ ? 1 : 0);
    b.i64(s.spawned_);
    b.u64(s.batch_start_);
    b.f64(s.max_radius_);
    b.f64(s.max_comfort_);
    b.f64(s.max_v0_);
    b.f64(s.neighbour_reach_);
    b.u64(s.behaviours_.size());
    b.array(s.added_targets_, [&](const std::string& t) { b.str(t); });
    b.array(s.exit_events_, [&](const ExitEvent& e) {
      b.u64(e.id);
      b.i64(e.exit);
      b.f64(e.time);
    });
    b.array(s.source_accum_, [&](double v) { b.f64(v); });
    b.array(s.source_spawned_, [&](long v) { b.i64(v); });
    const World& w = s.world_;
    b.u64(w.next_id_);
    b.array(w.slot_, [&](long v) { b.i64(v); });
    auto f64s = [&](const std::vector<double>& a) { b.array(a, [&](double v) { b.f64(v); }); };
    auto vec2s = [&](const std::vector<Vec2>& a) { b.array(a, [&](const Vec2& v) { b.vec2(v); }); };
    auto mat2s = [&](const std::vector<Mat2>& a) { b.array(a, [&](const Mat2& m) { b.mat2(m); }); };
    auto ints = [&](const std::vector<int>& a) { b.array(a, [&](int v) { b.i64(v); }); };
    vec2s(w.x);
    vec2s(w.v);
    mat2s(w.C);
    mat2s(w.F);
    f64s(w.J);
    b.array(w.id, [&](EntityId v) { b.u64(v); });
    f64s(w.radius);
    f64s(w.comfort);
    f64s(w.v0);
    ints(w.behaviour);
    ints(w.group);
    vec2s(w.accel);
    vec2s(w.heading);
    f64s(w.free_speed);
    vec2s(w.pair_force);
    f64s(w.pair_virial);
    f64s(w.pressure);
    const Grid& g = s.grid_;
    f64s(g.mass);
    vec2s(g.velocity);
    vec2s(g.velocity_old);
    f64s(s.route_pace_);  // version 2
    b.u32(s.routes_held_ ? 1 : 0);
  }

  static std::unique_ptr<Simulation> read(BinaryReader& r, int threads, uint32_t version) {
    const std::string doc_text = r.str("scenario");
    const std::string source = r.str("scenario name");
    const std::string model_text = r.str("model");
    ScenarioDef scenario;
    Model model;
    try {
      scenario = ScenarioDef::parse(parse_json_text(doc_text, "scenario"), source, ".");
      model = Model::parse(JsonReader(parse_json_text(model_text, "model"), ""), "model");
    } catch (const Error& e) {
      r.fail("scenario and model", e.what());
    }
    const double dt = r.f64("time step");
    const double duration = r.f64("duration");
    // The time step and duration as they were (the API or --duration may have changed them);
    // set before building, so that the world is built and checked with them. The document keeps
    // the values it was parsed with (sources' windows default to its duration).
    if (!(dt > 0 && dt <= 0.1)) r.fail("time step", "must be in (0, 0.1] s");
    if (!(duration >= 0 && duration <= 1e9)) r.fail("duration", "must be in [0, 1e9] s");
    scenario.dt = dt;
    scenario.duration = duration;
    std::unique_ptr<Simulation> sim;
    try {
      sim = std::make_unique<Simulation>(scenario, model, threads);
    } catch (const Error& e) {
      r.fail("scenario and model", e.what());
    }
    Simulation& s = *sim;
    s.steps_ = r.i64("clock");
    s.steps_at_dt_change_ = r.i64("clock");
    s.time_at_dt_change_ = r.f64("clock");
    constexpr long kMaxSteps = 1L << 53;  // far beyond any run; keeps ++steps_ and time() exact
    if (s.steps_ < 0 || s.steps_ > kMaxSteps || s.steps_at_dt_change_ < 0 || s.steps_at_dt_change_ > s.steps_ ||
        !(s.time_at_dt_change_ >= 0 && s.time_at_dt_change_ <= 1e12))
      r.fail("clock", "step counts and time must be >= 0, in order and in range");
    s.rng_.set_state(r.u64("random state"));
    if (r.u32("failed flag") != 0) r.fail("failed flag", "a world that became unstable has no state to restore");
    s.spawned_ = r.i64("spawned count");
    if (s.spawned_ < 0) r.fail("spawned count", "negative");
    s.batch_start_ = r.u64("batch start");
    s.max_radius_ = r.f64("cell list sizes");
    s.max_comfort_ = r.f64("cell list sizes");
    s.max_v0_ = r.f64("cell list sizes");
    const double reach = r.f64("cell list sizes");
    for (double v : {s.max_radius_, s.max_comfort_, s.max_v0_, reach})
      if (!(v >= 0 && v <= 1e3)) r.fail("cell list sizes", "out of range");
    const uint64_t behaviours = r.u64("behaviour count");
    std::vector<std::string> targets;
    // Each added target is a distinct exit or goal (or "nearest_exit").
    const size_t max_targets = s.scenario_.geo.exits.size() + s.scenario_.geo.goals.size() + 1;
    r.array(targets, "added targets", 8, [&] {
      if (targets.size() >= max_targets) r.fail("added targets", "more than the scenario's exits and goals");
      return r.str("added target");
    });
    for (const auto& t : targets) {
      try {
        s.behaviour_for_target(t);
      } catch (const Error& e) {
        r.fail("added targets", e.what());
      }
    }
    if (s.behaviours_.size() != behaviours)
      r.fail("behaviour count", "the scenario gives " + std::to_string(s.behaviours_.size()) + " behaviours, the snapshot " +
                                    std::to_string(behaviours));
    r.array(s.exit_events_, "exit events", 24, [&] {
      const EntityId id = r.u64("exit event");
      const int64_t exit = r.i64("exit event");
      const double t = r.f64("exit event");
      if (exit < 0 || static_cast<uint64_t>(exit) >= s.scenario_.geo.exits.size()) r.fail("exit event", "no such exit");
      if (!(t >= 0 && t <= 1e12)) r.fail("exit event", "time out of range");
      return ExitEvent{id, static_cast<int>(exit), t};
    });
    r.array(s.source_accum_, "source counters", 8, [&] {
      const double a = r.f64("source counter");
      if (!(a >= 0 && a <= 1e9)) r.fail("source counter", "out of range");
      return a;
    });
    r.array(s.source_spawned_, "source counters", 8, [&] { return static_cast<long>(r.i64("source counter")); });
    if (s.source_accum_.size() != s.scenario_.groups.size() || s.source_spawned_.size() != s.scenario_.groups.size())
      r.fail("source counters", "one per group and source expected");
    for (size_t g = 0; g < s.source_spawned_.size(); ++g)
      if (s.source_spawned_[g] < 0 || s.source_spawned_[g] > std::max(0, s.scenario_.groups[g].max_count))
        r.fail("source counters", "a source spawned more than its max_count, or a negative count");
    read_world(r, s);
    Grid& g = s.grid_;
    const size_t nodes = g.nodes();
    auto grid_array = [&](auto& a, const char* what, auto&& each) {
      r.array(a, what, 8, each);
      if (a.size() != nodes) r.fail(what, "has " + std::to_string(a.size()) + " nodes, the grid " + std::to_string(nodes));
    };
    grid_array(g.mass, "grid mass", [&] { return r.f64("grid mass"); });
    grid_array(g.velocity, "grid velocity", [&] { return r.vec2("grid velocity"); });
    grid_array(g.velocity_old, "grid velocity", [&] { return r.vec2("grid velocity"); });
    if (version >= 2) {
      // The pace the routes were last computed from (empty: shortest paths).
      r.array(s.route_pace_, "route pace", 8, [&] {
        const double v = r.f64("route pace");
        if (!(v >= 0 && v <= 1)) r.fail("route pace", "out of range [0, 1]");
        return v;
      });
      if (!s.route_pace_.empty() && s.route_pace_.size() != nodes)
        r.fail("route pace", "has " + std::to_string(s.route_pace_.size()) + " nodes, the grid " + std::to_string(nodes));
      const uint32_t held = r.u32("routes held flag");
      if (held > 1) r.fail("routes held flag", "must be 0 or 1");
      s.routes_held_ = held == 1;
      s.apply_route_pace();
    }
    if (s.batch_start_ > s.world_.size()) r.fail("batch start", "beyond the agents");
    if (reach < s.neighbour_reach() - 1e-12 * (1 + reach)) r.fail("cell list sizes", "the cells are narrower than the agents' reach");
    s.size_neighbour_cells(reach);
    return sim;
  }

  static void read_world(BinaryReader& r, Simulation& s) {
    World& w = s.world_;
    w.next_id_ = r.u64("next id");
    r.array(w.slot_, "id slots", 8, [&] { return static_cast<long>(r.i64("id slot")); });
    auto f64s = [&](std::vector<double>& a, const char* what) { r.array(a, what, 8, [&] { return r.f64(what); }); };
    auto vec2s = [&](std::vector<Vec2>& a, const char* what) { r.array(a, what, 16, [&] { return r.vec2(what); }); };
    auto mat2s = [&](std::vector<Mat2>& a, const char* what) { r.array(a, what, 32, [&] { return r.mat2(what); }); };
    auto ints = [&](std::vector<int>& a, const char* what, long lo, long hi) {
      r.array(a, what, 8, [&] {
        const int64_t v = r.i64(what);
        if (v < lo || v >= hi) r.fail(what, std::to_string(v) + " out of range");
        return static_cast<int>(v);
      });
    };
    vec2s(w.x, "positions");
    vec2s(w.v, "velocities");
    mat2s(w.C, "affine velocities");
    mat2s(w.F, "deformation gradients");
    f64s(w.J, "volume ratios");
    r.array(w.id, "ids", 8, [&] { return r.u64("id"); });
    f64s(w.radius, "body radii");
    f64s(w.comfort, "comfort distances");
    f64s(w.v0, "desired speeds");
    ints(w.behaviour, "behaviours", 0, static_cast<long>(s.behaviours_.size()));
    ints(w.group, "groups", -1, static_cast<long>(s.scenario_.groups.size()));
    vec2s(w.accel, "accelerations");
    vec2s(w.heading, "headings");
    f64s(w.free_speed, "free speeds");
    vec2s(w.pair_force, "pair forces");
    f64s(w.pair_virial, "pair virials");
    f64s(w.pressure, "pressures");
    const size_t n = w.id.size();
    for (size_t k : {w.x.size(), w.v.size(), w.C.size(), w.F.size(), w.J.size(), w.radius.size(), w.comfort.size(), w.v0.size(),
                     w.behaviour.size(), w.group.size(), w.accel.size(), w.heading.size(), w.free_speed.size(),
                     w.pair_force.size(), w.pair_virial.size(), w.pressure.size()})
      if (k != n) r.fail("agents", "component arrays of different lengths");
    // Ids and their slots must agree: one slot per id handed out (ids start at 1; id 0 is never
    // valid), every live id maps to its index, every other slot is -1.
    if (!(w.slot_.size() == w.next_id_ || (w.slot_.empty() && w.next_id_ == 1))) r.fail("id slots", "do not match the next id");
    if (!w.slot_.empty() && w.slot_[0] != -1) r.fail("id slots", "id 0 is never valid");
    size_t live = 0;
    for (size_t e = 0; e < w.slot_.size(); ++e) {
      const long i = w.slot_[e];
      if (i == -1) continue;
      if (i < 0 || static_cast<size_t>(i) >= n || w.id[static_cast<size_t>(i)] != e) r.fail("id slots", "do not match the ids");
      ++live;
    }
    if (live != n) r.fail("id slots", "do not match the ids");
    const double far = 2 * kMaxCoordinate;
    for (size_t p = 0; p < n; ++p) {
      if (!(w.radius[p] >= 0.05 && w.radius[p] <= 0.5) || !(w.comfort[p] >= 0.01 && w.comfort[p] <= 2) ||
          !(w.v0[p] >= 0 && w.v0[p] <= 12) || !(w.J[p] > 0 && w.J[p] <= 1e6))
        r.fail("agents", "agent " + std::to_string(w.id[p]) + " has a radius, comfort distance, speed or volume out of range");
      // Finite and in range: the step casts positions to cell indices.
      if (!(w.x[p].cwiseAbs().maxCoeff() <= far) || !(w.v[p].cwiseAbs().maxCoeff() <= 1e3) || !w.C[p].allFinite() ||
          !w.F[p].allFinite() || !w.accel[p].allFinite() || !w.heading[p].allFinite() || !std::isfinite(w.free_speed[p]) ||
          !w.pair_force[p].allFinite() || !std::isfinite(w.pair_virial[p]) || !std::isfinite(w.pressure[p]))
        r.fail("agents", "agent " + std::to_string(w.id[p]) + " has a non-finite or out-of-range state");
    }
  }
};

std::string save_snapshot(const Simulation& sim) {
  if (sim.failed()) throw Error("the world became unstable (non-finite state) at t = " + format_number(sim.time()) + " s: there is no state to save");
  BinaryWriter b;
  b.raw(kMagic, sizeof kMagic);
  b.u32(kSnapshotVersion);
  b.u32(kEndianMark);
  b.u64(0);  // payload length: set by reseal_snapshot
  SnapshotCodec::write(b, sim);
  b.u64(0);  // checksum: set by reseal_snapshot
  std::string bytes = b.bytes();
  reseal_snapshot(bytes);
  return bytes;
}

void reseal_snapshot(std::string& bytes) {
  if (bytes.size() < kHeaderBytes + 8) throw Error("reseal_snapshot: shorter than a header and a checksum");
  const uint64_t length = bytes.size() - kHeaderBytes - 8;
  std::memcpy(&bytes[kHeaderBytes - 8], &length, 8);
  const uint64_t sum = fnv1a64(bytes.data() + kHeaderBytes, static_cast<size_t>(length));
  std::memcpy(&bytes[kHeaderBytes + length], &sum, 8);
}

void save_snapshot_file(const Simulation& sim, const std::string& path) {
  const std::string bytes = save_snapshot(sim);
  const std::string tmp = path + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path + ": cannot open for writing");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      throw Error(path + ": write failed (disk full?)");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw Error(path + ": cannot move the snapshot into place: " + ec.message());
  }
}

std::unique_ptr<Simulation> restore_snapshot(const std::string& bytes, const std::string& source, int threads) {
  if (bytes.size() < 8 || bytes.compare(0, 8, kMagic, 8) != 0)
    throw Error(source + ": not a CrowdMPM snapshot (it does not start with CMPMSNAP)");
  BinaryReader head(bytes.data(), bytes.size(), source);
  head.u64("magic");
  const uint32_t version = head.u32("version");
  if (version < 1 || version > kSnapshotVersion)
    throw Error(source + ": snapshot format version " + std::to_string(version) + "; this engine reads versions 1 to " +
                std::to_string(kSnapshotVersion));
  if (head.u32("byte order") != kEndianMark) throw Error(source + ": snapshot written with another byte order");
  const uint64_t length = head.u64("payload length");
  const size_t available = bytes.size() - kHeaderBytes;
  if (available < 8 || length > available - 8)
    throw Error(source + ": truncated snapshot: the header announces " + std::to_string(length) + " bytes of state, the file has " +
                std::to_string(available < 8 ? 0 : available - 8));
  if (length < available - 8) throw Error(source + ": " + std::to_string(available - 8 - length) + " unexpected bytes after the snapshot");
  const char* payload = bytes.data() + kHeaderBytes;
  BinaryReader tail(payload + length, 8, source);
  if (tail.u64("checksum") != fnv1a64(payload, static_cast<size_t>(length)))
    throw Error(source + ": corrupted snapshot: the checksum does not match its contents");
  BinaryReader r(payload, static_cast<size_t>(length), source + " (state)");
  std::unique_ptr<Simulation> sim = SnapshotCodec::read(r, threads, version);
  if (!r.at_end()) r.fail("end", "unexpected bytes after the state");
  return sim;
}

std::unique_ptr<Simulation> load_snapshot_file(const std::string& path, int threads, const InputPolicy& policy) {
  return restore_snapshot(read_input_file(path, policy), path, threads);
}

}  // namespace crowdmpm
