#!/bin/sh
# The Python wheel as a user installs it: a fresh virtual environment (Debian's numpy visible
# through --system-site-packages; no network: pip --no-index), pip install of the wheel, then
# a program run from a folder outside the build tree with no PYTHONPATH: it must import the
# installed package, step the drill to the committed hash and pass numpy arrays in and out.
# usage: wheel_test.sh PYTHON WHEEL_DIR WORK_DIR DRILL STEPS HASH
set -eu
PY=$1 WHEELS=$2 WORK=$3 DRILL=$4 STEPS=$5 HASH=$6
rm -rf "$WORK"
mkdir -p "$WORK/run"
set -- "$WHEELS"/crowdmpm-*.whl
[ -f "$1" ] || { echo "no crowdmpm wheel in $WHEELS"; exit 1; }
echo "wheel: $(basename "$1")"
"$PY" -m venv --system-site-packages "$WORK/venv"
"$WORK/venv/bin/python" -m pip install --no-index --quiet "$1"
cp "$DRILL" "$WORK/run/drill.json"
# The extension finds libcrowdmpm.so.1 beside itself and nowhere else (no build-tree path).
set -- "$WORK"/venv/lib/python3*/site-packages/crowdmpm/_crowdmpm*.so
runpath=$(readelf -d "$1" | sed -n 's/.*R\(UN\)\{0,1\}PATH.*\[\(.*\)\]/\2/p')
[ "$runpath" = '$ORIGIN' ] || { echo "$(basename "$1") has RUNPATH '$runpath', expected \$ORIGIN"; exit 1; }
cd "$WORK/run"
env -u PYTHONPATH -u LD_LIBRARY_PATH "$WORK/venv/bin/python" - "$STEPS" "$HASH" "$WORK/venv" <<'PYEOF'
import os, sys
import numpy as np
import crowdmpm

steps, expected, venv = int(sys.argv[1]), sys.argv[2].lower(), os.path.realpath(sys.argv[3])
where = os.path.realpath(crowdmpm.__file__)
assert where.startswith(venv), "crowdmpm imported from %s, not from the venv %s" % (where, venv)
assert crowdmpm.World.__doc__ and "scenario" in crowdmpm.World.__doc__, "World has no docstring"
assert crowdmpm.World.step.__doc__, "World.step has no docstring"
w = crowdmpm.World("drill.json")
w.step(steps)
got = w.state_hash_hex()
assert got == expected, "hash %s, expected %s" % (got, expected)
xy = w.positions_array()
assert isinstance(xy, np.ndarray) and xy.shape == (w.agent_count(), 2) and np.isfinite(xy).all()
before = w.agent_count()
ids = w.add_agents(np.array([[1.0, 1.0], [1.5, 6.5]]), "door")
assert ids.dtype == np.int64 and ids.shape == (2,) and w.agent_count() == before + 2
try:
    w.add_agents(np.zeros((3,)), "door")
    raise SystemExit("add_agents accepted a (3,) array")
except ValueError as e:
    assert "(n, 2)" in str(e)
print("crowdmpm %s from %s: hash %s, %d agents" % (crowdmpm.__version__, where, got, w.agent_count()))
PYEOF
