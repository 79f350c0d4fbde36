#include "engine/sim/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace crowdmpm {

static std::string dir_of(const std::string& path) {
  auto pos = path.find_last_of('/');
  return pos == std::string::npos ? "." : path.substr(0, pos);
}

static Behaviour parse_behaviour(const JsonReader& r) {
  r.require_object();
  Behaviour b;
  b.path = r.path();
  std::string type = r.one_of("type", {"goal", "orbit", "attract", "heading", "none"}, std::nullopt);
  if (type == "none") {
    r.allow_only({"type"});
    b.kind = Behaviour::Kind::None;
  } else if (type == "heading") {
    r.allow_only({"type"});
    b.kind = Behaviour::Kind::Heading;
  } else if (type == "goal") {
    r.allow_only({"type", "target"});
    b.kind = Behaviour::Kind::Goal;
    b.target = r.string("target", "nearest_exit");
  } else if (type == "orbit") {
    r.allow_only({"type", "center", "around", "direction", "inward"});
    b.kind = Behaviour::Kind::Orbit;
    if (r.has("center") == r.has("around"))
      r.fail("orbit needs exactly one of \"center\" (a point) or \"around\" (the id of a goal or exit to circle)");
    if (r.has("center")) b.point = r.vec2("center", std::nullopt);
    else b.target = r.string("around", std::nullopt);
    b.sign = r.one_of("direction", {"ccw", "cw"}, "ccw") == "ccw" ? 1 : -1;
    b.inward = r.in_range("inward", -1, 1, 0.0);
  } else {
    r.allow_only({"type", "point", "arrive_radius"});
    b.kind = Behaviour::Kind::Attract;
    b.point = r.vec2("point", std::nullopt);
    b.arrive_radius = r.non_negative("arrive_radius", 0.5);
  }
  return b;
}

static void parse_agent_fields(const JsonReader& r, GroupDef& g) {
  g.velocity = r.vec2("velocity", Vec2::Zero());
  if (auto ds = r.get("desired_speed"); ds && ds->value().is_object()) {
    // A truncated normal distribution: each person draws their own free speed.
    ds->allow_only({"mean", "sd", "min", "max"});
    g.desired_speed = ds->in_range("mean", 0, 12, std::nullopt);
    g.speed_sd = ds->in_range("sd", 0, 5, std::nullopt);
    g.speed_min = ds->in_range("min", 0, 12, std::max(0.0, g.desired_speed - 3 * g.speed_sd));
    g.speed_max = ds->in_range("max", 0, 12, std::min(12.0, g.desired_speed + 3 * g.speed_sd));
    if (!(g.speed_min <= g.desired_speed && g.desired_speed <= g.speed_max))
      ds->fail("needs min <= mean <= max, got " + format_number(g.speed_min) + " <= " + format_number(g.desired_speed) +
               " <= " + format_number(g.speed_max));
  } else {
    g.desired_speed = r.in_range("desired_speed", 0, 12, 1.3);
    g.speed_min = g.speed_max = g.desired_speed;
  }
  if (r.has("body_radius")) g.body_radius = r.in_range("body_radius", 0.05, 0.5, std::nullopt);
  if (r.has("comfort_distance")) g.comfort_distance = r.in_range("comfort_distance", 0.01, 2, std::nullopt);
  g.behaviour = r.has("behaviour") ? parse_behaviour(r.at("behaviour")) : Behaviour{};
  if (!r.has("behaviour")) g.behaviour.kind = Behaviour::Kind::Goal, g.behaviour.target = "nearest_exit",
                           g.behaviour.path = r.child_path("behaviour");
}

static std::vector<NamedShape> parse_named_shapes(const JsonReader& arr, const std::string& what) {
  std::vector<NamedShape> out;
  for (size_t i = 0; i < arr.size(); ++i) {
    auto e = arr.item(i);
    e.require_object();
    NamedShape ns;
    ns.id = e.string("id", what + std::to_string(i));
    ns.shape = parse_region(e, {"id"});
    for (const auto& o : out)
      if (o.id == ns.id) e.fail_at("id", "duplicate id \"" + ns.id + "\"");
    out.push_back(std::move(ns));
  }
  return out;
}

