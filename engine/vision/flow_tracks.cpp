#include "engine/vision/flow_tracks.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <unordered_map>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/sim/stencil.hpp"
#include "engine/sim/world.hpp"
#include "engine/vision/video_learn.hpp"

namespace crowdmpm {

void FlowTrackOptions::check() const {
  if (!(density > 0 && density <= 12)) throw Error("flow tracks: density must be in (0, 12] persons/m2, got " + format_number(density));
  if (!(presence >= 0 && presence <= 600)) throw Error("flow tracks: presence must be in [0, 600] s, got " + format_number(presence));
  if (!(min_moving > 0 && min_moving <= 1)) throw Error("flow tracks: min_moving must be in (0, 1], got " + format_number(min_moving));
  if (!(seed_speed >= 0 && seed_speed <= 10)) throw Error("flow tracks: seed_speed must be in [0, 10] m/s, got " + format_number(seed_speed));
  if (!(clearance >= 0 && clearance <= 1)) throw Error("flow tracks: clearance must be in [0, 1] m, got " + format_number(clearance));
}

namespace {

struct Carried {
  Vec2 v = Vec2::Zero();
  double moving = 0;  // share of the stencil's weight on moving nodes
  bool on_grid = false;
};

// The field at x: the B-spline weighted mean over its moving nodes, and their share of the weight.
Carried carried(const GridVelocityField& f, const Vec2& x) {
  Carried c;
  double w_all = 0, w_moving = 0;
  for_stencil_on_grid(f.origin, f.dx, f.nx, f.ny, x, [&](size_t n, double w, const Vec2&) {
    w_all += w;
    if (f.mask[n] > 0) {
      c.v += w * f.velocity[n];
      w_moving += w;
    }
  });
  c.on_grid = w_all > 0;
  if (w_moving > 0) c.v /= w_moving;
  c.moving = w_all > 0 ? w_moving / w_all : 0;
  return c;
}

// Points in square buckets of side `cell`, for "is there one within r <= cell".
class Buckets {
 public:
  explicit Buckets(double cell) : cell_(cell) {}
  void add(const Vec2& x) { map_[key(cell_of(x.x()), cell_of(x.y()))].push_back(x); }
  bool any_within(const Vec2& x, double r) const {
    const long cx = cell_of(x.x()), cy = cell_of(x.y());
    for (long j = cy - 1; j <= cy + 1; ++j)
      for (long i = cx - 1; i <= cx + 1; ++i) {
        auto it = map_.find(key(i, j));
        if (it == map_.end()) continue;
        for (const Vec2& y : it->second)
          if ((y - x).squaredNorm() < r * r) return true;
      }
    return false;
  }

