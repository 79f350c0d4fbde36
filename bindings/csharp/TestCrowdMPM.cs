// C# binding test: same drill hash as the C test, bulk reads, and errors as exceptions.
// usage: mono TestCrowdMPM.exe DRILL STEPS HASH   (LD_LIBRARY_PATH must reach the native libraries)
using System;
using CrowdMPM;

public static class TestCrowdMPM {
  static int passed = 0, failed = 0;

  static void Check(bool ok, string what) {
    if (ok) passed++;
    else { failed++; Console.Error.WriteLine("FAILED: " + what); }
  }

  static void Raises(Action a, string word, string what) {
    try {
      a();
      failed++;
      Console.Error.WriteLine("FAILED (no exception): " + what);
    } catch (Exception e) {
      Check(e.Message.Contains(word), what + ": message was " + e.Message);
    }
  }

  public static int Main(string[] args) {
    string drill = args[0];
    int steps = int.Parse(args[1]);
    string hash = args[2].ToLower();

    using (World w = new World(drill)) {
      w.step(steps);
      Check(w.state_hash_hex() == hash, "state hash " + w.state_hash_hex() + " equals " + hash);
      Check(w.state_hash() == Convert.ToUInt64(hash, 16), "unsigned hash");
      int n = w.agent_count();
      DoubleVector xy = w.positions();
      Check(xy.Count == 2 * n, "positions hold 2 values per agent");
      bool inside = true;
      for (int i = 0; i < n; i++) inside &= xy[2 * i] >= 0 && xy[2 * i] <= 11;
      Check(inside, "positions inside the domain");
      long a = w.add_agent(9.5, 4.0, "door");
      w.remove_agent(a);
      Raises(() => w.agent_state(a), "was removed", "stale agent id");
    }
    // Snapshot at step 200, restored on 2 threads, run to the end: the uninterrupted run's hash.
    string snap = System.IO.Path.Combine(System.IO.Path.GetTempPath(), "crowdmpm_cs_drill_200.snap");
    using (World s = new World(drill)) {
      s.step(200);
      s.save_snapshot(snap);
      using (World r = World.from_snapshot(snap, 2)) {
        r.step(steps - 200);
        Check(r.state_hash_hex() == hash, "restored snapshot hash " + r.state_hash_hex() + " equals " + hash);
      }
    }
    Raises(() => World.from_snapshot(drill), "not a CrowdMPM snapshot", "a scenario is no snapshot");
    Raises(() => crowdmpm.diagnose("{\"scenario\": 3}", "diag"), "scenario", "diagnose names the bad key");
    Raises(() => new World("{\"format\": \"crowdmpm-scenario\","), "invalid JSON", "bad JSON");
    Raises(() => World.null_world().step(1), "null world", "null world");
    World d = new World(drill);
    d.destroy();
    Raises(() => d.step(1), "destroyed", "destroyed world");

    Console.WriteLine("csharp: " + passed + " passed, " + failed + " failed");
    return failed == 0 ? 0 : 1;
  }
}
