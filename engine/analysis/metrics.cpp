#include "engine/analysis/metrics.hpp"

#include <algorithm>
#include <filesystem>
#include <cmath>

namespace crowdmpm {

MetricsRecorder::MetricsRecorder(const ScenarioDef& s) : s_(s) {
  areas_.resize(s.areas.size());
  for (size_t i = 0; i < s.areas.size(); ++i) areas_[i].area = s.areas[i].shape.area();
}

const AreaStats& MetricsRecorder::area(const std::string& id) const {
  for (size_t i = 0; i < s_.areas.size(); ++i)
    if (s_.areas[i].id == id) return areas_[i];
  throw Error("no measurement area with id \"" + id + "\"");
}

void MetricsRecorder::record(const Simulation& sim, const FieldFrame& f) {
  const double t = sim.time();
  const World& w = sim.world();
  times_.push_back(t);
  remaining_.push_back(static_cast<long>(w.size()));
  std::vector<long> counts(s_.geo.exits.size(), 0);
  for (const auto& e : sim.exit_events()) ++counts[e.exit];
  exit_counts_.push_back(counts);

  for (size_t k = 0; k < f.density.size(); ++k) {
    int i = static_cast<int>(k % f.nx), j = static_cast<int>(k / f.nx);
    Vec2 at = f.node_position(i, j);
    // Peaks are reported where people can be: nodes in the grid's padding outside the domain
    // only carry the tail of the B-spline.
    if (!s_.geo.in_domain(at)) continue;
    if (f.density[k] > peak_density_.value) peak_density_ = {f.density[k], t, f.node_position(i, j)};
    if (f.pressure[k] > peak_pressure_.value) peak_pressure_ = {f.pressure[k], t, f.node_position(i, j)};
  }
  if (frames_ == 0) {
    sum_map_ = f;
    peak_map_ = f;
  } else {
    for (size_t k = 0; k < f.density.size(); ++k) {
      sum_map_.density[k] += f.density[k];
      sum_map_.pressure[k] += f.pressure[k];
      sum_map_.velocity[k] += f.velocity[k];
      peak_map_.density[k] = std::max(peak_map_.density[k], f.density[k]);
      peak_map_.pressure[k] = std::max(peak_map_.pressure[k], f.pressure[k]);
    }
  }
  ++frames_;

  for (size_t a = 0; a < s_.areas.size(); ++a) {
    const MeasurementArea& m = s_.areas[a];
    if (t < m.from - 1e-9 || t > m.to + 1e-9) continue;
    AreaStats& st = areas_[a];
    long inside = 0;
    double psum = 0;
    for (size_t p = 0; p < w.size(); ++p)
      if (m.shape.contains(w.x[p])) {
        ++inside;
        psum += w.pressure[p];
        st.pressure_peak = std::max(st.pressure_peak, w.pressure[p]);
      }
    ++st.frames;
    st.density_sum += static_cast<double>(inside) / st.area;
    st.series.push_back({t, static_cast<double>(inside) / st.area, inside ? psum / static_cast<double>(inside) : 0.0});
    if (inside) {
      st.pressure_sum += psum / static_cast<double>(inside);
      ++st.pressure_frames;
    }
    double gsum = 0;
    long gn = 0;
    for (int j = 0; j < f.ny; ++j)
      for (int i = 0; i < f.nx; ++i)
        if (m.shape.contains(f.node_position(i, j))) {
          gsum += f.at(f.pressure, i, j);
          ++gn;
        }
    if (gn) st.grid_pressure_sum += gsum / static_cast<double>(gn);
  }
}

FieldFrame MetricsRecorder::mean_map() const {
  FieldFrame m = sum_map_;
  if (frames_ == 0) return m;
  double inv = 1.0 / static_cast<double>(frames_);
  for (auto& v : m.density) v *= inv;
  for (auto& v : m.pressure) v *= inv;
  for (auto& v : m.velocity) v *= inv;
  return m;
}

static json peak_json(const Peak& p) {
  return {{"value", p.value}, {"x", p.where.x()}, {"y", p.where.y()}, {"time", p.time}};
}

json MetricsRecorder::to_json(const Simulation& sim) const {
  json j;
  j["scenario"] = s_.name;
  if (!s_.source.empty() && std::filesystem::exists(s_.source)) j["scenario_file"] = std::filesystem::absolute(s_.source).string();
  j["simulated_time"] = sim.time();
  j["steps"] = sim.steps();
  j["agents_spawned"] = sim.spawned();
  j["agents_remaining_final"] = sim.world().size();
  j["agents_exited"] = sim.exit_events().size();
  json rem = json::array();
  for (size_t k = 0; k < times_.size(); ++k) rem.push_back({times_[k], remaining_[k]});
  j["agents_remaining"] = rem;
  json exits = json::array();
  for (size_t e = 0; e < s_.geo.exits.size(); ++e) {
    json n = json::array();
    for (size_t k = 0; k < times_.size(); ++k) n.push_back({times_[k], exit_counts_[k][e]});
    std::vector<double> passes;
    for (const auto& ev : sim.exit_events())
      if (ev.exit == static_cast<int>(e)) passes.push_back(ev.time);
    json flow = nullptr;
    if (passes.size() >= 10) {
      // Flow over the middle 80% of the passages, so start-up and the last stragglers do not count.
      size_t a = passes.size() / 10, b = passes.size() - 1 - passes.size() / 10;
      if (passes[b] > passes[a]) flow = static_cast<double>(b - a) / (passes[b] - passes[a]);
    }
    exits.push_back({{"id", s_.geo.exits[e].id}, {"count", passes.size()}, {"flow_rate", flow}, {"N", n}});
  }
  j["exits"] = exits;
  bool evacuated = sim.world().size() == 0 && sim.pending_spawns() == 0 && !sim.exit_events().empty();
  j["evacuation_time"] = evacuated ? json(sim.exit_events().back().time) : json(nullptr);
  j["peak_density"] = peak_json(peak_density_);
  j["peak_pressure"] = peak_json(peak_pressure_);
  json areas = json::array();
  for (size_t a = 0; a < s_.areas.size(); ++a) {
    const AreaStats& st = areas_[a];
    areas.push_back({{"id", s_.areas[a].id},
                     {"area", st.area},
                     {"frames", st.frames},
                     {"mean_density", st.mean_density()},
                     {"mean_pressure", st.mean_pressure()},
                     {"mean_grid_pressure", st.mean_grid_pressure()},
                     {"peak_pressure", st.pressure_peak},
                     {"series", st.series}});
  }
  j["measurement_areas"] = areas;
  j["units"] = {{"time", "s"}, {"length", "m"}, {"density", "persons/m^2"}, {"flow_rate", "persons/s"},
                {"pressure", "model stress units (N/m per person of mass 1)"}};
  return j;
}

char fruin_level(double density) {
  if (!(density >= 0)) throw Error("level of service: density must be >= 0, got " + format_number(density));
  constexpr double kFt2 = 0.09290304;  // m^2 per square foot
  if (density == 0) return 'A';
  const double ft2_per_person = 1 / density / kFt2;
  if (ft2_per_person >= 35) return 'A';
  if (ft2_per_person >= 25) return 'B';
  if (ft2_per_person >= 15) return 'C';
  if (ft2_per_person >= 10) return 'D';
  if (ft2_per_person >= 5) return 'E';
  return 'F';
}

}  // namespace crowdmpm
