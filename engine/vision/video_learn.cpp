#include "engine/vision/video_learn.hpp"

#include <algorithm>
#include <cmath>

#include "engine/core/error.hpp"
#include "engine/io/chart.hpp"
#include "engine/sim/stencil.hpp"
#include "engine/vision/video_job.hpp"

namespace crowdmpm {

void VideoLearnOptions::check() const {
  if (!(density > 0 && density <= 12)) throw Error("video learning: density must be in (0, 12] persons/m2, got " + format_number(density));
  if (!(clip > 0 && stride > 0)) throw Error("video learning: clip and stride must be > 0 s");
  if (!(train_share > 0 && train_share < 1)) throw Error("video learning: train share must be in (0, 1), got " + format_number(train_share));
  if (start_frames < 1) throw Error("video learning: start_frames must be >= 1");
  if (!(presence >= 0)) throw Error("video learning: presence must be >= 0 s");
  if (horizons < 1 || horizons > 100) throw Error("video learning: horizons must be 1..100");
  if (ensemble < 1 || ensemble > 64) throw Error("video learning: ensemble must be 1..64 rollouts, got " + std::to_string(ensemble));
}

Vec2 ensemble_offset(int k) {
  const double g = 1.32471795724474602596;  // the plastic number: x^3 = x + 1
  const double a = static_cast<double>(k) / g, b = static_cast<double>(k) / (g * g);
  return Vec2(a - std::floor(a), b - std::floor(b));
}

ObservedState sample_particles(const GridVelocityField& f, double density, const Geometry* venue, const Vec2& offset) {
  if (!(density > 0)) throw Error("sample_particles: density must be > 0");
  if (!offset.allFinite()) throw Error("sample_particles: the lattice offset is not finite");
  ObservedState s;
  const double a = hexagonal_spacing(density);
  const double row = a * std::sqrt(3.0) / 2;
  const Vec2 lo = f.origin, hi = f.origin + f.dx * Vec2(f.nx - 1, f.ny - 1);
  const double ox = a * (offset.x() - std::floor(offset.x())), oy = 2 * row * (offset.y() - std::floor(offset.y()));
  // A shifted lattice starts a period before the edge so that it still covers it (the points
  // before the edge are skipped); the unshifted one starts on it.
  int r = 0;
  for (double y = lo.y() + (oy > 0 ? oy - 2 * row : 0); y <= hi.y(); y += row, ++r)
    for (double x = lo.x() + (ox > 0 ? ox - a : 0) + (r % 2 ? a / 2 : 0); x <= hi.x(); x += a) {
      if (x < lo.x() || y < lo.y()) continue;
      const int i = static_cast<int>(std::lround((x - f.origin.x()) / f.dx)), j = static_cast<int>(std::lround((y - f.origin.y()) / f.dx));
      if (i < 0 || j < 0 || i >= f.nx || j >= f.ny || !(f.mask[static_cast<size_t>(j) * f.nx + i] > 0)) continue;
      const Vec2 p(x, y);
      if (venue && venue->sdf(p) < a / 2) continue;
      Vec2 v = Vec2::Zero();
      double w_sum = 0;
      for_stencil_on_grid(f.origin, f.dx, f.nx, f.ny, p, [&](size_t n, double w, const Vec2&) {
        if (f.mask[n] > 0) {
          v += w * f.velocity[n];
          w_sum += w;
        }
      });
      if (!(w_sum > 0)) continue;
      v /= w_sum;
      s.ids.push_back(static_cast<long>(s.ids.size()) + 1);
      s.x.push_back(p);
      s.v.push_back(v);
      s.speed.push_back(v.norm());
      s.free_speed.push_back(v.norm());
    }
  return s;
}

GridVelocityField start_field(const std::vector<GridVelocityField>& fields, size_t start, double fps, const VideoLearnOptions& vo) {
  if (start >= fields.size()) throw Error("start_field: field " + std::to_string(start) + " of " + std::to_string(fields.size()));
  auto back = [&](long frames) { return static_cast<long>(start) + 1 >= frames ? static_cast<long>(start) + 1 - frames : 0L; };
  GridVelocityField f = mean_field(std::vector<GridVelocityField>(fields.begin() + back(vo.start_frames), fields.begin() + static_cast<long>(start) + 1));
  const long present = std::max(1L, std::lround(vo.presence * fps));
  for (long k = back(present); k <= static_cast<long>(start); ++k)
    for (size_t i = 0; i < f.mask.size(); ++i)
      if (fields[static_cast<size_t>(k)].mask[i] > 0 && !(f.mask[i] > 0)) {
        f.mask[i] = 1;
        f.velocity[i] = Vec2::Zero();
      }
  return f;
}

void make_video_windows(const ScenarioDef& venue, const std::vector<GridVelocityField>& fields, double fps, size_t end,
                        const VideoLearnOptions& vo, double validation_fraction, std::vector<TrainWindow>& train,
                        std::vector<TrainWindow>& validation, const std::vector<size_t>& glitches,
                        const std::vector<char>& covered) {
  vo.check();
  train.clear();
  validation.clear();
  end = std::min(end, fields.size());
  const size_t length = static_cast<size_t>(std::max(1L, std::lround(vo.clip * fps)));
  const size_t stride = static_cast<size_t>(std::max(1L, std::lround(vo.stride * fps)));
  std::vector<size_t> starts;
  const size_t lead = static_cast<size_t>(vo.start_frames) - 1;
  for (size_t s = lead; s + length < end; s += stride) {
    const bool crosses = std::any_of(glitches.begin(), glitches.end(), [&](size_t g) { return g + lead >= s && g <= s + length; });
    if (!crosses) starts.push_back(s);
  }
  const size_t n_val = static_cast<size_t>(std::ceil(validation_fraction * static_cast<double>(starts.size())));
  const size_t n_train = starts.size() - std::min(starts.size(), n_val);
  const size_t val_start = n_train < starts.size() ? starts[n_train] : end;
  for (size_t i = 0; i < starts.size(); ++i) {
    const bool is_val = i >= n_train;
    if (!is_val && starts[i] + length > val_start) continue;
    TrainWindow w;
    const GridVelocityField sf = start_field(fields, starts[i], fps, vo);
    w.start = sample_particles(sf, vo.density, &venue.geo);
    if (w.start.ids.empty()) continue;
    if (vo.inflow && !covered.empty()) w.inflow = edge_inflow(sf, covered, venue.geo, vo.density);
    w.start.frame = static_cast<long>(starts[i]);
    w.framerate = fps;
    w.fields.assign(fields.begin() + static_cast<long>(starts[i]) + 1, fields.begin() + static_cast<long>(starts[i] + length) + 1);
    (is_val ? validation : train).push_back(std::move(w));
  }
}

EdgeInflow edge_inflow(const GridVelocityField& f, const std::vector<char>& covered, const Geometry& geo, double density) {
  if (covered.size() != f.velocity.size()) throw Error("inflow: coverage mask does not match the grid");
  EdgeInflow in;
  in.density = density;
  const double spacing = hexagonal_spacing(density);
  for (int j = 0; j < f.ny; ++j)
    for (int i = 0; i < f.nx; ++i) {
      const size_t n = static_cast<size_t>(j) * f.nx + i;
      if (!covered[n] || !(f.mask[n] > 0)) continue;
      Vec2 out_dir = Vec2::Zero();
      for (const auto& d : {Vec2(1, 0), Vec2(-1, 0), Vec2(0, 1), Vec2(0, -1)}) {
        const int a = i + static_cast<int>(d.x()), b = j + static_cast<int>(d.y());
        if (a < 0 || b < 0 || a >= f.nx || b >= f.ny || !covered[static_cast<size_t>(b) * f.nx + a]) out_dir += d;
      }
      if (out_dir.squaredNorm() == 0) continue;
      const double in_speed = -f.velocity[n].dot(out_dir.normalized());
      const Vec2 x = f.origin + f.dx * Vec2(i, j);
      if (in_speed > 0 && geo.sdf(x) >= spacing / 2) in.points.push_back(EdgeInflow::Point{x, f.velocity[n], density * in_speed * f.dx});
    }
  return in;
}

size_t held_out_end(size_t fields, size_t start, const std::vector<size_t>& glitches) {
  for (size_t g : glitches)
    if (g > start && g < fields) return g;
  return fields;
}

namespace {

// Err_vel: mean over observed, non-border nodes of |predicted - observed|^2 (predicted 0 where it has nobody).
void score(const GridVelocityField& pred, const GridVelocityField& obs, const std::vector<char>& inner, VideoHorizon& h) {
  double s = 0;
  long n = 0, empty = 0;
  for (size_t i = 0; i < obs.velocity.size(); ++i) {
    if (!(obs.mask[i] > 0) || !inner[i]) continue;
    empty += pred.mask[i] > 0 ? 0 : 1;
    const Vec2 p = pred.mask[i] > 0 ? pred.velocity[i] : Vec2::Zero();
    s += (p - obs.velocity[i]).squaredNorm();
    ++n;
  }
  h.err_vel = n ? s / static_cast<double>(n) : std::nan("");
  h.nodes = n;
  h.empty = n ? static_cast<double>(empty) / static_cast<double>(n) : 0;
}

// The mean of an ensemble's predicted fields, a node where a member has nobody counting as
// velocity 0 in it (as Err_vel scores it); kept where any member has somebody.
GridVelocityField ensemble_mean(const std::vector<GridVelocityField>& members) {
  GridVelocityField m = members.front();
  for (size_t i = 0; i < m.velocity.size(); ++i) {
    Vec2 sum = Vec2::Zero();
    double any = 0;
    for (const GridVelocityField& f : members)
      if (f.mask[i] > 0) {
        sum += f.velocity[i];
        any = 1;
      }
    m.velocity[i] = sum / static_cast<double>(members.size());
    m.mask[i] = any;
  }
  return m;
}

}  // namespace

std::vector<VideoPrediction> predict_video(const ScenarioDef& scenario, const std::vector<Model>& models,
                                           const std::vector<GridVelocityField>& fields, const std::vector<char>& covered,
                                           double fps, size_t start, const VideoLearnOptions& vo, int threads,
                                           const std::vector<size_t>& glitches) {
  vo.check();
  const size_t end = held_out_end(fields.size(), start, glitches);
  if (start + 1 >= end)
    throw Error("video prediction: nothing held out after field " + std::to_string(start) +
                (end < fields.size() ? " (field " + std::to_string(end) + " is a camera glitch)" : std::string()));
  const GridVelocityField& f0 = fields[start];
  if (covered.size() != f0.velocity.size()) throw Error("video prediction: coverage mask does not match the grid");
  // Border: a node with an unseen neighbour.
  std::vector<char> inner(covered.size(), 0);
  for (int j = 1; j + 1 < f0.ny; ++j)
    for (int i = 1; i + 1 < f0.nx; ++i) {
      bool all = true;
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) all = all && covered[static_cast<size_t>(j + dj) * f0.nx + i + di];
      inner[static_cast<size_t>(j) * f0.nx + i] = all;
    }
  const size_t held = end - 1 - start;
  std::vector<size_t> at;
  for (int k = 1; k <= vo.horizons; ++k) {
    const size_t h = std::max<size_t>(1, static_cast<size_t>(std::lround(static_cast<double>(k) * static_cast<double>(held) / vo.horizons)));
    if (at.empty() || h > at.back()) at.push_back(h);
  }
  const GridVelocityField sf = start_field(fields, start, fps, vo);
  std::vector<ObservedState> samples;
  for (int k = 0; k < vo.ensemble; ++k) {
    samples.push_back(sample_particles(sf, vo.density, &scenario.geo, ensemble_offset(k)));
    if (samples.back().ids.empty()) throw Error("video prediction: the field at the start of the held-out part keeps no moving node");
  }
  std::vector<VideoPrediction> out;
  auto add = [&](const std::string& method, const std::function<GridVelocityField(size_t)>& predict) {
    VideoPrediction p;
    p.method = method;
    for (size_t h : at) {
      VideoHorizon vh;
      vh.frame = static_cast<long>(start + h);
      vh.seconds = static_cast<double>(h) / fps;
      score(predict(h), fields[start + h], inner, vh);
      p.horizons.push_back(vh);
    }
    out.push_back(std::move(p));
  };
  Grid shape;
  shape.origin = f0.origin;
  shape.dx = f0.dx;
  shape.nx = f0.nx;
  shape.ny = f0.ny;
  add("persistence", [&](size_t) { return fields[start]; });
  add("constant velocity", [&](size_t h) {
    std::vector<GridVelocityField> members;
    for (const ObservedState& s : samples) {
      std::vector<Vec2> x(s.x.size());
      for (size_t p = 0; p < x.size(); ++p) x[p] = s.x[p] + s.v[p] * (static_cast<double>(h) / fps);
      members.push_back(grid_velocity_of(x, s.v, 1, shape, vo.min_mass));
    }
    return ensemble_mean(members);
  });
  const ScenarioDef windowed = window_scenario(scenario, true);  // people leave by the exits, as they do on video
  EdgeInflow inflow;
  if (vo.inflow) inflow = edge_inflow(sf, covered, scenario.geo, vo.density);
  for (const Model& m : models) {
    std::vector<std::vector<GridVelocityField>> at_h(at.size());  // per horizon, per member
    for (const ObservedState& s : samples) {
      WindowSim ws = start_window(windowed, m, s, WindowOptions{threads, vo.desired_speed});
      Simulation& sim = *ws.sim;
      InflowRun run(inflow, vo.desired_speed);
      size_t done = 0;
      for (size_t i = 0; i < at.size(); ++i) {
        const long target = std::lround(static_cast<double>(at[i]) / fps / windowed.dt);
        while (static_cast<long>(done) < target) {
          sim.step();
          ++done;
          run.after_step(sim);
        }
        at_h[i].push_back(grid_velocity_of(sim.world().x, sim.world().v, 1, sim.grid(), vo.min_mass));
      }
    }
    size_t k = 0;
    add(model_label(m), [&](size_t) { return ensemble_mean(at_h[k++]); });
  }
  return out;
}

