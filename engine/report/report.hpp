#pragma once
// `crowdmpm report DIR`: one self-contained HTML page for a simulate output folder (pictures,
// charts and the video inlined; no network, no external file), docs/report.md.
#include <string>

#include "engine/core/input.hpp"

namespace crowdmpm {

struct ReportOptions {
  std::string scenario;        // the venue for the crowd-pressure map; empty: metrics.json's scenario_file
  std::string out;             // the page; empty: DIR/report.html
  int video_max_frames = 600;  // the inlined video keeps every n-th frame so that it has at most this many
  double video_scale = 0.5;    // and is scaled by this
  double pressure_window = 10; // s, crowd-pressure window
  double pressure_radius = 0.7;// m
  InputPolicy input;           // size limit of the files read (--max-input-mb)
};

// Writes the page and returns its path. Needs DIR/metrics.json; every other file (pictures,
// particles.mp4, trajectories) is shown when present, and the page lists what it could not show
// and why (a missing or unreadable file, a video that cannot be re-encoded).
std::string write_report(const std::string& dir, const ReportOptions& options = {});

}  // namespace crowdmpm
