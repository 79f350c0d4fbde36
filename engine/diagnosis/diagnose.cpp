#include "engine/diagnosis/diagnose.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <unordered_map>

#include "engine/core/input.hpp"
#include "engine/core/output.hpp"
#include "engine/core/parallel.hpp"
#include "engine/io/render.hpp"

namespace crowdmpm {
namespace {

const double kNan = std::numeric_limits<double>::quiet_NaN();
// How far along its line from the opening a constriction is judged, and its opening read (m).
const double kConstrictionSpan = 5;

// Report names of the laws (the and DESIGN.md's vocabulary) and back.
std::string report_type(const TermLaw* law) {
  const std::string t = law->type();
  if (t == "uniform") return "drift";
  if (t == "radial") return "attractor";
  if (t == "constriction") return "obstacle";  // an unmodelled solid, of another shape (report_params says which)
  return t;
}

bool is_constriction(const Term& t) { return std::string(t.law->type()) == "constriction"; }
// A constriction's unit direction along its wall, (-sin angle, cos angle).
Vec2 wall_direction(const Term& t) {
  const double a = t.params[3] * M_PI / 180;
  return Vec2(-std::sin(a), std::cos(a));
}
// The pieces of a constriction's wall, beside its opening, that stand in the walkable space at
// least `clearance` from the venue's own solids (sampled every 5 cm).
std::vector<std::pair<Vec2, Vec2>> wall_pieces(const Term& t, const Geometry& geo, double clearance) {
  const Vec2 c(t.params[0], t.params[1]), along = wall_direction(t);
  const double half = 0.5 * t.params[2], span = (geo.hi - geo.lo).norm(), step = 0.05;
  std::vector<std::pair<Vec2, Vec2>> pieces;
  for (const double k : {1.0, -1.0}) {
    bool open = false;
    for (double s = half; s < span; s += step) {
      const Vec2 q = c + k * s * along;
      const bool stands = geo.in_domain(q) && geo.sdf(q) > clearance;
      if (stands && !open) pieces.emplace_back(q, q);
      if (stands) pieces.back().second = q;
      open = stands;
    }
  }
  return pieces;
}

// A term's name within the diagnosis (progress lines, and what each step does with it): its
// report type, a constriction by its own name (its report type is "obstacle").
std::string term_name(const Term& t) { return is_constriction(t) ? "constriction" : report_type(t.law); }

// Report names of a term's parameters: {x, y, radius}, {ax, ay}, {xmin, ymin, xmax, ymax, factor}...
json report_params(const Term& t) {
  static const std::map<std::string, std::string> rename = {
      {"center.x", "x"},     {"center.y", "y"},     {"acceleration.x", "ax"}, {"acceleration.y", "ay"},
      {"min.x", "xmin"},     {"min.y", "ymin"},     {"max.x", "xmax"},        {"max.y", "ymax"},
      {"from.x", "x0"},      {"from.y", "y0"},      {"to.x", "x1"},           {"to.y", "y1"}};
  json p = json::object();
  if (is_constriction(t)) {
    // Reported as an obstacle: (x, y) the opening's centre, where the solid stands on both sides
    // beyond radius (half the opening), along the wall's line.
    p["shape"] = "constriction";
    p["radius"] = 0.5 * t.params[2];
  }
  const auto names = t.parameter_names();
  for (size_t k = 0; k < names.size(); ++k) {
    auto it = rename.find(names[k]);
    const double v = t.params[k];
    p[it == rename.end() ? names[k] : it->second] = std::abs(v) >= 1e300 ? json(nullptr) : json(v);
  }
  return p;
}

std::string num(double v, int digits = 2) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}
std::string point(const Vec2& p) { return "(" + num(p.x(), 1) + ", " + num(p.y(), 1) + ")"; }

// ---------------------------------------------------------------------------------------------
// Held-out and fitting windows.

struct Split {
  long train_from = 0, train_to = 0, heldout_from = 0, heldout_to = 0;  // frames
  std::vector<TrainWindow> fit, fit_validation, heldout;
};

TrainOptions fit_options(const DiagnoseOptions& d) {
  TrainOptions o;
  o.window = d.window;
  o.stride = d.stride;
  o.velocity_window = d.residual.velocity_window;
  o.speed_window = d.residual.speed_window;
  o.desired_speed = d.residual.desired_speed;
  o.params = d.params;
  o.learn_scalars = !d.params.empty();
  o.learn_network = false;
  o.iterations = d.iterations;
  o.learning_rate = d.learning_rate;
  o.batch = 4;
  o.eval_every = 5;
  o.patience = 4;
  o.lr_decay = 0.5;
  o.threads = d.threads;
  o.seed = d.seed;
  return o;
}

Split split_recording(const TrajectorySet& t, const DiagnoseOptions& d) {
  if (!(d.train_share > 0.2 && d.train_share < 0.9)) throw Error("diagnosis: train_share must be in (0.2, 0.9)");
  if (!(d.window > 0 && d.stride > 0)) throw Error("diagnosis: window and stride must be > 0 s");
  Split s;
  const TrainOptions o = fit_options(d);
  s.train_from = t.frame_min();
  s.heldout_to = t.frame_max();
  s.train_to = s.train_from + std::lround(d.train_share * static_cast<double>(s.heldout_to - s.train_from));
  s.heldout_from = s.train_to;
  const long length = std::lround(d.window * t.framerate), stride = std::max(1L, std::lround(d.stride * t.framerate));
  const long history = std::lround(std::max(o.velocity_window, o.speed_window) * t.framerate);
  std::vector<TrainWindow> fit;
  const auto speeds = speed_history_for(t, o.speed_window, o.desired_speed);
  for (long f = t.skip_gap(s.train_from + history, stride); f + length <= s.train_to; f = t.skip_gap(f + stride, stride)) {
    TrainWindow w = window_at(t, f, length, o, 0, speeds);
    if (!w.start.ids.empty()) fit.push_back(std::move(w));
  }
  for (long f = t.skip_gap(s.heldout_from, stride); f + length <= s.heldout_to; f = t.skip_gap(f + stride, stride)) {
    TrainWindow w = window_at(t, f, length, o, 0, speeds);
    if (!w.start.ids.empty()) s.heldout.push_back(std::move(w));
  }
  // Early stopping of every fit looks at the training part's last quarter (windows that do not
  // overlap the ones it fits), never at the held-out part.
  const size_t n_val = std::max<size_t>(1, fit.size() / 4);
  if (fit.size() < n_val + 2 || s.heldout.size() < 2)
    throw Error(t.source + ": too short to diagnose (" + std::to_string(fit.size()) + " fitting and " +
                std::to_string(s.heldout.size()) + " held-out windows of " + num(d.window, 1) +
                " s; needs at least 3 and 2): give a longer recording or shorter windows");
  const long val_start = fit[fit.size() - n_val].start.frame;
  for (size_t i = 0; i < fit.size(); ++i) {
    if (i >= fit.size() - n_val) s.fit_validation.push_back(std::move(fit[i]));
    else if (fit[i].start.frame + length <= val_start) s.fit.push_back(std::move(fit[i]));
  }
  if (s.fit.empty()) throw Error(t.source + ": too short to diagnose: no fitting window before the early-stopping ones");
  return s;
}

// Squared position errors of every person of every window (summed over the window's frames).
struct WindowErrors {
  std::vector<double> sq;
  std::vector<long> n;
  bool failed = false;
};

std::vector<WindowErrors> rollout_errors(const ScenarioDef& s, const Model& m, const std::vector<TrainWindow>& ws,
                                         DesiredSpeed ds, int threads) {
  const ScenarioDef windowed = window_scenario(s, false);
  std::vector<WindowErrors> out(ws.size());
  ThreadPool pool(std::max(1, threads));
  pool.parallel_for(ws.size(), [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) {
      const TrainWindow& tw = ws[i];
      WindowErrors& we = out[i];
      we.sq.assign(tw.start.ids.size(), 0);
      we.n.assign(tw.start.ids.size(), 0);
      try {
        WindowSim sim = start_window(windowed, m, tw.start, WindowOptions{1, ds});
        long done = 0;
        for (size_t k = 0; k < tw.seen.size(); ++k) {
          const long step = std::lround(static_cast<double>(k + 1) / tw.framerate / windowed.dt);
          sim.sim->run_steps(step - done);
          done = step;
          const World& w = sim.sim->world();
          for (size_t a = 0; a < sim.ids.size(); ++a) {
            if (!sim.ids[a] || !tw.seen[k][a].allFinite()) continue;
            const long idx = w.index_of(sim.ids[a]);
            if (idx < 0) continue;
            we.sq[a] += (w.x[static_cast<size_t>(idx)] - tw.seen[k][a]).squaredNorm();
            we.n[a] += 1;
          }
        }
      } catch (const Error&) {
        we.failed = true;
      }
    }
  }, 1);
  return out;
}

// Who of each window is counted (by window, by person).
using Membership = std::vector<std::vector<char>>;
// The people of each window passing within reach at its start or any frame seen (everyone for
// a venue-wide reach).
Membership members(const std::vector<TrainWindow>& ws, const Reach& reach) {
  Membership m(ws.size());
  const auto near = [&](const Vec2& x) { return segment_distance(x, reach.from, reach.to) <= reach.distance; };
  for (size_t i = 0; i < ws.size(); ++i) {
    const TrainWindow& tw = ws[i];
    m[i].assign(tw.start.ids.size(), reach.everyone());
    if (reach.everyone()) continue;
    for (size_t a = 0; a < tw.start.ids.size(); ++a) {
      bool in = near(tw.start.x[a]);
      for (size_t k = 0; k < tw.seen.size() && !in; ++k) in = tw.seen[k][a].allFinite() && near(tw.seen[k][a]);
      m[i][a] = in;
    }
  }
  return m;
}

