#pragma once
// ECS-style state: flat arrays (structure of arrays) of particle and agent components, dense
// indices 0..size()-1 and stable entity ids (never reused). Removing an agent moves the last
// one into its slot; ids keep pointing at the right agent through index_of().
#include <cmath>
#include <cstdint>
#include <vector>

#include "engine/core/vec.hpp"
#include "engine/geometry/geometry.hpp"

namespace crowdmpm {

using EntityId = uint64_t;  // 0 is never a valid id

struct AgentDef {
  Vec2 position = Vec2::Zero();  // m
  Vec2 velocity = Vec2::Zero();  // m/s
  double body_radius = 0.2;      // m
  double comfort_distance = 0.3; // m
  double desired_speed = 1.3;    // m/s
  int behaviour = 0;             // index into the simulation's behaviour table
  int group = 0;                 // index into the scenario's groups and sources
  Vec2 heading = Vec2(1, 0);     // unit direction at entry; Simulation::add_agent sets it from the velocity for the heading behaviour
};

class World {
 public:
  // Particle components.
  std::vector<Vec2> x, v;        // position (m), velocity (m/s)
  std::vector<Mat2> C;           // APIC affine velocity (1/s)
  std::vector<Mat2> F;           // deformation gradient (elastic material only; identity otherwise)
  std::vector<double> J;         // volume ratio to the reference area 1/rho0 (set on entry, see reference_volumes)
  // Agent components.
  std::vector<EntityId> id;
  std::vector<double> radius, comfort, v0;
  std::vector<int> behaviour, group;
  // Per-step derived quantities (written by the kernels, read by outputs and the next kernels).
  std::vector<Vec2> accel;       // active drive + body forces, m/s^2
  std::vector<Vec2> heading;     // unit desired direction (or motion direction)
  std::vector<double> free_speed;  // u = v0_scale v0 f of the drive (m/s); 0 without a desired direction
  std::vector<Vec2> pair_force;  // pair traction on the particle
  std::vector<double> pair_virial;  // sum over neighbours of f_pq . (x_p - x_q)
  std::vector<double> pressure;  // reported pressure (continuum + pair virial), written by P2G

  size_t size() const { return id.size(); }
  void reserve(size_t n);
  EntityId add(const AgentDef& def);
  void remove_at(size_t index);
  // Dense index of an entity, or -1 if it does not exist (never did, or was removed).
  long index_of(EntityId e) const;
  EntityId next_id() const { return next_id_; }

  // FNV-1a over id, x and v (raw bytes) of every live particle in id order.
  uint64_t state_hash() const;

