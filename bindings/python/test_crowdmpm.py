"""Python binding test: the drill gives the same state hash as the C test, bulk reads come back
as numpy arrays, errors (bad JSON, stale agent id, null or destroyed world) raise
RuntimeError with the library's message, and a model can be learned and a recording predicted
(train_model, predict_recording).

usage: test_crowdmpm.py DRILL_JSON STEPS EXPECTED_HASH_HEX"""
import sys
import unittest

import numpy as np

import crowdmpm

DRILL, STEPS, HASH = sys.argv[1], int(sys.argv[2]), sys.argv[3].lower()


class Bindings(unittest.TestCase):
    def test_hash_matches_c_and_cpp(self):
        w = crowdmpm.World(DRILL)
        w.step(STEPS)
        self.assertEqual(w.state_hash_hex(), HASH)
        self.assertEqual(w.state_hash(), int(HASH, 16))
        self.assertAlmostEqual(w.time(), STEPS * 0.01)

    def test_snapshot_continues_bit_identically(self):
        import os
        import tempfile
        path = os.path.join(tempfile.mkdtemp(), "drill_200.snap")
        w = crowdmpm.World(DRILL)
        w.step(200)
        w.save_snapshot(path)
        r = crowdmpm.World.from_snapshot(path, threads=2)
        self.assertAlmostEqual(r.time(), 2.0)
        r.step(STEPS - 200)
        self.assertEqual(r.state_hash_hex(), HASH)
        with open(path, "rb") as f:
            data = f.read()
        with open(path + ".cut", "wb") as f:
            f.write(data[: len(data) // 2])
        with self.assertRaisesRegex(RuntimeError, "truncated snapshot"):
            crowdmpm.World.from_snapshot(path + ".cut")
        with self.assertRaisesRegex(RuntimeError, "not a CrowdMPM snapshot"):
            crowdmpm.World.from_snapshot(DRILL)

    def test_bulk_reads_are_numpy(self):
        w = crowdmpm.World(DRILL, threads=2)
        w.step(10)
        xy = w.positions_array()
        self.assertIsInstance(xy, np.ndarray)
        self.assertEqual(xy.shape, (w.agent_count(), 2))
        self.assertTrue(np.all((xy[:, 0] >= 0) & (xy[:, 0] <= 11)))
        self.assertEqual(w.velocities_array().shape, xy.shape)
        self.assertEqual(w.pressures_array().shape, (w.agent_count(),))
        ids = w.agent_ids_array()
        self.assertEqual(len(set(ids.tolist())), w.agent_count())
        rho = w.field_array("density")
        self.assertEqual(rho.shape, (w.field_ny(), w.field_nx()))
        self.assertAlmostEqual(rho.sum() * 0.25, w.agent_count(), places=6)
        self.assertEqual(w.field_array("velocity").shape, (w.field_ny(), w.field_nx(), 2))

    def test_agents_and_parameters(self):
        w = crowdmpm.World(DRILL)
        a = w.add_agent(9.5, 4.0, "door")
        self.assertEqual(list(w.agent_state(a))[:2], [9.5, 4.0])
        w.set_parameter("E", 30)
        self.assertEqual(w.parameter("E"), 30)
        w.remove_agent(a)
        with self.assertRaisesRegex(RuntimeError, "agent %d was removed" % a):
            w.agent_state(a)
        with self.assertRaisesRegex(RuntimeError, "E must be in"):
            w.set_parameter("E", -1)

    def test_add_agents_all_or_none(self):
        w = crowdmpm.World(DRILL)
        n = w.agent_count()
        ids = w.add_agents([[2.0, 2.0], [2.6, 2.0]], "door", velocities=[[0.5, 0.0], [0.0, 0.5]])
        self.assertEqual(ids.dtype, np.int64)
        self.assertEqual(len(ids), 2)
        self.assertEqual(w.agent_count(), n + 2)
        self.assertEqual(list(w.agent_state(int(ids[1]))), [2.6, 2.0, 0.0, 0.5])
        with self.assertRaisesRegex(RuntimeError, "agent 1 of 2"):
            w.add_agents([[3.0, 2.0], [8.1, 1.0]], "door")  # the second inside a wall
        self.assertEqual(w.agent_count(), n + 2)
        with self.assertRaisesRegex(ValueError, "shape"):
            w.add_agents([1.0, 2.0, 3.0], "door")

    def test_errors_raise_with_messages(self):
        with self.assertRaisesRegex(RuntimeError, "invalid JSON"):
            crowdmpm.World('{"format": "crowdmpm-scenario",')
        with self.assertRaisesRegex(RuntimeError, "null world"):
            crowdmpm.World.null_world().step(1)
        w = crowdmpm.World(DRILL)
        w.destroy()
        self.assertFalse(w.is_valid())
        with self.assertRaisesRegex(RuntimeError, "destroyed"):
            w.step(1)
        with self.assertRaisesRegex(RuntimeError, "unknown field"):
            crowdmpm.World(DRILL).field("temperature")

    def test_train_model(self):
        # People walking down the bottleneck corridor, written here, then fitted.
        import json, os, tempfile
        tmp = tempfile.mkdtemp()
        traj = os.path.join(tmp, "walkers.txt")
        with open(traj, "w") as f:
            f.write("# framerate: 10\n")
            for frame in range(121):
                for i in range(12):
                    f.write("%d %d %.4f %.4f 0\n" % (i + 1, frame, -2.0 + 0.8 * (i % 6), 6.0 - 0.6 * (i // 6) - 0.03 * frame))
        scenario = os.path.join(os.path.dirname(DRILL), "bottleneck.json")
        request = {"datasets": [{"scenario": scenario, "trajectories": [traj]}],
                   "options": {"window": 1, "iterations": 2, "params": ["tau", "v0_scale"], "learn_network": False}}
        out = os.path.join(tmp, "model.json")
        crowdmpm.train_model(json.dumps(request), out)
        with open(out) as f:
            self.assertEqual(json.load(f)["name"], "learned crowd")
        crowdmpm.World(scenario, out).step(1)  # the learned model loads as it is
        report = os.path.join(tmp, "prediction.json")
        crowdmpm.predict_recording(json.dumps({"scenario": scenario, "trajectories": traj, "models": [out],
                                               "observe": 2, "horizon": 3}), report)
        with open(report) as f:
            methods = [m["method"] for m in json.load(f)["methods"]]
        self.assertEqual(methods, ["constant velocity", "untrained default (crowd)", "learned crowd"])
        with self.assertRaisesRegex(RuntimeError, "options.window"):
            request["options"]["window"] = -1
            crowdmpm.train_model(json.dumps(request), out)
        # Diagnosis of the same recording: the report and its pictures, and a bad request.
        diag = os.path.join(tmp, "diagnosis")
        crowdmpm.diagnose(json.dumps({"scenario": scenario, "trajectories": traj,
                                      "options": {"window": 1, "iterations": 2, "null_replicates": 1, "max_terms": 1,
                                                  "candidates": ["drift"]}}), diag)
        with open(os.path.join(diag, "report.json")) as f:
            report = json.load(f)
        self.assertIn(report["verdict"]["type"], ["none", "drift"])
        self.assertTrue(os.path.getsize(os.path.join(diag, "residual_before.png")) > 0)
        with self.assertRaisesRegex(RuntimeError, "ghost"):
            crowdmpm.diagnose(json.dumps({"scenario": scenario, "trajectories": traj,
                                          "options": {"candidates": ["ghost"]}}), diag)

    def test_docstrings(self):
        self.assertIn("advance", crowdmpm.World.step.__doc__)
        self.assertIn("numpy", crowdmpm.World.positions_array.__doc__)
        self.assertEqual(crowdmpm.version(), "0.1.0")


if __name__ == "__main__":
    result = unittest.main(argv=[sys.argv[0], "-v"], exit=False).result
    failed = len(result.failures) + len(result.errors)
    print("python: %d passed, %d failed" % (result.testsRun - failed, failed))
    sys.exit(1 if failed else 0)