// Errors per recorded person over the held-out windows they are in (a person is the unit of
// the comparisons: the windows overlap and one person's errors in them are not independent).
struct PersonErrors {
  double sq = 0, samples = 0;
  long windows = 0;  // held-out windows the person is compared in
};
struct ErrorStats {
  double rms = kNan;
  std::map<long, PersonErrors> person;  // by id
  bool failed = false;  // a simulation failed on some window
};
ErrorStats stats_of(const std::vector<WindowErrors>& e, const std::vector<TrainWindow>& ws, const Membership& m) {
  ErrorStats s;
  double sq = 0, n = 0;
  for (size_t i = 0; i < e.size(); ++i) {
    s.failed = s.failed || e[i].failed;
    for (size_t a = 0; a < e[i].sq.size(); ++a)
      if (m[i][a] && e[i].n[a] > 0) {
        PersonErrors& p = s.person[ws[i].start.ids[a]];
        p.sq += e[i].sq[a];
        p.samples += static_cast<double>(e[i].n[a]);
        p.windows += 1;
        sq += e[i].sq[a];
        n += static_cast<double>(e[i].n[a]);
      }
  }
  if (n > 0) s.rms = std::sqrt(sq / n);
  return s;
}

struct Comparison {
  double gain = 0, z = 0, score_before = 0, score_after = 0;
};
// Paired comparison over people (mean squared error of each, before minus after, in standard
// errors), and the information criterion n ln(MSE) + k ln(n) with n effective_sample_size of
// the people compared, in windows of `window` s every `stride` s.
Comparison compare(const ErrorStats& before, const ErrorStats& after, size_t k_before, size_t k_after, double stride,
                   double window) {
  Comparison c;
  c.score_after = std::numeric_limits<double>::infinity();
  if (after.failed || !(before.rms > 0) || !std::isfinite(after.rms)) {
    c.gain = -1;
    return c;
  }
  std::vector<double> d;
  std::vector<long> windows;
  for (const auto& [id, b] : before.person) {
    auto it = after.person.find(id);
    if (it == after.person.end() || !(b.samples > 0) || !(it->second.samples > 0)) continue;
    d.push_back(b.sq / b.samples - it->second.sq / it->second.samples);
    windows.push_back(b.windows);
  }
  const double n_eff = effective_sample_size(windows, stride, window);
  c.gain = 1 - after.rms / before.rms;
  if (d.size() < 2) return c;
  double mean = 0, var = 0;
  for (double v : d) mean += v;
  mean /= static_cast<double>(d.size());
  for (double v : d) var += (v - mean) * (v - mean);
  var /= static_cast<double>(d.size() - 1);
  const double n = static_cast<double>(d.size());
  c.z = var > 0 ? mean / std::sqrt(var / n) : (mean > 0 ? 1e9 : 0);
  c.score_before = n_eff * std::log(before.rms * before.rms) + static_cast<double>(k_before) * std::log(n_eff);
  c.score_after = n_eff * std::log(after.rms * after.rms) + static_cast<double>(k_after) * std::log(n_eff);
  return c;
}

// ---------------------------------------------------------------------------------------------
// Candidates.

Term make_term(const json& j) { return Term::parse(JsonReader(j, "candidate"), {}); }

double clampd(double v, double lo, double hi) { return std::max(lo, std::min(hi, v)); }

// An opening the recorded people pass through, read from where they cross a line.
struct Opening {
  Vec2 center = Vec2::Zero();
  double width = 0;
  long people = 0;    // crossing the line
  double offset = 0;  // of its line from where the search began, along the flow (m)
};
// Where the recorded people cross the line through `at` across the flow n (unit), walking with
// it, up to frame `last` and within `reach` of `at` along the line: the opening they pass
// through, as its middle and width. Each person counts once, where they last crossed (people
// shuffling forward in a queue cross a line many times); the crossings' 5th to 95th percentile
// along the line, taken as 90 % of the lane their centres use, plus a body on each side
// (centres pass a body radius from a post). Nothing with fewer than 10 people crossing.
std::optional<Opening> recorded_opening(const TrajectorySet& t, long last, const Vec2& at, const Vec2& n, double reach,
                                        double body_radius) {
  const Vec2 e(-n.y(), n.x());
  std::unordered_map<long, Vec2> previous;
  std::unordered_map<long, double> crossed;
  for (const TrackPoint& p : t.points) {  // sorted by frame
    if (p.frame > last) break;
    const Vec2 x(p.x, p.y);
    auto [it, fresh] = previous.try_emplace(p.id, x);
    if (fresh) continue;
    const double u0 = (it->second - at).dot(n), u1 = (x - at).dot(n);
    if (u0 < 0 && u1 >= 0) {
      const Vec2 cross = it->second + (x - it->second) * (u0 / (u0 - u1));
      const double along = (cross - at).dot(e);
      if (std::abs(along) <= reach) crossed[p.id] = along;
    }
    it->second = x;
  }
  if (crossed.size() < 10) return std::nullopt;
  std::vector<double> s;
  s.reserve(crossed.size());
  for (const auto& [id, along] : crossed) s.push_back(along);
  auto quantile = [&](double q) {
    const size_t k = std::min(s.size() - 1, static_cast<size_t>(q * static_cast<double>(s.size())));
    std::nth_element(s.begin(), s.begin() + static_cast<long>(k), s.end());
    return s[k];
  };
  const double lo = quantile(0.05), hi = quantile(0.95);
  Opening o;
  o.center = at + 0.5 * (lo + hi) * e;
  o.width = (hi - lo) / 0.9 + 2 * body_radius;
  o.people = static_cast<long>(s.size());
  return o;
}

// Where the recorded stream across the flow n through `at` is narrowest: of the lines across it
// every 0.25 m up to 1.5 m either side (in the walkable space), among those that at least half as
// many people cross as cross the most (recorded_opening, within the span a constriction is judged
// on), the nearest to `at` whose opening is at most 10 % wider than the narrowest's.
std::optional<Opening> narrowest_opening(const TrajectorySet& t, long last, const Vec2& at, const Vec2& n,
                                         const Geometry& geo, double body_radius) {
  std::vector<Opening> lines;
  long most = 0;
  for (int k = -6; k <= 6; ++k) {
    const Vec2 x = at + 0.25 * k * n;
    if (!geo.in_domain(x) || geo.sdf(x) <= 0.1) continue;
    if (auto o = recorded_opening(t, last, x, n, kConstrictionSpan, body_radius)) {
      o->offset = 0.25 * k;
      lines.push_back(*o);
      most = std::max(most, o->people);
    }
  }
  lines.erase(std::remove_if(lines.begin(), lines.end(), [&](const Opening& o) { return 2 * o.people < most; }),
              lines.end());
  double least = std::numeric_limits<double>::infinity();
  for (const Opening& o : lines) least = std::min(least, o.width);
  std::optional<Opening> chosen;
  for (const Opening& o : lines)
    if (o.width <= 1.1 * least && (!chosen || std::abs(o.offset) < std::abs(chosen->offset))) chosen = o;
  return chosen;
}

// The candidates of one region, initialised from what its residuals show (DESIGN.md section 6,
// step 3), and a constriction's opening from where the recorded people cross its line up to
// frame `last`. drift is initialised from the whole venue's mean residual. Each candidate is a
// list of starts, fitted each and the one with the lowest validation loss kept: an attractor's
// or vortex's range is fitted (a smooth edge 0.5 m wide) but learns only from the people near
// its edge, so it starts at twice the region's radius and at the radius (1.5-4 m both): a field
// reaching into the region's surroundings, or one as wide as the region the residuals show.
std::vector<std::vector<Term>> initial_candidates(const Cluster& c, const Vec2& global_mean, const Model& m, const Geometry& geo,
                                                  const TrajectorySet& t, long last, const std::vector<std::string>& types) {
  const double tau = m.params.tau;
  std::vector<double> ranges = {clampd(2 * c.radius, 1.5, 4)};
  if (clampd(c.radius, 1.5, 4) < ranges[0]) ranges.push_back(clampd(c.radius, 1.5, 4));
  std::vector<std::vector<Term>> out;
  for (const std::string& type : types) {
    if (type == "attractor" || type == "vortex") {
      const double strength = type == "attractor" ? -c.radial / tau : c.tangential / tau;
      std::vector<Term> starts;
      for (const double range : ranges) {
        const json j = {{"type", type}, {"center", {c.center.x(), c.center.y()}}, {"strength", clampd(strength, -5, 5)},
                        {"range", range}, {"edge", 0.5}, {"learn", {"center", "strength", "range"}}};
        starts.push_back(make_term(j));
      }
      out.push_back(std::move(starts));
      continue;
    }
    json j;
    if (type == "obstacle") {
      // The rim's stiffness stays at its default (a solid); where it is, how large and how early
      // people turn are fitted.
      j = {{"type", "obstacle"}, {"center", {c.hole.x(), c.hole.y()}}, {"radius", 0.4}, {"steer", 1},
           {"learn", {"center", "radius", "steer"}}};
    } else if (type == "constriction") {
      // A wall across the recorded flow, its opening in line with the region's middle, through
      // the hole (where the model puts people the recording lacks: beyond the wall), or at the
      // region's downstream end (people queue before it) where there is no hole.
      if (c.flow.norm() < 1e-6) continue;
      const Vec2 n = c.flow.normalized();
      double downstream = -1e300;
      if ((c.hole - c.center).norm() > 1e-9) {
        downstream = (c.hole - c.center).dot(n);
      } else {
        for (const Vec2& q : {c.lo, c.hi, Vec2(c.lo.x(), c.hi.y()), Vec2(c.hi.x(), c.lo.y())})
          downstream = std::max(downstream, (q - c.center).dot(n));
      }
      Vec2 at = c.center + downstream * n;
      // Back inside the walkable space if that lies in a wall or outside the domain.
      for (int k = 0; k < 40 && !(geo.in_domain(at) && geo.sdf(at) > 0.1); ++k) at -= 0.1 * n;
      // The opening where the recorded stream is narrowest; 1 m wide in line with the region's
      // middle where too few people cross there.
      double width = 1.0;
      if (const auto o = narrowest_opening(t, last, at, n, geo, m.params.body_radius)) {
        at = o->center;
        width = clampd(o->width, 0.4, 2 * kConstrictionSpan);
      }
      j = {{"type", "constriction"}, {"center", {at.x(), at.y()}}, {"width", width},
           {"angle", std::atan2(n.y(), n.x()) * 180 / M_PI}, {"steer", 1},
           {"learn", {"center", "width", "angle", "steer"}}};
    } else if (type == "drift") {
      const Vec2 a = global_mean / tau;
      j = {{"type", "drift"}, {"acceleration", {clampd(a.x(), -5, 5), clampd(a.y(), -5, 5)}}, {"learn", {"acceleration"}}};
    } else if (type == "slow_zone") {
      j = {{"type", "slow_zone"}, {"min", {c.lo.x(), c.lo.y()}}, {"max", {c.hi.x(), c.hi.y()}}, {"factor", 0.7},
           {"learn", {"min", "max", "factor"}}};
    } else if (type == "wall_friction") {
      // Along the whole straight wall nearest to the region (drag along one wall).
      const auto wall = straight_wall(geo, c.center);
      if (!wall) continue;
      const auto& [a, b] = *wall;
      j = {{"type", "wall_friction"}, {"from", {a.x(), a.y()}}, {"to", {b.x(), b.y()}}, {"coefficient", 1.0},
           {"range", 0.5}, {"learn", {"coefficient", "range"}}};
    } else if (type == "density_speed") {
      j = {{"type", "density_speed"}, {"gamma", kWeidmannGamma}, {"max_density", kWeidmannMaxDensity}, {"learn", {"gamma", "max_density"}}};
    } else if (type == "counterflow") {
      // The people walking another way leave a residual against the crowd's motion. A rollout
      // from the recorded state picks them by how they move (by_motion), not by a draw from
      // ids that are not the recording's: those not walking against that way at 0.3 m/s or
      // more, whether heading it or held up against the crowd. Pushed gently at the start
      // (0.3 m/s^2, people held up where they are; the fit raises it for people walking back):
      // from a walker's push (2.6) every person it picks is driven on and stays picked, and the
      // fit does not find its way back (on the suite's corridor counter-flow: validation loss
      // 0.251 from 2.6 against 0.184 from 0.3).
      const double angle = c.mean_residual.squaredNorm() > 0 ? std::atan2(c.mean_residual.y(), c.mean_residual.x()) * 180 / M_PI : 0;
      j = {{"type", "counterflow"}, {"min", {c.lo.x(), c.lo.y()}}, {"max", {c.hi.x(), c.hi.y()}}, {"direction", angle},
           {"share", 1.0}, {"push", 0.3}, {"by_motion", 1}, {"along", -0.3},
           {"learn", {"min", "max", "direction", "push", "along"}}};
    } else {
      continue;
    }
    out.push_back({make_term(j)});
  }
  return out;
}

