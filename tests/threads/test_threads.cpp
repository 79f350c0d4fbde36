// The C ABI's thread contract (capi/include/crowdmpm/crowdmpm.h), exercised from many threads:
// different worlds concurrently, one world from several threads, destroying a world while
// another thread steps or reads it, two threads destroying the same world, and training and
// prediction beside stepping. Run as a test, and in a ThreadSanitizer build
// (tests/tsan_threads.cmake), where it must run clean. Usage: test_threads REPO_DIR
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "crowdmpm/crowdmpm.h"

namespace {

std::atomic<int> g_failed{0}, g_checks{0};

#define CHECK(cond)                                                                                   \
  do {                                                                                                \
    ++g_checks;                                                                                       \
    if (!(cond)) {                                                                                    \
      ++g_failed;                                                                                     \
      std::fprintf(stderr, "%s:%d: CHECK(%s) failed; last error: %s\n", __FILE__, __LINE__, #cond,    \
                   cmpm_GetLastError());                                                              \
    }                                                                                                 \
  } while (0)

std::string g_repo;

// A small room emptying through a door: quick to step, with agents leaving (the count changes).
const char* kRoom = R"({"format": "crowdmpm-scenario", "version": 1, "name": "threads",
  "domain": {"min": [0, 0], "max": [8, 6], "cell_size": 0.5}, "time": {"dt": 0.01, "duration": 60}, "seed": 3,
  "geometry": {"walls": [{"points": [[6, 0], [6, 2.5]]}, {"points": [[6, 3.5], [6, 6]]}],
               "exits": [{"id": "door", "rect": [7.5, 0, 8, 6]}]},
  "groups": [{"id": "g", "spawn": {"rect": [0.5, 0.5, 5.5, 5.5]}, "density": 3, "behaviour": {"type": "goal", "target": "door"}}]})";

cmpm_WorldId make_room(int threads) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  def.scenario_json = kRoom;
  def.threads = threads;
  cmpm_WorldId w{0, 0};
  if (cmpm_CreateWorld(&def, &w) != CMPM_OK) {
    std::fprintf(stderr, "cannot create the test world: %s\n", cmpm_GetLastError());
    std::exit(1);
  }
  return w;
}

uint64_t hash_of(cmpm_WorldId w) {
  uint64_t h = 0;
  CHECK(cmpm_World_GetStateHash(w, &h) == CMPM_OK);
  return h;
}

// Worlds on different threads run concurrently and give the single-threaded run's hash.
void different_worlds() {
  cmpm_WorldId ref = make_room(1);
  CHECK(cmpm_World_Step(ref, 150) == CMPM_OK);
  const uint64_t expected = hash_of(ref);
  CHECK(cmpm_DestroyWorld(ref) == CMPM_OK);
  std::vector<std::thread> ts;
  for (int t = 0; t < 4; ++t)
    ts.emplace_back([&, t] {
      cmpm_WorldId w = make_room(1 + t % 2);  // a world's own worker threads too
      for (int k = 0; k < 15; ++k) CHECK(cmpm_World_Step(w, 10) == CMPM_OK);
      CHECK(hash_of(w) == expected);
      CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
    });
  for (auto& t : ts) t.join();
}

// One world, one thread stepping, others reading, adding and removing agents, setting
// parameters and saving snapshots: every call returns a status, reads are consistent.
void one_world_many_threads() {
  cmpm_WorldId w = make_room(2);
  std::atomic<bool> done{false};
  std::thread stepper([&] {
    for (int k = 0; k < 60; ++k) CHECK(cmpm_World_Step(w, 2) == CMPM_OK);
    done = true;
  });
  std::thread reader([&] {
    std::vector<double> buf;
    while (!done) {
      int32_t n = 0, written = 0;
      CHECK(cmpm_World_GetAgentCount(w, &n) == CMPM_OK);
      buf.resize(2 * static_cast<size_t>(n) + 2);
      const cmpm_Status s = cmpm_World_GetPositions(w, buf.data(), static_cast<int32_t>(buf.size()), &written);
      // Another thread may step between the count and the read: then the buffer may be short.
      CHECK(s == CMPM_OK || s == CMPM_ERROR_BUFFER_TOO_SMALL);
      if (s == CMPM_OK) CHECK(written % 2 == 0);
      int32_t nx = 0, ny = 0;
      CHECK(cmpm_World_GetFieldShape(w, &nx, &ny, nullptr, nullptr, nullptr) == CMPM_OK);
      std::vector<double> field(2 * static_cast<size_t>(nx) * static_cast<size_t>(ny));
      CHECK(cmpm_World_GetField(w, CMPM_FIELD_VELOCITY, field.data(), static_cast<int32_t>(field.size()), &written) == CMPM_OK);
      double t = 0;
      CHECK(cmpm_World_GetTime(w, &t) == CMPM_OK);
      hash_of(w);
    }
  });
  std::thread writer([&] {
    int k = 0;
    while (!done) {
      cmpm_AgentDef a = cmpm_DefaultAgentDef();
      a.x = 1 + 0.01 * (k % 100);
      a.y = 1;
      a.target = "door";
      cmpm_AgentId id{0};
      CHECK(cmpm_World_AddAgent(w, &a, &id) == CMPM_OK);
      const cmpm_Status r = cmpm_World_RemoveAgent(w, id);
      CHECK(r == CMPM_OK);
      CHECK(cmpm_World_SetParameter(w, "tau", 0.5 + 0.001 * (k % 10)) == CMPM_OK);
      if (k % 10 == 0) CHECK(cmpm_World_SaveSnapshot(w, "threads_world.snap") == CMPM_OK);
      ++k;
    }
  });
  stepper.join();
  reader.join();
  writer.join();
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
  std::remove("threads_world.snap");
}

