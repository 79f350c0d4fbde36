// Java binding test: same drill hash as the C test, bulk reads, and errors as exceptions.
// usage: java -Djava.library.path=DIR -cp crowdmpm.jar org.crowdmpm.test.TestCrowdMPM DRILL STEPS HASH
package org.crowdmpm.test;

import org.crowdmpm.DoubleVector;
import org.crowdmpm.World;

public class TestCrowdMPM {
  static int passed = 0, failed = 0;

  static void check(boolean ok, String what) {
    if (ok) passed++;
    else { failed++; System.err.println("FAILED: " + what); }
  }

  interface Action { void run(); }

  static void raises(Action a, String word, String what) {
    try {
      a.run();
      failed++;
      System.err.println("FAILED (no exception): " + what);
    } catch (RuntimeException e) {
      check(e.getMessage() != null && e.getMessage().contains(word), what + ": message was " + e.getMessage());
    }
  }

  public static void main(String[] args) {
    String drill = args[0];
    int steps = Integer.parseInt(args[1]);
    String hash = args[2].toLowerCase();

    World w = new World(drill);
    w.step(steps);
    check(w.state_hash_hex().equals(hash), "state hash " + w.state_hash_hex() + " equals " + hash);
    int n = w.agent_count();
    DoubleVector xy = w.positions();
    check(xy.size() == 2 * n, "positions hold 2 values per agent");
    boolean inside = true;
    for (int i = 0; i < n; i++) inside &= xy.get(2 * i) >= 0 && xy.get(2 * i) <= 11;
    check(inside, "positions inside the domain");
    check(w.agent_ids().size() == n, "one id per agent");

    // Snapshot at step 200, restored on 2 threads, run to the end: the uninterrupted run's hash.
    String snap = System.getProperty("java.io.tmpdir") + "/crowdmpm_java_drill_200.snap";
    World s = new World(drill);
    s.step(200);
    s.save_snapshot(snap);
    World r = World.from_snapshot(snap, 2);
    r.step(steps - 200);
    check(r.state_hash_hex().equals(hash), "restored snapshot hash " + r.state_hash_hex() + " equals " + hash);
    r.delete();
    s.delete();
    raises(() -> World.from_snapshot(drill), "not a CrowdMPM snapshot", "a scenario is no snapshot");

    raises(() -> new World("{\"format\": \"crowdmpm-scenario\","), "invalid JSON", "bad JSON");
    raises(() -> org.crowdmpm.crowdmpm.diagnose("{\"scenario\": 3}", "diag"), "scenario", "diagnose names the bad key");
    raises(() -> World.null_world().step(1), "null world", "null world");
    long a = w.add_agent(9.5, 4.0, "door");
    w.remove_agent(a);
    raises(() -> w.agent_state(a), "was removed", "stale agent id");
    World d = new World(drill);
    d.destroy();
    raises(() -> d.step(1), "destroyed", "destroyed world");
    w.delete();

    System.out.println("java: " + passed + " passed, " + failed + " failed");
    System.exit(failed == 0 ? 0 : 1);
  }
}