// Where a fitted term acts, whose passers-by judge it: within a metre of an obstacle's rim,
// within an attractor's or vortex's range (at most 3 m), over a zone's extent, along a wall's
// segment as far out as its drag reaches (twice its decay length and half a metre, at least a
// metre), along a constriction's wall near its opening; everyone for the venue-wide terms.
Reach influence(const Term& t) {
  const std::string type = term_name(t);
  const auto& p = t.params;
  const auto disc = [](const Vec2& c, double r) { return Reach{c, c, r}; };
  if (type == "constriction") {
    // Along the wall's line, as far out as people turn towards the opening (its reach and a
    // metre, at most 3 m), over the opening and 5 m of wall on each side.
    const Vec2 c(p[0], p[1]), along = wall_direction(t);
    const double half = 0.5 * p[2] + kConstrictionSpan;
    return Reach{c - half * along, c + half * along, std::clamp(p[8] + 1.0, 1.0, 3.0)};
  }
  if (type == "obstacle") return disc(Vec2(p[0], p[1]), p[2] + 1.0);
  if (type == "attractor" || type == "vortex") return disc(Vec2(p[0], p[1]), std::clamp(p[3], 1.0, 3.0));
  if (type == "slow_zone" || type == "counterflow") {
    const Vec2 lo(p[0], p[1]), hi(p[2], p[3]);
    return disc(0.5 * (lo + hi), std::max(1.0, 0.5 * (hi - lo).norm()));
  }
  if (type == "wall_friction") return Reach{Vec2(p[0], p[1]), Vec2(p[2], p[3]), std::max(1.0, 2 * p[5] + 0.5)};
  return Reach{};
}

// Why a fitted term cannot be the physics it names (empty if it can): an obstacle must stand in
// the venue's free space and have a body; one inside a known wall, or of a few centimetres,
// only reshapes how people meet the walls the venue already has. A constriction's wall must
// stand in the free space beside its opening.
std::string implausible(const Term& t, const Geometry& geo) {
  const std::string type = term_name(t);
  if (type == "constriction") {
    // Its opening must lie in the walkable space, and its wall must stand in it somewhere
    // (a wall only inside known solids, or an opening wider than the space, is nothing new).
    const Vec2 c(t.params[0], t.params[1]);
    if (!geo.in_domain(c) || geo.sdf(c) <= 0) return "its opening's centre " + point(c) + " lies outside the walkable space";
    double standing = 0;
    for (const auto& [a, b] : wall_pieces(t, geo, 0.2)) standing += (b - a).norm();
    if (standing < 0.3)
      return "its wall stands in the walkable space over " + num(standing, 2) + " m only (below 0.3 m)";
    return {};
  }
  if (type != "obstacle") return {};
  const Vec2 c(t.params[0], t.params[1]);
  const double r = t.params[2];
  if (r < 0.1) return "its radius " + num(r) + " m is below 0.1 m";
  if (!geo.in_domain(c)) return "its centre " + point(c) + " lies outside the domain";
  // A centre inside a known solid is that solid reaching further out (a constriction, a wall's
  // protrusion) when the disc reaches at least 0.1 m into the walkable space.
  const double s = geo.sdf(c);
  if (s <= 0 && r + s < 0.1)
    return "it lies inside a known solid (reaches " + num(std::max(r + s, 0.0), 2) + " m out of it, below 0.1 m)";
  return {};
}

// Terms that act on the whole venue (judged on everyone, tried once a round).
bool is_global(const Term& t) { return influence(t).everyone(); }

struct FitResult {
  Model model;
  std::vector<Term> terms;
  double validation = 0;  // the fit's best validation loss (m2)
  bool ok = false;
  std::string error;
};
FitResult fit(const ScenarioDef& scenario, const std::vector<Term>& terms, const Model& start, const Split& sp,
              const DiagnoseOptions& d, bool lbfgs) {
  FitResult f;
  ScenarioDef s = scenario;
  s.terms = terms;
  TrainOptions o = fit_options(d);
  if (lbfgs) o.optimizer = TrainOptions::Optimizer::Lbfgs;
  try {
    const TrainResult r = train_on_windows({s}, sp.fit, sp.fit_validation, start, o);
    f.model = r.model;
    f.terms = r.terms.empty() ? terms : r.terms[0];
    f.validation = r.best_validation;
    f.ok = true;
  } catch (const Error& e) {
    f.error = e.what();
  }
  return f;
}

// "; v0_scale 0.85, tau 0.56" for progress lines: the fitted values of the parameters a fit learns.
std::string values_of(const Model& m, const std::vector<std::string>& params) {
  std::string s;
  for (const auto& p : params) s += (s.empty() ? "; " : ", ") + p + " " + num(m.get(p), 3);
  return s;
}

ScenarioDef with_terms(const ScenarioDef& s, const std::vector<Term>& terms) {
  ScenarioDef out = s;
  out.terms = terms;
  return out;
}

// The significant regions of one round: residuals of (scenario, model) on the training part
// and the null's largest cluster statistics.
struct Localisation {
  ResidualSet set;
  ResidualMap map;
  std::vector<Cluster> clusters;
  Vec2 global_mean = Vec2::Zero();
};
Localisation localise(const ScenarioDef& s, const Model& m, const TrajectorySet& t, const Split& sp,
                      const DiagnoseOptions& d, const TrackError& noise, int round, bool with_null) {
  Localisation l;
  l.set = recorded_residuals(s, m, t, sp.train_from, sp.train_to, d.residual);
  l.map = bin_residuals(l.set, s.geo, d.residual);
  l.clusters = find_clusters(l.map, l.set, d.residual);
  // The mean residual away from walls (a wall takes up a body force pushing people into it).
  double n = 0;
  for (const auto& r : l.set.velocity)
    if (s.geo.sdf(r.x) > 0.75) {
      l.global_mean += r.r;
      n += 1;
    }
  if (n > 0) l.global_mean /= n;
  if (!with_null || l.clusters.empty()) return l;
  std::vector<double> maxima;
  for (int k = 0; k < d.null_replicates; ++k) {
    const ResidualSet ns = null_residuals(s, m, t, sp.train_from, sp.train_to, d.residual, noise,
                                          d.seed + 1000 * static_cast<uint64_t>(round) + static_cast<uint64_t>(k));
    const ResidualMap nm = bin_residuals(ns, s.geo, d.residual);
    const auto nc = find_clusters(nm, ns, d.residual);
    maxima.push_back(nc.empty() ? 0.0 : nc.front().statistic);
  }
  assess_clusters(l.clusters, maxima, d.residual);
  return l;
}

std::string explain(const DiagnoseOptions& o, const DiagnosisResult& r);

}  // namespace

Reach term_reach(const Term& t) { return influence(t); }

const std::vector<std::string>& diagnosis_candidates() {
  static const std::vector<std::string> c = {"obstacle", "constriction", "drift", "attractor", "vortex", "slow_zone",
                                             "wall_friction", "density_speed", "counterflow"};
  return c;
}

namespace {
// straight_wall follows a wall in steps of this length (m), so the ends it finds from two points
// of one wall differ by up to a step; candidates starting that close are one (run_diagnosis).
constexpr double kWallStep = 0.25;
}  // namespace

