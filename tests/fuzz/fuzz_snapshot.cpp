// Snapshot bytes: restore, step, save again. Inputs that carry the snapshot magic get their
// length and checksum fixed up first, so that mutations reach the state parser instead of all
// stopping at the checksum. A restored world must step and save without a crash.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "engine/core/binary.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/sim/snapshot.hpp"
#include "fuzz_common.hpp"

using namespace crowdmpm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  constexpr size_t kHeader = kSnapshotHeaderBytes;
  if (bytes.size() >= kHeader + 8 && bytes.compare(0, 8, "CMPMSNAP") == 0) {
    reseal_snapshot(bytes);
    const uint64_t length = bytes.size() - kHeader - 8;
    // The same bound on work as the scenario target: the scenario is the payload's first string.
    try {
      BinaryReader r(bytes.data() + kHeader, length, "fuzz");
      const ScenarioDef s = ScenarioDef::parse(parse_json_text(r.str("scenario"), "fuzz"), "fuzz", ".");
      if (!fuzz::small_enough(s)) return 0;
    } catch (const Error&) {
      return 0;
    }
  }
  try {
    auto sim = restore_snapshot(bytes, "fuzz", 1);
    sim->run_steps(2);
    (void)save_snapshot(*sim);
  } catch (const Error&) {
  }
  return 0;
}
