// Load the drill, run 60 s, print how many agents left.
using System;
using CrowdMPM;

public static class Example {
  public static void Main(string[] args) {
    using (World world = new World(args.Length > 0 ? args[0] : "scenarios/drill.json")) {
      world.step(6000);
      Console.WriteLine(world.exited_count() + " agents left in 60 s");
    }
  }
}
