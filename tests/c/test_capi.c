/* C99 test of the C ABI: the drill through cmpm_* calls gives the same state hash as the C++
 * engine; bulk reads work; every misuse returns its status code and a message, never a crash.
 * Usage: test_capi REPO_DIR */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crowdmpm/crowdmpm.h"
#include "expected_hashes.h"

static int passed = 0, failed = 0;

#define CHECK(cond)                                                              \
  do {                                                                           \
    if (cond) {                                                                  \
      ++passed;                                                                  \
    } else {                                                                     \
      ++failed;                                                                  \
      fprintf(stderr, "%s:%d: CHECK(%s) failed; last error: %s\n", __FILE__,     \
              __LINE__, #cond, cmpm_GetLastError());                             \
    }                                                                            \
  } while (0)

/* The call fails with `status` and the message mentions `word`. */
#define CHECK_FAILS(call, status, word)                                          \
  do {                                                                           \
    cmpm_Status s_ = (call);                                                     \
    CHECK(s_ == (status));                                                       \
    CHECK(strstr(cmpm_GetLastError(), (word)) != NULL);                          \
  } while (0)

static char drill_path[4096];

static cmpm_WorldId make_drill(void) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  cmpm_WorldId w;
  def.scenario_path = drill_path;
  CHECK(cmpm_CreateWorld(&def, &w) == CMPM_OK);
  return w;
}

static void test_hash_and_bulk_reads(void) {
  cmpm_WorldId w = make_drill();
  uint64_t hash = 0;
  int32_t n = 0, written = 0, i;
  double *xy, t = 0, xmin = 1e300, xmax = -1e300;
  CHECK(cmpm_World_IsValid(w) == 1);
  CHECK(cmpm_World_Step(w, CMPM_EXPECTED_DRILL_STEPS) == CMPM_OK);
  CHECK(cmpm_World_GetStateHash(w, &hash) == CMPM_OK);
  if (hash != CMPM_EXPECTED_DRILL_HASH)
    fprintf(stderr, "hash 0x%016llx, expected 0x%016llx\n", (unsigned long long)hash, (unsigned long long)CMPM_EXPECTED_DRILL_HASH);
  CHECK(hash == CMPM_EXPECTED_DRILL_HASH);
  CHECK(cmpm_World_GetTime(w, &t) == CMPM_OK);
  CHECK(fabs(t - CMPM_EXPECTED_DRILL_STEPS * 0.01) < 1e-9);
  CHECK(cmpm_World_GetAgentCount(w, &n) == CMPM_OK);
  CHECK(n > 250);
  xy = (double*)malloc(sizeof(double) * 2 * (size_t)n);
  /* capacity counts doubles, the length of the buffer (ABI 2), as for every bulk read. */
  CHECK(cmpm_World_GetPositions(w, xy, 2 * n, &written) == CMPM_OK);
  CHECK(written == 2 * n);
  for (i = 0; i < n; ++i) {
    if (xy[2 * i] < xmin) xmin = xy[2 * i];
    if (xy[2 * i] > xmax) xmax = xy[2 * i];
  }
  CHECK(xmin >= 0 && xmax <= 11); /* the drill's domain */
  /* One double short: refused, nothing written; a count of agents is no longer enough (issue 13's trap). */
  CHECK_FAILS(cmpm_World_GetPositions(w, xy, 2 * n - 1, &written), CMPM_ERROR_BUFFER_TOO_SMALL, "buffer holds");
  CHECK(written == 0);
  CHECK_FAILS(cmpm_World_GetVelocities(w, xy, n, &written), CMPM_ERROR_BUFFER_TOO_SMALL, "velocities (doubles)");
  free(xy);
  {
    int32_t nx = 0, ny = 0, wr = 0;
    double ox, oy, cell, *f, total = 0;
    CHECK(cmpm_World_GetFieldShape(w, &nx, &ny, &ox, &oy, &cell) == CMPM_OK);
    CHECK(nx > 0 && ny > 0 && cell == 0.5);
    f = (double*)malloc(sizeof(double) * 2 * (size_t)nx * (size_t)ny);
    CHECK(cmpm_World_GetField(w, CMPM_FIELD_DENSITY, f, nx * ny, &wr) == CMPM_OK);
    for (i = 0; i < wr; ++i) total += f[i] * cell * cell;
    CHECK(fabs(total - n) < 1e-6 * n); /* density integrates to the head count */
    CHECK_FAILS(cmpm_World_GetField(w, CMPM_FIELD_VELOCITY, f, nx * ny, &wr), CMPM_ERROR_BUFFER_TOO_SMALL, "field");
    CHECK_FAILS(cmpm_World_GetField(w, 7, f, 2 * nx * ny, &wr), CMPM_ERROR_INVALID_ARGUMENT, "unknown field");
    free(f);
  }
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
}