ScenarioDef ScenarioDef::parse(const json& j, const std::string& source, const std::string& base_dir,
                               const InputPolicy& policy) {
  JsonReader r(j, "");
  r.require_object();
  // The format before the keys: a model file given as a scenario is named as one, not answered
  // with the keys a scenario allows.
  const std::string format = r.string("format", std::nullopt);
  if (format != "crowdmpm-scenario")
    r.fail_at("format", "must be \"crowdmpm-scenario\", got \"" + format + "\"" +
                            (format == "crowdmpm-model" ? ": a model file (give it with --model, or name it in a scenario's \"model\")" : ""));
  r.allow_only({"format", "version", "name", "description", "domain", "time", "seed", "model",
                "geometry", "goals", "groups", "sources", "forces", "measurement_areas", "outputs",
                "navigation"});
  int version = r.integer("version", 1, 1000, std::nullopt);
  if (version != 1) r.fail_at("version", "unsupported scenario version " + std::to_string(version) + " (this engine reads 1)");
  ScenarioDef s;
  s.document = j;
  s.source = source;
  s.base_dir = base_dir;
  s.name = r.string("name", "scenario");
  s.description = r.string("description", "");

  auto dom = r.at("domain");
  dom.require_object();
  dom.allow_only({"min", "max", "cell_size"});
  s.geo.lo = dom.vec2("min", std::nullopt);
  s.geo.hi = dom.vec2("max", std::nullopt);
  if (!(s.geo.hi.x() > s.geo.lo.x() && s.geo.hi.y() > s.geo.lo.y()))
    dom.fail_at("max", "must be greater than domain.min in both x and y");
  // Positions are doubles: at 1e8 m from the origin they still resolve 15 nm, far beyond that
  // the spacing of representable coordinates grows towards body sizes (0.125 m at 1e15 m) and
  // placement and motion lose their meaning. Venues are placed near the origin.
  for (const char* key : {"min", "max"}) {
    const Vec2 v = std::string(key) == "min" ? s.geo.lo : s.geo.hi;
    if (std::abs(v.x()) > kMaxCoordinate || std::abs(v.y()) > kMaxCoordinate)
      dom.fail_at(key, "coordinates must lie within +-" + format_number(kMaxCoordinate) + " m of the origin (got [" +
                           format_number(v.x()) + ", " + format_number(v.y()) +
                           "]): far from it, doubles cannot resolve positions finely enough; shift the venue towards the origin");
  }
  s.cell_size = dom.in_range("cell_size", 0.05, 10, 0.5);
  Vec2 ext = s.geo.hi - s.geo.lo;
  if (ext.x() / s.cell_size > 1e6 || ext.y() / s.cell_size > 1e6)
    dom.fail_at("cell_size", "gives more than 1e6 grid cells along one side of the domain (" + format_number(ext.x()) +
                                 " m x " + format_number(ext.y()) + " m); use a larger cell");
  if (ext.x() / s.cell_size * ext.y() / s.cell_size > 2e7)
    dom.fail_at("cell_size", "gives more than 2e7 grid cells for this domain (" + format_number(ext.x()) + " m x " +
                                 format_number(ext.y()) + " m); use a larger cell");

  // Default navigation cell: 0.1 m, coarser on venues so large that 0.1 m would exceed 1e7 cells.
  s.nav_cell = std::max(0.1, std::ceil(std::sqrt(ext.x() * ext.y() / 1e7) * 100) / 100);
  if (auto nav = r.get("navigation")) {
    nav->require_object();
    nav->allow_only({"cell_size"});
    s.nav_cell = nav->in_range("cell_size", 0.02, 5, s.nav_cell);
  }
  if (ext.x() / s.nav_cell * ext.y() / s.nav_cell > 2e7 || ext.x() / s.nav_cell > 1e6 || ext.y() / s.nav_cell > 1e6)
    r.fail_at("navigation.cell_size", "gives more than 2e7 navigation cells for this domain (" + format_number(ext.x()) +
                                          " m x " + format_number(ext.y()) + " m); set a larger navigation.cell_size");

  auto t = r.at("time");
  t.require_object();
  t.allow_only({"dt", "duration", "output_rate", "stop_when_empty"});
  s.dt = t.in_range("dt", 1e-5, 0.1, 0.01);
  s.duration = t.in_range("duration", 0, 1e6, std::nullopt);
  s.output_rate = t.positive("output_rate", 10.0);
  s.stop_when_empty = t.boolean("stop_when_empty", true);
  double spf = 1.0 / (s.output_rate * s.dt);
  if (spf < 1 - 1e-9) t.fail_at("output_rate", "is faster than the step rate 1/dt = " + format_number(1 / s.dt) + " per second");
  if (spf > 1e7) t.fail_at("output_rate", "is so low that one frame takes more than 10,000,000 steps");
  if (std::abs(spf - std::round(spf)) > 1e-6)
    t.fail_at("output_rate", "1/(output_rate * dt) must be a whole number of steps, got " + format_number(spf));

  s.seed = static_cast<uint64_t>(r.integer("seed", 0, 2147483647, 1));

  if (auto m = r.get("model")) {
    if (m->value().is_string()) {
      std::string name = m->as_string();
      if (name != "default") {
        try {
          s.model = Model::load(confined_path(base_dir, base_dir, name, policy, ""), policy);
        } catch (const Error& e) {
          m->fail(std::string("cannot load model: ") + e.what());
        }
      }
    } else {
      s.model = Model::parse(*m, source + " (model)");
    }
  }

  if (auto g = r.get("geometry")) {
    g->require_object();
    g->allow_only({"walls", "obstacles", "exits"});
    if (auto walls = g->get("walls"))
      for (size_t i = 0; i < walls->size(); ++i) s.geo.solids.push_back(parse_wall(walls->item(i)));
    if (auto obs = g->get("obstacles"))
      for (size_t i = 0; i < obs->size(); ++i) s.geo.solids.push_back(parse_region(obs->item(i), {"id"}));
    if (auto ex = g->get("exits")) s.geo.exits = parse_named_shapes(*ex, "exit");
  }
  if (auto goals = r.get("goals")) s.geo.goals = parse_named_shapes(*goals, "goal");
  for (const auto& gl : s.geo.goals)
    for (const auto& e : s.geo.exits)
      if (gl.id == e.id) r.fail_at("goals", "id \"" + gl.id + "\" is also an exit id");
  for (size_t i = 0; i < s.geo.exits.size(); ++i) {
    const Shape& e = s.geo.exits[i].shape;
    if (e.hi.x() <= s.geo.lo.x() || e.lo.x() >= s.geo.hi.x() || e.hi.y() <= s.geo.lo.y() || e.lo.y() >= s.geo.hi.y())
      r.fail_at("geometry.exits[" + std::to_string(i) + "]", "lies outside the domain (exits must be inside domain.min..max)");
    // People leave where their centre enters the exit: it needs a point clear of the solids.
    if (s.geo.free_area(e, 0) <= 0)
      r.fail_at("geometry.exits[" + std::to_string(i) + "]",
                "lies wholly inside walls or obstacles (or outside the domain): nobody can reach it (\"" + s.geo.exits[i].id + "\")");
  }

  auto check_target = [&](const Behaviour& b) {
    if (b.kind == Behaviour::Kind::Orbit && !b.target.empty() && !s.geo.find_target(b.target))
      throw Error(b.path + ".around: no exit or goal with id \"" + b.target + "\"");
    if (b.kind != Behaviour::Kind::Goal) return;
    if (b.target == "nearest_exit") {
      if (s.geo.exits.empty()) throw Error(b.path + ": behaviour goal \"nearest_exit\" needs at least one exit in geometry.exits");
    } else if (!s.geo.find_target(b.target)) {
      throw Error(b.path + ".target: no exit or goal with id \"" + b.target + "\"");
    }
  };
  std::vector<std::string> agent_keys = {"id", "velocity", "desired_speed", "body_radius", "comfort_distance", "behaviour"};
  if (auto groups = r.get("groups"))
    for (size_t i = 0; i < groups->size(); ++i) {
      auto gr = groups->item(i);
      gr.require_object();
      auto keys = agent_keys;
      keys.insert(keys.end(), {"spawn", "count", "density"});
      gr.allow_only(keys);
      GroupDef g;
      g.path = gr.path();
      g.id = gr.string("id", "group" + std::to_string(i));
      g.region = parse_region(gr.at("spawn"), {});
      bool has_count = gr.has("count"), has_density = gr.has("density");
      if (has_count == has_density) gr.fail("needs exactly one of \"count\" or \"density\"");
      if (has_count) g.count = gr.integer("count", 0, 10000000, std::nullopt);
      else g.density = gr.in_range("density", 1e-6, 12, std::nullopt);
      parse_agent_fields(gr, g);
      check_target(g.behaviour);
      s.groups.push_back(std::move(g));
    }
  if (auto sources = r.get("sources"))
    for (size_t i = 0; i < sources->size(); ++i) {
      auto sr = sources->item(i);
      sr.require_object();
      auto keys = agent_keys;
      keys.insert(keys.end(), {"region", "rate", "start", "end", "max_count"});
      sr.allow_only(keys);
      GroupDef g;
      g.is_source = true;
      g.path = sr.path();
      g.id = sr.string("id", "source" + std::to_string(i));
      g.region = parse_region(sr.at("region"), {});
      g.rate = sr.in_range("rate", 1e-6, 1e5, std::nullopt);
      g.start = sr.non_negative("start", 0.0);
      g.end = sr.number("end", s.duration);
      if (!(g.end > g.start)) sr.fail_at("end", "must be greater than start (" + format_number(g.start) + "), got " + format_number(g.end));
      if (g.start >= s.duration)
        sr.fail_at("start", "is at or after time.duration (" + format_number(s.duration) + " s): the source would never spawn");
      if (sr.has("max_count")) {
        g.max_count = sr.integer("max_count", 0, 10000000, std::nullopt);
      } else {
        double expected = std::ceil(g.rate * (std::min(g.end, s.duration) - g.start));
        if (expected > 1e7)
          sr.fail_at("rate", "spawns " + format_number(expected) + " people over its window, more than 10,000,000; set max_count or lower the rate");
        g.max_count = static_cast<int>(expected);
      }
      parse_agent_fields(sr, g);
      check_target(g.behaviour);
      s.groups.push_back(std::move(g));
    }
  for (size_t i = 0; i < s.groups.size(); ++i)
    for (size_t k = 0; k < i; ++k)
      if (s.groups[i].id == s.groups[k].id) throw Error(s.groups[i].path + ".id: duplicate group/source id \"" + s.groups[i].id + "\"");

  if (auto forces = r.get("forces")) {
    std::vector<std::string> group_ids;
    for (const auto& g : s.groups) group_ids.push_back(g.id);
    for (size_t i = 0; i < forces->size(); ++i) s.terms.push_back(Term::parse(forces->item(i), group_ids));
  }

  if (auto areas = r.get("measurement_areas"))
    for (size_t i = 0; i < areas->size(); ++i) {
      auto ar = areas->item(i);
      ar.require_object();
      MeasurementArea a;
      a.id = ar.string("id", "area" + std::to_string(i));
      a.shape = parse_region(ar, {"id", "from", "to"});
      a.from = ar.non_negative("from", 0.0);
      a.to = ar.number("to", 1e300);
      if (!(a.to > a.from)) ar.fail_at("to", "must be greater than from");
      for (const auto& o : s.areas)
        if (o.id == a.id) ar.fail_at("id", "duplicate measurement area id \"" + a.id + "\"");
      s.areas.push_back(a);
    }

  if (auto o = r.get("outputs")) {
    o->require_object();
    o->allow_only({"trajectories", "trajectories_sqlite", "fields", "pictures", "video", "metrics", "pixels_per_metre", "pressure_max", "density_max"});
    s.outputs.trajectories = o->boolean("trajectories", true);
    s.outputs.trajectories_sqlite = o->boolean("trajectories_sqlite", true);
    s.outputs.fields = o->boolean("fields", true);
    s.outputs.pictures = o->boolean("pictures", true);
    s.outputs.video = o->boolean("video", true);
    s.outputs.metrics = o->boolean("metrics", true);
    s.outputs.pixels_per_metre = o->in_range("pixels_per_metre", 0, 500, 0.0);
    s.outputs.pressure_max = o->non_negative("pressure_max", 0.0);
    s.outputs.density_max = o->positive("density_max", 8.0);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// "extends": a scenario written as changes to another (docs/scenario-format.md#extends).

namespace fs = std::filesystem;

namespace {

// Deep enough for a variant of a variant of a base, short enough that a mistake is reported
// rather than followed.
constexpr size_t kMaxExtendsChain = 16;

struct ChainFile {
  std::string name;  // as shown in messages
  std::string key;   // canonical path, to find a cycle however the path was spelled; "" for text
};

ChainFile chain_file(const std::string& path, const std::string& name) {
  std::error_code ec;
  fs::path canonical = fs::weakly_canonical(path, ec);
  return {name, ec ? path : canonical.string()};
}

// A scenario JSON with its "extends" chain applied. `chain` lists the files from the one the
// user named down to the one `j` came from (its last entry), whose folder is `dir`.
json apply_extends(json j, const std::string& dir, std::vector<ChainFile>& chain, const std::string& root,
                   const InputPolicy& policy) {
  if (!j.is_object() || !j.contains("extends")) return j;
  const std::string here = chain.back().name;
  auto fail = [&](const std::string& reason) { throw Error(here + ": extends: " + reason); };
  if (!j["extends"].is_string()) fail("must be a string: the file name of the base scenario, relative to this file's folder");
  const std::string rel = j["extends"].get<std::string>();
  std::string path;
  try {
    path = confined_path(root, dir, rel, policy, "");
  } catch (const Error& e) {
    fail(e.what());
  }
  const ChainFile base_file = chain_file(path, fs::path(path).lexically_normal().string());
  for (const auto& f : chain)
    if (f.key == base_file.key) {
      std::string cycle;
      for (const auto& g : chain) cycle += g.name + " -> ";
      fail("cycle " + cycle + base_file.name);
    }
  if (chain.size() >= kMaxExtendsChain)
    fail("more than " + std::to_string(kMaxExtendsChain) + " files extend one another; the chain starts at " + chain.front().name);
  std::string text;
  try {
    text = read_input_file(path, policy);
  } catch (const Error& e) {
    fail("cannot read '" + rel + "' (" + e.what() + ")");
  }
  json base = parse_json_text(text, base_file.name);
  if (!base.is_object()) fail("'" + rel + "' must hold a JSON object (a scenario)");
  chain.push_back(base_file);
  base = apply_extends(std::move(base), dir_of(path), chain, root, policy);
  // A relative model path is relative to the file that names it: seen from this file, a model
  // named by the base lies in the base's folder.
  const std::string base_folder = fs::path(rel).parent_path().string();
  auto model = base.find("model");
  if (!base_folder.empty() && model != base.end() && model->is_string()) {
    const std::string m = model->get<std::string>();
    if (m != "default" && !m.empty() && m[0] != '/') *model = base_folder + "/" + m;
  }
  j.erase("extends");
  base.merge_patch(j);  // RFC 7396: objects merge, anything else replaces, null deletes
  return base;
}

// What parse() validates, and the files it extends for messages (" (extends a.json, b.json)"
// or empty), since a JSON path in the merged scenario may point into any of them.
struct MergedScenario {
  json j;
  std::string bases;
};

MergedScenario merge_chain(json j, const std::string& dir, std::vector<ChainFile> chain, const InputPolicy& policy) {
  MergedScenario m{apply_extends(std::move(j), dir, chain, dir, policy), ""};
  for (size_t i = 1; i < chain.size(); ++i) m.bases += (i == 1 ? " (extends " : ", ") + chain[i].name;
  if (chain.size() > 1) m.bases += ")";
  return m;
}

MergedScenario merge_file(const std::string& path, const InputPolicy& policy) {
  return merge_chain(load_json_file(path, policy), dir_of(path), {chain_file(path, path)}, policy);
}

}  // namespace

ScenarioDef ScenarioDef::parse_text(const std::string& text, const std::string& base_dir, const InputPolicy& policy) {
  MergedScenario m = merge_chain(parse_json_text(text, "<scenario>"), base_dir, {{"<scenario>", ""}}, policy);
  try {
    return parse(m.j, "<scenario>", base_dir, policy);
  } catch (const Error& e) {
    if (m.bases.empty()) throw;  // text that extends nothing: the JSON path says it all
    throw Error("<scenario>" + m.bases + ": " + e.what());
  }
}

ScenarioDef ScenarioDef::load(const std::string& path, const InputPolicy& policy) {
  MergedScenario m = merge_file(path, policy);
  try {
    return parse(m.j, path, dir_of(path), policy);
  } catch (const Error& e) {
    throw Error(path + m.bases + ": " + e.what());
  }
}

json ScenarioDef::load_json(const std::string& path, const InputPolicy& policy) { return merge_file(path, policy).j; }

int ScenarioDef::steps_per_frame() const { return static_cast<int>(std::lround(1.0 / (output_rate * dt))); }

}  // namespace crowdmpm