std::optional<std::pair<Vec2, Vec2>> straight_wall(const Geometry& geo, const Vec2& x) {
  const Vec2 n = geo.normal(x);
  if (!n.allFinite() || n.squaredNorm() < 0.5) return std::nullopt;
  const Vec2 on = x - geo.sdf(x) * n, t(-n.y(), n.x());
  const auto continues = [&](const Vec2& q) {
    const Vec2 probe = q + 0.1 * n;
    if (!geo.in_domain(probe)) return false;
    const Vec2 m = geo.normal(probe);
    return std::abs(geo.sdf(probe) - 0.1) < 0.03 && m.allFinite() && m.dot(n) > 0.95;
  };
  if (!continues(on)) return std::nullopt;
  const double step = kWallStep, longest = 500;
  double back = 0, ahead = 0;
  while (back < longest && continues(on - (back + step) * t)) back += step;
  while (ahead < longest && continues(on + (ahead + step) * t)) ahead += step;
  if (back + ahead < 0.5) return std::nullopt;
  return std::make_pair(Vec2(on - back * t), Vec2(on + ahead * t));
}

double effective_sample_size(const std::vector<long>& windows, double stride, double window) {
  const double disjoint = window > 0 ? std::min(stride / window, 1.0) : 1.0;
  double n = 0;
  for (long w : windows) n += 1 + static_cast<double>(std::max(w, 1L) - 1) * disjoint;
  return n;
}

namespace {

// A request's "video": its source, its track method and options, and the tracks it gives as
// the job's recording.
void read_video_recording(const JsonReader& v, const std::string& base_dir, const InputPolicy& input, DiagnoseJob& job) {
  v.require_object();
  v.allow_only({"path", "calibration", "scale", "first", "frames", "fps", "method", "smoothing", "tracks", "body_radius", "head_radius", "contrast", "coast", "smoother", "smooth", "cell",
                "density", "presence", "seed_speed", "min_speed", "min_moving_share"});
  job.from_video = true;
  VideoSource& src = job.video;
  src.path = resolve_path(base_dir, v.string("path", std::nullopt));
  src.video.input = input;
  if (v.has("calibration") == v.has("scale")) v.fail("a video needs \"calibration\" (a calibration file) or \"scale\" (metres per pixel), one of them");
  if (v.has("calibration")) src.calibration = resolve_path(base_dir, v.string("calibration", std::nullopt));
  if (v.has("scale")) src.scale = v.in_range("scale", 1e-6, 100, std::nullopt);
  src.video.first = v.integer("first", 0, 1000000000, 0);
  src.video.count = v.integer("frames", 0, 1000000000, 0);
  if (src.video.count == 1) v.at("frames").fail("a video needs at least 2 frames for a flow field");
  src.video.fps = v.in_range("fps", 0, 1000, 0);
  // Farneback and a walking crowd's 0.2 m/s by default: against the filmed tracks of the rendered
  // suite (docs/diagnosis.md "From video") DIS saw walkers 35% slow and Farneback 12%, and
  // slower flow was mostly the halo flow smooths round each walker.
  src.flow.method = flow_method(v.one_of("method", {"dis", "farneback"}, std::string("farneback")));
  src.flow.smoothing = v.in_range("smoothing", 0, 0.99, 0);
  job.tracks.density = v.in_range("density", 0.01, 12, job.tracks.density);
  job.tracks.presence = v.in_range("presence", 0, 600, job.tracks.presence);
  job.tracks.seed_speed = v.in_range("seed_speed", 0, 10, job.tracks.seed_speed);
  src.field.min_speed = v.in_range("min_speed", 0, 10, 0.2);
  src.field.min_moving_share = v.in_range("min_moving_share", 0, 1, src.field.min_moving_share);
  job.trajectories_path = src.path;
  // The tracks are carried on a grid of their own, finer than the simulation's, covering the
  // whole view: a field splatted at the simulation's spacing (0.5 m) carries them through
  // anything smaller than a metre that the crowd walks round.
  src.cell = v.in_range("cell", 0.05, 2, 0.25);
  job.detect = v.one_of("tracks", {"detect", "flow"}, std::string("detect")) == "detect";
  // Keys of the other method would be ignored: name them.
  for (const char* k : job.detect ? std::vector<const char*>{"cell", "density", "presence", "seed_speed", "min_speed", "min_moving_share"}
                                  : std::vector<const char*>{"body_radius", "head_radius", "contrast", "coast", "smoother", "smooth"})
    if (v.has(k)) v.fail_at(k, std::string("applies to \"tracks\": \"") + (job.detect ? "flow" : "detect") + "\", not to the \"" +
                                   (job.detect ? "detect" : "flow") + "\" tracks asked for");
  job.detection.body_radius = v.in_range("body_radius", 0.05, 1, job.detection.body_radius);
  job.detection.head_radius = v.in_range("head_radius", 0, 1, job.detection.head_radius);
  if (!head_radius_fits(job.detection.head_radius, job.detection.body_radius))
    v.at("head_radius").fail("a head's radius must be 0 (positions at the body's blob) or 0.03 m up to the body's radius " +
                             format_number(job.detection.body_radius) + " m");
  job.detection.contrast = v.in_range("contrast", 0.1, 100, job.detection.contrast);
  job.detection.coast = v.in_range("coast", 0, 60, job.detection.coast);
  job.detection.smoother = v.one_of("smoother", {"rts", "none"}, std::string("rts")) == "rts";
  job.detection.smooth = v.in_range("smooth", 0, 10, job.detection.smooth);
  if (job.detect) {
    job.recording = detected_tracks(src, job.scenario.geo, job.detection, &job.track_noise);
  } else {
    const VideoFields vf = load_video_fields(src, nullptr);
    job.recording = flow_tracks(vf.flow, job.scenario.geo, job.tracks, src.path);
  }
}

}  // namespace

DiagnoseJob parse_diagnose_job(const json& request, const std::string& base_dir) {
  JsonReader r(request, "");
  r.require_object();
  r.allow_only({"scenario", "trajectories", "video", "model", "options", "input"});
  DiagnoseJob job;
  const InputPolicy input = input_policy(r);
  job.scenario_path = resolve_path(base_dir, r.string("scenario", std::nullopt));
  if (r.has("trajectories") == r.has("video")) r.fail("a diagnosis request needs \"trajectories\" or \"video\" (one of them)");
  job.scenario = ScenarioDef::load(job.scenario_path, input);
  // How the recording's tracks are smoothed: a video's detected tracks by the video's own
  // "smoother"; recorded trajectories by the options' (default rts), checked before the recording is read.
  std::string smoother = "rts";
  if (auto op = r.get("options")) {
    op->require_object();
    if (r.has("video") && op->has("smoother"))
      op->fail_at("smoother", "applies to \"trajectories\"; a video's tracks are smoothed by its own \"smoother\" (in \"video\")");
    smoother = op->one_of("smoother", {"rts", "none"}, smoother);
  }
  if (r.has("trajectories")) {
    job.trajectories_path = resolve_path(base_dir, r.string("trajectories", std::nullopt));
    job.recording = TrajectorySet::read(job.trajectories_path, 0, input);
    check_recording_scale(job.recording, job.scenario.geo, job.scenario.source);
  } else {
    read_video_recording(r.at("video"), base_dir, input, job);
  }
  if (!job.from_video && smoother == "rts") {
    job.track_noise = smooth_under_own_noise(job.recording);
    job.trajectories_smoothed = job.track_noise.position > 0;
  }
  job.model = r.has("model") ? Model::load(resolve_path(base_dir, r.string("model", std::nullopt)), input)
                             : job.scenario.model_or_default();
  if (job.model.material == MaterialKind::Elastic) r.fail_at("model", "diagnosis covers the crowd, fluid and social_force models, not elastic");
  DiagnoseOptions& o = job.options;
  if (auto op = r.get("options")) {
    op->require_object();
    op->allow_only({"train_share", "window", "stride", "horizon", "residual_stride", "cell", "time_bin", "z_threshold", "source_margin",
                    "null_replicates", "alpha", "max_terms", "min_gain", "min_gain_venue", "min_gain_z", "candidates", "params",
                    "iterations", "learning_rate", "baseline_restarts", "final_restarts", "threads", "seed", "desired_speed", "density_law", "baseline_optimizer",
                    "optimizer", "smoother"});
    o.train_share = op->in_range("train_share", 0.2, 0.9, o.train_share);
    o.window = op->in_range("window", 0.2, 30, o.window);
    o.stride = op->in_range("stride", 0.05, 30, o.stride);
    o.residual.horizon = op->in_range("horizon", 0.2, 10, o.residual.horizon);
    o.residual.stride = op->in_range("residual_stride", 0.05, 10, o.residual.stride);
    o.residual.cell = op->in_range("cell", 0.1, 10, o.residual.cell);
    o.residual.time_bin = op->in_range("time_bin", 0.5, 600, o.residual.time_bin);
    o.residual.source_margin = op->in_range("source_margin", 0, 100, o.residual.source_margin);
    o.residual.z_threshold = op->in_range("z_threshold", 1, 20, o.residual.z_threshold);
    o.null_replicates = static_cast<int>(op->in_range("null_replicates", 1, 100, o.null_replicates));
    o.alpha = op->in_range("alpha", 1e-9, 0.5, o.alpha);
    o.max_terms = static_cast<int>(op->in_range("max_terms", 0, 3, o.max_terms));
    o.min_gain = op->in_range("min_gain", 0, 1, o.min_gain);
    o.min_gain_venue = op->in_range("min_gain_venue", 0, 1, o.min_gain_venue);
    o.min_gain_z = op->in_range("min_gain_z", 0, 100, o.min_gain_z);
    o.iterations = static_cast<int>(op->in_range("iterations", 1, 10000, o.iterations));
    o.learning_rate = op->in_range("learning_rate", 1e-6, 10, o.learning_rate);
    o.baseline_restarts = op->integer("baseline_restarts", 0, 20, o.baseline_restarts);
    o.final_restarts = op->integer("final_restarts", 0, 20, o.final_restarts);
    o.baseline_lbfgs = op->one_of("baseline_optimizer", {"adam", "lbfgs"}, std::string(o.baseline_lbfgs ? "lbfgs" : "adam")) == "lbfgs";
    o.candidates_lbfgs = op->one_of("optimizer", {"adam", "lbfgs"}, std::string(o.candidates_lbfgs ? "lbfgs" : "adam")) == "lbfgs";
    o.threads = static_cast<int>(op->in_range("threads", 1, 256, o.threads));
    o.residual.threads = o.threads;
    o.seed = static_cast<uint64_t>(op->in_range("seed", 0, 9e15, static_cast<double>(o.seed)));
    const std::string ds = op->one_of("desired_speed", {"auto", "recording", "scenario", "observed", "free"}, std::string("auto"));
    o.auto_speed = ds == "auto";
    o.recording_speed = ds == "recording" || ds == "auto";
    o.density_law = op->boolean("density_law", o.density_law);
    o.residual.desired_speed = ds == "scenario" ? DesiredSpeed::Scenario : ds == "observed" ? DesiredSpeed::Observed : DesiredSpeed::Free;
    if (auto c = op->get("candidates")) {
      o.candidates.clear();
      for (size_t i = 0; i < c->size(); ++i) {
        const std::string name = c->item(i).as_string();
        const auto& known = diagnosis_candidates();
        if (std::find(known.begin(), known.end(), name) == known.end()) {
          std::string list;
          for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
          c->item(i).fail("unknown candidate \"" + name + "\" (known: " + list + ")");
        }
        o.candidates.push_back(name);
      }
    }
    if (auto p = op->get("params")) {
      o.params_given = true;
      for (size_t i = 0; i < p->size(); ++i) o.params.push_back(p->item(i).as_string());
    }
  }
  // A baseline that behaves like a crowd slows people where it is dense: a crowd material without
  // a speed-density law of its own gets Weidmann's (its parameters refitted with the baseline's).
  if (o.density_law && job.model.is_continuum() && !material_density_law(job.model.params)) {
    job.model.params.density_speed_gamma = kWeidmannGamma;
    job.model.params.density_speed_max = kWeidmannMaxDensity;
    job.density_law_added = true;
  }
  if (!o.params_given) {
    const std::vector<std::string> learnable = learnable_params(job.model);
    for (const char* name : {"v0_scale", "tau", "time_gap", "density_speed_gamma", "density_speed_max"})
      if (std::find(learnable.begin(), learnable.end(), name) != learnable.end()) o.params.push_back(name);
  }
  // Unknown or unlearnable parameter names fail here, naming them.
  const ParamMap check(Fitted::of(job.model, {job.scenario}), o.params, false, !o.params.empty());
  (void)check;
  return job;
}

