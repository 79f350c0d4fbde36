#pragma once
// What a user says about a video (file, frame range, region of interest, flow method,
// calibration or scale, grid) and what `crowdmpm flow` makes of it: the velocity fields on the
// grid, written as NumPy with pictures (docs/video.md).
#include <string>

#include "engine/sim/scenario.hpp"
#include "engine/vision/video.hpp"

namespace crowdmpm {

struct VideoSource {
  std::string path;
  VideoOptions video;
  FlowOptions flow;
  FieldOptions field;
  std::string calibration;  // calibration JSON; empty: a top-view scale
  double scale = 0;         // metres per pixel without a calibration (origin: bottom-left pixel)
  double cell = 0.5;        // grid spacing (m) when no scenario gives the grid
};

struct VideoFields {
  VideoFlow flow;
  Calibration calibration;
  Grid grid;  // origin, dx, nx, ny of the fields
};

// The calibration a source names: its file, or its scale (one of the two is required; info gives
// the image height a scale's default origin needs).
Calibration video_calibration(const VideoSource& src, const VideoInfo& info);

// Probes the video, loads its calibration (or the scale; one of the two is required), takes the
// scenario's grid when a scenario is given (else a grid covering the region of interest) and
// extracts the fields. Throws Error naming the file and the problem.
VideoFields load_video_fields(const VideoSource& src, const ScenarioDef* scenario, const FlowProgress& progress = nullptr,
                              const FlowHook& hook = nullptr);

// `crowdmpm flow`: extracts the fields and writes DIR/fields.npy (+ .json sidecar),
// DIR/field_mean.png and DIR/field_middle.png (speed and arrows on the grid), DIR/frame_flow.png
// (the middle frame with its flow arrows, pixels) and DIR/flow.json (what was read and found).
// Returns flow.json's content.
json run_flow_job(const VideoSource& src, const ScenarioDef* scenario, const std::string& dir,
                  const FlowProgress& progress = nullptr);

// The mean of fields over time: per node, the mean velocity over the frames whose mask keeps it,
// kept where at least `min_share` of the frames do.
GridVelocityField mean_field(const std::vector<GridVelocityField>& fields, double min_share = 0.5);

}  // namespace crowdmpm
