/* CrowdMPM stable C ABI.
 *
 * Pure C (C99 and C++), one export macro, no C++ types or exceptions cross it. Every call that
 * can fail returns a cmpm_Status; on failure a message saying what and where is available from
 * cmpm_GetLastError() on the same thread. Handles are small value structs: a zeroed handle is
 * null, and a destroyed world's handle is detected (generation count) rather than crashing.
 *
 * Units are SI: metres, seconds, persons/m^2, m/s. Buffers are owned by the caller. Every bulk
 * read takes `capacity` as the number of elements of the buffer it is given (doubles for a
 * double buffer, ids for an id buffer: the array's length, never a count of agents or nodes)
 * and sets *out_written to the number of elements it wrote; it fails with
 * CMPM_ERROR_BUFFER_TOO_SMALL (writing nothing) if the capacity is short. Positions take 2
 * doubles per agent, a velocity field 2 per node: query the count or shape first.
 *
 * Thread contract (ABI version 2):
 *  - Any function may be called from any thread. Calls on different worlds run concurrently;
 *    calls on the same world are serialised (each holds the world for its whole duration), so
 *    a read never sees a half-made step. cmpm_TrainModel, cmpm_PredictRecording and cmpm_Diagnose use no
 *    world and run concurrently with anything.
 *  - cmpm_DestroyWorld while another thread is in a call on that world waits for that call to
 *    return, then frees the world; calls that were waiting to start on it, and every later
 *    call, fail with CMPM_ERROR_STALE_HANDLE. Memory is never freed under a running call.
 *  - Checking a handle and destroying it are one atomic step: of two threads destroying the
 *    same world, one gets CMPM_OK and the other CMPM_ERROR_STALE_HANDLE.
 *  - cmpm_GetLastError is per thread. A world's own worker threads (threads > 1) are internal.
 *  - Do not destroy a world from a thread that must not block: it waits for the call in progress.
 *
 * Input files (scenario, model, snapshot) must be regular files below an input size limit (256
 * MiB unless max_input_bytes says otherwise); files a scenario names ("model", "extends") must
 * lie inside its folder (scenario_json: the working directory) unless allow_outside_paths is 1
 * (docs/scenario-format.md, "Files a scenario names"). Messages never quote file contents.
 *
 * The number of functions does not depend on the number of materials or force terms: the
 * material and its parameters are addressed by name, models and scenarios are JSON.
 */
#ifndef CROWDMPM_H
#define CROWDMPM_H

#include <stddef.h>
#include <stdint.h>

#define CMPM_VERSION_MAJOR 0
#define CMPM_VERSION_MINOR 1
#define CMPM_VERSION_PATCH 0
/* Incremented whenever a struct layout or a function signature changes incompatibly. */
#define CMPM_ABI_VERSION 2

#if defined(_WIN32)
#  if defined(CROWDMPM_BUILDING)
#    define CMPM_API __declspec(dllexport)
#  else
#    define CMPM_API __declspec(dllimport)
#  endif
#else
#  define CMPM_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef enum cmpm_Status {
  CMPM_OK = 0,
  CMPM_ERROR_NULL_HANDLE = 1,         /* a zeroed (null) world handle */
  CMPM_ERROR_STALE_HANDLE = 2,        /* a destroyed world, or a removed agent */
  CMPM_ERROR_INVALID_ARGUMENT = 3,    /* null pointer, value out of range, unknown name */
  CMPM_ERROR_INVALID_INPUT = 4,       /* scenario or model JSON that does not parse or validate */
  CMPM_ERROR_BUFFER_TOO_SMALL = 5,
  CMPM_ERROR_UNINITIALIZED_DEF = 6,   /* a def struct not made by its cmpm_Default... function */
  CMPM_ERROR_SIMULATION = 7,          /* the simulation became unstable (non-finite state) */
  CMPM_ERROR_INTERNAL = 8
} cmpm_Status;

/* A world. index1 counts from 1 so that a zeroed id is null. */
typedef struct cmpm_WorldId {
  uint32_t index1;
  uint32_t generation;
} cmpm_WorldId;

/* An agent of a world. Agent ids are never reused within a world, so the id of a removed agent
 * stays stale forever (CMPM_ERROR_STALE_HANDLE) and never aliases a newer agent. 0 is null. */
