// One SWIG interface for Python, Java and C#. It wraps crowdmpm_binding::World, a thin class
// over the C ABI that raises the library's error messages as exceptions.
%module(docstring="CrowdMPM: high-density crowd simulation with a learned MPM crowd material.") crowdmpm

%{
#include "crowdmpm_binding.hpp"
%}

%include <exception.i>
%include <std_string.i>
%include <std_vector.i>
%include <stdint.i>

%exception {
  try {
    $action
  } catch (const std::exception& e) {
    SWIG_exception(SWIG_RuntimeError, e.what());
  }
}

%template(DoubleVector) std::vector<double>;
%template(LongVector) std::vector<long long>;

%newobject crowdmpm_binding::World::null_world;
%newobject crowdmpm_binding::World::from_snapshot;

#ifdef SWIGJAVA
// The jar carries its native libraries (org/crowdmpm/native/<os>-<arch>/): they are extracted to
// a temporary folder and loaded from there, libcrowdmpm.so.1 first so that the JNI library finds
// it by its SONAME. Without them in the jar (a build-tree jar), java.library.path is used.
%pragma(java) jniclasscode=%{
  static {
    String os = System.getProperty("os.name", "").toLowerCase();
    String arch = System.getProperty("os.arch", "");
    if (arch.equals("amd64")) arch = "x86_64";
    String dir = "/org/crowdmpm/native/" + (os.startsWith("linux") ? "linux" : os) + "-" + arch + "/";
    String[] libs = {"libcrowdmpm.so.1", "libcrowdmpm_java.so"};
    if (crowdmpmJNI.class.getResource(dir + libs[1]) != null) {
      try {
        java.nio.file.Path tmp = java.nio.file.Files.createTempDirectory("crowdmpm-native");
        tmp.toFile().deleteOnExit();
        for (String name : libs) {
          java.nio.file.Path file = tmp.resolve(name);
          try (java.io.InputStream in = crowdmpmJNI.class.getResourceAsStream(dir + name)) {
            if (in == null) throw new UnsatisfiedLinkError("CrowdMPM: the jar lacks " + dir + name);
            java.nio.file.Files.copy(in, file);
          }
          file.toFile().deleteOnExit();
          System.load(file.toAbsolutePath().toString());
        }
      } catch (java.io.IOException e) {
        throw new UnsatisfiedLinkError("CrowdMPM: cannot extract the native libraries from the jar: " + e);
      }
    } else {
      System.loadLibrary("crowdmpm_java");
    }
  }
%}
#endif

