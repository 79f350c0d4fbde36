/* Load the drill, run 60 s, print how many agents left. cc example.c -lcrowdmpm */
#include <stdio.h>

#include "crowdmpm/crowdmpm.h"

int main(int argc, char** argv) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  cmpm_WorldId world;
  int32_t exited = 0;
  def.scenario_path = argc > 1 ? argv[1] : "scenarios/drill.json";
  if (cmpm_CreateWorld(&def, &world) != CMPM_OK) {
    fprintf(stderr, "error: %s\n", cmpm_GetLastError());
    return 1;
  }
  if (cmpm_World_Step(world, 6000) != CMPM_OK || cmpm_World_GetExitedCount(world, &exited) != CMPM_OK) {
    fprintf(stderr, "error: %s\n", cmpm_GetLastError());
    return 1;
  }
  printf("%d agents left in 60 s\n", exited);
  cmpm_DestroyWorld(world);
  return 0;
}