typedef struct cmpm_AgentId {
  uint64_t value;
} cmpm_AgentId;

typedef enum cmpm_Field {
  CMPM_FIELD_DENSITY = 0,   /* persons/m^2, one value per grid node */
  CMPM_FIELD_PRESSURE = 1,  /* model stress units, one value per node */
  CMPM_FIELD_VELOCITY = 2   /* m/s, two values (vx, vy) per node */
} cmpm_Field;

/* World definition. Give the scenario as JSON text or as a file path, or a snapshot saved by
 * cmpm_World_SaveSnapshot (exactly one of the three), and optionally a model as JSON text or
 * path (otherwise the scenario's model, else the default; a snapshot holds its own model). File
 * names inside scenario_json ("model", "extends") are relative to the working directory.
 * Strings are copied during cmpm_CreateWorld; the caller keeps ownership. */
typedef struct cmpm_WorldDef {
  const char* scenario_json;
  const char* scenario_path;
  const char* model_json;
  const char* model_path;
  const char* snapshot_path;   /* restore a saved world: it continues bit-identically */
  int64_t max_input_bytes;     /* largest file read, bytes; 0: the default, 256 MiB */
  int32_t allow_outside_paths; /* 1: a scenario may name files outside its folder. Default 0. */
  int32_t threads;             /* worker threads, 1..256; results do not depend on it. Default 1. */
  int32_t internal_cookie;     /* set by cmpm_DefaultWorldDef; do not touch */
} cmpm_WorldDef;

/* One agent. target: id of an exit or goal to walk to, or "nearest_exit"; NULL gives the
 * behaviour of group `group` (index into the scenario's groups then sources). group also
 * selects which group-restricted scenario forces act on the agent; -1 (the default) is no
 * group: only forces that apply to everyone. */
typedef struct cmpm_AgentDef {
  double x, y;               /* position, m */
  double vx, vy;             /* velocity, m/s */
  double body_radius;        /* m, [0.05, 0.5]; default: the model's */
  double comfort_distance;   /* m, [0.01, 2]; default: the model's */
  double desired_speed;      /* m/s, [0, 12]; default 1.3 */
  const char* target;
  int32_t group;
  int32_t internal_cookie;   /* set by cmpm_DefaultAgentDef; do not touch */
} cmpm_AgentDef;

/* Version "MAJOR.MINOR.PATCH" of the library actually loaded, and its ABI version. */
CMPM_API const char* cmpm_GetVersion(void);
CMPM_API int32_t cmpm_GetAbiVersion(void);

/* The message of the last failed call on this thread ("" if none). Valid until the next call
 * into the library on this thread. */
CMPM_API const char* cmpm_GetLastError(void);

CMPM_API cmpm_WorldDef cmpm_DefaultWorldDef(void);
CMPM_API cmpm_AgentDef cmpm_DefaultAgentDef(void);

/* Worlds. Creating places the scenario's groups; destroying invalidates the id. */
CMPM_API cmpm_Status cmpm_CreateWorld(const cmpm_WorldDef* def, cmpm_WorldId* out_world);
CMPM_API cmpm_Status cmpm_DestroyWorld(cmpm_WorldId world);
CMPM_API int32_t cmpm_World_IsValid(cmpm_WorldId world);  /* 1 if it refers to a live world */

/* Saves the world to a snapshot file (docs/snapshot-format.md: versioned, checksummed; written
 * to PATH.partial and renamed into place). cmpm_CreateWorld with snapshot_path restores it: the
 * restored world continues exactly as this one would (same state hash after the same steps,
 * on any thread count). A truncated, corrupted or newer snapshot is CMPM_ERROR_INVALID_INPUT
 * naming the file and what is wrong. */
CMPM_API cmpm_Status cmpm_World_SaveSnapshot(cmpm_WorldId world, const char* path);

/* Advance by `steps` steps of the scenario's dt (0 <= steps <= 10,000,000). */
CMPM_API cmpm_Status cmpm_World_Step(cmpm_WorldId world, int32_t steps);
/* Change the step length, s, in (0, 0.1] and at most cell_size / (4 max_speed). The simulated
 * time keeps what has elapsed; later steps advance it by the new dt. */
