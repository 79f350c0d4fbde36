#pragma once
// Force terms: a venue's extra physics beside the crowd material (DESIGN.md sections 2 and 6).
// A term law adds, per agent, an acceleration a(x, v) (m/s^2) to the drive and/or multiplies
// the agent's desired speed by a factor f(x, v); both may depend on its own named parameters
// (units, ranges), the agent's group and the time. The drive (kernels.cpp, drive_point) and its
// adjoint (learn/differentiable.cpp) loop over the same list of terms.
//
// A law is written once, as a formula templated on the scalar type: evaluated with double in
// the step, and with forward-mode dual numbers in the backward pass, which gives its exact
// vector-Jacobian product with respect to x, v and every parameter (DESIGN.md section 4).
// Adding a law is one file in sim/terms/ and one line in term_laws() (terms.cpp).
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "engine/core/json_reader.hpp"
#include "engine/core/vec.hpp"

namespace crowdmpm {

// A dual number with derivatives along up to kDualDirs directions (x, y, vx, vy, parameters).
constexpr int kDualDirs = 16;
struct Dual {
  double v = 0;
  double d[kDualDirs] = {0};
  Dual() = default;
  Dual(double value) : v(value) {}  // NOLINT: constants mix freely with duals
  static Dual seed(double value, int dir) {
    Dual r(value);
    r.d[dir] = 1;
    return r;
  }
};
// The same names for double, so that a formula reads the same for both scalar types.
inline double sqrt(double a) { return std::sqrt(a); }
inline double exp(double a) { return std::exp(a); }
inline double log(double a) { return std::log(a); }
inline double cos(double a) { return std::cos(a); }
inline double sin(double a) { return std::sin(a); }
inline double value_of(double x) { return x; }
inline double value_of(const Dual& x) { return x.v; }
inline Dual operator-(const Dual& a) {
  Dual r(-a.v);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = -a.d[k];
  return r;
}
inline Dual operator+(const Dual& a, const Dual& b) {
  Dual r(a.v + b.v);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = a.d[k] + b.d[k];
  return r;
}
inline Dual operator-(const Dual& a, const Dual& b) {
  Dual r(a.v - b.v);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = a.d[k] - b.d[k];
  return r;
}
inline Dual operator*(const Dual& a, const Dual& b) {
  Dual r(a.v * b.v);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
  return r;
}
inline Dual operator/(const Dual& a, const Dual& b) {
  Dual r(a.v / b.v);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = (a.d[k] * b.v - a.v * b.d[k]) / (b.v * b.v);
  return r;
}
inline Dual chain(const Dual& a, double value, double derivative) {
  Dual r(value);
  for (int k = 0; k < kDualDirs; ++k) r.d[k] = derivative * a.d[k];
  return r;
}
inline Dual sqrt(const Dual& a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, s > 0 ? 0.5 / s : 0);
}
inline Dual exp(const Dual& a) {
  const double e = std::exp(a.v);
  return chain(a, e, e);
}
inline Dual log(const Dual& a) { return chain(a, std::log(a.v), 1 / a.v); }
inline Dual cos(const Dual& a) { return chain(a, std::cos(a.v), -std::sin(a.v)); }
inline Dual sin(const Dual& a) { return chain(a, std::sin(a.v), std::cos(a.v)); }

// Where a term is evaluated: one agent's state and the simulation clock.
// heading, density and id are read as they are: a law's derivatives do not flow through them.
struct TermPoint {
  Vec2 x = Vec2::Zero(), v = Vec2::Zero();  // m, m/s
  Vec2 heading = Vec2::Zero();  // walking direction of the previous step
  int group = 0;
  double time = 0;  // s
  // persons/m^2 around the agent (local_density over kDensityRadius, world.hpp); computed only
  // when a term of the scenario needs it (TermLaw::needs_density), 0 otherwise.
  double density = 0;
  // persons/m^2 ahead of the agent (local_density_ahead with the model's reach and focus, world.hpp), which the
  // material's density-speed law reads (kernels.hpp); 0 when the model has no such law.
  double density_ahead = 0;
  uint64_t id = 0;  // the agent's entity id (a stable per-person draw for laws that pick people)
};