static void test_agents_and_parameters(void) {
  cmpm_WorldId w = make_drill();
  cmpm_AgentDef a = cmpm_DefaultAgentDef();
  cmpm_AgentId id, zero = {0};
  double x, y, vx, vy, e;
  a.x = 9.5; /* outside the room, beyond the door */
  a.y = 4.0;
  a.target = "door";
  CHECK(cmpm_World_AddAgent(w, &a, &id) == CMPM_OK);
  CHECK(cmpm_World_GetAgentState(w, id, &x, &y, &vx, &vy) == CMPM_OK);
  CHECK(x == 9.5 && y == 4.0);
  CHECK(cmpm_World_SetAgentTarget(w, id, "nearest_exit") == CMPM_OK);
  CHECK_FAILS(cmpm_World_SetAgentTarget(w, id, "nowhere"), CMPM_ERROR_INVALID_ARGUMENT, "nowhere");
  CHECK(cmpm_World_RemoveAgent(w, id) == CMPM_OK);
  CHECK_FAILS(cmpm_World_GetAgentState(w, id, &x, &y, &vx, &vy), CMPM_ERROR_STALE_HANDLE, "was removed");
  CHECK_FAILS(cmpm_World_RemoveAgent(w, id), CMPM_ERROR_STALE_HANDLE, "was removed");
  CHECK_FAILS(cmpm_World_RemoveAgent(w, zero), CMPM_ERROR_NULL_HANDLE, "null agent");
  a.x = 8.1; /* inside the wall */
  a.y = 1.0;
  CHECK_FAILS(cmpm_World_AddAgent(w, &a, &id), CMPM_ERROR_INVALID_ARGUMENT, "inside a wall");
  a.x = 2;
  a.y = 2;
  a.target = NULL;
  a.group = 5;
  CHECK_FAILS(cmpm_World_AddAgent(w, &a, &id), CMPM_ERROR_INVALID_ARGUMENT, "group 5 out of range");
  a.group = -1;
  CHECK_FAILS(cmpm_World_AddAgent(w, &a, &id), CMPM_ERROR_INVALID_ARGUMENT, "needs a target or a group");
  a.group = 0;
  a.body_radius = 3;
  CHECK_FAILS(cmpm_World_AddAgent(w, &a, &id), CMPM_ERROR_INVALID_ARGUMENT, "body_radius");
  a.body_radius = NAN;
  CHECK_FAILS(cmpm_World_AddAgent(w, &a, &id), CMPM_ERROR_INVALID_ARGUMENT, "body_radius");

  /* Several agents in one call: all or none. */
  {
    cmpm_AgentDef batch[3];
    cmpm_AgentId ids[3];
    int32_t before = 0, after = 0, k;
    CHECK(cmpm_World_GetAgentCount(w, &before) == CMPM_OK);
    for (k = 0; k < 3; ++k) {
      batch[k] = cmpm_DefaultAgentDef();
      batch[k].x = 2 + 0.6 * k;
      batch[k].y = 2;
      batch[k].target = "door";
    }
    batch[2].x = 8.1; /* inside the wall */
    batch[2].y = 1.0;
    CHECK_FAILS(cmpm_World_AddAgents(w, batch, 3, ids), CMPM_ERROR_INVALID_ARGUMENT, "agent 2 of 3");
    CHECK(cmpm_World_GetAgentCount(w, &after) == CMPM_OK && after == before);
    CHECK(ids[0].value == 0 && ids[1].value == 0);
    batch[2].x = 3.2;
    batch[2].y = 2;
    batch[1].target = "nowhere";
    CHECK_FAILS(cmpm_World_AddAgents(w, batch, 3, ids), CMPM_ERROR_INVALID_ARGUMENT, "agent 1 of 3");
    batch[1].target = "door";
    CHECK(cmpm_World_AddAgents(w, batch, 3, ids) == CMPM_OK);
    CHECK(cmpm_World_GetAgentCount(w, &after) == CMPM_OK && after == before + 3);
    CHECK(cmpm_World_GetAgentState(w, ids[2], &x, &y, &vx, &vy) == CMPM_OK && x == 3.2 && y == 2);
    CHECK(cmpm_World_AddAgents(w, NULL, 0, NULL) == CMPM_OK);
    CHECK_FAILS(cmpm_World_AddAgents(w, batch, -1, ids), CMPM_ERROR_INVALID_ARGUMENT, "count must be >= 0");
    CHECK_FAILS(cmpm_World_AddAgents(w, NULL, 2, ids), CMPM_ERROR_INVALID_ARGUMENT, "defs");
    for (k = 0; k < 3; ++k) CHECK(cmpm_World_RemoveAgent(w, ids[k]) == CMPM_OK);
  }

  CHECK(cmpm_World_GetParameter(w, "E", &e) == CMPM_OK);
  CHECK(e == 20);
  CHECK(cmpm_World_SetParameter(w, "E", 35) == CMPM_OK);
  CHECK(cmpm_World_GetParameter(w, "E", &e) == CMPM_OK && e == 35);
  CHECK_FAILS(cmpm_World_SetParameter(w, "E", -1), CMPM_ERROR_INVALID_ARGUMENT, "E must be in");
  CHECK_FAILS(cmpm_World_SetParameter(w, "E", NAN), CMPM_ERROR_INVALID_ARGUMENT, "E must be in");
  CHECK_FAILS(cmpm_World_GetParameter(w, "stiffness", &e), CMPM_ERROR_INVALID_ARGUMENT, "unknown material parameter");
  CHECK(cmpm_World_LoadTraction(w, "{\"constant\": 3}") == CMPM_OK);
  CHECK_FAILS(cmpm_World_LoadTraction(w, "{\"layers\": [{\"weights\": [[1, 2]], \"biases\": [0]}]}"),
              CMPM_ERROR_INVALID_INPUT, "traction.layers[0].weights[0]");
  CHECK_FAILS(cmpm_World_LoadTraction(w, "{\"constant\": "), CMPM_ERROR_INVALID_INPUT, "invalid JSON");
  CHECK(cmpm_World_Step(w, 5) == CMPM_OK);
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
}

