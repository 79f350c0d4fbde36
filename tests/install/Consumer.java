// A Java program that uses only crowdmpm.jar: load a scenario, step it, print the state hash.
// Run: java -cp crowdmpm.jar Consumer.java SCENARIO STEPS
import org.crowdmpm.World;
import org.crowdmpm.crowdmpm;

public class Consumer {
  public static void main(String[] args) {
    World world = new World(args[0]);
    world.step(Integer.parseInt(args[1]));
    System.out.println("crowdmpm " + crowdmpm.version() + " hash " + world.state_hash_hex());
    world.destroy();
  }
}
