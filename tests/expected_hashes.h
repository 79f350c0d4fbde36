/* Expected state hashes shared by the C++, C, Python, Java and C# determinism tests.
 * FNV-1a of (id, x, y, vx, vy) of every live agent in id order after CMPM_EXPECTED_DRILL_STEPS
 * steps of scenarios/drill.json. Changing the physics changes it on purpose: update it in the
 * same commit and say why. */
#ifndef CROWDMPM_EXPECTED_HASHES_H
#define CROWDMPM_EXPECTED_HASHES_H
#define CMPM_EXPECTED_DRILL_STEPS 400
#define CMPM_EXPECTED_DRILL_HASH 0xcf04c55dc80ffdf7ULL
#endif
