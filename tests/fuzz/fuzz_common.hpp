#pragma once
// Shared by the libFuzzer targets (tests/fuzz/README.md): the bound on the work one input may
// ask for. A valid scenario may legitimately describe a stadium with 100,000 people, which takes
// seconds to build; the fuzzers look for crashes, leaks, undefined behaviour and hangs, so they
// skip (without building) scenarios above a small size instead of reporting them as slow.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "engine/sim/scenario.hpp"

namespace crowdmpm::fuzz {

inline bool small_enough(const ScenarioDef& s) {
  const Vec2 ext = s.geo.hi - s.geo.lo;
  const double area = ext.x() * ext.y();
  if (!(area > 0) || area / (s.cell_size * s.cell_size) > 2e4 || area / (s.nav_cell * s.nav_cell) > 2e5) return false;
  if (s.groups.size() > 16 || s.geo.solids.size() > 64 || s.terms.size() > 16) return false;
  double people = 0;
  for (const auto& g : s.groups) people += g.is_source ? g.max_count : g.count >= 0 ? g.count : g.density * area;
  return people <= 1500;
}

// A folder for files the targets write (snapshots), removed by the OS's tmp cleaning.
inline std::string scratch_dir() {
  const char* t = std::getenv("TMPDIR");
  return t ? t : "/tmp";
}

}  // namespace crowdmpm::fuzz
