// Prints the state hash of a scenario after a number of steps: state_hash SCENARIO STEPS [THREADS].
// Used to compare builds from different compilers (tests/cross_compiler.cmake).
#include <cstdio>
#include <cstdlib>

#include "engine/sim/simulation.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: state_hash SCENARIO STEPS [THREADS]\n");
    return 2;
  }
  try {
    crowdmpm::ScenarioDef s = crowdmpm::ScenarioDef::load(argv[1]);
    crowdmpm::Simulation sim(s, s.model_or_default(), argc > 3 ? std::atoi(argv[3]) : 1);
    sim.run_steps(std::atol(argv[2]));
    std::printf("%016llx\n", static_cast<unsigned long long>(sim.world().state_hash()));
  } catch (const crowdmpm::Error& e) {
    std::fprintf(stderr, "state_hash: %s\n", e.what());
    return 1;
  }
  return 0;
}