ScenarioDef video_venue(const VideoSource& src) {
  const VideoInfo info = probe_video(src.path, src.video);
  const Calibration cal = video_calibration(src, info);
  const Grid g = grid_covering(cal, src.video.roi, info.width, info.height, src.cell);
  // The ground in view plus a margin of two cells on every side, whose outer half is the exits:
  // people walk out of view and leave there, away from the nodes the prediction is scored on.
  const double margin = 2 * g.dx;
  const Vec2 lo = g.origin + Vec2(2 * g.dx, 2 * g.dx) - Vec2(margin, margin);
  // Grid::init gives nx = ceil((hi - lo) / dx) + 5: a hair under a whole number of cells.
  const Vec2 hi = lo + g.dx * (Vec2(g.nx - 1, g.ny - 1) - Vec2(1e-9, 1e-9));
  const double band = margin / 2;
  const double steps = std::ceil(1 / (info.fps * 0.01) - 1e-9);  // per frame
  const double dt = 1 / (info.fps * steps);
  const json doc{{"format", "crowdmpm-scenario"},
                 {"version", 1},
                 {"name", "video venue"},
                 {"description", "the ground seen in " + src.path + ", without walls; people walk on the way they moved when placed"},
                 {"domain", {{"min", {lo.x(), lo.y()}}, {"max", {hi.x(), hi.y()}}, {"cell_size", g.dx}}},
                 {"time", {{"dt", dt}, {"duration", 3600}, {"output_rate", info.fps}}},
                 {"geometry",
                  {{"exits", json::array({{{"id", "west_edge"}, {"rect", {lo.x(), lo.y(), lo.x() + band, hi.y()}}},
                                          {{"id", "east_edge"}, {"rect", {hi.x() - band, lo.y(), hi.x(), hi.y()}}},
                                          {{"id", "south_edge"}, {"rect", {lo.x(), lo.y(), hi.x(), lo.y() + band}}},
                                          {{"id", "north_edge"}, {"rect", {lo.x(), hi.y() - band, hi.x(), hi.y()}}}})}}},
                 {"groups", json::array({{{"id", "crowd"},
                                           {"spawn", {{"rect", {lo.x(), lo.y(), hi.x(), hi.y()}}}},
                                           {"count", 0},
                                           {"desired_speed", 1.0},
                                           {"behaviour", {{"type", "heading"}}}}})}};
  return ScenarioDef::parse_text(doc.dump(), ".");
}