static void test_misuse(void) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef(), raw;
  cmpm_WorldId w, null_world = {0, 0}, bogus = {77, 1};
  cmpm_AgentDef agent_raw;
  cmpm_AgentId id;
  double t, buf[4];
  int32_t n;
  uint64_t h;

  /* Def structs not made by their default functions. */
  memset(&raw, 0, sizeof raw);
  raw.scenario_path = drill_path;
  raw.threads = 1;
  CHECK_FAILS(cmpm_CreateWorld(&raw, &w), CMPM_ERROR_UNINITIALIZED_DEF, "cmpm_DefaultWorldDef");
  CHECK(w.index1 == 0);
  CHECK_FAILS(cmpm_CreateWorld(NULL, &w), CMPM_ERROR_INVALID_ARGUMENT, "def is NULL");
  def.scenario_path = drill_path;
  CHECK_FAILS(cmpm_CreateWorld(&def, NULL), CMPM_ERROR_INVALID_ARGUMENT, "out_world is NULL");
  def.threads = 0;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_ARGUMENT, "threads");
  def.threads = 1;
  def.scenario_json = "{}";
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_ARGUMENT, "exactly one of scenario_json, scenario_path or snapshot_path");
  def.scenario_path = NULL;
  def.scenario_json = "{\"format\": \"crowdmpm-scenario\", \"version\": 1,";
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "invalid JSON");
  def.scenario_json = "{\"format\": \"crowdmpm-scenario\", \"version\": 1, \"domain\": {\"min\": [0, 0], \"max\": [5, 5]},"
                      " \"time\": {\"duration\": 1}, \"groups\": [{\"spawn\": {\"rect\": [1, 1, 2, 2]}, \"density\": -2}]}";
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "groups[0].density");
  def.scenario_json = NULL;
  def.scenario_path = "/nonexistent/scenario.json";
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "/nonexistent/scenario.json");

  /* Null and never-created worlds. */
  CHECK_FAILS(cmpm_World_Step(null_world, 1), CMPM_ERROR_NULL_HANDLE, "null world");
  CHECK_FAILS(cmpm_World_GetTime(bogus, &t), CMPM_ERROR_STALE_HANDLE, "does not exist");
  CHECK(cmpm_World_IsValid(null_world) == 0);
  CHECK(cmpm_World_IsValid(bogus) == 0);

  /* A destroyed world. */
  w = make_drill();
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
  CHECK(cmpm_World_IsValid(w) == 0);
  CHECK_FAILS(cmpm_World_Step(w, 1), CMPM_ERROR_STALE_HANDLE, "destroyed");
  CHECK_FAILS(cmpm_World_GetStateHash(w, &h), CMPM_ERROR_STALE_HANDLE, "destroyed");
  CHECK_FAILS(cmpm_DestroyWorld(w), CMPM_ERROR_STALE_HANDLE, "destroyed");
  {
    /* Its slot is reused with a new generation; the old id stays stale. */
    cmpm_WorldId w2 = make_drill();
    CHECK(w2.index1 == w.index1 && w2.generation != w.generation);
    CHECK_FAILS(cmpm_World_GetAgentCount(w, &n), CMPM_ERROR_STALE_HANDLE, "destroyed");

    /* Out-of-range steps and time steps, NULL outputs, zeroed agent def. */
    CHECK_FAILS(cmpm_World_Step(w2, -1), CMPM_ERROR_INVALID_ARGUMENT, "steps must be in");
    CHECK_FAILS(cmpm_World_Step(w2, 20000000), CMPM_ERROR_INVALID_ARGUMENT, "steps must be in");
    CHECK_FAILS(cmpm_World_SetTimeStep(w2, 0), CMPM_ERROR_INVALID_ARGUMENT, "time.dt");
    CHECK_FAILS(cmpm_World_SetTimeStep(w2, NAN), CMPM_ERROR_INVALID_ARGUMENT, "time.dt");
    CHECK_FAILS(cmpm_World_SetTimeStep(w2, 0.09), CMPM_ERROR_INVALID_ARGUMENT, "too large");
    CHECK(cmpm_World_Step(w2, 100) == CMPM_OK);
    CHECK(cmpm_World_SetTimeStep(w2, 0.005) == CMPM_OK);
    CHECK(cmpm_World_GetTimeStep(w2, &t) == CMPM_OK && t == 0.005);
    CHECK(cmpm_World_GetTime(w2, &t) == CMPM_OK && fabs(t - 1.0) < 1e-12); /* the past is kept */
    CHECK(cmpm_World_Step(w2, 100) == CMPM_OK);
    CHECK(cmpm_World_GetTime(w2, &t) == CMPM_OK && fabs(t - 1.5) < 1e-12);
    CHECK_FAILS(cmpm_World_GetTime(w2, NULL), CMPM_ERROR_INVALID_ARGUMENT, "out_seconds is NULL");
    CHECK_FAILS(cmpm_World_GetPositions(w2, NULL, 1000, &n), CMPM_ERROR_INVALID_ARGUMENT, "out is NULL");
    CHECK_FAILS(cmpm_World_GetPositions(w2, buf, -5, &n), CMPM_ERROR_INVALID_ARGUMENT, "capacity");
    CHECK_FAILS(cmpm_World_GetPositions(w2, buf, 2, NULL), CMPM_ERROR_INVALID_ARGUMENT, "out_written is NULL");
    memset(&agent_raw, 0, sizeof agent_raw);
    CHECK_FAILS(cmpm_World_AddAgent(w2, &agent_raw, &id), CMPM_ERROR_UNINITIALIZED_DEF, "cmpm_DefaultAgentDef");
    CHECK(cmpm_DestroyWorld(w2) == CMPM_OK);
  }
  /* A successful call clears the message. */
  CHECK(strcmp(cmpm_GetVersion(), "0.1.0") == 0);
  CHECK(cmpm_GetAbiVersion() == CMPM_ABI_VERSION);
}

