#include "engine/run/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include "engine/core/output.hpp"
#include "engine/io/jupedsim_sqlite.hpp"
#include "engine/io/render.hpp"
#include "engine/sim/snapshot.hpp"

namespace crowdmpm {

namespace fs = std::filesystem;

NpyWriter::NpyWriter(const std::string& path, int rows, int cols, int comps)
    : path_(path), rows_(rows), cols_(cols), comps_(comps) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) throw Error(path + ": cannot open for writing: " + std::strerror(errno));
  write_header();
}

NpyWriter::~NpyWriter() {
  if (f_) std::fclose(f_);
}

void NpyWriter::write_header() {
  // Fixed 128-byte header so the frame count can be rewritten in place.
  std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(frames_) + ", " +
                     std::to_string(rows_) + ", " + std::to_string(cols_) + (comps_ > 1 ? ", " + std::to_string(comps_) : "") + "), }";
  std::string header = "\x93NUMPY";
  header += '\x01';
  header += '\x00';
  size_t len = 128 - 10;
  dict.resize(len - 1, ' ');
  dict += '\n';
  header += static_cast<char>(len & 0xff);
  header += static_cast<char>(len >> 8);
  header += dict;
  std::fseek(f_, 0, SEEK_SET);
  std::fwrite(header.data(), 1, header.size(), f_);
  std::fseek(f_, 0, SEEK_END);
}

void NpyWriter::write_frame(const std::vector<float>& data) {
  if (data.size() != static_cast<size_t>(rows_) * cols_ * comps_) throw Error(path_ + ": internal error: frame size mismatch");
  if (std::fwrite(data.data(), sizeof(float), data.size(), f_) != data.size()) throw Error(path_ + ": write failed (disk full?)");
  ++frames_;
}

void NpyWriter::close() {
  if (!f_) return;
  write_header();
  bool bad = std::fclose(f_) != 0;
  f_ = nullptr;
  if (bad) throw Error(path_ + ": write failed (disk full?)");
}

namespace {
// Area per person (m^2) of each level: A from 3.25 up, ..., F below 0.46.
const std::vector<Category> kFruinLegend = {{"A >3.25", 26, 150, 65},  {"B >2.32", 145, 207, 96}, {"C >1.39", 255, 224, 80},
                                            {"D >0.93", 253, 150, 50}, {"E >0.46", 220, 50, 40},  {"F <0.46", 120, 0, 90}};
}  // namespace

RunSummary run_scenario(const ScenarioDef& s, const Model& model, const RunOptions& opt) {
  auto t0 = std::chrono::steady_clock::now();
  Simulation sim(s, model, opt.threads);
  const double setup = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RunSummary r = run_simulation(sim, opt);
  r.wall_seconds += setup;
  return r;
}