constexpr double kRequired = std::numeric_limits<double>::quiet_NaN();

// A JSON key of a term: a number or a point (two parameters, key.x and key.y).
struct TermField {
  const char* key;
  int dims;                 // 1 or 2
  const char* unit;
  double lo, hi;            // range of each component
  double default_value;     // NaN: required
  bool learnable;           // false where the term is not differentiable in it (a hard cutoff)
  const char* meaning;
  // Learnable only while this other field is > 0 (a range whose cutoff is smooth only with an
  // edge), or nullptr.
  const char* learnable_while = nullptr;
};

class TermLaw {
 public:
  virtual ~TermLaw() = default;
  virtual const char* type() const = 0;
  virtual const char* alias() const { return nullptr; }  // a second name accepted in scenarios
  virtual bool needs_density() const { return false; }    // reads TermPoint::density
  virtual const char* summary() const = 0;
  virtual const std::vector<TermField>& fields() const = 0;
  size_t parameter_count() const;
  // Extra checks of a parsed parameter set beyond each field's range (xmin < xmax, ...);
  // returns an error message naming the key, or empty.
  virtual std::string check(const double* /*params*/) const { return {}; }
  // The field of parameter k (a point's two parameters share one field).
  const TermField& field(size_t k) const;
  // Why field `key` cannot be learned with these parameters (not differentiable at all, or a
  // range with a hard cutoff: TermField::learnable_while), or empty.
  std::string why_not_learnable(const std::string& key, const double* params) const;
  // accel += a(x, v); factor *= f(x, v).
  virtual void eval(const double* params, const TermPoint& pt, Vec2& accel, double& factor) const = 0;
  // Given a_bar = dL/da and f_bar = dL/df (f this term's own factor), adds dL/dx, dL/dv and
  // dL/dparams (parameter_count() values).
  virtual void vjp(const double* params, const TermPoint& pt, const Vec2& a_bar, double f_bar, Vec2& x_bar,
                   Vec2& v_bar, double* params_bar) const = 0;
};

// The laws with formula<T> (T = double or Dual) get eval and vjp from this:
//   template <class T> void formula(const T* p, const T x[2], const T v[2], const TermPoint& pt,
//                                   T a[2], T& f) const;   // a starts at 0, f at 1
template <class Law>
class TermFormula : public TermLaw {
 public:
  void eval(const double* p, const TermPoint& pt, Vec2& accel, double& factor) const override {
    const double x[2] = {pt.x.x(), pt.x.y()}, v[2] = {pt.v.x(), pt.v.y()};
    double a[2] = {0, 0}, f = 1;
    static_cast<const Law*>(this)->formula(p, x, v, pt, a, f);
    accel += Vec2(a[0], a[1]);
    factor *= f;
  }
  void vjp(const double* p, const TermPoint& pt, const Vec2& a_bar, double f_bar, Vec2& x_bar, Vec2& v_bar,
           double* p_bar) const override {
    const size_t np = parameter_count();
    Dual pd[kDualDirs - 4];
    for (size_t k = 0; k < np; ++k) pd[k] = Dual::seed(p[k], 4 + static_cast<int>(k));
    const Dual x[2] = {Dual::seed(pt.x.x(), 0), Dual::seed(pt.x.y(), 1)};
    const Dual v[2] = {Dual::seed(pt.v.x(), 2), Dual::seed(pt.v.y(), 3)};
    Dual a[2] = {Dual(0), Dual(0)}, f(1);
    static_cast<const Law*>(this)->formula(pd, x, v, pt, a, f);
    auto along = [&](int k) { return a_bar.x() * a[0].d[k] + a_bar.y() * a[1].d[k] + f_bar * f.d[k]; };
    x_bar += Vec2(along(0), along(1));
    v_bar += Vec2(along(2), along(3));
    for (size_t k = 0; k < np; ++k) p_bar[k] += along(4 + static_cast<int>(k));
  }
};

