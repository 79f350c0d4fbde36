// A C# program that uses only the CrowdMPM package: load a scenario, step it, print the hash.
// mcs -r:CrowdMPM.dll Consumer.cs && mono Consumer.exe SCENARIO STEPS
using System;
using CrowdMPM;

public static class Consumer {
  public static int Main(string[] args) {
    using (var world = new World(args[0])) {
      world.step(int.Parse(args[1]));
      Console.WriteLine("crowdmpm " + crowdmpm.version() + " hash " + world.state_hash_hex());
    }
    return 0;
  }
}