RunSummary run_simulation(Simulation& sim, const RunOptions& opt) {
  auto t0 = std::chrono::steady_clock::now();
  const ScenarioDef& s = sim.scenario();
  const Model& model = sim.model();
  MetricsRecorder metrics(s);
  RunSummary out;
  const bool files = !opt.out_dir.empty();
  std::unique_ptr<TrajectoryWriter> traj;
  std::unique_ptr<JupedsimSqliteWriter> traj_sqlite;
  std::unique_ptr<NpyWriter> npy_density, npy_velocity, npy_pressure;
  std::unique_ptr<ParticleVideo> video;
  View view = View::fit(s.geo, s.outputs.pixels_per_metre);
  double pmax = s.outputs.pressure_max > 0 ? s.outputs.pressure_max : std::max(1.0, model.params.E);
  auto file = [&](const std::string& name) {
    std::string p = (fs::path(opt.out_dir) / name).string();
    out.files.push_back(p);
    return p;
  };
  if (files) {
    prepare_output_folder(opt.out_dir);
    if (s.outputs.trajectories)
      traj = std::make_unique<TrajectoryWriter>(file("trajectories.txt"), s.output_rate,
                                                "crowdmpm simulate " + s.source + " (scenario \"" + s.name + "\")");
    if (s.outputs.trajectories_sqlite) {
      const Vec2 lo = s.geo.lo, hi = s.geo.hi;
      traj_sqlite = std::make_unique<JupedsimSqliteWriter>(file("trajectories.sqlite"), s.output_rate,
                                                           rectangle_wkt(lo.x(), lo.y(), hi.x(), hi.y()), lo.x(),
                                                           lo.y(), hi.x(), hi.y());
    }
    if (s.outputs.fields) {
      const Grid& g = sim.grid();
      npy_density = std::make_unique<NpyWriter>(file("density.npy"), g.ny, g.nx, 1);
      npy_velocity = std::make_unique<NpyWriter>(file("velocity.npy"), g.ny, g.nx, 2);
      npy_pressure = std::make_unique<NpyWriter>(file("pressure.npy"), g.ny, g.nx, 1);
    }
    if (s.outputs.video) video = std::make_unique<ParticleVideo>(file("particles.mp4"), s.geo, view, s.output_rate, pmax);
  }
  std::vector<float> buf;
  long last_frame = -1;
  // The crowd at the frame of peak density, for peak.png (a copy only when the peak rises).
  std::unique_ptr<World> peak_world;
  double peak_time = 0;
  auto emit = [&]() {
    FieldFrame f = compute_fields(sim.world(), sim.grid());
    const double peak_before = metrics.peak_density().value;
    metrics.record(sim, f);
    if (video && s.outputs.pictures && metrics.peak_density().value > peak_before) {
      peak_world = std::make_unique<World>(sim.world());
      peak_time = sim.time();
    }
    // A run that ends between two frames (all evacuated, or a duration that is not a whole
    // number of frames) gets its final state in the metrics only: a frame number must stand
    // for one time, and files must not repeat one.
    long frame = std::lround(sim.time() * s.output_rate);
    if (frame <= last_frame || std::abs(static_cast<double>(frame) / s.output_rate - sim.time()) > 0.25 * s.dt) {
      if (opt.progress) opt.progress(sim.time(), s.duration, sim.world().size());
      return;
    }
    last_frame = frame;
    if (traj) traj->write_frame(sim.world(), frame);
    if (traj_sqlite) traj_sqlite->write_frame(sim.world(), frame);
    if (npy_density) {
      buf.assign(f.density.begin(), f.density.end());
      npy_density->write_frame(buf);
      buf.assign(f.pressure.begin(), f.pressure.end());
      npy_pressure->write_frame(buf);
      buf.resize(f.velocity.size() * 2);
      for (size_t k = 0; k < f.velocity.size(); ++k) {
        buf[2 * k] = static_cast<float>(f.velocity[k].x());
        buf[2 * k + 1] = static_cast<float>(f.velocity[k].y());
      }
      npy_velocity->write_frame(buf);
    }
    if (video) video->add_frame(sim.world(), sim.time());
    if (opt.progress) opt.progress(sim.time(), s.duration, sim.world().size());
  };
  bool snapshot_due = !opt.snapshot_path.empty();
  auto save_snapshot_now = [&]() {
    save_snapshot_file(sim, opt.snapshot_path);
    out.files.push_back(opt.snapshot_path);
    snapshot_due = false;
  };
  emit();
  const int spf = s.steps_per_frame();
  while (!sim.finished()) {
    for (int k = 0; k < spf && !sim.finished(); ++k) {
      sim.step();
      if (snapshot_due && opt.snapshot_at >= 0 && sim.time() >= opt.snapshot_at - 1e-9) save_snapshot_now();
    }
    emit();
  }
  if (snapshot_due) save_snapshot_now();
  out.metrics = metrics.to_json(sim);
  if (files) {
    if (traj) traj->close();
    if (traj_sqlite) traj_sqlite->close();
    if (npy_density) {
      npy_density->close();
      npy_velocity->close();
      npy_pressure->close();
      const Grid& g = sim.grid();
      json meta = {{"origin", {g.origin.x(), g.origin.y()}}, {"cell_size", g.dx}, {"nx", g.nx}, {"ny", g.ny},
                   {"frames", metrics.frames()}, {"output_rate", s.output_rate},
                   {"layout", "arrays of shape (frames, ny, nx[, 2]); node (i, j) is at origin + cell_size * (i, j)"},
                   {"files", {{"density.npy", "persons/m^2"}, {"velocity.npy", "m/s"}, {"pressure.npy", "model stress units"}}}};
      std::ofstream(file("fields.json")) << meta.dump(2) << "\n";
    }
    if (s.outputs.pictures && metrics.frames() > 0) {
      FieldFrame mean = metrics.mean_map();
      const FieldFrame& peak = metrics.peak_map();
      double pm = *std::max_element(mean.pressure.begin(), mean.pressure.end());
      double pk = *std::max_element(peak.pressure.begin(), peak.pressure.end());
      write_field_png(file("pressure_mean.png"), s.geo, view, mean, mean.pressure, 0, std::max(pm, 1e-6),
                      s.name + ": time-averaged pressure", "pressure");
      write_field_png(file("pressure_peak.png"), s.geo, view, peak, peak.pressure, 0, std::max(pk, 1e-6),
                      s.name + ": peak pressure over time", "pressure");
      write_field_png(file("density_mean.png"), s.geo, view, mean, mean.density, 0, s.outputs.density_max,
                      s.name + ": time-averaged density", "pers/m2");
      // Fruin's level of service of each node's peak density (where anyone was).
      std::vector<int> level(peak.density.size(), -1);
      for (size_t k = 0; k < level.size(); ++k)
        if (peak.density[k] >= 0.1) level[k] = fruin_level(peak.density[k]) - 'A';
      write_category_png(file("level_of_service.png"), s.geo, view, peak, level, kFruinLegend,
                         s.name + ": Fruin level of service at peak density (m2/person)");
      if (video) video->write_snapshot(file("final.png"), sim.world(), sim.time());
      if (video && peak_world) video->write_snapshot(file("peak.png"), *peak_world, peak_time);
    }
    if (s.outputs.metrics) {
      std::ofstream m(file("metrics.json"));
      m << out.metrics.dump(2) << "\n";
      if (!m) throw Error(opt.out_dir + "/metrics.json: write failed");
    }
  }
  video.reset();
  out.time = sim.time();
  out.steps = sim.steps();
  out.spawned = sim.spawned();
  out.exited = static_cast<long>(sim.exit_events().size());
  out.remaining = sim.world().size();
  if (!out.metrics["evacuation_time"].is_null()) out.evacuation_time = out.metrics["evacuation_time"].get<double>();
  out.peak_density = metrics.peak_density();
  out.peak_pressure = metrics.peak_pressure();
  out.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace crowdmpm