#ifdef SWIGPYTHON
%feature("autodoc", "2");
%feature("kwargs");
%feature("compactdefaultargs");
%feature("docstring") crowdmpm_binding::World "A simulated crowd: World(scenario, model='', threads=1, allow_outside_paths=False, max_input_bytes=0). scenario is a file path or JSON text; model likewise ('' for the scenario's own or the default). Errors raise RuntimeError with the library's message.";
%feature("docstring") crowdmpm_binding::World::step "step(steps=1): advance by steps steps of the scenario's dt.";
%feature("docstring") crowdmpm_binding::World::time "time() -> float: simulated time, s.";
%feature("docstring") crowdmpm_binding::World::time_step "time_step() -> float: dt, s.";
%feature("docstring") crowdmpm_binding::World::set_time_step "set_time_step(dt): change dt (s); checked against the grid.";
%feature("docstring") crowdmpm_binding::World::state_hash "state_hash() -> int: FNV-1a hash of all agents' id, position and velocity (equal across languages and thread counts).";
%feature("docstring") crowdmpm_binding::World::state_hash_hex "state_hash_hex() -> str: the state hash as 16 hex digits.";
%feature("docstring") crowdmpm_binding::World::agent_count "agent_count() -> int: agents currently in the world.";
%feature("docstring") crowdmpm_binding::World::exited_count "exited_count() -> int: agents that have left through exits.";
%feature("docstring") crowdmpm_binding::World::positions "positions() -> list of x0, y0, x1, y1, ... (m); see positions_array() for numpy.";
%feature("docstring") crowdmpm_binding::World::velocities "velocities() -> list of vx0, vy0, ... (m/s); see velocities_array() for numpy.";
%feature("docstring") crowdmpm_binding::World::pressures "pressures() -> list of agent pressures; see pressures_array() for numpy.";
%feature("docstring") crowdmpm_binding::World::agent_ids "agent_ids() -> list of agent ids, in the order of the bulk reads.";
%feature("docstring") crowdmpm_binding::World::field "field(name) -> list: grid field 'density', 'pressure' or 'velocity', row-major; see field_array().";
%feature("docstring") crowdmpm_binding::World::field_nx "field_nx() -> int: grid nodes along x.";
%feature("docstring") crowdmpm_binding::World::field_ny "field_ny() -> int: grid nodes along y.";
%feature("docstring") crowdmpm_binding::World::add_agent "add_agent(x, y, target, vx=0, vy=0, desired_speed=1.3) -> int: add an agent walking to target (exit or goal id, or 'nearest_exit'); returns its id.";
%feature("docstring") crowdmpm_binding::World::remove_agent "remove_agent(id): remove an agent; its id becomes stale.";
%feature("docstring") crowdmpm_binding::World::set_agent_target "set_agent_target(id, target): send an agent to another exit or goal.";
%feature("docstring") crowdmpm_binding::World::agent_state "agent_state(id) -> [x, y, vx, vy] of one agent.";
%feature("docstring") crowdmpm_binding::World::parameter "parameter(name) -> float: a material parameter by name (E, gamma, tau, ...).";
%feature("docstring") crowdmpm_binding::World::set_parameter "set_parameter(name, value): set a material parameter (range-checked).";
%feature("docstring") crowdmpm_binding::World::load_traction "load_traction(json): replace the traction network ({'layers': [...]} or {'constant': K}).";
%feature("docstring") crowdmpm_binding::World::destroy "destroy(): free the world now; later calls raise.";
%feature("docstring") crowdmpm_binding::World::is_valid "is_valid() -> bool: whether the world still exists.";
%feature("docstring") crowdmpm_binding::World::from_snapshot "from_snapshot(path, threads=1) -> World: a world restored from a snapshot file; it continues exactly as the saved world would have.";
%feature("docstring") crowdmpm_binding::World::save_snapshot "save_snapshot(path): save the world to a snapshot file (versioned, checksummed).";
%feature("docstring") crowdmpm_binding::World::null_world "null_world() -> World: a world with a null id (every call raises); for testing error handling.";
%feature("docstring") crowdmpm_binding::version "version() -> str: library version.";
%feature("docstring") crowdmpm_binding::abi_version "abi_version() -> int: C ABI version.";
%feature("docstring") crowdmpm_binding::train_model "train_model(request_json, out_model_path): learn a model from recordings (docs/learning.md).";
%feature("docstring") crowdmpm_binding::predict_recording "predict_recording(request_json, out_json_path): prediction errors of models on a recording (docs/learning.md).";
%feature("docstring") crowdmpm_binding::diagnose "diagnose(request_json, out_dir): find physics a scenario lacks; writes report.json, summary.txt and residual pictures (docs/diagnosis.md).";
#endif

%include "crowdmpm_binding.hpp"

#ifdef SWIGPYTHON
%pythoncode %{
import numpy as _np

def _positions_array(self):
    """positions_array() -> numpy array (n, 2) of agent positions, m."""
    return _np.asarray(self.positions(), dtype=_np.float64).reshape(-1, 2)

def _velocities_array(self):
    """velocities_array() -> numpy array (n, 2) of agent velocities, m/s."""
    return _np.asarray(self.velocities(), dtype=_np.float64).reshape(-1, 2)

def _pressures_array(self):
    """pressures_array() -> numpy array (n,) of agent pressures."""
    return _np.asarray(self.pressures(), dtype=_np.float64)

def _agent_ids_array(self):
    """agent_ids_array() -> numpy int64 array (n,) of agent ids."""
    return _np.asarray(self.agent_ids(), dtype=_np.int64)

def _field_array(self, name):
    """field_array(name) -> numpy array (ny, nx) or (ny, nx, 2) of a grid field."""
    a = _np.asarray(self.field(name), dtype=_np.float64)
    return a.reshape(self.field_ny(), self.field_nx(), -1).squeeze(-1) if name != "velocity" else a.reshape(self.field_ny(), self.field_nx(), 2)

World.positions_array = _positions_array
World.velocities_array = _velocities_array
World.pressures_array = _pressures_array
World.agent_ids_array = _agent_ids_array


def _add_agents(self, positions, target, velocities=None, desired_speed=1.3):
    """add_agents(positions, target, velocities=None, desired_speed=1.3) -> numpy int64 array of
    the new ids. positions: array-like (n, 2), m; velocities: (n, 2), m/s, or None for rest;
    target: exit or goal id, or 'nearest_exit'. One call (cmpm_World_AddAgents): if one agent is
    refused, none is added."""
    p = _np.asarray(positions, dtype=_np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError("add_agents: positions must have shape (n, 2), got %s" % (p.shape,))
    v = _np.zeros_like(p) if velocities is None else _np.asarray(velocities, dtype=_np.float64)
    if v.shape != p.shape:
        raise ValueError("add_agents: velocities must have the shape of positions %s, got %s" % (p.shape, v.shape))
    return _np.array(self.add_agents_xy(DoubleVector(p.ravel().tolist()), target, DoubleVector(v.ravel().tolist()),
                                        float(desired_speed)), dtype=_np.int64)

World.field_array = _field_array
World.add_agents = _add_agents
%}
#endif
