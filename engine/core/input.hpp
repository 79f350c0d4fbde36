#pragma once
// Bounded, confined input. Every file the engine reads (scenario, model, trajectories, snapshots)
// goes through read_input_file: it must be a regular file (not a device, pipe, socket or folder)
// no larger than the policy's limit, and messages name the file and the reason, never its
// contents. A path named inside a file (a scenario's "model" or "extends") must stay inside the
// folder of the file the user named, unless the caller allows otherwise (docs/scenario-format.md,
// "Files a scenario names").
#include <cstdint>
#include <string>

namespace crowdmpm {

struct InputPolicy {
  // 256 MiB: far above any scenario, model or recording we know (the largest real recording we
  // ship tests against is 3 MB), far below what would exhaust memory.
  static constexpr uint64_t kDefaultMaxBytes = uint64_t{256} << 20;
  uint64_t max_bytes = kDefaultMaxBytes;
  // Whether paths named inside a file may leave the folder of the file the user named.
  bool allow_outside_paths = false;
};

// The checks read_input_file makes before reading, for files another library opens (videos):
// returns the size in bytes, or throws Error as read_input_file does.
uint64_t check_input_file(const std::string& path, const InputPolicy& policy = {});

// p relative to base (p itself when absolute or base is empty): a request's file names.
std::string resolve_path(const std::string& base, const std::string& p);

// The whole file as bytes. Throws Error "<path>: <reason>" for a missing or unreadable file, a
// folder or special file, or a file above policy.max_bytes (checked before and while reading).
std::string read_input_file(const std::string& path, const InputPolicy& policy = {});

// `name` (relative to `dir`, or absolute) as a path to open, refused with Error unless it lies
// inside `root` (after resolving "..", "." and symbolic links) or the policy allows outside paths.
// `what` (may be empty) starts the message.
std::string confined_path(const std::string& root, const std::string& dir, const std::string& name,
                          const InputPolicy& policy, const std::string& what);

}  // namespace crowdmpm