 private:
  friend struct SnapshotCodec;  // engine/sim/snapshot.cpp
  std::vector<long> slot_;  // id -> index, -1 once removed
  EntityId next_id_ = 1;
};

// Spacing (m) of a hexagonal lattice of `density` persons per m^2 (rows a sqrt(3)/2 apart).
inline double hexagonal_spacing(double density) { return std::sqrt(2 / (std::sqrt(3.0) * density)); }

// Persons per m^2 at each agent of [first, w.size()), counting every agent (itself included)
// with the kernel W(r) = 2 / (pi R^2) (1 - r^2 / R^2) for r < R, which integrates to 1 over the
// plane: a uniform crowd gives its density, a person alone 2 / (pi R^2).
std::vector<double> local_density(const World& w, size_t first, double R);
// The same over the points x (recorded positions, ...): persons/m^2 at x[first..] among all of x.
std::vector<double> local_density(const std::vector<Vec2>& x, size_t first, double R);
// The density ahead of each point: the same kernel, neighbour q weighted by (1 + cos a)^k / N_k,
// a the angle between x_q - x_p and heading p (unit, or zero: every neighbour weighs 1), k >= 1
// the focus and N_k = (2k)! / (k!^2 2^k) (Gamma functions for k not whole) the mean of (1 + cos)^k
// over the circle; the point itself weighs 1. A uniform crowd gives its density whatever R and k;
// people behind count for nothing, people straight ahead 2^k / N_k times (k = 1: twice; k = 4:
// 3.7 times, about 2/3 of the weight within 50 degrees of the heading).
// With velocities v and opening > 0, a neighbour walking away at s = (v_q - v_p).heading_p > 0
// is further weighted by exp(-s / opening) (MaterialParams::density_opening_speed).
std::vector<double> local_density_ahead(const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R, double focus,
                                        const std::vector<Vec2>* v = nullptr, double opening = 0);
// Its adjoint: given rho_bar[p] = dL/drho_p, adds dL/dx to x_bar and dL/dheading to heading_bar,
// and with v and opening > 0, dL/dv to *v_bar and dL/dopening to *opening_bar.
// The kernel's slope jumps at r = R (a neighbour entering the radius) and at s = 0: exact away
// from them.
void local_density_ahead_vjp(const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R, double focus,
                             const std::vector<double>& rho_bar, std::vector<Vec2>& x_bar, std::vector<Vec2>& heading_bar,
                             const std::vector<Vec2>* v = nullptr, double opening = 0, std::vector<Vec2>* v_bar = nullptr,
                             double* opening_bar = nullptr);

// The walkable part of a venue on a square lattice of spacing h (cell centres lo + h (i + 1/2,
// j + 1/2), row-major): the venue's signed distance at each centre (walkable where positive;
// outside the lattice, which covers the domain, nothing is walkable), and a fingerprint of the
// lattice (equal lattices, equal fingerprints) for caches of what is read through it.
struct WalkableLattice {
  Vec2 lo = Vec2::Zero();
  double h = 0;
  long nx = 0, ny = 0;
  std::vector<float> clearance;  // m
  uint64_t fingerprint = 0;
  bool empty() const { return nx == 0 || ny == 0; }
};
WalkableLattice walkable_lattice(const Geometry& geo, double h);
// The walkable share of the density-ahead kernel of reach R and focus k at each point (heading
// as in local_density_ahead): s_p = sum_c chi_c W(y_c - x_p) / sum_c W(y_c - x_p) over the
// lattice's centres y_c within R (chi_c = 1 where walkable), 1 where the whole disc is walkable.
// The density ahead divided by it is a density per walkable area: a corridor narrower than the
// disc reads its density, not a part of it, and the space behind a wall is not taken for empty.
std::vector<double> walkable_share_ahead(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                                         double R, double focus);
// Its adjoint: given share_bar[p] = dL/ds_p, adds dL/dx to x_bar and dL/dheading to heading_bar
// (exact: the lattice is fixed in space and every weight vanishes at the disc's edge).
void walkable_share_ahead_vjp(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                              double R, double focus, const std::vector<double>& share_bar, std::vector<Vec2>& x_bar,
                              std::vector<Vec2>& heading_bar);
// The share with what its adjoint needs, at the points where need[p] (every point when need is
// empty; elsewhere share 1 and no derivatives): ds = (dx . dx_p + de . dheading_p) / s0, with
// s0 = 0 where the whole disc is walkable (no derivatives). One pass over the lattice gives both.
struct ShareAhead {
  double share = 1;
  double s0 = 0;
  Vec2 dx = Vec2::Zero(), de = Vec2::Zero();
};
std::vector<ShareAhead> walkable_share_ahead_derivatives(const WalkableLattice& walk, const std::vector<Vec2>& x,
                                                         const std::vector<Vec2>& heading, double R, double focus,
                                                         const std::vector<char>& need = {});
// The adjoint from them: adds share_bar[p] ds_p to x_bar and heading_bar.
void walkable_share_ahead_vjp(const std::vector<ShareAhead>& d, const std::vector<double>& share_bar, std::vector<Vec2>& x_bar,
                              std::vector<Vec2>& heading_bar);
// The least walkable share a density ahead is divided by (a person facing a wall reads at most
// 1 / kMinWalkableShare times the people in the disc's walkable part).
constexpr double kMinWalkableShare = 0.25;
// Densities ahead rho (local_density_ahead at x, heading) made per walkable area: each divided by
// max(walkable share, kMinWalkableShare).
void per_walkable_area(const WalkableLattice& walk, const std::vector<Vec2>& x, const std::vector<Vec2>& heading, double R,
                       double focus, std::vector<double>& rho);

// Model v2's reference volumes: J = clamp(rho0 / rho, j_min, 1) for the agents [first, size())
// with rho their local_density over kDensityRadius, so that a crowd entering denser than rest
// starts compressed (and pressed apart by the material) and one sparser starts at rest.
constexpr double kDensityRadius = 1.0;  // m
// The smallest volume ratio of the crowd and fluid materials (also the clamp of the step).
constexpr double kMinJ = 0.2;
void reference_volumes(World& w, size_t first, double rest_density);

}  // namespace crowdmpm
