#include "engine/core/output.hpp"

#include <filesystem>
#include <fstream>
#include <system_error>
#include <unistd.h>

#include "engine/core/error.hpp"

namespace crowdmpm {
namespace fs = std::filesystem;

namespace {
// Writes and removes a probe file in the folder `dir`; the reason when that fails, else empty.
std::string probe_write(const fs::path& dir) {
  const fs::path probe = dir / (".crowdmpm-write-probe-" + std::to_string(static_cast<long>(::getpid())));
  {
    std::ofstream f(probe, std::ios::binary);
    if (!f) return "no new file can be created there";
    f << "probe";
    f.close();
    if (!f) return "a file written there cannot be completed (is the disk full?)";
  }
  std::error_code ec;
  fs::remove(probe, ec);
  return {};
}
}  // namespace

void prepare_output_folder(const std::string& dir, const std::string& what) {
  if (dir.empty()) throw Error(what + ": the folder name is empty");
  std::error_code ec;
  const fs::path p(dir);
  if (fs::exists(p, ec) && !fs::is_directory(p, ec)) throw Error(dir + ": cannot use as the " + what + ": a file of that name is in the way");
  fs::create_directories(p, ec);
  if (ec) throw Error(dir + ": cannot create the " + what + " (" + ec.message() + ")");
  if (const std::string why = probe_write(p); !why.empty()) throw Error(dir + ": cannot write in the " + what + " (" + why + ")");
}

void check_output_file(const std::string& path, const std::string& what) {
  if (path.empty()) throw Error(what + ": the file name is empty");
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) throw Error(path + ": cannot write the " + what + ": it is a folder");
  const fs::path dir = fs::absolute(p, ec).parent_path();
  if (ec || !fs::is_directory(dir, ec)) throw Error("cannot write " + path + ": folder " + dir.string() + " does not exist");
  if (const std::string why = probe_write(dir); !why.empty()) throw Error("cannot write " + path + ": folder " + dir.string() + ": " + why);
}

}  // namespace crowdmpm
