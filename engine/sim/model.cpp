#include "engine/sim/model.hpp"

namespace crowdmpm {

namespace {
const char* const kDefaultModelJson =
#include "default_model.inc"
    ;
}

const std::vector<ParamInfo>& param_table() {
  static const std::vector<ParamInfo> table = {
      {"E", &MaterialParams::E, 0, 1e6, "stress units (N per person per m)", kContinuum, false},
      {"gamma", &MaterialParams::gamma, 0.1, 10, "1", kContinuum, false},
      {"tension_scale", &MaterialParams::tension_scale, 0, 1, "1", kContinuum, false},
      {"tau", &MaterialParams::tau, 0.01, 10, "s", kContinuum | kSocialForce, false},
      {"v0_scale", &MaterialParams::v0_scale, 0, 5, "1", kContinuum | kSocialForce, false},
      {"comfort_distance", &MaterialParams::comfort_distance, 0.01, 2, "m", kContinuum, true},
      {"body_radius", &MaterialParams::body_radius, 0.05, 0.5, "m", kFixed, true},
      {"rest_density", &MaterialParams::rest_density, 0.1, 10, "persons/m^2", kFixed, true},
      {"mass", &MaterialParams::mass, 1e-3, 1e3, "1 per person", kFixed, true},
      {"poisson_ratio", &MaterialParams::poisson_ratio, 0, 0.49, "1", kFixed, false},
      // No adjoint of the wall friction yet: fixed in training.
      {"wall_friction", &MaterialParams::wall_friction, 0, 1, "1", kFixed, false},
      {"max_speed", &MaterialParams::max_speed, 0.1, 20, "m/s", kFixed, false},
      {"contact_epsilon", &MaterialParams::contact_epsilon, 1e-4, 0.1, "m", kFixed, false},
      {"wall_clearance", &MaterialParams::wall_clearance, 0, 0.5, "m", kFixed, true},
      {"shoulder_clearance", &MaterialParams::shoulder_clearance, 0, 0.5, "m", kFixed, false},
      {"alignment_time", &MaterialParams::alignment_time, 1e-3, 1e3, "s", kContinuum, false},
      {"time_gap", &MaterialParams::time_gap, 0, 5, "s", kContinuum, false},
      {"headway_gap", &MaterialParams::headway_gap, 0, 1, "m", kContinuum, false},
      // A hard lane edge: no gradient, fixed in training.
      {"headway_width", &MaterialParams::headway_width, 0.05, 1, "1", kFixed, false},
      {"density_speed_gamma", &MaterialParams::density_speed_gamma, 0, 50, "persons/m^2", kContinuum, false},
      {"density_speed_max", &MaterialParams::density_speed_max, 0.5, 12, "persons/m^2", kContinuum, false},
      {"density_opening_speed", &MaterialParams::density_opening_speed, 0, 5, "m/s", kContinuum, false},
      {"density_speed_floor", &MaterialParams::density_speed_floor, 0, 0.9, "1", kContinuum, false},
      // How the floor combines with Weidmann's factor (added or a max): set by hand, fixed in training.
      {"density_speed_floor_max", &MaterialParams::density_speed_floor_max, 0, 1, "1", kFixed, false},
      // The density ahead's kernel: set by hand (no adjoint with respect to its shape), fixed in training.
      {"density_speed_reach", &MaterialParams::density_speed_reach, 0.5, 5, "m", kFixed, false},
      {"density_speed_focus", &MaterialParams::density_speed_focus, 1, 8, "1", kFixed, false},
      // Routes are recomputed from the crowd's density once a second; held fixed through a
      // gradient window (no adjoint of the route choice).
      {"route_congestion", &MaterialParams::route_congestion, 0, 4, "1", kFixed, false},
      {"sf_A", &MaterialParams::sf_A, 0, 1e4, "m/s^2", kSocialForce, false},
      {"sf_B", &MaterialParams::sf_B, 0.01, 1, "m", kSocialForce, false},
      {"sf_k", &MaterialParams::sf_k, 0, 1e5, "1/s^2", kSocialForce, false},
      {"sf_kappa", &MaterialParams::sf_kappa, 0, 1e5, "1/(m s)", kSocialForce, false},
  };
  return table;
}

const char* material_name(MaterialKind k) {
  switch (k) {
    case MaterialKind::Crowd: return "crowd";
    case MaterialKind::Fluid: return "fluid";
    case MaterialKind::Elastic: return "elastic";
    case MaterialKind::SocialForce: return "social_force";
  }
  return "crowd";
}

Model Model::default_model() {
  return parse(JsonReader(parse_json_text(kDefaultModelJson, "<built-in default model>"), ""),
               "<built-in default model>");
}

Model Model::default_of(const std::string& kind) {
  Model m = default_model();
  if (kind == "crowd") return m;
  if (kind == "fluid") {
    m.material = MaterialKind::Fluid;
    m.params.tension_scale = 1;
  } else if (kind == "social_force") {
    m.material = MaterialKind::SocialForce;
    // Its wall force keeps bodies off walls (at r); the projection is only a backstop.
    m.params.shoulder_clearance = 0;
    m.params.tau = 0.5;  // Helbing, Farkas & Vicsek (2000)
    m.params.route_congestion = 0;  // the classic model: shortest paths
  } else if (kind == "elastic") {
    m.material = MaterialKind::Elastic;
  } else {
    throw Error("unknown model kind '" + kind + "' (known: crowd, fluid, elastic, social_force)");
  }
  m.traction = TractionNet();
  m.name = "default " + kind;
  return m;
}

Model Model::load(const std::string& path, const InputPolicy& policy) {
  json j = load_json_file(path, policy);
  try {
    return parse(JsonReader(j, ""), path);
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
}

Model Model::parse(const JsonReader& r, const std::string& source) {
  r.require_object();
  r.allow_only({"format", "version", "name", "description", "material", "parameters", "traction"});
  if (r.string("format", std::nullopt) != "crowdmpm-model")
    r.fail_at("format", "must be \"crowdmpm-model\"");
  int version = r.integer("version", 1, 1000, std::nullopt);
  if (version > kLatestVersion)
    r.fail_at("version", "unsupported model version " + std::to_string(version) + " (this engine reads 1 and 2)");
  Model m;
  m.version = version;
  if (version == 1) {  // the defaults of version 1 for parameters its files leave out
    m.params.time_gap = 0;
    m.params.rest_density = 2;
    m.params.tau = 0.5;
    m.params.comfort_distance = 0.3;
  }
  m.source = source;
  m.name = r.string("name", std::string());
  m.description = r.string("description", std::string());
  std::string kind = r.one_of("material", {"crowd", "fluid", "elastic", "social_force"}, "crowd");
  m.material = kind == "fluid"          ? MaterialKind::Fluid
               : kind == "elastic"      ? MaterialKind::Elastic
               : kind == "social_force" ? MaterialKind::SocialForce
                                        : MaterialKind::Crowd;
  if (m.material == MaterialKind::Fluid) m.params.tension_scale = 1;
  if (auto p = r.get("parameters")) {
    p->require_object();
    std::vector<std::string> names;
    for (const auto& info : param_table()) names.push_back(info.name);
    p->allow_only(names);
    for (const auto& info : param_table())
      m.params.*info.field = p->in_range(info.name, info.lo, info.hi, m.params.*info.field);
  }
  if (m.material == MaterialKind::Fluid && m.params.tension_scale != 1)
    r.fail_at("parameters.tension_scale", "the fluid material is symmetric: tension_scale must be 1");
  auto t = r.get("traction");
  if (m.material == MaterialKind::Crowd) {
    if (!t) r.fail_at("traction", "is required for material \"crowd\" (a network or {\"constant\": K})");
    m.traction = TractionNet::parse(*t);
  } else if (t) {
    t->fail(std::string("the ") + kind + " material has no traction network; remove this key");
  }
  return m;
}

json Model::to_json() const {
  json j;
  j["format"] = "crowdmpm-model";
  j["version"] = version;
  if (!name.empty()) j["name"] = name;
  if (!description.empty()) j["description"] = description;
  j["material"] = material_name(material);
  json p = json::object();
  for (const auto& info : param_table()) p[info.name] = params.*info.field;
  j["parameters"] = p;
  if (has_traction()) j["traction"] = traction.to_json();
  return j;
}

MaterialParams zero_params() {
  MaterialParams z;
  for (const auto& info : param_table()) z.*info.field = 0;
  return z;
}

std::string ParamInfo::not_learnable_in(const Model& m) const {
  if (m.material == MaterialKind::Elastic) return "the elastic material is not learned";
  if (m.material == MaterialKind::Fluid && field == &MaterialParams::tension_scale)
    return "the fluid material is symmetric: tension_scale is fixed at 1";
  if (field == &MaterialParams::time_gap && m.params.time_gap == 0)
    return "time_gap is 0 in the starting model (the headway adaptation is off): start from a value above 0 to learn it";
  if (field == &MaterialParams::headway_gap && (m.params.headway_gap == 0 || m.params.time_gap == 0))
    return m.params.time_gap == 0 ? "headway_gap belongs to the headway adaptation, which is off (time_gap 0)"
                                  : "headway_gap is 0 in the starting model: start from a value above 0 to learn it "
                                    "(it is learned in log coordinates)";
  if ((field == &MaterialParams::density_speed_gamma || field == &MaterialParams::density_speed_max) &&
      m.params.density_speed_gamma == 0)
    return std::string(name) + " belongs to the density-speed law, which is off in the starting model "
           "(density_speed_gamma 0): start from a value above 0 to learn it (it is learned in log coordinates)";
  // The law's opening speed and floor: learned only with the law on and from a start above 0.
  const bool opening = field == &MaterialParams::density_opening_speed, floor = field == &MaterialParams::density_speed_floor;
  if ((opening || floor) && (m.params.density_speed_gamma == 0 || m.params.*field == 0))
    return std::string(name) +
           (m.params.density_speed_gamma == 0
                ? " belongs to the density-speed law, which is off in the starting model (density_speed_gamma 0)"
                : std::string(" is 0 in the starting model (") +
                      (opening ? "everyone ahead counts in full" : "the law goes down to standstill") +
                      "): start from a value above 0 to learn it (it is learned in log coordinates)");
  if ((learned_by & (m.is_continuum() ? kContinuum : kSocialForce)) == 0)
    return std::string(name) + " is not learned by the " + material_name(m.material) + " model";
  return {};
}

const ParamInfo& param_info(const std::string& name) {
  for (const auto& info : param_table())
    if (name == info.name) return info;
  std::string list;
  for (const auto& info : param_table()) list += (list.empty() ? "" : ", ") + std::string(info.name);
  throw Error("unknown material parameter \"" + name + "\" (known: " + list + ")");
}

double Model::get(const std::string& param) const { return params.*param_info(param).field; }

void Model::set(const std::string& param, double value) {
  const auto& info = param_info(param);
  if (!(value >= info.lo && value <= info.hi))
    throw Error("material parameter " + param + " must be in [" + format_number(info.lo) + ", " +
                format_number(info.hi) + "] " + info.unit + ", got " + format_number(value));
  if (material == MaterialKind::Fluid && param == "tension_scale" && value != 1)
    throw Error("the fluid material is symmetric: tension_scale must be 1");
  params.*info.field = value;
}

}  // namespace crowdmpm
