#pragma once
// What a group of people does (the scenario's "behaviour"), and, once a simulation resolved it,
// the navigation field and goal region it walks by. The drive reads it (kernels.hpp).
#include <string>

#include "engine/core/vec.hpp"
#include "engine/geometry/shape.hpp"

namespace crowdmpm {

struct Behaviour {
  // Heading: each person walks on in the direction they were moving when placed (their
  // heading at entry), for crowds seen without goals (video).
  enum class Kind { None, Goal, Orbit, Attract, Heading };
  Kind kind = Kind::None;
  // As the scenario gives it.
  std::string target;          // Goal: exit or goal id, or "nearest_exit"; Orbit: structure to circle (or empty)
  Vec2 point = Vec2::Zero();   // Orbit: centre; Attract: the point
  double sign = 1;             // Orbit: +1 counter-clockwise, -1 clockwise
  double inward = 0;           // Orbit: weight of the inward (centre-seeking) component
  double arrive_radius = 0.5;  // Attract: agents within this distance stop, m
  std::string path;            // JSON path, for messages
  // Resolved by the simulation.
  int nav = -1;                // Goal, Orbit around a structure: index of the navigation field
  const Shape* goal = nullptr; // Goal: agents inside this (non-exit) goal region stop
};

}  // namespace crowdmpm
