// The step allocates nothing once warmed up: every kernel reuses its buffers. Counted by
// replacing the global operator new in this test program.
#include <catch2/catch.hpp>
#include <atomic>
#include <cstdlib>
#include <new>

#include "support.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace crowdmpm;

TEST_CASE("no allocation in the step after warm-up", "[performance]") {
  // Two groups charging each other: contacts, traction network, no exits or sources.
  ScenarioDef s = ScenarioDef::load(test::scenario_path("hellfest_crush"));
  for (int threads : {1, 2}) {
    long at_start = g_allocations.load();
    Simulation sim(s, test::model_of(s), threads);
    CHECK(g_allocations.load() > at_start);  // the counter sees the engine's allocations
    sim.run_steps(20);
    long before = g_allocations.load();
    sim.run_steps(100);
    long during = g_allocations.load() - before;
    INFO(threads << " thread(s): " << during << " allocations in 100 steps of " << sim.world().size() << " agents");
    CHECK(during == 0);
  }
}