 private:
  long cell_of(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  static unsigned long long key(long i, long j) {
    return (static_cast<unsigned long long>(i) << 32) ^ static_cast<unsigned long long>(static_cast<unsigned>(j));
  }
  double cell_;
  std::unordered_map<unsigned long long, std::vector<Vec2>> map_;
};

struct Track {
  long id = 0;
  Vec2 x = Vec2::Zero();
  long still = 0;  // frames standing where flow sees no motion
};

}  // namespace

TrajectorySet flow_tracks(const VideoFlow& vf, const Geometry& venue, const FlowTrackOptions& o, const std::string& source) {
  o.check();
  if (!(vf.info.fps > 0)) throw Error(source + ": the video's frame rate is unknown");
  const double dt = 1 / vf.info.fps;
  const double spacing = hexagonal_spacing(o.density);
  const long presence_frames = std::lround(o.presence * vf.info.fps);
  TrajectorySet out;
  out.framerate = vf.info.fps;
  out.source = source;
  std::vector<Track> tracks;
  long next_id = 1;
  auto covered_at = [&](const GridVelocityField& f, const Vec2& x) {
    const int i = static_cast<int>(std::lround((x.x() - f.origin.x()) / f.dx)), j = static_cast<int>(std::lround((x.y() - f.origin.y()) / f.dx));
    if (i < 0 || j < 0 || i >= f.nx || j >= f.ny) return false;
    return vf.covered.empty() || vf.covered[static_cast<size_t>(j) * f.nx + i] != 0;
  };
  auto record = [&](long frame) {
    for (const Track& t : tracks) out.points.push_back(TrackPoint{t.id, frame, t.x.x(), t.x.y()});
  };
  // New tracks on the lattice of field f wherever no track is within 0.9 spacings (a lattice's
  // neighbours are a spacing apart; no point of it is farther than 0.58 from its nearest).
  auto fill = [&](const GridVelocityField& f) {
    Buckets near(spacing);
    for (const Track& t : tracks) near.add(t.x);
    const ObservedState lattice = sample_particles(f, o.density, &venue);
    for (const Vec2& x : lattice.x) {
      // Where the field would carry it (see the step below), not merely next to a moving node.
      const Carried c = carried(f, x);
      if (c.moving >= o.min_moving && c.v.norm() >= o.seed_speed && !near.any_within(x, 0.9 * spacing) && venue.sdf(x) >= o.clearance && venue.exit_at(x) < 0 && covered_at(f, x)) {
        tracks.push_back(Track{next_id++, x, 0});
        near.add(x);
      }
    }
  };
  if (vf.fields.empty()) throw Error(source + ": the video gave no velocity field (fewer than two frames)");
  fill(vf.fields[0]);
  record(vf.first);
  for (size_t k = 0; k < vf.fields.size(); ++k) {
    const GridVelocityField& f = vf.fields[k];
    std::vector<Track> moved;
    moved.reserve(tracks.size());
    for (Track t : tracks) {
      const Carried c = carried(f, t.x);
      if (!c.on_grid) continue;
      // Slower than half the seeding speed is standing: the slow drift of flow's halo round a
      // walker (or of noise) would otherwise carry tracks into ground nobody walks on.
      if (c.moving >= o.min_moving && c.v.norm() >= 0.5 * o.seed_speed) {
        // Midpoint rule through the field of this frame interval.
        const Carried m = carried(f, t.x + 0.5 * dt * c.v);
        t.x += dt * (m.on_grid && m.moving >= o.min_moving ? m.v : c.v);
        t.still = 0;
      } else {
        if (++t.still > presence_frames) continue;
      }
      if (!t.x.allFinite()) continue;
      const double d = venue.sdf(t.x);
      if (d < o.clearance) t.x += (o.clearance - d) * venue.normal(t.x);
      if (!venue.in_domain(t.x) || venue.exit_at(t.x) >= 0 || !covered_at(f, t.x)) continue;
      moved.push_back(t);
    }
    // Two tracks closer than half a spacing are one: the younger (larger id) ends.
    std::sort(moved.begin(), moved.end(), [](const Track& a, const Track& b) { return a.id < b.id; });
    Buckets kept(spacing);
    tracks.clear();
    for (const Track& t : moved)
      if (!kept.any_within(t.x, 0.5 * spacing)) {
        kept.add(t.x);
        tracks.push_back(t);
      }
    fill(f);
    record(vf.first + static_cast<long>(k) + 1);
  }
  if (out.points.empty()) throw Error(source + ": flow saw no crowd moving (no track could start); check the calibration and the region of interest");
  out.sort_checked();
  return out;
}

// ---- Detected tracks ------------------------------------------------------------------------

void DetectOptions::check() const {
  if (!(body_radius >= 0.05 && body_radius <= 1)) throw Error("detection: body_radius must be in [0.05, 1] m, got " + format_number(body_radius));
  if (!(contrast >= 0.1 && contrast <= 100)) throw Error("detection: contrast must be in [0.1, 100], got " + format_number(contrast));
  if (!(gate > 0 && gate <= 5)) throw Error("detection: gate must be in (0, 5] m, got " + format_number(gate));
  if (!(coast >= 0 && coast <= 60)) throw Error("detection: coast must be in [0, 60] s, got " + format_number(coast));
  if (!head_radius_fits(head_radius, body_radius))
    throw Error("detection: head_radius must be 0 (no head) or in [0.03, body_radius " + format_number(body_radius) + "] m, got " +
                format_number(head_radius));
  if (!(smooth >= 0 && smooth <= 10)) throw Error("detection: smooth must be in [0, 10] s, got " + format_number(smooth));
}

bool head_radius_fits(double head_radius, double body_radius) {
  return head_radius == 0 || (head_radius >= 0.03 && head_radius <= body_radius);
}

namespace {

// The absolute difference of Gaussians (sigma r / sqrt 2 and 1.6 times that) of a frame, and its
// robust spread (the median of |response| is 0.6745 standard deviations of a zero-mean normal).
cv::Mat band_pass(const cv::Mat& f, double r, double& sd) {
  cv::Mat g1, g2;
  const double s1 = std::max(0.7, r / std::sqrt(2.0));
  cv::GaussianBlur(f, g1, cv::Size(), s1);
  cv::GaussianBlur(f, g2, cv::Size(), 1.6 * s1);
  cv::Mat d = cv::abs(g1 - g2);
  std::vector<float> v;
  v.reserve(static_cast<size_t>(d.total() / 16 + 1));
  for (int y = 0; y < d.rows; y += 4)
    for (int x = 0; x < d.cols; x += 4) v.push_back(d.at<float>(y, x));
  sd = 0;
  if (v.empty()) return d;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  sd = v[v.size() / 2] / 0.6745;
  return d;
}

// How far from a body's detection its head is looked for, in body radii (a tilted view draws
// the shoulders beside the head, not round it).
constexpr double kHeadReach = 1.2;

// Blobs of radius `r` pixels standing out of the frame, bright or dark: local maxima of the
// absolute band-pass (band_pass) above `contrast` robust standard deviations of the response
// over the frame, the largest within 1.8 r. With head > 0, each is then moved to the largest
// response of a band-pass at `head` pixels within kHeadReach r of it (to a fraction of a pixel:
// the vertex of the parabola through it and its neighbours each way), where that stands
// `contrast` robust spreads out of its frame; else the body's place is kept.
std::vector<Vec2> find_blobs(const cv::Mat& grey, double r, double contrast, double head) {
  cv::Mat f;
  grey.convertTo(f, CV_32F);
  double sd = 0;
  cv::Mat d = band_pass(f, r, sd);
  if (d.empty()) return {};
  // (A frame mostly flat, masked or letterboxed has a median near 0: a tenth of a grey level at least.)
  const double threshold = contrast * std::max(sd, 0.1);
  // Two people stand at least a body's width apart: one detection within 1.8 body radii.
  const int k = std::max(1, static_cast<int>(std::lround(1.8 * r)));
  cv::Mat peak;
  cv::dilate(d, peak, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * k + 1, 2 * k + 1)));
  std::vector<Vec2> out;
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x) {
      const float a = d.at<float>(y, x);
      if (a >= threshold && a >= peak.at<float>(y, x)) {
        // One detection per plateau of equal maxima: the first in scan order within k is kept.
        bool taken = false;
        for (auto it = out.rbegin(); it != out.rend() && y - it->y() <= k; ++it)
          if (std::abs(it->x() - x) <= k && std::abs(it->y() - y) <= k) { taken = true; break; }
        if (!taken) out.emplace_back(x, y);
      }
    }
  if (head > 0) {
    double hsd = 0;
    const cv::Mat h = band_pass(f, head, hsd);
    const double hthreshold = contrast * std::max(hsd, 0.1);
    const int reach = std::max(1, static_cast<int>(std::lround(kHeadReach * r)));
    // Sub-pixel: the vertex of the parabola through the maximum and its neighbours, each way.
    const auto vertex = [](double a, double b, double c) { const double den = a - 2 * b + c; return den < 0 ? 0.5 * (a - c) / den : 0.0; };
    for (Vec2& p : out) {
      const int px = static_cast<int>(p.x()), py = static_cast<int>(p.y());
      float best = -1;
      int bx = px, by = py;
      for (int y = std::max(1, py - reach); y <= std::min(h.rows - 2, py + reach); ++y)
        for (int x = std::max(1, px - reach); x <= std::min(h.cols - 2, px + reach); ++x) {
          if ((x - px) * (x - px) + (y - py) * (y - py) > reach * reach) continue;
          const float a = h.at<float>(y, x);
          if (a > best) best = a, bx = x, by = y;
        }
      if (best < hthreshold) continue;  // (also where the search met no interior pixel: best -1)
      p = Vec2(bx + vertex(h.at<float>(by, bx - 1), best, h.at<float>(by, bx + 1)),
               by + vertex(h.at<float>(by - 1, bx), best, h.at<float>(by + 1, bx)));
    }
  }
  return out;
}

