// Trajectory text (PeTrack): parse, then everything observation does with a recording: counts,
// duration, frames, the observed state at a frame, free speeds, and a sampled recording's frames
// filled in.
#include <cstddef>
#include <cstdint>
#include <string>

#include "engine/io/trajectory.hpp"
#include "engine/observe/observe.hpp"

using namespace crowdmpm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const TrajectorySet t = TrajectorySet::parse(text, "fuzz");
    (void)t.person_count();
    if (!(t.duration() >= 0)) __builtin_trap();
    const long mid = t.frame_min() + (t.frame_max() - t.frame_min()) / 2;
    auto [b, e] = t.frame(mid);
    if (e < b) __builtin_trap();
    const ObservedState st = observe_at(t, mid, 0.5, 1.0);
    if (st.ids.size() != st.x.size()) __builtin_trap();
    (void)free_speeds(t, 1.0, mid);
    // A sampled recording's frames filled in (as predict does, where that stays small).
    const long step = t.frame_step();
    if (step < 1) __builtin_trap();
    if (step > 1 && step <= 64 && t.points.size() * static_cast<size_t>(step) <= 1000000) {
      try {
        TrajectorySet filled = t;
        const size_t added = filled.fill_frames(step);
        if (filled.points.size() != t.points.size() + added) __builtin_trap();
        for (size_t i = 1; i < filled.points.size(); ++i) {  // sorted by (frame, id), no duplicate
          const TrackPoint &p = filled.points[i - 1], &q = filled.points[i];
          if (!(p.frame < q.frame || (p.frame == q.frame && p.id < q.id))) __builtin_trap();
        }
        if (filled.fill_frames(step) != 0) __builtin_trap();  // every gap up to step is filled
      } catch (const Error&) {
        __builtin_trap();  // filling a recording that parsed must not fail
      }
    }
  } catch (const Error&) {
  }
  return 0;
}
