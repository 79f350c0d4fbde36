#pragma once
// Trajectories in the PeTrack/JuPedSim text format used by PedPy and the Julich data archive:
// comment lines start with '#' ("# framerate: 16", "# unit: cm", a column header such as
// "# id frame x/cm y/cm z/cm"), then whitespace-separated rows "id frame x y [z]".
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "engine/core/input.hpp"
#include "engine/sim/world.hpp"

namespace crowdmpm {

struct TrackPoint {
  long id = 0;
  long frame = 0;
  double x = 0, y = 0;  // metres
};

class TrajectorySet {
 public:
  double framerate = 0;           // frames per second
  std::string source;             // file name, for messages
  std::vector<TrackPoint> points; // sorted by (frame, id)

  // Reads a file; positions are converted to metres from the unit its header states (m, cm or
  // mm; metres if none). framerate_override > 0 replaces the header's frame rate, which is
  // otherwise required. Malformed rows, non-finite numbers, duplicate (id, frame) pairs and a
  // missing frame rate are errors naming file and line.
  // A JuPedSim SQLite file (engine/io/jupedsim_sqlite.hpp) is recognised by its header and read
  // as such.
  static TrajectorySet read(const std::string& path, double framerate_override = 0, const InputPolicy& policy = {});
  static TrajectorySet parse(const std::string& text, const std::string& source, double framerate_override = 0);

  // Sorts the points by (frame, id); throws Error naming source for no rows or a duplicate.
  void sort_checked();

  // Smallest and largest x and y of all points (metres); both zero for an empty set.
  std::pair<Vec2, Vec2> bounds() const;

  long frame_min() const { return points.empty() ? 0 : points.front().frame; }
  long frame_max() const { return points.empty() ? 0 : points.back().frame; }
  size_t person_count() const;
  // Each person's points (indices into `points`) in frame order, people in the order they first
  // appear; the points need not be sorted.
  std::vector<std::vector<size_t>> tracks() const;
  double duration() const { return framerate > 0 ? static_cast<double>(frame_max() - frame_min()) / framerate : 0; }
  // The points of one frame (a contiguous, id-sorted range).
  std::pair<const TrackPoint*, const TrackPoint*> frame(long f) const;
  // For loops over frames f, f + stride, ...: f itself if it has rows, else the first frame of
  // that sequence at or after the next recorded frame (frame_max() + 1 if none). Loops that
  // step through it cost the number of recorded frames, not the span of frame numbers (a
  // recording may leave a gap of any length).
  long skip_gap(long f, long stride) const;
  // The most common number of frames between a person's consecutive rows: 1 for a recording with
  // a row every frame, 10 for ETH/UCY's every 10th frame (1 when nobody has two rows).
  long frame_step() const;
  // Adds a row for every frame strictly between two consecutive rows of a person at most max_gap
  // frames apart, its position interpolated linearly between them; a longer gap (the person out
  // of view) is left as it is. Returns the number of rows added; the points stay sorted.
  size_t fill_frames(long max_gap);
};

// Writes frames of a world (or a recording's points) as "id frame x y z" rows under a
// "# framerate:" header (metres).
class TrajectoryWriter {
 public:
  TrajectoryWriter(const std::string& path, double framerate, const std::string& comment);
  ~TrajectoryWriter();
  TrajectoryWriter(const TrajectoryWriter&) = delete;
  TrajectoryWriter& operator=(const TrajectoryWriter&) = delete;
  void write_frame(const World& w, long frame);
  // Every point of a recording, in its order (tracks made elsewhere: from video, say).
  void write_points(const TrajectorySet& t);
  void close();

 private:
  std::FILE* f_ = nullptr;
  std::string path_;
};

}  // namespace crowdmpm
