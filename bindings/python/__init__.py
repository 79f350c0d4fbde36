"""CrowdMPM: high-density crowd simulation with a learned MPM crowd material.

    import crowdmpm
    w = crowdmpm.World("drill.json", threads=2)
    w.step(100)
    xy = w.positions_array()          # numpy (n, 2), m
    ids = w.add_agents([[1.0, 2.0]], "door")

World, train_model, predict_recording, diagnose, version and abi_version are documented with
help(); errors raise RuntimeError with the library's message.
"""
import ctypes as _ctypes
import os as _os

# libcrowdmpm.so.1 ships beside the extension; load it first so that the extension finds it by
# its SONAME wherever the package is installed.
_ctypes.CDLL(_os.path.join(_os.path.dirname(__file__), "libcrowdmpm.so.1"), mode=_ctypes.RTLD_GLOBAL)

from .crowdmpm import *  # noqa: E402,F401,F403
from .crowdmpm import version as _version  # noqa: E402

__version__ = _version()