// "desired_speed": "auto" keeps each person's own walking speed only where the baseline fitted
// with it has less than this share of the validation loss it has with everyone at the median
// free speed. A person's speed at a window's start carries whatever slowed them there, a
// concealed gate's queue included, so that reading hides part of what the diagnosis looks for:
// it is for crowds that one typical speed cannot fit at all (agents with paces of their own).
// Measured (validation loss, own / median): ORCA corridor recordings 0.15-0.29, the real
// CrowdQueue 030, AO_300 and uo-180-180-180 and -070 runs 0.72-1.06 (own speeds hid the CrowdQueue
// gate), the social-force suite's cases 0.89-1.9 (benchmarks/results/diagnosis.md).
constexpr double kOwnPaceShare = 0.5;

namespace {
// The least position noise (m, white) the null adds: a recording read as clean (real tracks
// read 1e-6 to 0.002 m) still differs from the model by more than rounding.
constexpr double kMinNullNoise = 0.005;

// Whether the recording's tracks were smoothed (a video's detected tracks by the video's
// "smoother", trajectories by the options'), under job.track_noise.
bool tracks_smoothed(const DiagnoseJob& job) {
  return job.from_video ? job.detect && job.detection.smoother : job.trajectories_smoothed;
}
}  // namespace

DiagnosisResult run_diagnosis(const DiagnoseJob& job, const DiagnoseProgress& progress) {
  DiagnoseOptions d = job.options;
  if (d.recording_speed) d.residual.desired_speed = DesiredSpeed::Scenario;  // the groups' speed, set below
  const TrajectorySet& t = job.recording;
  const auto t0 = std::chrono::steady_clock::now();
  auto say = [&](const std::string& s) {
    const double at = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (progress) progress("[" + num(at, 0) + " s] " + s);
  };
  DiagnosisResult res;
  const Split sp = split_recording(t, d);
  res.train_windows = static_cast<long>(sp.fit.size() + sp.fit_validation.size());
  res.heldout_windows = static_cast<long>(sp.heldout.size());
  res.train_end = static_cast<double>(sp.train_to) / t.framerate;
  res.heldout_start = static_cast<double>(sp.heldout_from) / t.framerate;
  res.heldout_end = static_cast<double>(sp.heldout_to) / t.framerate;
  res.tracking_noise = tracking_noise(t);
  // The errors the null adds to the model's own motion (step 4): those the recording's tracks
  // carry, at least kMinNullNoise of white noise. Smoothed tracks carry the smoother's
  // steady-state error, correlated from frame to frame, so that a velocity over the window errs
  // less than two independent position errors would make it (and the second differences of
  // smoothed tracks see next to none of it); raw tracks the white noise their second
  // differences show.
  const TrackError least = white_track_error(kMinNullNoise, d.residual.velocity_window, t.framerate);
  if (tracks_smoothed(job) && job.track_noise.position > 0) {
    const SmoothedError e = smoothed_error(job.track_noise, 1 / t.framerate, velocity_lag_frames(d.residual.velocity_window, t.framerate));
    res.null_error = {std::max(e.position, least.position), std::max(e.velocity, least.velocity)};
  } else {
    res.null_error = white_track_error(std::max(res.tracking_noise, kMinNullNoise), d.residual.velocity_window, t.framerate);
  }
  if (job.trajectories_smoothed)
    say("tracks smoothed under the noise they show: position " + num(job.track_noise.position, 4) + " m, acceleration " +
        num(job.track_noise.acceleration, 3) + " m^2/s^3");
  say("tracking noise " + num(res.tracking_noise, 3) + " m" + (job.trajectories_smoothed ? " left in the smoothed tracks" : "") + "; the null's error " +
      num(res.null_error.position, 4) + " m, " + num(res.null_error.velocity, 4) + " m/s; " + std::to_string(res.train_windows) + " fitting, " +
      std::to_string(res.heldout_windows) + " held-out windows");

  // The venue as the user believes it; with "desired_speed": "recording", its crowd walking at
  // the training part's typical free speed.
  ScenarioDef belief = job.scenario;
  const ScenarioDef belief_as_given = job.scenario;
  if (d.recording_speed) {
    res.free_speed = free_speed_distribution(t, d.residual.speed_window, sp.train_to, &job.model.params);
    for (GroupDef& g : belief.groups) {
      g.desired_speed = g.speed_min = g.speed_max = res.free_speed.median;
      g.speed_sd = 0;
    }
    say("desired speed " + num(res.free_speed.median, 2) + " m/s: the median free speed of " +
        std::to_string(res.free_speed.people) + " people in the training part (spread " + num(res.free_speed.sd, 2) + " m/s)");
  }

  // A fit run again from where it stopped (`again`: fresh optimiser state and learning rate) while
  // its validation loss falls by more than 0.1%, at most `runs` times; returns how many runs improved it.
  const auto fit_on = [&](FitResult& b, const std::function<FitResult(const FitResult&)>& again_from, int runs,
                          const std::vector<std::string>& params, const std::string& what) {
    int improved = 0;
    for (int k = 0; k < runs; ++k) {
      FitResult again = again_from(b);
      if (!again.ok || !(again.validation < b.validation * (1 - 1e-3))) break;
      say(what + " continued: validation loss " + num(b.validation, 4) + " -> " + num(again.validation, 4) + " m2" +
          values_of(again.model, params));
      b = std::move(again);
      ++improved;
    }
    return improved;
  };

  // 1. The baseline: the user's venue and model, its material refitted on the training part.
  FitResult now;  // the current model: the baseline, then with each accepted term
  now.model = job.model;
  now.terms = belief.terms;
  now.validation = std::numeric_limits<double>::quiet_NaN();  // of its fit
  now.ok = true;
  if (!d.params.empty()) {
    // One fit, continued while it improves (baseline_restarts), under the options' reading.
    const auto fit_baseline = [&](const ScenarioDef& venue, const DiagnoseOptions& o, const std::string& label) {
      FitResult b = fit(venue, venue.terms, job.model, sp, o, o.baseline_lbfgs);
      if (!b.ok) throw Error("diagnosis: the baseline could not be fitted" + label + ": " + b.error);
      fit_on(b, [&](const FitResult& f) { return fit(venue, f.terms, f.model, sp, o, o.baseline_lbfgs); }, o.baseline_restarts,
             o.params, "baseline fit" + label);
      return b;
    };
    FitResult b = fit_baseline(belief, d, d.auto_speed ? std::string(" (everyone at the median free speed)") : std::string());
    if (d.auto_speed) {
      // The other reading: each person at their own walking speed, the venue's groups as given.
      DiagnoseOptions own = d;
      own.recording_speed = false;
      own.residual.desired_speed = DesiredSpeed::Observed;
      FitResult o = fit_baseline(belief_as_given, own, " (everyone at their own speed)");
      res.validation_recording = b.validation;
      res.validation_observed = o.validation;
      const bool keep_own = o.validation < kOwnPaceShare * b.validation;
      say("desired speed: " + std::string(keep_own ? "each person's own walking speed" : "the median free speed") +
          " (baseline validation loss " + num(b.validation, 4) + " m2 at the median free speed, " + num(o.validation, 4) +
          " m2 at each person's own speed; the second is kept below " + num(kOwnPaceShare, 2) + " times the first)");
      if (keep_own) {
        d = own;
        belief = belief_as_given;
        b = std::move(o);
      }
    }
    now = std::move(b);
  }
  res.recording_speed = d.recording_speed;
  res.desired_speed = d.residual.desired_speed;
  res.scenario_terms = now.terms;
  for (Term& term : now.terms) term.learn.assign(term.params.size(), 0);
  res.baseline = now.model;
  const FitResult baseline = now;
  const std::vector<std::string> types = d.candidates.empty() ? diagnosis_candidates() : d.candidates;
  const DesiredSpeed ds = d.residual.desired_speed;
  // From here on the venue and options are fixed, and some fits are asked for twice from the same
  // start (a round's refit of its starting model is the report's first further fit of the
  // baseline, or of a final model that a last round left unchanged): each is made once, and each
  // model's held-out errors computed once.
  const auto key_of = [](const FitResult& f) {
    json key = {{"model", f.model.to_json()}, {"terms", json::array()}};
    for (const Term& term : f.terms) key["terms"].push_back(term.to_json());
    return key.dump();
  };
  std::map<std::string, FitResult> refits;  // by start and optimiser
  std::map<std::string, std::vector<WindowErrors>> heldout;  // by model
  const auto refit = [&](const FitResult& from, bool lbfgs) -> const FitResult& {
    const std::string k = key_of(from) + (lbfgs ? " lbfgs" : " adam");
    auto it = refits.find(k);
    if (it == refits.end()) it = refits.emplace(k, fit(belief, from.terms, from.model, sp, d, lbfgs)).first;
    return it->second;
  };
  const auto heldout_errors = [&](const FitResult& f) -> const std::vector<WindowErrors>& {
    const std::string k = key_of(f);
    auto it = heldout.find(k);
    if (it == heldout.end())
      it = heldout.emplace(k, rollout_errors(with_terms(belief, f.terms), f.model, sp.heldout, ds, d.threads)).first;
    return it->second;
  };
  const Membership everyone = members(sp.heldout, Reach{});
  // The fitted baseline's held-out errors: what every round's best term is compared with first,
  // and the "before" of the report.
  const std::vector<WindowErrors> baseline_err = heldout_errors(now);
  std::vector<WindowErrors> base_err = baseline_err;
  res.heldout_before = stats_of(base_err, sp.heldout, everyone).rms;
  say("baseline fitted: held-out error " + num(res.heldout_before, 3) + " m" + values_of(now.model, d.params));

  size_t after_terms = 0;  // accepted terms residual_after was made with (0: none made)
  for (int round = 0; round < std::max(1, d.max_terms); ++round) {
    const ScenarioDef current = with_terms(belief, now.terms);
    Localisation loc = localise(current, now.model, t, sp, d, res.null_error, round, true);
    if (round == 0) res.residual_before = loc.map;
    else {
      res.residual_after = loc.map;
      after_terms = res.terms.size();
    }
    std::vector<const Cluster*> significant;
    for (const Cluster& c : loc.clusters) {
      Region reg{c.center, c.radius, c.t_start, c.t_end, c.significance, c.statistic, round};
      res.regions.push_back(reg);
      if (c.significance < d.alpha && static_cast<int>(significant.size()) < d.max_regions) significant.push_back(&c);
    }
    say("round " + std::to_string(round + 1) + ": " + std::to_string(loc.clusters.size()) + " residual clusters, " +
        std::to_string(significant.size()) + " significant");
    if (significant.empty() || round >= d.max_terms) break;
    // Every candidate's fit also refits the baseline's parameters; what that alone gains is not
    // the term's. The baseline refitted once more the same way, with no new term, is the second
    // reference: a candidate is compared with whichever of the two predicts the people it is
    // judged on better.
    std::vector<WindowErrors> refit_err;
    Model refit_model = now.model;
    {
      const FitResult& again = refit(now, d.candidates_lbfgs);
      if (again.ok) {
        refit_err = heldout_errors(again);
        refit_model = again.model;
      }
    }
    const auto reference = [&](const Membership& m) {
      ErrorStats a = stats_of(base_err, sp.heldout, m);
      if (refit_err.empty()) return a;
      ErrorStats b = stats_of(refit_err, sp.heldout, m);
      return !b.failed && b.rms < a.rms ? b : a;
    };
    const ErrorStats base_global = reference(everyone);
    const double before_refit = stats_of(base_err, sp.heldout, everyone).rms;
    // Where the refit alone predicts everyone clearly better (by min_gain, what a local term must gain),
    // the baseline's fit had stopped short: the candidates start from the refit, or each would
    // spend its fit on that convergence and its term gain little against the refit. Otherwise
    // they start from the baseline the regions were found with (a refit that gains little may
    // still wander off along a flat direction: on an ORCA recording with a concealed gate, tau
    // 3.7 -> 6.4 s for 1.2 %, a start from which the gate's wall no longer fits).
    const bool from_refit = !refit_err.empty() && base_global.rms <= before_refit * (1 - d.min_gain);
    const Model& start = from_refit ? refit_model : now.model;
    say("  baseline refitted alone: held-out error " + num(base_global.rms, 3) + " m (was " + num(before_refit, 3) + " m)" +
        values_of(refit_model, d.params) + (from_refit ? "; candidates start from it" : ""));
    std::optional<size_t> best;
    std::vector<WindowErrors> best_err;
    FitResult best_fit;
    // Each significant region's local candidates, then the venue-wide ones once (judged on everyone).
    std::vector<std::pair<const Cluster*, std::vector<Term>>> trials, venue_wide;
    for (const Cluster* c : significant)
      for (std::vector<Term>& starts : initial_candidates(*c, loc.global_mean, now.model, belief.geo, t, sp.train_to, types)) {
        if (!is_global(starts.front())) trials.emplace_back(c, std::move(starts));
        else if (c == significant.front()) venue_wide.emplace_back(nullptr, std::move(starts));
      }
    for (auto& v : venue_wide) trials.push_back(std::move(v));
    // Two regions can start the same candidate (the same straight wall's friction, its ends
    // found from two points up to a wall step apart): it is fitted once.
    std::vector<Term> tried;
    for (auto& [c, starts] : trials) {
      const Term& fresh = starts.front();  // (C++17 lambdas cannot capture a structured binding)
      const auto same_start = [&](const Term& u) {
        if (u.law != fresh.law || u.params.size() != fresh.params.size() || u.learn != fresh.learn) return false;
        for (size_t k = 0; k < u.params.size(); ++k)
          if (!(std::abs(u.params[k] - fresh.params[k]) <= kWallStep)) return false;
        return true;
      };
      if (std::any_of(tried.begin(), tried.end(), same_start)) continue;
      tried.push_back(fresh);
      const int region_index = c ? static_cast<int>(c - loc.clusters.data()) +
                                       static_cast<int>(res.regions.size() - loc.clusters.size())
                                 : -1;
      Hypothesis h;
      h.round = round;
      h.region = region_index;
      h.from_refit = from_refit;
      say("  fitting " + term_name(fresh) + (c ? " at " + point(c->center) : std::string(" (whole venue)")));
      // From each start; the fit with the lowest validation loss (the training part's) is judged.
      FitResult f;
      Term cand = fresh;
      size_t differs = 0;  // the first parameter in which the starts differ, named in the progress lines
      while (differs + 1 < fresh.params.size() &&
             std::all_of(starts.begin(), starts.end(), [&](const Term& s0) { return s0.params[differs] == fresh.params[differs]; }))
        ++differs;
      for (const Term& from : starts) {
        std::vector<Term> trial = now.terms;
        trial.push_back(from);
        FitResult g = fit(belief, trial, start, sp, d, d.candidates_lbfgs);
        if (starts.size() > 1)
          say("    from " + from.parameter_names()[differs] + " " + num(from.params[differs], 2) + ": " +
              (g.ok ? "validation loss " + num(g.validation, 4) + " m2" : "fit failed: " + g.error));
        if (!f.ok || (g.ok && g.validation < f.validation)) {
          f = std::move(g);
          cand = from;
        }
      }
      if (!f.ok) {
        h.term = cand;
        h.why = "fit failed: " + f.error;
        h.heldout_error = h.heldout_error_global = kNan;
        res.hypotheses.push_back(h);
        continue;
      }
      h.term = f.terms.back();
      h.term.learn.assign(h.term.params.size(), 0);
      f.terms.back() = h.term;
      // Judged on the people the fitted term acts on (everyone for a venue-wide term).
      h.judged = influence(h.term);
      const Membership near = members(sp.heldout, h.judged);
      const ErrorStats base_region = reference(near);
      h.baseline_error = base_region.rms;
      std::vector<WindowErrors> err = rollout_errors(with_terms(belief, f.terms), f.model, sp.heldout, ds, d.threads);
      const ErrorStats region = stats_of(err, sp.heldout, near), global = stats_of(err, sp.heldout, everyone);
      h.heldout_error = region.rms;
      h.heldout_error_global = global.rms;
      // The term against a reference: its held-out gain, in standard errors, and the information
      // criterion; the reason it fails, or empty.
      const size_t k_term = cand.learned_count();
      const double min_gain = h.judged.everyone() ? d.min_gain_venue : d.min_gain;  // a venue-wide term's or a local one's
      const auto judge = [&](const ErrorStats& before) {
        const Comparison cmp = compare(before, region, 0, k_term, d.stride, d.window);
        h.baseline_error = before.rms;
        h.gain = cmp.gain;
        h.gain_z = cmp.z;
        h.score = cmp.score_after;
        h.baseline_score = cmp.score_before;
        if (!(cmp.gain >= min_gain)) return "held-out gain " + num(100 * cmp.gain, 1) + "% below " + num(100 * min_gain, 0) + "%";
        if (!(cmp.z >= d.min_gain_z)) return "gain " + num(cmp.z, 1) + " standard errors, below " + num(d.min_gain_z, 1);
        if (!(cmp.score_after < cmp.score_before)) return std::string("information criterion does not fall");
        return std::string();
      };
      const double global_change = global.rms / base_global.rms - 1;
      std::string why = implausible(h.term, belief.geo);
      // Nobody it acts on in the held-out part: nothing to judge it on (not a loss of 100 %).
      if (why.empty() && base_region.person.empty()) why = "nobody it acts on is in the held-out part";
      if (why.empty()) why = judge(base_region);
      if (why.empty() && !(global_change <= 0.02)) why = "held-out error of everyone rises by " + num(100 * global_change, 1) + "%";
      if (why.empty()) {
        // The third reference: the material parameters this fit refitted, without the term. A
        // fit may find better parameters than the round's refitted baseline did (a stochastic
        // optimiser, another start) with a term that does next to nothing; that gain is not the
        // term's.
        std::vector<Term> without = f.terms;
        without.pop_back();
        const ErrorStats alone = stats_of(rollout_errors(with_terms(belief, without), f.model, sp.heldout, ds, d.threads), sp.heldout, near);
        if (!alone.failed && alone.rms < base_region.rms) {
          why = judge(alone);
          if (!why.empty()) why = "against its own refitted parameters without it (" + num(alone.rms, 3) + " m): " + why;
        }
      }
      h.why = why.empty() ? "held-out gain " + num(100 * h.gain, 1) + "% (" + num(h.gain_z, 1) + " standard errors)" : why;
      const bool passes = why.empty();
      say("    " + term_name(cand) + ": region " + num(h.baseline_error, 3) + " -> " + num(region.rms, 3) + " m, " + h.why + values_of(f.model, d.params));
      res.hypotheses.push_back(h);
      if (passes && (!best || h.heldout_error_global < res.hypotheses[*best].heldout_error_global)) {
        best = res.hypotheses.size() - 1;
        best_err = std::move(err);
        best_fit = f;
      }
    }
    if (!best) break;
    Hypothesis& h = res.hypotheses[*best];
    h.accepted = true;
    now = std::move(best_fit);
    base_err = std::move(best_err);
    res.terms.push_back(h.term);
    if (res.terms.size() == 1) {
      res.region = h.judged;
    }
    say("accepted " + term_name(h.term) + ": " + h.why);
  }
  // The report's before and after: the baseline and the final model, each fitted on while it
  // improves (final_restarts), so that neither is compared short of its own convergence.
  std::vector<WindowErrors> before_err = baseline_err;
  if (!res.terms.empty() && !d.params.empty() && d.final_restarts > 0 && std::isfinite(baseline.validation) &&
      std::isfinite(now.validation)) {
    const auto converge = [&](FitResult& f, bool lbfgs, const std::string& what, std::vector<WindowErrors>& err,
                              DiagnosisResult::FurtherFits& further) {
      further.validation_first = f.validation;
      further.improving =
          fit_on(f, [&](const FitResult& from) { return refit(from, lbfgs); }, d.final_restarts, d.params, what);
      further.validation = f.validation;
      if (further.improving > 0) err = heldout_errors(f);
    };
    FitResult converged = baseline;
    converge(converged, d.baseline_lbfgs, "for the report: the baseline's fit", before_err, res.final_baseline);
    res.baseline = converged.model;
    converge(now, d.candidates_lbfgs, "for the report: the final model's fit", base_err, res.final_model);
    if (res.final_model.improving > 0) after_terms = 0;  // the residual map after is made again with it
    res.heldout_before = stats_of(before_err, sp.heldout, everyone).rms;
  }
  res.model = now.model;
  if (!res.terms.empty() && after_terms != res.terms.size()) {
    const ScenarioDef current = with_terms(belief, now.terms);
    res.residual_after = localise(current, now.model, t, sp, d, res.null_error, d.max_terms, false).map;
  } else if (res.terms.empty()) {
    res.residual_after = res.residual_before;
  }
  if (res.terms.empty()) res.region = d.report_reach;
  const Membership region = members(sp.heldout, res.region);
  res.region_before = stats_of(before_err, sp.heldout, region).rms;
  res.region_after = stats_of(base_err, sp.heldout, region).rms;
  res.heldout_after = stats_of(base_err, sp.heldout, everyone).rms;
  res.explanation = explain(d, res);
  return res;
}

