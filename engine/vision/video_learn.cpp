#include "engine/vision/video_learn.hpp"

#include <algorithm>
#include <cmath>

#include "engine/core/error.hpp"
#include "engine/sim/stencil.hpp"
#include "engine/vision/video_job.hpp"

namespace crowdmpm {

void VideoLearnOptions::check() const {
  if (!(density > 0 && density <= 12)) throw Error("video learning: density must be in (0, 12] persons/m2, got " + format_number(density));
  if (!(clip > 0 && stride > 0)) throw Error("video learning: clip and stride must be > 0 s");
  if (!(train_share > 0 && train_share < 1)) throw Error("video learning: train share must be in (0, 1), got " + format_number(train_share));
  if (start_frames < 1) throw Error("video learning: start_frames must be >= 1");
  if (horizons < 1 || horizons > 100) throw Error("video learning: horizons must be 1..100");
}

ObservedState sample_particles(const GridVelocityField& f, double density) {
  if (!(density > 0)) throw Error("sample_particles: density must be > 0");
  ObservedState s;
  const double a = std::sqrt(2 / (std::sqrt(3.0) * density));  // hexagonal spacing
  const double row = a * std::sqrt(3.0) / 2;
  const Vec2 lo = f.origin, hi = f.origin + f.dx * Vec2(f.nx - 1, f.ny - 1);
  int r = 0;
  for (double y = lo.y(); y <= hi.y(); y += row, ++r)
    for (double x = lo.x() + (r % 2 ? a / 2 : 0); x <= hi.x(); x += a) {
      const int i = static_cast<int>(std::lround((x - f.origin.x()) / f.dx)), j = static_cast<int>(std::lround((y - f.origin.y()) / f.dx));
      if (i < 0 || j < 0 || i >= f.nx || j >= f.ny || !(f.mask[static_cast<size_t>(j) * f.nx + i] > 0)) continue;
      const Vec2 p(x, y);
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

namespace {
GridVelocityField start_field(const std::vector<GridVelocityField>& fields, size_t start, int frames) {
  const size_t first = start + 1 >= static_cast<size_t>(frames) ? start + 1 - static_cast<size_t>(frames) : 0;
  return mean_field(std::vector<GridVelocityField>(fields.begin() + static_cast<long>(first), fields.begin() + static_cast<long>(start) + 1));
}
}  // namespace

void make_video_windows(const std::vector<GridVelocityField>& fields, double fps, size_t end, const VideoLearnOptions& vo,
                        double validation_fraction, std::vector<TrainWindow>& train, std::vector<TrainWindow>& validation) {
  vo.check();
  train.clear();
  validation.clear();
  end = std::min(end, fields.size());
  const size_t length = static_cast<size_t>(std::max(1L, std::lround(vo.clip * fps)));
  const size_t stride = static_cast<size_t>(std::max(1L, std::lround(vo.stride * fps)));
  std::vector<size_t> starts;
  for (size_t s = static_cast<size_t>(vo.start_frames) - 1; s + length < end; s += stride) starts.push_back(s);
  const size_t n_val = static_cast<size_t>(std::ceil(validation_fraction * static_cast<double>(starts.size())));
  const size_t n_train = starts.size() - std::min(starts.size(), n_val);
  const size_t val_start = n_train < starts.size() ? starts[n_train] : end;
  for (size_t i = 0; i < starts.size(); ++i) {
    const bool is_val = i >= n_train;
    if (!is_val && starts[i] + length > val_start) continue;
    TrainWindow w;
    w.start = sample_particles(start_field(fields, starts[i], vo.start_frames), vo.density);
    if (w.start.ids.empty()) continue;
    w.start.frame = static_cast<long>(starts[i]);
    w.framerate = fps;
    w.fields.assign(fields.begin() + static_cast<long>(starts[i]) + 1, fields.begin() + static_cast<long>(starts[i] + length) + 1);
    (is_val ? validation : train).push_back(std::move(w));
  }
}

namespace {

// Err_vel: mean over observed, non-border nodes of |predicted - observed|^2 (predicted 0 where it has nobody).
void score(const GridVelocityField& pred, const GridVelocityField& obs, const std::vector<char>& inner, VideoHorizon& h) {
  double s = 0;
  long n = 0;
  for (size_t i = 0; i < obs.velocity.size(); ++i) {
    if (!(obs.mask[i] > 0) || !inner[i]) continue;
    const Vec2 p = pred.mask[i] > 0 ? pred.velocity[i] : Vec2::Zero();
    s += (p - obs.velocity[i]).squaredNorm();
    ++n;
  }
  h.err_vel = n ? s / static_cast<double>(n) : std::nan("");
  h.nodes = n;
}

}  // namespace

std::vector<VideoPrediction> predict_video(const ScenarioDef& scenario, const std::vector<Model>& models,
                                           const std::vector<GridVelocityField>& fields, const std::vector<char>& covered,
                                           double fps, size_t start, const VideoLearnOptions& vo, int threads) {
  vo.check();
  if (start + 1 >= fields.size()) throw Error("video prediction: nothing held out after field " + std::to_string(start));
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
  const size_t held = fields.size() - 1 - start;
  std::vector<size_t> at;
  for (int k = 1; k <= vo.horizons; ++k) {
    const size_t h = std::max<size_t>(1, static_cast<size_t>(std::lround(static_cast<double>(k) * static_cast<double>(held) / vo.horizons)));
    if (at.empty() || h > at.back()) at.push_back(h);
  }
  const ObservedState s = sample_particles(start_field(fields, start, vo.start_frames), vo.density);
  if (s.ids.empty()) throw Error("video prediction: the field at the start of the held-out part keeps no moving node");
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
    std::vector<Vec2> x(s.x.size());
    for (size_t p = 0; p < x.size(); ++p) x[p] = s.x[p] + s.v[p] * (static_cast<double>(h) / fps);
    return grid_velocity_of(x, s.v, 1, shape, vo.min_mass);
  });
  const ScenarioDef windowed = window_scenario(scenario, false);
  for (const Model& m : models) {
    WindowSim ws = start_window(windowed, m, s, WindowOptions{threads, DesiredSpeed::Observed});
    Simulation& sim = *ws.sim;
    std::vector<GridVelocityField> at_h;
    size_t done = 0;
    for (size_t h : at) {
      const long target = std::lround(static_cast<double>(h) / fps / windowed.dt);
      while (static_cast<long>(done) < target) {
        sim.step();
        ++done;
      }
      at_h.push_back(grid_velocity_of(sim.world().x, sim.world().v, 1, sim.grid(), vo.min_mass));
    }
    size_t k = 0;
    add(model_label(m), [&](size_t) { return at_h[k++]; });
  }
  return out;
}

json video_prediction_json(const std::vector<VideoPrediction>& ps) {
  json a = json::array();
  for (const auto& p : ps) {
    json hs = json::array();
    for (const auto& h : p.horizons)
      hs.push_back({{"seconds", h.seconds}, {"frame", h.frame}, {"err_vel", h.err_vel}, {"nodes", h.nodes}});
    a.push_back({{"method", p.method}, {"horizons", hs}});
  }
  return a;
}

}  // namespace crowdmpm
