#pragma once
// One MPM step of the crowd material, kernel by kernel (DESIGN.md section 2). Each kernel is a
// function of the arrays it names; outputs are per particle or per grid node and never shared
// between threads, so results do not depend on the thread count. P2G scatters particles sorted
// by stencil base in row blocks that never share a node (even blocks, then odd), not with atomics.
#include <algorithm>
#include <vector>

#include "engine/sim/stencil.hpp"
#include "engine/geometry/geometry.hpp"
#include "engine/sim/behaviour.hpp"
#include "engine/sim/model.hpp"
#include "engine/sim/terms.hpp"
#include "engine/geometry/navigation.hpp"
#include "engine/core/parallel.hpp"
#include "engine/sim/world.hpp"

namespace crowdmpm {

// Background grid, fixed for the life of a world. Nodes at origin + dx (i, j).
struct Grid {
  Vec2 origin = Vec2::Zero();
  double dx = 0.5;
  int nx = 0, ny = 0;
  std::vector<double> mass;
  std::vector<Vec2> velocity;      // momentum during P2G, velocity after the grid update (v_new)
  std::vector<Vec2> velocity_old;  // the same without the stress impulse and boundary conditions
  std::vector<char> solid;     // node inside a solid
  std::vector<Vec2> normal;    // outward normal of that solid
  // Scratch, reused every step: particle stencil bases, binning, P2G payloads.
  std::vector<int> bin_start, order, base, cursor;
  std::vector<Vec2> momentum;
  std::vector<Mat2> affine, stress;
  std::vector<Stencil> stencils;

  void init(const Geometry& geo, double cell);
  size_t nodes() const { return static_cast<size_t>(nx) * ny; }
  int node(int i, int j) const { return j * nx + i; }
};

// Cell lists for the pair traction: every pair within `range` lies within `span` cells.
struct NeighbourGrid {
  Vec2 origin = Vec2::Zero();
  double h = 1;
  double range = 0;  // pair interaction reach the cells were sized for
  int span = 1;      // cells searched on each side for a pair: ceil(range / h)
  // The largest body radius (set with the cells, Simulation::size_neighbour_cells): how far
  // aside of p's lane a person ahead may stand (for_each_candidate_ahead).
  double max_radius = 0;
  int nx = 0, ny = 0;
  std::vector<int> start, order, cell, cursor;
  void init(const Geometry& geo, double reach, double min_cell = 0);
  // Calls f(q) for every other particle q in the cells within `span` of p's cell, always in the
  // same order (cells row by row, particles by index): the traction, its adjoint and the
  // statistics share this one loop.
  template <class F>
  void for_each_candidate(size_t p, F&& f) const {
    const int c0 = cell[p], ci = c0 % nx, cj = c0 / nx;
    for (int dj = -span; dj <= span; ++dj)
      for (int di = -span; di <= span; ++di) {
        const int i = ci + di, j = cj + dj;
        if (i < 0 || j < 0 || i >= nx || j >= ny) continue;
        visit_cell(j * nx + i, p, f);
      }
  }
  // The candidates that may stand in the lane ahead of p (at x, radius r, heading e) within
  // `look` m of free distance (headway_point): a strip `look + r + max_radius` long and
  // `width (r + max_radius)` to each side. Visits the cells of the strip's bounding box, less
  // those whose circumscribed circle misses the strip (the edge cells, which hold clamped
  // particles, are always kept), in the order of for_each_candidate. The strip, not the cell
  // size, bounds the search: the cells stay sized for the pairs.
  template <class F>
  void for_each_candidate_ahead(size_t p, const Vec2& x, double r, const Vec2& e, double look, double width, F&& f) const {
    const double length = look + r + max_radius, half_width = width * (r + max_radius);
    const Vec2 tip = x + length * e, side_extent = half_width * Vec2(e.y(), e.x()).cwiseAbs();
    const Vec2 lo = x.cwiseMin(tip) - side_extent, hi = x.cwiseMax(tip) + side_extent;
    auto index = [&](double v, double o, int n) { return std::clamp(static_cast<int>(std::floor((v - o) / h)), 0, n - 1); };
    const int i0 = index(lo.x(), origin.x(), nx), i1 = index(hi.x(), origin.x(), nx);
    const int j0 = index(lo.y(), origin.y(), ny), j1 = index(hi.y(), origin.y(), ny);
    const double rho = 0.7072 * h;
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        if (i > 0 && j > 0 && i < nx - 1 && j < ny - 1) {
          const Vec2 c = origin + h * Vec2(i + 0.5, j + 0.5) - x;
          const double along = c.dot(e), side = c.x() * e.y() - c.y() * e.x();
          if (along < -rho || along > length + rho || std::abs(side) > half_width + rho) continue;
        }
        visit_cell(j * nx + i, p, f);
      }
  }
  template <class F>
  void visit_cell(int k, size_t p, F&& f) const {
    for (int s = start[static_cast<size_t>(k)]; s < start[static_cast<size_t>(k) + 1]; ++s) {
      const size_t q = static_cast<size_t>(order[static_cast<size_t>(s)]);
      if (q != p) f(q);
    }
  }
  void build(const World& w, ThreadPool& pool);
};