// Laws that act around a point within a range (radial, vortex): their fields (p[0..1] center,
// p[2] strength, p[3] range, p[4] edge), and the offset r = x - center, distance d = |r| and
// weight w where they act. edge = 0: a hard cutoff, w = 1 for 1e-9 < d <= range (the range is
// then not learnable: its learnable_while is "edge"); edge > 0: the field fades out smoothly across the range,
// w = 1 / (1 + exp(-4 (range - d) / edge)) (from 88% to 12% over one edge width), for
// 1e-9 < d <= range + 3 edge (w < 7e-6 beyond), and the range is learnable.
std::vector<TermField> centred_fields(const char* strength_meaning);
template <class T>
bool centred_offset(const T* p, const T x[2], T& rx, T& ry, T& d, T& w) {
  rx = x[0] - p[0];
  ry = x[1] - p[1];
  d = sqrt(rx * rx + ry * ry);
  const double edge = value_of(p[4]);
  if (!(value_of(d) >= 1e-9 && value_of(d) <= value_of(p[3]) + 3 * edge)) return false;
  w = edge > 0 ? T(1) / (T(1) + exp(T(-4) * (p[3] - d) / p[4])) : T(1);
  return true;
}

// Laws over a rectangle with smooth edges (slow_zone, counterflow): p[0..3] = xmin, ymin, xmax,
// ymax, and s(x - xmin) s(xmax - x) s(y - ymin) s(ymax - y), s(u) = 1 / (1 + exp(-4 u / edge))
// (from 12% to 88% over one edge width), so that every corner has a gradient.
template <class T>
T smooth_box(const T* p, const T x[2], const T& edge) {
  const T k = T(4) / edge;
  auto s = [&](const T& u) { return T(1) / (T(1) + exp(-(k * u))); };
  return s(x[0] - p[0]) * s(p[2] - x[0]) * s(x[1] - p[1]) * s(p[3] - x[1]);
}

// Every law the engine knows, by type name.
const std::vector<const TermLaw*>& term_laws();
// The "density_speed" law (Weidmann's relation), which the crowd material also applies itself
// (MaterialParams::density_speed_gamma, kernels.hpp material_density_factor).
const TermLaw* density_speed_term();
const TermLaw* find_term_law(const std::string& type);  // nullptr if unknown

// One term of a scenario: a law, its parameter values, which of them training fits, and the
// groups it applies to.
struct Term {
  const TermLaw* law = nullptr;
  std::string id;                // optional, for messages and written-back scenarios
  std::vector<double> params;    // TermLaw::fields() order, points as two values
  std::vector<char> learn;       // per parameter
  std::vector<std::string> groups;  // group or source ids; empty: everyone
  std::vector<char> applies_to;  // per group index; empty: everyone
  std::string path;              // JSON path, for messages

  bool applies(int group) const {
    return applies_to.empty() || (group >= 0 && group < static_cast<int>(applies_to.size()) && applies_to[group]);
  }
  // Names of the parameters ("strength", "center.x", ...), in params order.
  std::vector<std::string> parameter_names() const;
  size_t learned_count() const;
  // Parses one entry of a scenario's "forces"; group_ids are the scenario's groups and sources.
  static Term parse(const JsonReader& r, const std::vector<std::string>& group_ids);
  // The entry as a scenario writes it (parse(to_json()) gives the same term).
  json to_json() const;
  // Sets parameter k, clamped to its field's range.
  void set_clamped(size_t k, double value);
};

// Whether any of the terms reads TermPoint::density.
bool terms_need_density(const std::vector<Term>& terms);

// The drive's share of every term at one agent: sum of accelerations, product of speed factors.
void apply_terms(const std::vector<Term>& terms, const TermPoint& pt, Vec2& accel, double& factor);

}  // namespace crowdmpm