// Destroying a world while another thread is in a long step on it: the step finishes (or, if
// the destroy came first, fails as stale); the world is freed after; later calls are stale.
void destroy_during_step(int rounds) {
  for (int r = 0; r < rounds; ++r) {
    cmpm_WorldId w = make_room(1 + r % 2);
    std::atomic<bool> started{false};
    cmpm_Status step_status = CMPM_ERROR_INTERNAL;
    std::thread stepper([&] {
      started = true;
      step_status = cmpm_World_Step(w, 40);
    });
    std::vector<std::thread> readers;
    std::atomic<int> read_ok{0}, read_stale{0};
    for (int k = 0; k < 2; ++k)
      readers.emplace_back([&] {
        for (int i = 0; i < 20; ++i) {
          uint64_t h;
          const cmpm_Status s = cmpm_World_GetStateHash(w, &h);
          CHECK(s == CMPM_OK || s == CMPM_ERROR_STALE_HANDLE);
          (s == CMPM_OK ? read_ok : read_stale)++;
        }
      });
    while (!started) std::this_thread::yield();
    if (r % 3 != 0) std::this_thread::sleep_for(std::chrono::microseconds(200 * (r % 7)));
    CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
    stepper.join();
    for (auto& t : readers) t.join();
    CHECK(step_status == CMPM_OK || step_status == CMPM_ERROR_STALE_HANDLE);
    CHECK(cmpm_World_Step(w, 1) == CMPM_ERROR_STALE_HANDLE);
    CHECK(cmpm_World_IsValid(w) == 0);
  }
}

// Issue 13's race: two threads destroying the same world both got CMPM_OK in one of 300 runs.
void double_destroy(int rounds) {
  int both_ok = 0;
  for (int r = 0; r < rounds; ++r) {
    cmpm_WorldId w = make_room(1);
    std::atomic<int> go{0};
    cmpm_Status s1 = CMPM_ERROR_INTERNAL, s2 = CMPM_ERROR_INTERNAL;
    std::thread a([&] {
      ++go;
      while (go < 2) {}
      s1 = cmpm_DestroyWorld(w);
    });
    std::thread b([&] {
      ++go;
      while (go < 2) {}
      s2 = cmpm_DestroyWorld(w);
    });
    a.join();
    b.join();
    CHECK((s1 == CMPM_OK) != (s2 == CMPM_OK));
    CHECK(s1 == CMPM_ERROR_STALE_HANDLE || s2 == CMPM_ERROR_STALE_HANDLE);
    both_ok += s1 == CMPM_OK && s2 == CMPM_OK;
  }
  CHECK(both_ok == 0);
}

// Training and prediction (no world) beside a world stepping on another thread.
void jobs_beside_stepping() {
  const char* traj = "threads_walkers.txt";
  FILE* f = std::fopen(traj, "w");
  CHECK(f != nullptr);
  if (!f) return;
  std::fprintf(f, "# framerate: 10\n");
  for (int frame = 0; frame <= 40; ++frame)
    for (int id = 1; id <= 6; ++id)  // two rows of three in RiMEA test 1's corridor (2 m wide)
      std::fprintf(f, "%d %d %.3f %.3f\n", id, frame, 0.8 + 0.6 * ((id - 1) % 3) + 0.03 * frame, 0.6 + 0.8 * ((id - 1) / 3));
  std::fclose(f);
  const std::string scenario = g_repo + "/scenarios/rimea_01.json";
  cmpm_WorldId w = make_room(1);
  std::thread stepper([&] { CHECK(cmpm_World_Step(w, 60) == CMPM_OK); });
  std::thread predictor([&] {
    const std::string req = "{\"scenario\": \"" + scenario + "\", \"trajectories\": \"" + traj + "\", \"observe\": 1, \"horizon\": 1, \"windows\": 1}";
    CHECK(cmpm_PredictRecording(req.c_str(), "threads_prediction.json") == CMPM_OK);
  });
  std::thread trainer([&] {
    const std::string req = "{\"datasets\": [{\"scenario\": \"" + scenario + "\", \"trajectories\": [\"" + traj +
                            "\"]}], \"options\": {\"window\": 1, \"iterations\": 1, \"batch\": 1, \"params\": [\"tau\"], "
                            "\"learn_network\": false, \"validation\": 0.3, \"eval_every\": 1}}";
    CHECK(cmpm_TrainModel(req.c_str(), "threads_model.json") == CMPM_OK);
  });
  stepper.join();
  predictor.join();
  trainer.join();
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
  for (const char* p : {traj, "threads_prediction.json", "threads_model.json"}) std::remove(p);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: test_threads REPO_DIR\n");
    return 2;
  }
  g_repo = argv[1];
  // Fewer rounds under a sanitizer (CROWDMPM_THREADS_ROUNDS), where every call is slower.
  const char* env = std::getenv("CROWDMPM_THREADS_ROUNDS");
  const int rounds = env ? std::atoi(env) : 300;
  different_worlds();
  one_world_many_threads();
  destroy_during_step(rounds / 10);
  double_destroy(rounds);
  jobs_beside_stepping();
  std::printf("threads: %d checks, %d failed\n", g_checks.load(), g_failed.load());
  return g_failed == 0 ? 0 : 1;
}
