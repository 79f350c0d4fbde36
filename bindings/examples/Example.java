// Load the drill, run 60 s, print how many agents left.
import org.crowdmpm.World;

public class Example {
  public static void main(String[] args) {
    World world = new World(args.length > 0 ? args[0] : "scenarios/drill.json");
    world.step(6000);
    System.out.println(world.exited_count() + " agents left in 60 s");
    world.delete();
  }
}