struct StepInputs {
  const Model& model;
  const Geometry& geo;
  const std::vector<NavField>& navs;
  const std::vector<Behaviour>& behaviours;
  const std::vector<Term>& terms;  // the venue's force terms (scenario "forces")
  double dt;
  double time;  // s, at the start of the step
  // The venue's walkable lattice at the material law's reach / 8 (Simulation keeps it while the
  // model has a density-speed law), through which the law reads a density per walkable area;
  // null: the density ahead as read over the whole disc.
  const WalkableLattice* walkable = nullptr;
};

// phi(d) of the pair traction for contact distance theta1, comfort distance c, smallest gap eps.
double contact_potential(double d, double theta1, double c, double eps);
// Continuum pressure P(J) of the crowd/fluid material (positive in compression).
double material_pressure(const MaterialParams& p, double J);
// Kirchhoff stress tau = J sigma of the particle's material.
Mat2 kirchhoff_stress(const Model& m, const Mat2& F, double J);

// Unit desired direction of a behaviour at x (zero where the agent stands still).
Vec2 desired_direction(const StepInputs& in, const Behaviour& b, const Vec2& x, const Vec2& heading);
// One agent's drive, a_p = (s v0 f e - v) / tau + sum of the terms' accelerations, with f the
// product of the terms' speed factors and the material's density factor, and its heading; kernel_drive applies it to every agent.
// pt: the agent's position, velocity, previous heading, group, the time, and its local density
// and id for the terms (terms_point).
void drive_point(const StepInputs& in, const Behaviour& beh, const TermPoint& pt, double v0, Vec2& accel, Vec2& heading,
                 double& free_speed);
// The TermPoint of agent p of w (density: terms_density, ahead: material_density; each may be
// empty).
TermPoint terms_point(const StepInputs& in, const World& w, size_t p, const Vec2& heading, const std::vector<double>& density,
                      const std::vector<double>& ahead);
// The local densities the scenario's terms read (empty when none reads them).
std::vector<double> terms_density(const StepInputs& in, const World& w);
// The densities ahead (local_density_ahead at positions x with the headings before the step) that
// the material's density-speed law reads (empty when the model has none), each divided by the
// kernel's walkable share there (walkable_share_ahead, at least kMinWalkableShare) when the
// inputs carry the venue's walkable lattice.
std::vector<double> material_density(const StepInputs& in, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                                     const std::vector<Vec2>& v);
// Its adjoint: given density_bar[p] = dL/d(material_density)_p, adds dL/dx to x_bar, dL/dheading
// to heading_bar, dL/dv to v_bar and dL/d(density_opening_speed) to *opening_bar.
void material_density_vjp(const StepInputs& in, const std::vector<Vec2>& x, const std::vector<Vec2>& heading,
                          const std::vector<Vec2>& v, const std::vector<double>& density_bar, std::vector<Vec2>& x_bar,
                          std::vector<Vec2>& heading_bar, std::vector<Vec2>& v_bar, double* opening_bar);
