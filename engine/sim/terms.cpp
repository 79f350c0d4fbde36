#include "engine/sim/terms.hpp"

#include <algorithm>

namespace crowdmpm {

// One line per law (sim/terms/*.cpp).
const TermLaw* uniform_term();
const TermLaw* radial_term();
const TermLaw* vortex_term();
const TermLaw* obstacle_term();
const TermLaw* slow_zone_term();
const TermLaw* wall_friction_term();
const TermLaw* counterflow_term();
const TermLaw* constriction_term();

const std::vector<const TermLaw*>& term_laws() {
  static const std::vector<const TermLaw*> laws = {uniform_term(), radial_term(), vortex_term(), obstacle_term(),
                                                    slow_zone_term(), wall_friction_term(), density_speed_term(),
                                                    counterflow_term(), constriction_term()};
  return laws;
}

const TermLaw* find_term_law(const std::string& type) {
  for (const TermLaw* l : term_laws())
    if (type == l->type() || (l->alias() && type == l->alias())) return l;
  return nullptr;
}

std::vector<TermField> centred_fields(const char* strength_meaning) {
  return {{"center", 2, "m", -1e9, 1e9, kRequired, true, "the centre"},
          {"strength", 1, "m/s^2", -50, 50, kRequired, true, strength_meaning},
          {"range", 1, "m", 1e-9, 1e300, 1e300, true, "no acceleration farther than this (learnable with edge > 0)", "edge"},
          {"edge", 1, "m", 0, 10, 0, false, "0: a hard cutoff at the range; > 0: the field fades out over this width"}};
}

bool terms_need_density(const std::vector<Term>& terms) {
  for (const Term& t : terms)
    if (t.law->needs_density()) return true;
  return false;
}

size_t TermLaw::parameter_count() const {
  size_t n = 0;
  for (const auto& f : fields()) n += static_cast<size_t>(f.dims);
  return n;
}

std::vector<std::string> Term::parameter_names() const {
  std::vector<std::string> names;
  for (const auto& f : law->fields()) {
    if (f.dims == 1) names.push_back(f.key);
    else {
      names.push_back(std::string(f.key) + ".x");
      names.push_back(std::string(f.key) + ".y");
    }
  }
  return names;
}

size_t Term::learned_count() const { return static_cast<size_t>(std::count(learn.begin(), learn.end(), 1)); }

const TermField& TermLaw::field(size_t k) const {
  for (const auto& f : fields()) {
    if (k < static_cast<size_t>(f.dims)) return f;
    k -= static_cast<size_t>(f.dims);
  }
  throw Error("term parameter index out of range");
}

std::string TermLaw::why_not_learnable(const std::string& key, const double* params) const {
  for (const auto& f : fields()) {
    if (key == f.key) {
      if (!f.learnable) return "not differentiable";
      if (f.learnable_while) {
        size_t k = 0;
        for (const auto& g : fields()) {
          if (std::string(g.key) == f.learnable_while && !(params[k] > 0))
            return std::string("it is not differentiable while ") + g.key + " is 0 (a hard cutoff): give " + g.key +
                   " > 0 " + g.unit;
          k += static_cast<size_t>(g.dims);
        }
      }
      return {};
    }
  }
  return "no such key";
}

void Term::set_clamped(size_t k, double value) {
  const TermField& f = law->field(k);
  params.at(k) = std::clamp(value, f.lo, f.hi);
}

Term Term::parse(const JsonReader& r, const std::vector<std::string>& group_ids) {
  r.require_object();
  std::vector<std::string> types;
  for (const TermLaw* l : term_laws()) {
    types.push_back(l->type());
    if (l->alias()) types.push_back(l->alias());
  }
  Term t;
  t.path = r.path();
  t.law = find_term_law(r.one_of("type", types, std::nullopt));
  std::vector<std::string> keys = {"type", "id", "groups", "learn"};
  for (const auto& f : t.law->fields()) keys.push_back(f.key);
  r.allow_only(keys);
  t.id = r.string("id", std::string());
  for (const auto& f : t.law->fields()) {
    const bool required = std::isnan(f.default_value);
    if (f.dims == 2) {
      const Vec2 def(f.default_value, f.default_value);
      const Vec2 p = required ? r.vec2(f.key, std::nullopt) : r.vec2(f.key, def);
      t.params.push_back(p.x());
      t.params.push_back(p.y());
    } else if (f.lo > 0 && f.hi >= 1e300) {
      t.params.push_back(required ? r.positive(f.key, std::nullopt) : r.positive(f.key, f.default_value));
    } else {
      t.params.push_back(required ? r.in_range(f.key, f.lo, f.hi, std::nullopt) : r.in_range(f.key, f.lo, f.hi, f.default_value));
    }
  }
  // The law's own checks first: they say more than a component's range ("check the units").
  const std::string bad = t.law->check(t.params.data());
  if (!bad.empty()) {
    const size_t colon = bad.find(':');
    r.fail_at(bad.substr(0, colon), bad.substr(colon + 2));
  }
  size_t first = 0;  // of each field's parameters
  for (const auto& f : t.law->fields()) {
    if (f.dims == 2)
      for (size_t c = first; c < first + 2; ++c)
        if (!(t.params[c] >= f.lo && t.params[c] <= f.hi))
          r.fail_at(f.key, std::string("components must be in [") + format_number(f.lo) + ", " + format_number(f.hi) +
                               "] " + f.unit + ", got " + format_number(t.params[c]));
    first += static_cast<size_t>(f.dims);
  }
  t.learn.assign(t.params.size(), 0);
  if (auto lr = r.get("learn")) {
    for (size_t i = 0; i < lr->size(); ++i) {
      const std::string key = lr->item(i).as_string();
      size_t k = 0;
      bool found = false;
      for (const auto& f : t.law->fields()) {
        if (key == f.key) {
          if (const std::string why = t.law->why_not_learnable(key, t.params.data()); !why.empty())
            lr->item(i).fail(std::string("\"") + key + "\" of a " + t.law->type() + " term cannot be learned: " + why);
          for (int c = 0; c < f.dims; ++c) t.learn[k + static_cast<size_t>(c)] = 1;
          found = true;
        }
        k += static_cast<size_t>(f.dims);
      }
      if (!found) {
        std::string known;
        for (const auto& f : t.law->fields())
          if (f.learnable) known += (known.empty() ? "" : ", ") + std::string(f.key);
        lr->item(i).fail("\"" + key + "\" is not a parameter of a " + t.law->type() + " term (learnable: " + known + ")");
      }
    }
  }
  if (auto gl = r.get("groups"))
    for (size_t k = 0; k < gl->size(); ++k) {
      const std::string id = gl->item(k).as_string();
      auto it = std::find(group_ids.begin(), group_ids.end(), id);
      if (it == group_ids.end()) gl->item(k).fail("no group or source with id \"" + id + "\"");
      if (t.applies_to.empty()) t.applies_to.assign(group_ids.size(), 0);
      t.applies_to[static_cast<size_t>(it - group_ids.begin())] = 1;
      t.groups.push_back(id);
    }
  return t;
}

json Term::to_json() const {
  json j = json::object();
  j["type"] = law->type();
  if (!id.empty()) j["id"] = id;
  size_t k = 0;
  json learned = json::array();
  for (const auto& f : law->fields()) {
    if (f.dims == 2) j[f.key] = {params[k], params[k + 1]};
    else j[f.key] = params[k];
    if (learn[k]) learned.push_back(f.key);
    k += static_cast<size_t>(f.dims);
  }
  if (!groups.empty()) j["groups"] = groups;
  if (!learned.empty()) j["learn"] = learned;
  return j;
}

void apply_terms(const std::vector<Term>& terms, const TermPoint& pt, Vec2& accel, double& factor) {
  for (const Term& t : terms)
    if (t.applies(pt.group)) t.law->eval(t.params.data(), pt, accel, factor);
}

}  // namespace crowdmpm