// ---------------------------------------------------------------------------------------------
// The report.

namespace {
std::string describe(const Term& t) {
  const std::string type = term_name(t);
  const auto& p = t.params;
  if (type == "constriction")
    return "a wall across the flow (heading " + num(p[3], 0) + " degrees) with an opening of " + num(p[2]) + " m at " +
           point(Vec2(p[0], p[1]));
  if (type == "obstacle") return "an obstacle of radius " + num(p[2]) + " m at " + point(Vec2(p[0], p[1]));
  if (type == "drift") return "a uniform drift of (" + num(p[0]) + ", " + num(p[1]) + ") m/s^2";
  if (type == "attractor")
    return std::string(p[2] >= 0 ? "an attractor" : "a repeller") + " at " + point(Vec2(p[0], p[1])) + " of strength " +
           num(std::abs(p[2])) + " m/s^2 within " + num(p[3], 1) + " m";
  if (type == "vortex")
    return std::string("a ") + (p[2] >= 0 ? "counter-clockwise" : "clockwise") + " vortex at " + point(Vec2(p[0], p[1])) +
           " of strength " + num(std::abs(p[2])) + " m/s^2 within " + num(p[3], 1) + " m";
  if (type == "slow_zone")
    return "a slow zone [" + num(p[0], 1) + ", " + num(p[2], 1) + "] x [" + num(p[1], 1) + ", " + num(p[3], 1) +
           "] m where the desired speed is " + num(p[4]) + " times its own";
  if (type == "wall_friction")
    return "friction along the wall from " + point(Vec2(p[0], p[1])) + " to " + point(Vec2(p[2], p[3])) + " (" + num(p[4]) +
           " /s within " + num(p[5]) + " m)";
  if (type == "density_speed")
    return "a desired speed falling with density (Weidmann form, gamma " + num(p[0]) + " /m^2, stopping at " + num(p[1], 1) + " /m^2)";
  if (type == "counterflow") {
    const std::string box = "[" + num(p[0], 1) + ", " + num(p[2], 1) + "] x [" + num(p[1], 1) + ", " + num(p[3], 1) + "] m";
    if (p[8] != 1) return num(100 * p[5], 0) + "% of the people in " + box + " heading " + num(p[4], 0) + " degrees";
    return "the people in " + box +
           (p[9] < 0 ? " not walking against " + num(p[4], 0) + " degrees at " + num(-p[9]) + " m/s or more"
                     : " moving towards " + num(p[4], 0) + " degrees at more than " + num(p[9]) + " m/s") +
           " heading that way (pushed at " + num(p[6]) + " m/s^2)";
  }
  return "a " + type + " term";
}

std::string what_it_shows(const Term& t) {
  const std::string type = term_name(t);
  const auto& p = t.params;
  if (type == "constriction") return "Flow queues and narrows through " + point(Vec2(p[0], p[1])) + "; ";
  if (type == "obstacle") return "Flow slows and splits around " + point(Vec2(p[0], p[1])) + "; ";
  if (type == "drift") return "Everyone is pushed the same way; ";
  if (type == "attractor") return std::string("People are ") + (p[2] >= 0 ? "drawn towards " : "pushed away from ") + point(Vec2(p[0], p[1])) + "; ";
  if (type == "vortex") return "Flow turns around " + point(Vec2(p[0], p[1])) + "; ";
  if (type == "slow_zone") return "People walk slower in part of the venue; ";
  if (type == "wall_friction") return "People along a wall are held back; ";
  if (type == "density_speed") return "People slow down where the crowd is dense; ";
  if (type == "counterflow") return "Part of the crowd moves against the rest; ";
  return "";
}

std::string explain(const DiagnoseOptions& o, const DiagnosisResult& r) {
  std::string text;
  if (!r.terms.empty()) {
    text = what_it_shows(r.terms[0]) + describe(r.terms[0]) + " explains it; held-out error " + num(r.region_before) +
           " -> " + num(r.region_after) + " m for the people passing there (everyone: " + num(r.heldout_before) + " -> " +
           num(r.heldout_after) + " m).";
    for (size_t k = 1; k < r.terms.size(); ++k) text += " Then " + describe(r.terms[k]) + ".";
  } else {
    const Region* strongest = nullptr;
    for (const Region& g : r.regions)
      if (g.significance < o.alpha && (!strongest || g.statistic > strongest->statistic)) strongest = &g;
    if (!strongest)
      text = "No missing physics found: the fitted model and the recording differ no more than the model with tracking noise does (held-out error " +
             num(r.heldout_before) + " m).";
    else
      text = "Unexplained discrepancy at " + point(strongest->center) + " (radius " + num(strongest->radius, 1) + " m, " +
             num(strongest->t_start, 0) + "-" + num(strongest->t_end, 0) + " s, p = " + num(strongest->significance, 3) +
             "): no candidate term lowered the held-out error clearly (held-out error " + num(r.heldout_before) + " m).";
  }
  return text;
}

GridVelocityField residual_field(const ResidualMap& m, int min_people) {
  GridVelocityField f;
  f.origin = m.origin + Vec2(0.5 * m.cell, 0.5 * m.cell);
  f.dx = m.cell;
  f.nx = m.nx;
  f.ny = m.ny;
  f.velocity = m.mean;
  f.mask.assign(m.mean.size(), 0);
  for (size_t c = 0; c < m.mean.size(); ++c) f.mask[c] = m.people[c] >= min_people ? 1 : 0;
  return f;
}

// "(12.0, 2.2)" for a disc round a point, "the segment from (0.0, 0.0) to (24.0, 0.0)" otherwise.
std::string where(const Reach& r) {
  return r.from == r.to ? point(r.from) : "the segment from " + point(r.from) + " to " + point(r.to);
}
// "everyone", or the disc round it ({center, radius}) and, along a segment, its ends and the distance.
json reach_json(const Reach& r) {
  if (r.everyone()) return "everyone";
  json j = {{"center", {r.center().x(), r.center().y()}}, {"radius", r.radius()}};
  if (r.from != r.to) {
    j["from"] = {r.from.x(), r.from.y()};
    j["to"] = {r.to.x(), r.to.y()};
    j["distance"] = r.distance;
  }
  return j;
}

std::string error_unit(const DiagnoseOptions& o) {
  return "m: root-mean-square position error over " + num(o.window, 1) + " s rollouts from the recorded state, held-out part";
}
}  // namespace

