#pragma once
// Recordings with known answers for diagnosis: a scenario (with whatever effect it conceals)
// run by a model, written as a tracker with Gaussian position noise would record it.
#include <cstdint>
#include <string>

#include "engine/sim/simulation.hpp"

namespace crowdmpm {

// Runs `truth` with `model` to its end and writes every agent at every output frame as PeTrack
// text ("id frame x y", metres, "# framerate:" header) with independent Gaussian noise of sd
// `noise` (m) on each coordinate. Throws Error if the file cannot be written.
void write_noisy_recording(const ScenarioDef& truth, const Model& model, double noise, uint64_t seed, int threads,
                           const std::string& path);

}  // namespace crowdmpm