// The material's own density-speed law (density_speed_gamma > 0; the "density_speed" term's
// formula with the model's gamma and max density, at the density ahead of the person,
// pt.density_ahead), raised by its floor phi (density_speed_floor) to (1 - m)(phi + (1 - phi) f) +
// m M(f, phi), M a smooth max of sharpness kFloorSharpness, m = density_speed_floor_max (model.hpp): the factor
// on the free speed at pt (1 when off), and, given dL/df, adds dL/d(density_speed_gamma),
// dL/d(density_speed_max) and dL/d(density_speed_floor) to grad and returns dL/d(pt.density_ahead)
// (which local_density_ahead_vjp, world.hpp, takes on to the positions and headings).
inline bool material_density_law(const MaterialParams& P) { return P.density_speed_gamma > 0; }
constexpr double kFloorSharpness = 20;  // b of the floor's smooth max: f + ln(1 + e^(b (phi - f))) / b
double material_density_factor(const MaterialParams& P, const TermPoint& pt);
double material_density_factor_vjp(const MaterialParams& P, const TermPoint& pt, double f_bar, MaterialParams& grad);
// Headway speed adaptation (model parameter time_gap T > 0; after Tordeux, Chraibi & Seyfried
// 2016): people walk no faster than the gap to the nearest person ahead of them allows,
//   V_p = min(u_p, max(0, (s_p - s0) / T)),  s_p = min over q ahead of (x_q - x_p) . e_p - r_p - r_q,
// s0 = headway_gap (0: Tordeux's law with the body length r_p + r_q),
// over the neighbours q ahead ((x_q - x_p) . e_p > 0) and within a lane of half-width
// headway_width (r_p + r_q) (|(x_q - x_p) x e_p| below it: 1 is everyone whose body overlaps
// p's path; smaller lets a person half a body aside be followed closely, the zipper effect of
// bottlenecks); u_p is the drive's free speed and e_p its direction. Not reciprocal: nobody
// slows for the person behind. The drive is corrected by
//   a_p += (V_p - u_p) e_p / tau.
struct Headway {
  size_t q = static_cast<size_t>(-1);  // the nearest person ahead, or none
  double gap = 1e300;                  // s_p, m
};
// The free distance T u + s0 beyond which nobody ahead limits a person walking at u (the search
// for the nearest person ahead stops there); V = headway_speed(P, gap) below it.
inline double headway_look(const MaterialParams& P, double u) { return P.time_gap * u + P.headway_gap; }
inline double headway_speed(const MaterialParams& P, double gap) { return std::max(0.0, (gap - P.headway_gap) / P.time_gap); }
// `look`: headway_look of p's free speed.
Headway headway_point(const NeighbourGrid& nb, const World& w, size_t p, const Vec2& e, double width, double look);
void kernel_headway(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool);
// How far beyond body contact (r_p + r_q) a pair interacts: the comfort distance c for the
// continuum materials' pair traction; for the social force, where the exponential repulsion
// has decayed to e^-8 of its strength (8 B, at most 3 m).
double interaction_margin(const Model& m, double comfort);
// Social force (Helbing, Farkas & Vicsek 2000, with body compression and sliding friction), per
// unit mass: for neighbours q with d = |x_p - x_q|, n = (x_p - x_q)/d, t = (-n_y, n_x),
// r_pq = r_p + r_q, g(s) = max(s, 0):
//   f_p += [A exp((r_pq - d)/B) + k g(r_pq - d)] n + kappa g(r_pq - d) ((v_q - v_p) . t) t
// and from the nearest solid (distance d_w and outward normal n_w from the SDF, t_w its tangent):
//   f_p += [A exp((r_p - d_w)/B) + k g(r_p - d_w)] n_w - kappa g(r_p - d_w) (v_p . t_w) t_w.
// Writes pair_force, pair_virial (sum of f_pq . (x_p - x_q) over agents) and the reported
// pressure (virial / (2 V), V = 1 / rest_density, as for the crowd material).
void kernel_social_force(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool);
// The clearance that the projection keeps a centre at x from the solids: wall_clearance, or with
// shoulder_clearance above it, between the two by the width of the opening at x
// (docs/model-format.md, step 7).
double projection_clearance(const MaterialParams& P, const Geometry& geo, const Vec2& x);
// One particle's projection out of solids, with the clearance at its position; kernel_project
// applies it to every particle. The second form keeps a given clearance (the adjoint holds the
// clearance fixed: it changes with position only across openings, not along walls).
void project_point(const StepInputs& in, Vec2& x, Vec2& v);
void project_point(const StepInputs& in, Vec2& x, Vec2& v, double clearance);
void kernel_drive(const StepInputs& in, World& w, ThreadPool& pool);
void kernel_traction(const StepInputs& in, const NeighbourGrid& nb, World& w, ThreadPool& pool);
// Also writes each particle's reported pressure (it has the stress at hand).
void kernel_p2g(const StepInputs& in, World& w, Grid& g, ThreadPool& pool);
void kernel_grid_update(const StepInputs& in, Grid& g, ThreadPool& pool);
void kernel_g2p(const StepInputs& in, const Grid& g, World& w, ThreadPool& pool);
void kernel_project(const StepInputs& in, World& w, ThreadPool& pool);

}  // namespace crowdmpm
