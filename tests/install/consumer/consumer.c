/* Outside consumer of an installed CrowdMPM: load a scenario, step it, print the state hash.
 * Usage: consumer SCENARIO STEPS */
#include <crowdmpm/crowdmpm.h>
#include <stdio.h>
#include <stdlib.h>

int main(int argc, char** argv) {
  cmpm_WorldDef def = cmpm_DefaultWorldDef();
  cmpm_WorldId world;
  uint64_t hash = 0;
  if (argc != 3) {
    fprintf(stderr, "usage: consumer SCENARIO STEPS\n");
    return 2;
  }
  def.scenario_path = argv[1];
  if (cmpm_CreateWorld(&def, &world) != CMPM_OK ||
      cmpm_World_Step(world, (int32_t)atoi(argv[2])) != CMPM_OK ||
      cmpm_World_GetStateHash(world, &hash) != CMPM_OK) {
    fprintf(stderr, "error: %s\n", cmpm_GetLastError());
    return 1;
  }
  printf("crowdmpm %s hash %016llx\n", cmpm_GetVersion(), (unsigned long long)hash);
  cmpm_DestroyWorld(world);
  return 0;
}