CMPM_API cmpm_Status cmpm_World_SetTimeStep(cmpm_WorldId world, double dt);
CMPM_API cmpm_Status cmpm_World_GetTimeStep(cmpm_WorldId world, double* out_dt);
CMPM_API cmpm_Status cmpm_World_GetTime(cmpm_WorldId world, double* out_seconds);
/* FNV-1a over (id, x, y, vx, vy) of every live agent in id order: equal across thread counts,
 * compilers (same flags) and host languages for the same scenario and steps. */
CMPM_API cmpm_Status cmpm_World_GetStateHash(cmpm_WorldId world, uint64_t* out_hash);
CMPM_API cmpm_Status cmpm_World_GetAgentCount(cmpm_WorldId world, int32_t* out_count);
/* Agents that have left through exits since the world was created. */
CMPM_API cmpm_Status cmpm_World_GetExitedCount(cmpm_WorldId world, int32_t* out_count);

/* Bulk reads of all live agents in a consistent order (the same order for every read between
 * two steps). capacity and *out_written count elements of `out`: ids for agent ids, doubles for
 * the rest; positions and velocities take 2 doubles per agent (x0, y0, x1, y1, ...). */
CMPM_API cmpm_Status cmpm_World_GetAgentIds(cmpm_WorldId world, cmpm_AgentId* out, int32_t capacity, int32_t* out_written);
CMPM_API cmpm_Status cmpm_World_GetPositions(cmpm_WorldId world, double* out_xy, int32_t capacity, int32_t* out_written);
CMPM_API cmpm_Status cmpm_World_GetVelocities(cmpm_WorldId world, double* out_vxy, int32_t capacity, int32_t* out_written);
CMPM_API cmpm_Status cmpm_World_GetPressures(cmpm_WorldId world, double* out, int32_t capacity, int32_t* out_written);

/* Grid fields of the current state. Node (i, j) is at origin + cell * (i, j); values are
 * row-major (j slowest). capacity and *out_written count doubles: nx * ny, or 2 * nx * ny for
 * the velocity field. */
CMPM_API cmpm_Status cmpm_World_GetFieldShape(cmpm_WorldId world, int32_t* out_nx, int32_t* out_ny,
                                              double* out_origin_x, double* out_origin_y, double* out_cell);
/* field: a cmpm_Field value (passed as int32_t so that any value a host sends is well defined). */
CMPM_API cmpm_Status cmpm_World_GetField(cmpm_WorldId world, int32_t field, double* out, int32_t capacity,
                                         int32_t* out_written);

/* Agents. People added between two steps are one batch: each call recomputes the reference
 * volumes (the density-referenced J) of the whole batch, so a call costs O(agents); add many
 * people with cmpm_World_AddAgents (or through the scenario's groups). */
CMPM_API cmpm_Status cmpm_World_AddAgent(cmpm_WorldId world, const cmpm_AgentDef* def, cmpm_AgentId* out_agent);
/* Adds count agents in one call and one reference-volume pass: the same state as count calls of
 * cmpm_World_AddAgent. Every definition is checked before any agent is added: if one is refused,
 * none is, and the message names it ("agent 3 of 10: ..."). out_agents (count entries) receives
 * the new ids in order (0 on failure). count 0 adds nothing (defs and out_agents may be null). */
CMPM_API cmpm_Status cmpm_World_AddAgents(cmpm_WorldId world, const cmpm_AgentDef* defs, int32_t count,
                                          cmpm_AgentId* out_agents);
CMPM_API cmpm_Status cmpm_World_RemoveAgent(cmpm_WorldId world, cmpm_AgentId agent);
CMPM_API cmpm_Status cmpm_World_SetAgentTarget(cmpm_WorldId world, cmpm_AgentId agent, const char* target);
CMPM_API cmpm_Status cmpm_World_GetAgentState(cmpm_WorldId world, cmpm_AgentId agent, double* out_x, double* out_y,
                                              double* out_vx, double* out_vy);