struct Followed {
  long id = 0;
  Vec2 pixel = Vec2::Zero(), x = Vec2::Zero();
  long missed = 0;
  std::vector<std::pair<long, Vec2>> coasted;  // frames predicted while missed (ground)
};

// Each track's positions replaced by their mean over the frames within `half` of each (fewer at
// its ends, the same number on both sides): a detection's place on a body jitters from frame to
// frame by a few centimetres, which at 10 fps is a speed error of tenths of a metre per second.
void smooth_tracks(TrajectorySet& t, long half) {
  if (half <= 0) return;
  std::vector<TrackPoint> smoothed = t.points;
  for (const auto& idx : t.tracks()) {
    const long n = static_cast<long>(idx.size());
    for (long k = 0; k < n; ++k) {
      const long h = std::min({half, k, n - 1 - k});
      double x = 0, y = 0;
      for (long j = k - h; j <= k + h; ++j) {
        x += t.points[idx[static_cast<size_t>(j)]].x;
        y += t.points[idx[static_cast<size_t>(j)]].y;
      }
      smoothed[idx[static_cast<size_t>(k)]].x = x / static_cast<double>(2 * h + 1);
      smoothed[idx[static_cast<size_t>(k)]].y = y / static_cast<double>(2 * h + 1);
    }
  }
  t.points = std::move(smoothed);
}

}  // namespace

