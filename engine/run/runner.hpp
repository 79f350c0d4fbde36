#pragma once
// Running a scenario to its outputs: trajectories (PeTrack text), per-frame fields (NumPy .npy),
// pictures (PNG), a video (MP4) and metrics.json, all in one output folder.
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/analysis/metrics.hpp"
#include "engine/io/trajectory.hpp"

namespace crowdmpm {

// Streams frames of a float32 array of shape (frames, rows, cols[, comps]) to a .npy file and
// fixes the frame count in the header on close.
class NpyWriter {
 public:
  NpyWriter(const std::string& path, int rows, int cols, int comps);
  ~NpyWriter();
  void write_frame(const std::vector<float>& data);
  void close();

 private:
  void write_header();
  std::FILE* f_ = nullptr;
  std::string path_;
  int rows_, cols_, comps_;
  long frames_ = 0;
};

struct RunOptions {
  std::string out_dir;  // created if missing; empty: no files, metrics only
  int threads = 1;
  // Called after every output frame with (time, duration, agents).
  std::function<void(double, double, size_t)> progress;
  // Save a snapshot of the world (engine/sim/snapshot.hpp) to this file: at the first step that
  // reaches snapshot_at seconds, or at the end of the run if snapshot_at < 0 or is never reached.
  std::string snapshot_path;
  double snapshot_at = -1;
};

struct RunSummary {
  double time = 0;
  long steps = 0;
  long spawned = 0, exited = 0;
  size_t remaining = 0;
  std::optional<double> evacuation_time;
  Peak peak_density, peak_pressure;
  double wall_seconds = 0;
  json metrics;
  std::vector<std::string> files;
};

RunSummary run_scenario(const ScenarioDef& scenario, const Model& model, const RunOptions& options);
// The same for a world that exists (one restored from a snapshot continues its clock; its
// outputs cover the time from where it stands to its duration).
RunSummary run_simulation(Simulation& sim, const RunOptions& options);

}  // namespace crowdmpm
