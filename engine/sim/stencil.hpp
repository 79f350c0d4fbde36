#pragma once
// Quadratic B-spline weights of a particle on a grid with nodes at origin + dx (i, j): the base
// node of its 3x3 stencil and 3 weights per axis (the same for P2G, G2P and output fields).
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "engine/core/vec.hpp"

namespace crowdmpm {

struct Stencil {
  int bx, by;
  double wx[3], wy[3];
  double fx, fy;  // position in cells relative to the base node
};

inline Stencil make_stencil(const Vec2& origin, double dx, int nx, int ny, const Vec2& x) {
  Stencil s;
  double gx = (x.x() - origin.x()) / dx, gy = (x.y() - origin.y()) / dx;
  s.bx = std::clamp(static_cast<int>(std::floor(gx - 0.5)), 0, nx - 3);
  s.by = std::clamp(static_cast<int>(std::floor(gy - 0.5)), 0, ny - 3);
  s.fx = gx - s.bx;
  s.fy = gy - s.by;
  s.wx[0] = 0.5 * (1.5 - s.fx) * (1.5 - s.fx);
  s.wx[1] = 0.75 - (s.fx - 1) * (s.fx - 1);
  s.wx[2] = 0.5 * (s.fx - 0.5) * (s.fx - 0.5);
  s.wy[0] = 0.5 * (1.5 - s.fy) * (1.5 - s.fy);
  s.wy[1] = 0.75 - (s.fy - 1) * (s.fy - 1);
  s.wy[2] = 0.5 * (s.fy - 0.5) * (s.fy - 0.5);
  return s;
}

// Derivatives with respect to the position (1/m) of the three weights per axis of a stencil on
// a grid of spacing dx (its base node held fixed).
inline void stencil_weight_gradients(const Stencil& s, double dx, double dwx[3], double dwy[3]) {
  const double inv = 1 / dx;
  dwx[0] = -(1.5 - s.fx) * inv;
  dwx[1] = -2 * (s.fx - 1) * inv;
  dwx[2] = (s.fx - 0.5) * inv;
  dwy[0] = -(1.5 - s.fy) * inv;
  dwy[1] = -2 * (s.fy - 1) * inv;
  dwy[2] = (s.fy - 0.5) * inv;
}

// One node of a particle's 3x3 stencil: its index (row-major, nx columns), its weight w, its
// offset from the particle x_i - x_p (m) and its place (a, b) in the stencil.
struct StencilNode {
  size_t k;
  double w;
  Vec2 dpos;
  int a, b;
};

// Calls fn(node) for the 9 nodes of stencil s on a grid of nx columns and spacing dx, rows
// outer: the one 3x3 loop of every transfer (P2G, G2P, output fields and their adjoints).
template <class F>
inline void for_each_stencil_node(const Stencil& s, int nx, double dx, F&& fn) {
  for (int b = 0; b < 3; ++b)
    for (int a = 0; a < 3; ++a)
      fn(StencilNode{static_cast<size_t>((s.by + b) * nx + (s.bx + a)), s.wx[a] * s.wy[b], dx * Vec2(a - s.fx, b - s.fy), a, b});
}

// Calls fn(node, w, dw/dx) for the 9 nodes of x's stencil; nothing for a point whose stencil
// does not fit on the grid (make_stencil would clamp it, and its weights mean nothing there).
template <class F>
inline void for_stencil_on_grid(const Vec2& origin, double dx, int nx, int ny, const Vec2& x, F&& fn) {
  const double bx = std::floor((x.x() - origin.x()) / dx - 0.5), by = std::floor((x.y() - origin.y()) / dx - 0.5);
  if (!(bx >= 0 && by >= 0 && bx <= nx - 3 && by <= ny - 3)) return;
  const Stencil s = make_stencil(origin, dx, nx, ny, x);
  double dwx[3], dwy[3];
  stencil_weight_gradients(s, dx, dwx, dwy);
  for_each_stencil_node(s, nx, dx, [&](const StencilNode& n) {
    fn(n.k, n.w, Vec2(dwx[n.a] * s.wy[n.b], s.wx[n.a] * dwy[n.b]));
  });
}

}  // namespace crowdmpm