void write_video_prediction_png(const std::string& path, const std::vector<VideoPrediction>& ps, const std::string& title) {
  static const std::array<int, 3> colours[] = {{120, 120, 120}, {40, 120, 220}, {230, 120, 30}, {40, 160, 60}, {200, 40, 40}, {140, 60, 180}};
  Chart c;
  c.title = title;
  c.x_label = "horizon (s)";
  c.y_label = "Err_vel (m2/s2)";
  for (size_t i = 0; i < ps.size(); ++i) {
    ChartSeries s;
    s.name = ps[i].method;
    s.style = ChartSeries::Style::LinePoints;
    s.rgb = colours[i % 6];
    for (const auto& h : ps[i].horizons)
      if (std::isfinite(h.err_vel)) s.points.emplace_back(h.seconds, h.err_vel);
    c.series.push_back(std::move(s));
  }
  write_chart_png(path, c);
}

json video_prediction_json(const std::vector<VideoPrediction>& ps) {
  json a = json::array();
  for (const auto& p : ps) {
    json hs = json::array();
    for (const auto& h : p.horizons)
      hs.push_back({{"seconds", h.seconds}, {"frame", h.frame}, {"err_vel", h.err_vel}, {"nodes", h.nodes}, {"empty", h.empty}});
    a.push_back({{"method", p.method}, {"horizons", hs}});
  }
  return a;
}

}  // namespace crowdmpm
