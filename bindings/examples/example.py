"""Load the drill, run 60 s, print how many agents left."""
import sys

import crowdmpm

world = crowdmpm.World(sys.argv[1] if len(sys.argv) > 1 else "scenarios/drill.json")
world.step(6000)
print("%d agents left in 60 s" % world.exited_count())
print("positions of those still inside:", world.positions_array().shape)
