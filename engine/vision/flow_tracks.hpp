#pragma once
// Tracks from a video's velocity fields, for the methods that read people's positions over time
// (diagnosis, docs/diagnosis.md "From video"). Optical flow sees where the crowd moves and how
// fast, not who is who: the tracks are points laid on a hexagonal lattice at a given density
// where the crowd walks (at least seed_speed), each carried by the field from frame to frame
// (the flow of the crowd around them, as a person is), so that they bend round what the crowd
// bends round and crowd where it crowds. Where the walking crowd has no track within 0.9 lattice
// spacings (people coming into view, a gap opening) a new one starts; where two come closer than
// half a spacing the younger ends; a track ends where it leaves the view, the venue or through
// an exit, and after standing `presence` seconds where flow sees no motion (flow does not see
// people who wait).
#include <string>

#include "engine/geometry/geometry.hpp"
#include "engine/io/trajectory.hpp"
#include "engine/observe/track_smoother.hpp"
#include "engine/vision/video.hpp"
#include "engine/vision/video_job.hpp"

namespace crowdmpm {

struct FlowTrackOptions {
  double density = 1.5;     // persons/m^2: the lattice the tracks start on where the crowd moves
  double presence = 2;      // s a track may stand where flow sees no motion before it ends
  // m/s a track starts at: flow on an empty floor (sensor noise, compression, the halo the flow
  // smooths round a walker) moves nodes slowly in random directions; a walking crowd is faster.
  double seed_speed = 0.3;
  double min_moving = 0.5;  // share of a point's B-spline weight on moving nodes for the field to carry it
  double clearance = 0.15;  // m a track keeps from walls and obstacles (a body's half width)
  void check() const;       // throws Error naming the option out of range
};

// Tracks through vf.fields (field k carries frame first + k to first + k + 1) as a recording at
// the video's frame rate, frames numbered as the video's; `source` names it in messages. Throws
// Error when no field has a moving node (nothing to track).
TrajectorySet flow_tracks(const VideoFlow& vf, const Geometry& venue, const FlowTrackOptions& o, const std::string& source);

// Tracks of the people a video shows, for a crowd sparse enough to see each person: every
// frame, people are found as blobs of body size (DetectOptions::body_radius, converted to pixels
// by the calibration at the middle of the view) that stand out of the floor, bright or dark
// (the absolute response of a difference of Gaussians above `contrast` times its robust spread
// over the frame, the largest within 1.8 body radii), each then placed at its head
// (head_radius); each track's next position is predicted by the optical flow at it, and the
// nearest unclaimed detection within `gate` metres continues it.
// A track missing its detection coasts on the flow for up to `coast` seconds, then ends; a
// detection no track claims starts one. Positions are the detections' (ground metres), each
// track smoothed (`smoother`) and averaged over `smooth` seconds centred on each, if smooth > 0.
struct DetectOptions {
  // m: about the radius of the disc with a body's area seen from above (an ellipse of a
  // shoulder breadth of 0.45 m and a chest depth of 0.25 m: 0.17 m).
  double body_radius = 0.18;
  // m: a head seen from above. Each body's detection is moved to its head, the strongest blob
  // at half this radius within 1.2 body radii (a body's blob takes in the shoulders, which a
  // tilted camera sees beside the head: on the rendered suite's corridor the detections stood
  // 0.085 m off the filmed heads on average, 0.10 m sd over people; at the head, 0.02 and 0.04).
  // 0: positions are the bodies' blobs.
  double head_radius = 0.11;
  double contrast = 4;        // robust standard deviations of the band-pass response
  double gate = 0.35;         // m a detection may lie from a track's predicted position
  // s: each position is the mean of the track's positions within half this of it (0: none). A
  // diagnosis that gives everyone the recording's typical free speed finds more without it
  // (benchmarks/results/diagnosis_video.md); a track's own speeds are smoother with 0.4.
  double smooth = 0;
  // The detections' tracks smoothed by the Rauch-Tung-Striebel smoother under the noise levels
  // they show themselves (engine/observe/track_smoother.hpp), before `smooth`: a head's place
  // jitters by 2-3 cm from frame to frame, which the smoother takes out without averaging a
  // turn away (on the rendered suite's corridor: frame-to-frame velocity error 0.28 -> 0.06 m/s
  // each way, the position error's part varying from frame to frame 0.022 -> 0.013 m).
  bool smoother = true;
  double coast = 1;           // s a track coasts on the flow without a detection (a person the detector misses a while)
  void check() const;
};

// DetectOptions::head_radius is 0 (no head) or 0.03 m up to the body's radius.
bool head_radius_fits(double head_radius, double body_radius);

// Reads the video of `src` (its flow options; the calibration it names), detects and tracks
// its people within the venue's domain and out of its solids (the frame `first` itself only
// starts the flow: detection begins with the frame after it). Throws Error naming the file when it
// cannot be read or nobody is found.
// With o.smoother, `noise` (if given) receives the noise levels the tracks were smoothed under.
TrajectorySet detected_tracks(const VideoSource& src, const Geometry& venue, const DetectOptions& o, TrackNoise* noise = nullptr);

}  // namespace crowdmpm