/* Snapshots: save at step 200, restore (on another thread count), run both to 400: the same
 * hash as the uninterrupted run; damaged files are refused with a clear error. */
static void test_snapshots(void) {
  const char* snap = "capi_drill_200.snap";
  cmpm_WorldId a = make_drill(), b = {0, 0};
  uint64_t ha = 0, hb = 0;
  double t = 0;
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  CHECK(cmpm_World_Step(a, 200) == CMPM_OK);
  remove(snap);
  CHECK(cmpm_World_SaveSnapshot(a, snap) == CMPM_OK);
  def.snapshot_path = snap;
  def.threads = 2;
  CHECK(cmpm_CreateWorld(&def, &b) == CMPM_OK);
  CHECK(cmpm_World_GetTime(b, &t) == CMPM_OK && fabs(t - 2.0) < 1e-12);
  CHECK(cmpm_World_Step(a, CMPM_EXPECTED_DRILL_STEPS - 200) == CMPM_OK);
  CHECK(cmpm_World_Step(b, CMPM_EXPECTED_DRILL_STEPS - 200) == CMPM_OK);
  CHECK(cmpm_World_GetStateHash(a, &ha) == CMPM_OK);
  CHECK(cmpm_World_GetStateHash(b, &hb) == CMPM_OK);
  CHECK(ha == CMPM_EXPECTED_DRILL_HASH);
  CHECK(hb == CMPM_EXPECTED_DRILL_HASH);
  CHECK(cmpm_DestroyWorld(b) == CMPM_OK);
  CHECK_FAILS(cmpm_World_SaveSnapshot(a, NULL), CMPM_ERROR_INVALID_ARGUMENT, "path is NULL");
  CHECK_FAILS(cmpm_World_SaveSnapshot(a, "/nonexistent-folder/x.snap"), CMPM_ERROR_INVALID_ARGUMENT, "cannot open for writing");
  /* Truncated and corrupted copies. */
  {
    static char bytes[1 << 20];
    FILE* f = fopen(snap, "rb");
    size_t n = f ? fread(bytes, 1, sizeof bytes, f) : 0;
    if (f) fclose(f);
    CHECK(n > 1000 && n < sizeof bytes);
    f = fopen("capi_cut.snap", "wb");
    fwrite(bytes, 1, n / 2, f);
    fclose(f);
    def.snapshot_path = "capi_cut.snap";
    CHECK_FAILS(cmpm_CreateWorld(&def, &b), CMPM_ERROR_INVALID_INPUT, "truncated snapshot");
    bytes[n / 2] ^= 0x40;
    f = fopen("capi_bad.snap", "wb");
    fwrite(bytes, 1, n, f);
    fclose(f);
    def.snapshot_path = "capi_bad.snap";
    CHECK_FAILS(cmpm_CreateWorld(&def, &b), CMPM_ERROR_INVALID_INPUT, "checksum");
    def.snapshot_path = drill_path;
    CHECK_FAILS(cmpm_CreateWorld(&def, &b), CMPM_ERROR_INVALID_INPUT, "not a CrowdMPM snapshot");
    def.snapshot_path = snap;
    def.model_path = drill_path;
    CHECK_FAILS(cmpm_CreateWorld(&def, &b), CMPM_ERROR_INVALID_ARGUMENT, "a snapshot holds its model");
    def.model_path = NULL;
    def.scenario_path = drill_path;
    CHECK_FAILS(cmpm_CreateWorld(&def, &b), CMPM_ERROR_INVALID_ARGUMENT, "exactly one of scenario_json, scenario_path or snapshot_path");
  }
  CHECK(cmpm_DestroyWorld(a) == CMPM_OK);
}

