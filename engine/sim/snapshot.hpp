#pragma once
// World snapshots: a running world saved to a versioned binary file with a checksum, and
// restored to continue bit-identically (docs/snapshot-format.md). A snapshot holds everything a
// step reads: the scenario and model as JSON, the clock and time step, the random stream, every
// agent and particle component, the grid's state, exit events, source counters and the
// behaviours (navigation targets) added after the world was built.
#include <cstdint>
#include <memory>
#include <string>

#include "engine/core/input.hpp"
#include "engine/sim/simulation.hpp"

namespace crowdmpm {

// Version 2 adds the route density (route choice under congestion); version 1 still reads.
constexpr uint32_t kSnapshotVersion = 2;
// Magic, version, byte-order mark, payload length; the payload follows, then its checksum.
constexpr size_t kSnapshotHeaderBytes = 8 + 4 + 4 + 8;

// Sets a snapshot's payload length and checksum to match the bytes between header and checksum
// (bytes must hold at least a header and a checksum). save_snapshot seals what it writes with
// it; tools that edit a snapshot's state (the fuzz target, tests of the reader) reseal after.
void reseal_snapshot(std::string& bytes);

// The snapshot as bytes (header, payload, FNV-1a checksum of the payload).
std::string save_snapshot(const Simulation& sim);
// Writes it to path (through a temporary file renamed into place, so a crash never leaves a
// half-written snapshot under the name). Throws Error naming the path.
void save_snapshot_file(const Simulation& sim, const std::string& path);

// A world restored from snapshot bytes, stepping on `threads` worker threads (results do not
// depend on it). Throws Error naming `source` and the byte offset for a truncated, corrupted
// (checksum), foreign (magic) or newer (version) snapshot, or contents that do not fit together.
std::unique_ptr<Simulation> restore_snapshot(const std::string& bytes, const std::string& source, int threads);
std::unique_ptr<Simulation> load_snapshot_file(const std::string& path, int threads, const InputPolicy& policy = {});

}  // namespace crowdmpm
