#pragma once
// The crowd material: its kind, its scalar parameters and its traction network. Read from and
// written to model JSON ("format": "crowdmpm-model"); see docs/model-format.md.
#include <string>
#include <vector>

#include "engine/sim/traction.hpp"

namespace crowdmpm {

enum class MaterialKind { Crowd, Fluid, Elastic, SocialForce };

// Weidmann's (1993) speed-density relation: gamma and the density where people stop.
constexpr double kWeidmannGamma = 1.913;        // persons/m^2
constexpr double kWeidmannMaxDensity = 5.4;     // persons/m^2

struct MaterialParams {
  double E = 20;                 // stiffness of the continuum stress
  double gamma = 1;              // exponent of P(J) = E (J^-gamma - 1)
  double tension_scale = 0;      // s_t: stress scale for J >= 1 (0: crowd scatters freely)
  double tau = 0.4;              // relaxation time of the drive, s (social force default: 0.5)
  double v0_scale = 1;           // multiplies every agent's desired speed
  double comfort_distance = 0.15; // c, m (default for agents that do not set their own)
  double body_radius = 0.2;      // r_b, m (default for agents)
  double rest_density = 6;       // rho0, persons/m^2: particle volume V = 1/rho0 (model version 1: 2)
  double mass = 1;               // per person
  double poisson_ratio = 0.3;    // elastic material only
  double wall_friction = 0;      // tangential velocity removed at walls, fraction per contact
  double max_speed = 4;          // m/s: safety limit on particle speed
  double contact_epsilon = 0.01; // m: smallest gap used in phi(d) = -log((d - 2 r_b)/c)
  double wall_clearance = 0.1;   // m: particle centres are kept at least this far from solids
  // m: where the opening allows, centres keep this far from solids instead (shoulders off the
  // wall); in openings narrower than that people squeeze down to wall_clearance. 0 (or below
  // wall_clearance): off.
  double shoulder_clearance = 0;
  double alignment_time = 0.5;   // s: particle velocities relax towards the local grid flow (PIC share dt/this)
  double time_gap = 0.8;         // s: T of the headway speed adaptation (0: off; model version 1: 0); speed <= gap ahead / T
  double headway_gap = 0;        // m: s0, the gap kept at standstill beyond the bodies: speed <= (gap ahead - s0) / T
  double headway_width = 0.5;    // lane half-width of the headway, as a fraction of r_p + r_q
  // Desired speed falling with the local density (Weidmann 1993), part of the material: the free
  // speed is multiplied by f = 1 - exp(-gamma s(1/rho - 1/max)) (the "density_speed" force
  // term's law, terms/density_speed.cpp), rho the persons/m^2 ahead of the person within the
  // reach, weighted towards the heading by the focus (local_density_ahead, world.hpp: people
  // behind do not count). gamma 0: off.
  double density_speed_gamma = 0;  // persons/m^2 (Weidmann: kWeidmannGamma)
  double density_speed_max = kWeidmannMaxDensity;  // persons/m^2: where people stop
  double density_speed_reach = 1;  // m: R, how far ahead the density is read
  // The law's floor phi: people in a dense crowd still want to move (and press on those ahead)
  // at phi times their free speed; the headway and contact hold them where there is no room.
  // The factor is (1 - m) (phi + (1 - phi) f) + m M(f, phi), M(f, phi) = f + ln(1 + e^(b (phi -
  // f))) / b with b = 20 a smooth max(f, phi), m = density_speed_floor_max: 0 the floor adds to
  // Weidmann's factor everywhere, 1 it only raises it where it falls below phi. phi 0: off
  // (Weidmann's law down to standstill).
  double density_speed_floor = 0;
  double density_speed_floor_max = 0;  // m in [0, 1]
  double density_speed_focus = 1;  // k >= 1: neighbours weighted by (1 + cos)^k (1: the half-plane ahead; 4: a cone of ~50 degrees)
  // The gap that opens: a neighbour ahead walking away from the person, at s = (v_q - v_p).e_p > 0,
  // counts in that density with the weight exp(-s / u), u this speed (0: off, everyone counts in
  // full). In a uniform flow nobody walks away from anybody; at a door's mouth the people ahead
  // accelerate into the space beyond it, and the people behind them may follow.
  double density_opening_speed = 0;  // m/s
  // Route choice under congestion (Hughes 2002): goal routes minimise the travel cost
  // 1 + w (u_ref / v(rho) - 1) per metre, v(rho) the headway's speed at the local density; 0: the
  // shortest path (model version 1 and social_force's default).
  double route_congestion = 0;
  // social_force model (Helbing, Farkas & Vicsek 2000), per unit mass (their values / 80 kg):
  double sf_A = 25;              // m/s^2: strength of the exponential repulsion A exp((r_pq - d)/B)
  double sf_B = 0.08;            // m: its range
  double sf_k = 1500;            // 1/s^2: body compression k g(r_pq - d)
  double sf_kappa = 3000;        // 1/(m s): sliding friction kappa g(r_pq - d) dv_t
};

// Which models learn a parameter, and so how its gradient is had: through the simulator's
// adjoint (the continuum materials: crowd and fluid) or by central differences (social_force).
enum LearnedBy : unsigned { kFixed = 0, kContinuum = 1, kSocialForce = 2 };

// The one declaration of every parameter: its name in model files and APIs, where it lives, its
// range and unit, and which models learn it. A gradient (ModelGradient::params) is a
// MaterialParams too, so `field` also reads a parameter's gradient.
struct ParamInfo {
  const char* name;
  double MaterialParams::*field;
  double lo, hi;
  const char* unit;
  unsigned learned_by;  // LearnedBy bits
  bool sets_up_world;   // read when a world is built (agent sizes, placement, navigation): fixed afterwards
  // Empty when model m learns this parameter; otherwise the reason it does not.
  std::string not_learnable_in(const class Model& m) const;
  bool learnable_in(const class Model& m) const { return not_learnable_in(m).empty(); }
};
const std::vector<ParamInfo>& param_table();
// The row of a parameter; throws Error listing the known names.
const ParamInfo& param_info(const std::string& name);
// Every field 0 (the start of a gradient).
MaterialParams zero_params();

class Model {
 public:
  MaterialKind material = MaterialKind::Crowd;
  MaterialParams params;
  TractionNet traction;  // used by the crowd material only
  std::string source;    // where it was loaded from, for messages
  std::string name, description;  // free text, kept through load and save
  // Model format version. 2: each particle's reference volume comes from the local density when
  // it enters the world (J = min(1, rho0 / rho), world.hpp), so the pressure is referenced to the
  // rest density rho0. 1: J = 1 wherever a person is placed (pressure referenced to the spawn
  // layout; files of version 1 keep that meaning).
  int version = 2;
  static constexpr int kLatestVersion = 2;
  // Whether J starts from the local density (continuum crowd and fluid of version 2).
  bool density_referenced() const { return version >= 2 && is_continuum() && material != MaterialKind::Elastic; }

  static Model default_model();
  // The default model's parameters as another kind (fluid: tension_scale 1; no traction
  // network outside the crowd material). Throws Error for an unknown name.
  static Model default_of(const std::string& kind);
  static Model parse(const JsonReader& r, const std::string& source);
  static Model load(const std::string& path, const InputPolicy& policy = {});
  json to_json() const;

  bool has_traction() const { return material == MaterialKind::Crowd; }
  bool is_continuum() const { return material != MaterialKind::SocialForce; }  // simulated with MPM
  // Named access for the C ABI and the optimisers; throws Error on unknown names or bad values.
  double get(const std::string& param) const;
  void set(const std::string& param, double value);
};

const char* material_name(MaterialKind k);

}  // namespace crowdmpm