/* Material parameters by name (see docs/model-format.md: E, gamma, tension_scale, tau, ...),
 * range-checked. Setting one gives the same run as loading the model with that value (the
 * world's derived state, such as its neighbour search reach, follows). The parameters that set
 * up a world (docs/model-format.md, column "World": body_radius, comfort_distance, rest_density,
 * mass, wall_clearance) are fixed once it exists: setting them is CMPM_ERROR_INVALID_ARGUMENT,
 * as is a max_speed too large for the time step. route_congestion changes the routes at the next
 * step that begins a simulated second (at once when it turns route choice on or off). */
CMPM_API cmpm_Status cmpm_World_GetParameter(cmpm_WorldId world, const char* name, double* out_value);
CMPM_API cmpm_Status cmpm_World_SetParameter(cmpm_WorldId world, const char* name, double value);
/* Replace the traction network from JSON: {"layers": [...]} or {"constant": K} (crowd material). */
CMPM_API cmpm_Status cmpm_World_LoadTraction(cmpm_WorldId world, const char* traction_json);

/* Learning (docs/learning.md): fits a model to recorded trajectories by gradient descent
 * through the simulator, as `crowdmpm train` does, and writes the learned model JSON (which
 * cmpm_CreateWorld loads as model_path) to out_model_path. request_json:
 *   {"datasets": [{"scenario": PATH, "trajectories": [PATH, ...]}, ...],
 *    "model": PATH  or  "material": "crowd" | "fluid" | "social_force"   (optional start),
 *    "options": {"window": 2, "stride": 1, "iterations": 120, "batch": 4, "learning_rate": 0.03,
 *                "clip": 1, "validation": 0.25, "eval_every": 5, "patience": 6, "seed": 1,
 *                "threads": 1, "params": [NAME, ...], "learn_network": true,
 *                "loss": "trajectory" | "grid_velocity", "desired_speed": "observed" | "scenario" | "free",
 *                "area_weight": 0},
 *    "input": {"max_bytes": 268435456, "allow_outside_paths": false}   (optional: input limits)}
 * Relative paths resolve from the working directory. Blocks until training ends (seconds to
 * minutes); the result does not depend on "threads". CMPM_ERROR_INVALID_INPUT for a request,
 * scenario, model or recording that does not parse or validate (the message names the JSON
 * path, or the file and line), or recordings too short for training and validation windows.
 * CMPM_ERROR_INVALID_ARGUMENT when out_model_path is a folder or its folder is missing or takes
 * no new file: checked after the request is read and before training, not after. */
CMPM_API cmpm_Status cmpm_TrainModel(const char* request_json, const char* out_model_path);

/* Prediction (docs/learning.md), as `crowdmpm predict`: rolls a recording's observed states
 * forward with constant velocity, the scenario's model and every model given, and writes the
 * errors (ADE/FDE per second of horizon, grid velocity error; the prediction.json format) to
 * out_json_path. A recording with a row every few frames (ETH/UCY: every 10th), at most a second
 * apart, is compared at every frame with its positions between a person's rows interpolated
 * linearly; windows start on recorded rows ("recording_frame_step", "interpolated_rows" in the
 * report). request_json:
 *   {"scenario": PATH, "trajectories": PATH, "models": [PATH, ...], "observe": 2, "horizon": 4,
 *    "stride": (horizon), "windows": 0 (all), "threads": 1, "desired_speed": "observed" | "scenario" | "free",
 *    "input": {"max_bytes": 268435456, "allow_outside_paths": false}}
 * CMPM_ERROR_INVALID_INPUT as for cmpm_TrainModel, and when observe + horizon exceed the
 * recording; CMPM_ERROR_INVALID_ARGUMENT for an out_json_path that cannot be written (as
 * cmpm_TrainModel's out_model_path, checked before the predictions). */
CMPM_API cmpm_Status cmpm_PredictRecording(const char* request_json, const char* out_json_path);