TrajectorySet detected_tracks(const VideoSource& src, const Geometry& venue, const DetectOptions& o, TrackNoise* noise) {
  o.check();
  const VideoInfo info = probe_video(src.path, src.video);
  const Calibration cal = video_calibration(src, info);
  // Pixels per metre at the middle of the view (the body's size in the image).
  const Vec2 centre(0.5 * info.width, 0.5 * info.height);
  const Vec2 g = cal.to_world(centre);
  const double ppm = 0.5 * ((cal.to_image(g + Vec2(o.body_radius, 0)) - centre).norm() +
                            (cal.to_image(g + Vec2(0, o.body_radius)) - centre).norm()) / o.body_radius;
  if (!(ppm > 0 && std::isfinite(ppm))) throw Error(src.path + ": the calibration gives no scale at the middle of the view");
  const double r_px = o.body_radius * ppm;
  const long coast_frames = std::lround(o.coast * info.fps);
  TrajectorySet out;
  out.source = src.path;
  std::vector<Followed> tracks;
  long next_id = 1;
  auto walkable = [&](const Vec2& x) { return x.allFinite() && venue.in_domain(x) && venue.sdf(x) >= 0; };
  // Each frame after the first, with the flow from the frame before it.
  auto follow = [&](long frame, const cv::Mat& grey, const cv::Mat& flow) {
    std::vector<Vec2> px, ground;
    // The head's outline at half its radius: a band-pass at its whole radius takes in the
    // shoulders round it too (on the suite's corridor: 0.078 m spread of the per-person offset
    // at 0.11 m, 0.044 m at half of it).
    for (const Vec2& p : find_blobs(grey, r_px, o.contrast, 0.5 * o.head_radius * ppm)) {
      const Vec2 x = cal.to_world(p);
      if (walkable(x)) px.push_back(p), ground.push_back(x);
    }
    // Predictions by the flow at each track's pixel.
    std::vector<Vec2> pred_px(tracks.size()), pred(tracks.size());
    for (size_t t = 0; t < tracks.size(); ++t) {
      const int u = std::clamp(static_cast<int>(std::lround(tracks[t].pixel.x())), 0, flow.cols - 1);
      const int w = std::clamp(static_cast<int>(std::lround(tracks[t].pixel.y())), 0, flow.rows - 1);
      const cv::Vec2f f = flow.at<cv::Vec2f>(w, u);
      pred_px[t] = tracks[t].pixel + Vec2(f[0], f[1]);
      pred[t] = cal.to_world(pred_px[t]);
    }
    // Greedy matching, closest pairs first.
    std::vector<std::tuple<double, size_t, size_t>> pairs;
    for (size_t t = 0; t < tracks.size(); ++t)
      for (size_t d = 0; d < ground.size(); ++d) {
        const double dist = (ground[d] - pred[t]).norm();
        if (dist <= o.gate) pairs.emplace_back(dist, t, d);
      }
    std::sort(pairs.begin(), pairs.end());
    std::vector<char> track_done(tracks.size(), 0), det_done(ground.size(), 0);
    for (const auto& [dist, t, d] : pairs) {
      if (track_done[t] || det_done[d]) continue;
      track_done[t] = det_done[d] = 1;
      Followed& f = tracks[t];
      for (const auto& [cf, cx] : f.coasted) out.points.push_back(TrackPoint{f.id, cf, cx.x(), cx.y()});
      f.coasted.clear();
      f.pixel = px[d];
      f.x = ground[d];
      f.missed = 0;
      out.points.push_back(TrackPoint{f.id, frame, f.x.x(), f.x.y()});
    }
    std::vector<Followed> kept;
    kept.reserve(tracks.size() + ground.size());
    for (size_t t = 0; t < tracks.size(); ++t) {
      Followed& f = tracks[t];
      if (!track_done[t]) {
        if (++f.missed > coast_frames || !walkable(pred[t])) continue;
        f.pixel = pred_px[t];
        f.x = pred[t];
        f.coasted.emplace_back(frame, f.x);
      }
      kept.push_back(std::move(f));
    }
    for (size_t d = 0; d < ground.size(); ++d)
      if (!det_done[d]) {
        kept.push_back(Followed{next_id, px[d], ground[d], 0, {}});
        out.points.push_back(TrackPoint{next_id++, frame, ground[d].x(), ground[d].y()});
      }
    tracks = std::move(kept);
  };
  VideoReader reader(src.path, src.video);
  FlowEstimator estimator(src.flow);
  cv::Mat grey, flow;
  long flows = 0;
  while (reader.next(grey))
    if (estimator.push(grey, flow)) {
      follow(reader.frame(), grey, flow);
      ++flows;
    }
  if (flows == 0) throw Error(src.path + ": fewer than two frames in the range; flow needs two");
  out.framerate = reader.info().fps;
  if (o.smoother && !out.points.empty()) {
    const TrackNoise levels = smooth_under_own_noise(out);
    if (noise) *noise = levels;
  }
  smooth_tracks(out, std::lround(o.smooth * info.fps / 2));
  if (out.points.empty()) throw Error(src.path + ": nobody was found in the video (no blob of " + format_number(o.body_radius) +
                                      " m stood out of the floor); check the calibration, or use the flow's tracks");
  out.sort_checked();
  return out;
}

}  // namespace crowdmpm