json diagnosis_json(const DiagnoseJob& job, const DiagnosisResult& r) {
  // The noise levels the recording's tracks were smoothed under (a video's detected tracks, or trajectories).
  const json smoother = tracks_smoothed(job) ? json{{"method", "rts"},
                                        {"position_noise_m", job.track_noise.position},
                                        {"acceleration_noise_m2_s3", job.track_noise.acceleration},
                                        {"innovations", job.track_noise.samples}}
                                 : json("none");
  json verdict;
  if (!r.terms.empty()) {
    verdict = {{"type", report_type(r.terms[0].law)}, {"params", report_params(r.terms[0])}};
  } else {
    verdict = {{"type", "none"}, {"params", json::object()}};
  }
  verdict["heldout_error_before"] = r.region_before;
  verdict["heldout_error_after"] = r.region_after;
  verdict["heldout_error_global_before"] = r.heldout_before;
  verdict["heldout_error_global_after"] = r.heldout_after;
  verdict["error_unit"] = error_unit(job.options) +
                          (r.region.everyone() ? ", everyone"
                                               : ", people passing within " + num(r.region.distance, 1) + " m of " + where(r.region) +
                                                     (r.terms.empty() ? " (the report's region asked for; global figures beside)"
                                                                      : ", where the first term acts (global figures beside)"));
  verdict["explanation"] = r.explanation;
  json regions = json::array();
  for (const Region& g : r.regions)
    regions.push_back({{"center", {g.center.x(), g.center.y()}}, {"radius", g.radius}, {"t_start", g.t_start},
                       {"t_end", g.t_end}, {"significance", g.significance}, {"statistic", g.statistic}, {"round", g.round + 1}});
  json hyps = json::array();
  for (const Hypothesis& h : r.hypotheses) {
    auto fin = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
    hyps.push_back({{"type", report_type(h.term.law)}, {"params", report_params(h.term)}, {"heldout_error", fin(h.heldout_error)},
                    {"heldout_error_global", fin(h.heldout_error_global)}, {"baseline_error", fin(h.baseline_error)},
                    {"score", fin(h.score - h.baseline_score)}, {"gain", fin(h.gain)}, {"gain_z", fin(h.gain_z)},
                    {"round", h.round + 1}, {"region", h.region}, {"accepted", h.accepted}, {"reason", h.why},
                    {"judged_on", reach_json(h.judged)}, {"fit_start", h.from_refit ? "refitted baseline" : "baseline"},
                    {"term", h.term.to_json()}});
  }
  json terms = json::array();
  for (const Term& t : r.terms) {
    json j = t.to_json();
    j["report_type"] = report_type(t.law);
    j["params"] = report_params(t);
    terms.push_back(j);
  }
  // The believed scenario's own force terms, those it marks "learn" as the baseline fitted them.
  json scenario_terms = json::array();
  for (const Term& t : r.scenario_terms) scenario_terms.push_back(t.to_json());
  json speed = {{"mode", r.recording_speed ? "recording" : desired_speed_name(r.desired_speed)}};
  if (job.options.auto_speed && std::isfinite(r.validation_recording)) {
    speed["chosen_by"] = "desired_speed auto: each person's own speed (observed) where the baseline fitted with it has less than " +
                         format_number(kOwnPaceShare) + " times the validation loss it has with everyone at the median free speed (recording)";
    speed["validation_loss_recording_m2"] = r.validation_recording;
    speed["validation_loss_observed_m2"] = r.validation_observed;
  }
  if (r.recording_speed) {
    speed["speed"] = r.free_speed.median;
    speed["spread"] = r.free_speed.sd;
    speed["people"] = r.free_speed.people;
    speed["effective"] = r.free_speed.median * r.baseline.params.v0_scale;
    const bool law = material_density_law(job.model.params);
    speed["definition"] = "every person walks at the median free speed (m/s, times the fitted v0_scale: effective) of the training part's people, each person's free speed the 90th percentile of their speed over " +
                          num(job.options.residual.speed_window, 1) + " s along their track" +
                          (law ? ", each speed divided by the starting model's speed-density factor at the density ahead of them (the speed they would walk if nobody were ahead)" : "") +
                          "; spread: 1.4826 x the median absolute deviation";
  }
  const auto further = [](const DiagnosisResult::FurtherFits& f) {
    return json{{"improving_fits", f.improving}, {"validation_first", f.validation_first}, {"validation", f.validation}};
  };
  json final_fits = nullptr;
  if (r.final_model.validation_first > 0)
    final_fits = {{"definition", "before the held-out errors before and after were taken, the baseline and the final model were each fitted again while the validation loss (m^2, training part) fell by more than 0.1%, at most final_restarts times"},
                  {"baseline", further(r.final_baseline)},
                  {"model", further(r.final_model)}};
  return {{"format", "crowdmpm-diagnosis"},
          {"version", 1},
          {"scenario", job.scenario_path},
          {"trajectories", job.trajectories_path},
          {"verdict", verdict},
          {"regions", regions},
          {"hypotheses", hyps},
          {"terms", terms},
          {"scenario_terms", scenario_terms},
          {"score_definition", "n ln(MSE) + k ln(n) over the people passing the hypothesis' region (everyone for a venue-wide term), n the disjoint windows their held-out time spans (the effective sample size), k the term's fitted parameters, minus the same of the baseline (lower is better)"},
          {"tracking_noise_m", r.tracking_noise},
          {"null_error", {{"position_m", r.null_error.position}, {"velocity_m_s", r.null_error.velocity}}},
          {"desired_speed", speed},
          {"density_law", job.density_law_added ? "Weidmann's speed-density law added to the model's material (gamma " + format_number(kWeidmannGamma) +
                                                    ", max " + format_number(kWeidmannMaxDensity) +
                                                    " persons/m^2), its gamma and max refitted with the baseline (baseline_model)"
                          : material_density_law(job.model.params) ? "the model's own speed-density law"
                                                                   : "none"},
          {"split", {{"train_end_s", r.train_end}, {"heldout_start_s", r.heldout_start}, {"heldout_end_s", r.heldout_end},
                     {"train_windows", r.train_windows}, {"heldout_windows", r.heldout_windows}}},
          {"baseline_model", r.baseline.to_json()},
          {"final_fits", final_fits},
          {"recording", job.from_video ? json{{"video", job.video.path},
                                              {"tracks", job.detect ? "people detected in its frames and followed by its optical flow (video_tracks.txt)"
                                                                    : "points carried by its flow fields (video_tracks.txt)"},
                                              {"tracks_method", job.detect ? "detect" : "flow"},
                                              {"smoother", smoother},
                                              {"tracks_count", job.recording.person_count()}}
                                       : json{{"trajectories", job.trajectories_path},
                                              {"people", job.recording.person_count()},
                                              {"smoother", smoother}}}};
}