/* Diagnosis (docs/diagnosis.md), as `crowdmpm diagnose`: fits the model on the recording's
 * first part, locates where it and the recording disagree, fits candidate force terms there and
 * keeps those that lower the held-out error; writes report.json (verdict, regions, hypotheses,
 * terms, scenario_terms), summary.txt, residual_before.png, residual_after.png, scenario.json
 * (the venue with its own force terms as fitted -- those it marks "learn" are fitted with the
 * baseline -- and the accepted terms) and model.json into the folder out_dir (created if
 * missing). request_json:
 *   {"scenario": PATH, "trajectories": PATH, "model": PATH (optional; default the scenario's),
 *    or instead of "trajectories" a video, whose tracks become the recording (also written
 *    to out_dir/video_tracks.txt): its people detected in every frame and followed by its
 *    optical flow ("tracks": "detect"), or points laid where its flow moves and carried by it
 *    ("flow", for crowds too dense to see each person):
 *    "video": {"path": PATH, "calibration": PATH | "scale": metres per pixel, "first": 0,
 *              "frames": 0 (to the end), "fps": 0 (the container's), "method": "farneback" | "dis",
 *              "smoothing": 0, "tracks": "detect",
 *              detection: "body_radius": 0.18 (m), "head_radius": 0.11 (m; 0: positions at
 *              the body's blob, not its head), "contrast": 4 (robust sd of the blob response),
 *              "coast": 1 (s), "smoother": "rts" (each track smoothed under the noise
 *              levels it shows, docs/diagnosis.md) | "none", "smooth": 0 (s);
 *              flow tracks: "cell": 0.25 (m), "min_speed": 0.2 (m/s: slower flow counts as
 *              still), "min_moving_share": 0.3, "density": 1.5 (persons/m2), "seed_speed": 0.3
 *              (m/s), "presence": 2 (s)},
 *    "options": {"train_share": 0.6, "window": 3, "stride": 1, "horizon": 1.5,
 *                "residual_stride": 0.5, "cell": 0.5, "time_bin": 5, "z_threshold": 3.5,
 *                "source_margin": 2, "null_replicates": 6, "alpha": 0.01, "max_terms": 3,
 *                "min_gain": 0.1, "min_gain_venue": 0.05 (what a venue-wide term, drift
 *                or density_speed, must gain on everyone), "min_gain_z": 3,
 *                "candidates": [NAME, ...] (default all:
 *                "obstacle", "constriction", "drift", "attractor", "vortex", "slow_zone",
 *                "wall_friction", "density_speed", "counterflow"; a constriction, a wall across
 *                the flow with one opening, is reported as an obstacle with "shape"),
 *                "params": [NAME, ...], "iterations": 60, "learning_rate": 0.05,
 *                "baseline_restarts": 0 (up to this many times, the baseline's fit run
 *                again from where it stopped while its validation loss falls by more than 0.1%),
 *                "final_restarts": 3 (where terms were accepted, the baseline and the final
 *                model are each fitted on the same way, at most this many times, before the
 *                report's held-out errors before and after are taken; selection unaffected),
 *                "threads": 1, "seed": 1,
 *                "desired_speed": "auto" (the baseline fitted with "recording" and with
 *                "observed", the second kept only where its validation loss is under half the
 *                first's; report.json "desired_speed" gives the mode and both losses) |
 *                "recording" (everyone at the median free speed of the recording's training
 *                part) | "free" (each person's own so far) | "observed" (each person's speed at
 *                the window's start) | "scenario",
 *                "density_law": true (a crowd material without a speed-density law gets
 *                Weidmann's in the baseline, refitted with it; false: the material as given,
 *                2-5 times faster),
 *                "baseline_optimizer": "adam", "optimizer": "adam",
 *                "smoother": "rts" (recorded trajectories smoothed under the noise levels they
 *                show, report.json "recording.smoother"; "none": read as they are; not with a
 *                "video", whose own "smoother" applies)},
 *    "input": {"max_bytes": 268435456, "allow_outside_paths": false}}
 * Blocks for seconds to minutes; the result does not depend on "threads".
 * CMPM_ERROR_INVALID_INPUT as for cmpm_TrainModel, and for recordings too short to split into
 * fitting and held-out windows; CMPM_ERROR_INVALID_ARGUMENT when out_dir cannot be created or
 * takes no new file (a file of that name in the way, a read-only parent), checked after the
 * request is read and before the diagnosis runs. */
CMPM_API cmpm_Status cmpm_Diagnose(const char* request_json, const char* out_dir);

#ifdef __cplusplus
}
#endif

#endif /* CROWDMPM_H */