/* Bounded, confined input through the ABI (issue 13): a scenario naming /dev/zero as its model,
 * with and without allow_outside_paths, and a tiny input limit. */
static void test_input_limits(void) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  cmpm_WorldId w = {0, 0};
  const char* zero_model =
      "{\"format\": \"crowdmpm-scenario\", \"version\": 1, \"domain\": {\"min\": [0, 0], \"max\": [4, 4]},"
      " \"time\": {\"dt\": 0.01, \"duration\": 1}, \"model\": \"/dev/zero\"}";
  def.scenario_json = zero_model;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "lies outside the folder");
  def.allow_outside_paths = 1;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "is not a regular file");
  def.allow_outside_paths = 2;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_ARGUMENT, "allow_outside_paths must be 0 or 1");
  def = cmpm_DefaultWorldDef();
  def.scenario_path = drill_path;
  def.max_input_bytes = 100;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_INPUT, "above the input limit");
  def.max_input_bytes = -1;
  CHECK_FAILS(cmpm_CreateWorld(&def, &w), CMPM_ERROR_INVALID_ARGUMENT, "max_input_bytes");
}

/* Learning through the ABI: a recording of people walking down the bottleneck corridor, written
 * here, is fitted; the model file loads as a world's model; bad requests are errors. */
static char repo_dir[4096];
static void test_train(void) {
  char traj[64], scen[8192], request[32768], model[] = "capi_learned_model.json";
  snprintf(traj, sizeof traj, "capi_walkers.txt");
  snprintf(scen, sizeof scen, "%s/scenarios/bottleneck.json", repo_dir);
  FILE* f = fopen(traj, "w");
  CHECK(f != NULL);
  if (!f) return;
  fprintf(f, "# framerate: 10\n# unit: m\n");
  for (int frame = 0; frame <= 120; ++frame)
    for (int id = 1; id <= 12; ++id) {
      const double x = -2.0 + 0.8 * ((id - 1) % 6), y = 6.0 - 0.6 * ((id - 1) / 6) - 0.03 * frame;
      fprintf(f, "%d %d %.4f %.4f 0\n", id, frame, x, y);
    }
  fclose(f);
  snprintf(request, sizeof request,
           "{\"datasets\": [{\"scenario\": \"%s\", \"trajectories\": [\"%s\"]}],"
           " \"options\": {\"window\": 1, \"iterations\": 2, \"params\": [\"tau\", \"v0_scale\"],"
           " \"learn_network\": false, \"threads\": 2}}",
           scen, traj);
  remove(model);
  CHECK(cmpm_TrainModel(request, model) == CMPM_OK);
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  cmpm_WorldId w = {0, 0};
  def.scenario_path = scen;
  def.model_path = model;
  CHECK(cmpm_CreateWorld(&def, &w) == CMPM_OK);
  double v0 = 0;
  CHECK(cmpm_World_GetParameter(w, "v0_scale", &v0) == CMPM_OK);
  CHECK(v0 > 0.5 && v0 < 2); /* the learned model's, within the trainer's reach of the start */
  CHECK(cmpm_DestroyWorld(w) == CMPM_OK);
  /* Predict the recording with the learned model. */
  snprintf(request, sizeof request,
           "{\"scenario\": \"%s\", \"trajectories\": \"%s\", \"models\": [\"%s\"], \"observe\": 2, \"horizon\": 3}",
           scen, traj, model);
  remove("capi_prediction.json");
  CHECK(cmpm_PredictRecording(request, "capi_prediction.json") == CMPM_OK);
  {
    char text[65536] = {0};
    FILE* pf = fopen("capi_prediction.json", "r");
    CHECK(pf != NULL);
    if (pf) {
      size_t got = fread(text, 1, sizeof text - 1, pf);
      fclose(pf);
      CHECK(got > 0);
      CHECK(strstr(text, "constant velocity") != NULL);
      CHECK(strstr(text, "learned crowd") != NULL);
      CHECK(strstr(text, "ade_m") != NULL);
    }
  }
  CHECK_FAILS(cmpm_PredictRecording(NULL, "x.json"), CMPM_ERROR_INVALID_ARGUMENT, "request_json");
  CHECK_FAILS(cmpm_PredictRecording("{\"scenario\": 3}", "x.json"), CMPM_ERROR_INVALID_INPUT, "scenario");
  snprintf(request, sizeof request, "{\"scenario\": \"%s\", \"trajectories\": \"%s\", \"observe\": 10, \"horizon\": 10}", scen, traj);
  CHECK_FAILS(cmpm_PredictRecording(request, "x.json"), CMPM_ERROR_INVALID_INPUT, "exceed the recording");
  /* Misuse and bad requests. */
  CHECK_FAILS(cmpm_TrainModel(NULL, model), CMPM_ERROR_INVALID_ARGUMENT, "request_json");
  CHECK_FAILS(cmpm_TrainModel(request, NULL), CMPM_ERROR_INVALID_ARGUMENT, "out_model_path");
  CHECK_FAILS(cmpm_TrainModel("{\"datasets\": [", model), CMPM_ERROR_INVALID_INPUT, "invalid JSON");
  CHECK_FAILS(cmpm_TrainModel("{\"datasets\": []}", model), CMPM_ERROR_INVALID_INPUT, "datasets");
  CHECK_FAILS(cmpm_TrainModel("{\"datasets\": [{\"scenario\": \"nowhere.json\", \"trajectories\": [\"x\"]}]}", model),
              CMPM_ERROR_INVALID_INPUT, "nowhere.json");
  snprintf(request, sizeof request,
           "{\"datasets\": [{\"scenario\": \"%s\", \"trajectories\": [\"%s\"]}], \"options\": {\"window\": -1}}", scen, traj);
  CHECK_FAILS(cmpm_TrainModel(request, model), CMPM_ERROR_INVALID_INPUT, "options.window");
  snprintf(request, sizeof request,
           "{\"datasets\": [{\"scenario\": \"%s\", \"trajectories\": [\"%s\"]}], \"options\": {\"params\": [\"nonsense\"]}}", scen, traj);
  CHECK_FAILS(cmpm_TrainModel(request, model), CMPM_ERROR_INVALID_INPUT, "nonsense");
  /* An output that cannot be written fails before the work, naming it. */
  snprintf(request, sizeof request,
           "{\"datasets\": [{\"scenario\": \"%s\", \"trajectories\": [\"%s\"]}], \"options\": {\"window\": 1, \"iterations\": 2}}",
           scen, traj);
  CHECK_FAILS(cmpm_TrainModel(request, "."), CMPM_ERROR_INVALID_ARGUMENT, "is a folder");
  snprintf(request, sizeof request, "{\"scenario\": \"%s\", \"trajectories\": \"%s\", \"observe\": 2, \"horizon\": 3}", scen, traj);
  CHECK_FAILS(cmpm_PredictRecording(request, "capi_walkers.txt/prediction.json"), CMPM_ERROR_INVALID_ARGUMENT, "does not exist");
  /* Diagnosis of the same recording in its venue: the report and its pictures, and bad requests. */
  snprintf(request, sizeof request,
           "{\"scenario\": \"%s\", \"trajectories\": \"%s\", \"options\": {\"window\": 1, \"iterations\": 2, "
           "\"null_replicates\": 1, \"max_terms\": 1, \"candidates\": [\"drift\"]}}", scen, traj);
  remove("capi_diagnosis/report.json");
  CHECK(cmpm_Diagnose(request, "capi_diagnosis") == CMPM_OK);
  {
    char text[1 << 16] = {0};
    FILE* rf = fopen("capi_diagnosis/report.json", "r");
    CHECK(rf != NULL);
    if (rf) {
      size_t got = fread(text, 1, sizeof text - 1, rf);
      fclose(rf);
      CHECK(got > 0);
      CHECK(strstr(text, "\"verdict\"") != NULL);
      CHECK(strstr(text, "\"hypotheses\"") != NULL);
    }
    FILE* pf = fopen("capi_diagnosis/residual_before.png", "rb");
    CHECK(pf != NULL);
    if (pf) fclose(pf);
  }
  CHECK_FAILS(cmpm_Diagnose(NULL, "capi_diagnosis"), CMPM_ERROR_INVALID_ARGUMENT, "request_json");
  CHECK_FAILS(cmpm_Diagnose(request, NULL), CMPM_ERROR_INVALID_ARGUMENT, "out_dir");
  CHECK_FAILS(cmpm_Diagnose(request, traj), CMPM_ERROR_INVALID_ARGUMENT, "in the way"); /* a file where the folder goes */
  CHECK_FAILS(cmpm_Diagnose("{\"scenario\": ", "capi_diagnosis"), CMPM_ERROR_INVALID_INPUT, "invalid JSON");
  snprintf(request, sizeof request, "{\"scenario\": \"%s\", \"trajectories\": \"%s\", \"options\": {\"candidates\": [\"ghost\"]}}",
           scen, traj);
  CHECK_FAILS(cmpm_Diagnose(request, "capi_diagnosis"), CMPM_ERROR_INVALID_INPUT, "ghost");
}

int main(int argc, char** argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: test_capi REPO_DIR\n");
    return 2;
  }
  snprintf(drill_path, sizeof drill_path, "%s/scenarios/drill.json", argv[1]);
  snprintf(repo_dir, sizeof repo_dir, "%s", argv[1]);
  test_hash_and_bulk_reads();
  test_agents_and_parameters();
  test_misuse();
  test_snapshots();
  test_input_limits();
  test_train();
  printf("capi: %d passed, %d failed\n", passed, failed);
  return failed ? 1 : 0;
}