void write_diagnosis(const DiagnoseJob& job, const DiagnosisResult& res, const std::string& out_dir) {
  namespace fs = std::filesystem;
  prepare_output_folder(out_dir);
  const DiagnosisResult& r = res;
  const std::string& text = r.explanation;
  save_json_file(diagnosis_json(job, r), (fs::path(out_dir) / "report.json").string());
  {
    std::ofstream f(fs::path(out_dir) / "summary.txt");
    f << text << "\n";
    for (const Hypothesis& h : r.hypotheses)
      f << "  round " << h.round + 1 << ": " << describe(h.term) << ": held-out error " << num(h.baseline_error, 3) << " -> "
        << num(h.heldout_error, 3) << " m" << (h.accepted ? " (accepted)" : "") << "; " << h.why << "\n";
    if (!f) throw Error(out_dir + "/summary.txt: cannot write");
  }
  const View view = View::fit(job.scenario.geo, 0);
  double vmax = 0;
  for (const ResidualMap* m : {&r.residual_before, &r.residual_after})
    for (size_t c = 0; c < m->mean.size(); ++c)
      if (m->people[c] >= job.options.residual.min_people) vmax = std::max(vmax, m->mean[c].norm());
  vmax = vmax > 0 ? vmax : 1;
  std::vector<std::pair<Vec2, double>> circles;
  for (const Region& g : r.regions)
    if (g.round == 0 && g.significance < job.options.alpha) circles.emplace_back(g.center, g.radius);
  const int mp = job.options.residual.min_people;
  write_velocity_png((fs::path(out_dir) / "residual_before.png").string(), job.scenario.geo, view,
                     residual_field(r.residual_before, mp), vmax, "residual velocity, fitted baseline (training part)", 1, circles);
  std::vector<std::pair<Vec2, double>> found;
  std::vector<std::pair<Vec2, Vec2>> walls;
  for (const Term& t : r.terms) {
    const std::string type = term_name(t);
    if (type == "constriction") {
      // Its wall on both sides of the opening, where it stands in the walkable space.
      for (const auto& piece : wall_pieces(t, job.scenario.geo, 0)) walls.push_back(piece);
    } else if (type == "obstacle") {
      found.emplace_back(Vec2(t.params[0], t.params[1]), t.params[2]);
    } else if (type == "attractor" || type == "vortex") {
      found.emplace_back(Vec2(t.params[0], t.params[1]), std::min(t.params[3], 3.0));
    }
  }
  write_velocity_png((fs::path(out_dir) / "residual_after.png").string(), job.scenario.geo, view,
                     residual_field(r.residual_after, mp), vmax,
                     r.terms.empty() ? "residual velocity: no term accepted" : "residual velocity with the accepted terms", 1, found,
                     walls);
  // The venue with the accepted terms and the refitted model, ready to simulate.
  json sc = ScenarioDef::load_json(job.scenario_path);
  sc["model"] = r.model.to_json();
  json forces = json::array();
  for (const Term& t : r.scenario_terms) forces.push_back(t.to_json());
  for (const Term& t : r.terms) forces.push_back(t.to_json());
  sc["forces"] = forces;
  if (r.recording_speed)  // the crowd's speeds as read from the recording, which v0_scale was fitted to
    for (const char* key : {"groups", "sources"})
      if (sc.contains(key))
        for (json& g : sc[key]) g["desired_speed"] = {{"mean", r.free_speed.median}, {"sd", r.free_speed.sd}};
  save_json_file(sc, (fs::path(out_dir) / "scenario.json").string());
  save_json_file(r.model.to_json(), (fs::path(out_dir) / "model.json").string());
  if (job.from_video) {
    TrajectoryWriter w((fs::path(out_dir) / "video_tracks.txt").string(), job.recording.framerate,
                       job.detect ? "people detected in " + job.video.path + " and followed by its optical flow"
                                  : "tracks carried by the flow of " + job.video.path + " at " + num(job.tracks.density, 2) + " persons/m2");
    w.write_points(job.recording);
    w.close();
  }
}

}  // namespace crowdmpm
