#include "engine/sim/world.hpp"

#include <algorithm>
#include <cstring>
#include <numeric>

namespace crowdmpm {

void World::reserve(size_t n) {
  x.reserve(n); v.reserve(n); C.reserve(n); F.reserve(n); J.reserve(n);
  id.reserve(n); radius.reserve(n); comfort.reserve(n); v0.reserve(n);
  behaviour.reserve(n); group.reserve(n);
  accel.reserve(n); heading.reserve(n); free_speed.reserve(n); pair_force.reserve(n); pair_virial.reserve(n); pressure.reserve(n);
}

EntityId World::add(const AgentDef& d) {
  EntityId e = next_id_++;
  if (slot_.size() <= e) slot_.resize(e + 1, -1);
  slot_[e] = static_cast<long>(size());
  x.push_back(d.position);
  v.push_back(d.velocity);
  C.push_back(Mat2::Zero());
  F.push_back(Mat2::Identity());
  J.push_back(1.0);
  id.push_back(e);
  radius.push_back(d.body_radius);
  comfort.push_back(d.comfort_distance);
  v0.push_back(d.desired_speed);
  behaviour.push_back(d.behaviour);
  group.push_back(d.group);
  accel.push_back(Vec2::Zero());
  heading.push_back(Vec2(1, 0));
  free_speed.push_back(0);
  pair_force.push_back(Vec2::Zero());
  pair_virial.push_back(0);
  pressure.push_back(0);
  return e;
}

template <class T>
static void swap_pop(std::vector<T>& a, size_t i) {
  a[i] = a.back();
  a.pop_back();
}

void World::remove_at(size_t i) {
  slot_[id[i]] = -1;
  if (i + 1 != size()) slot_[id.back()] = static_cast<long>(i);
  swap_pop(x, i); swap_pop(v, i); swap_pop(C, i); swap_pop(F, i); swap_pop(J, i);
  swap_pop(id, i); swap_pop(radius, i); swap_pop(comfort, i); swap_pop(v0, i);
  swap_pop(behaviour, i); swap_pop(group, i);
  swap_pop(accel, i); swap_pop(heading, i); swap_pop(free_speed, i); swap_pop(pair_force, i); swap_pop(pair_virial, i);
  swap_pop(pressure, i);
}

long World::index_of(EntityId e) const {
  if (e == 0 || e >= slot_.size()) return -1;
  return slot_[e];
}

uint64_t World::state_hash() const {
  std::vector<size_t> order(size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return id[a] < id[b]; });
  uint64_t h = 14695981039346656037ull;
  auto mix = [&](const void* data, size_t n) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (size_t k = 0; k < n; ++k) {
      h ^= p[k];
      h *= 1099511628211ull;
    }
  };
  for (size_t i : order) {
    double buf[4] = {x[i].x(), x[i].y(), v[i].x(), v[i].y()};
    mix(&id[i], sizeof(EntityId));
    mix(buf, sizeof(buf));
  }
  return h;
}

}  // namespace crowdmpm
