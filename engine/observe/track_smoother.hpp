#pragma once
// Smoothing tracked positions. A tracker's place for a person jitters from frame to frame (a
// video detection by 2-3 cm on a head's blob), and a speed from one frame to the next
// magnifies that: 0.02 m at 10 frames/s is 0.3 m/s. People's own motion is smooth on that scale.
// Each track is therefore read as a person moving at a velocity that changes by a white
// acceleration (the constant-velocity model of target tracking), seen with white position
// noise, and replaced by the Rauch-Tung-Striebel smoother's estimate: the Kalman filter run
// forward over the track, then corrected backward with what came after. The two noise levels
// are the recording's own, estimated from every track at once by maximum likelihood of the
// filter's innovations, so no smoothing time is chosen by hand: a clean recording is left
// almost as it is, a jittering one smoothed as much as its jitter asks.
#include "engine/io/trajectory.hpp"

namespace crowdmpm {

struct TrackNoise {
  double position = 0;      // m: sd of a tracked position about the person's, each axis
  double acceleration = 0;  // m^2/s^3: spectral density of the people's (white) acceleration, each axis
  long samples = 0;         // innovations the estimate rests on (0: too few consecutive frames)
};

// The noise levels of a recording's tracks (each axis alike): the pair that maximises the
// likelihood of the constant-velocity Kalman filter's innovations over all tracks, started from
// the moments of second differences (their variance and lag-one covariance) and refined by a
// compass search in log space. An innovation beyond 5 of its standard deviations (a track that
// jumps to another person) counts as 5. Tracks need 3 frames; a recording with fewer than 20
// innovations gives samples 0 and both levels 0.
TrackNoise estimate_track_noise(const TrajectorySet& t);

// The recording with each track's positions replaced by the Rauch-Tung-Striebel smoother's
// under the noise levels given (frame gaps within a track are stepped over by their length).
// Ids, frames and the frame rate are kept. position 0 returns the tracks unchanged; a level
// that is negative or not finite is an Error naming it.
TrajectorySet smoothed_tracks(const TrajectorySet& t, const TrackNoise& noise);

// The error the smoother leaves on a long track sampled every dt s under these noise levels,
// each axis, in its steady state (away from a track's ends): the sd of a smoothed position, and
// the sd of a velocity taken as the difference of two smoothed positions `lag` frames apart over
// their time. The errors of nearby smoothed positions are correlated (the smoother's lag
// covariance: cov(e_k, e_k+m) = G^m P, G its backward gain, P its error covariance), so such a
// velocity errs less than two independent position errors would make it (at 0.05 m and
// 0.1 m^2/s^3, 10 frames/s: 11 % less over 5 frames, 72 % less over one). position 0 gives
// zeros; a level that is negative or not finite, dt <= 0 or lag < 1 is an Error naming it.
struct SmoothedError {
  double position = 0;  // m
  double velocity = 0;  // m/s
};
SmoothedError smoothed_error(const TrackNoise& noise, double dt, long lag);

// The recording smoothed in place under the noise levels it shows (estimate_track_noise, then
// smoothed_tracks), which are returned; with position 0 (too few frames, or clean) it is left as it is.
TrackNoise smooth_under_own_noise(TrajectorySet& t);

}  // namespace crowdmpm
