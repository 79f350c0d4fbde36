#include "engine/core/input.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "engine/core/error.hpp"

namespace crowdmpm {

namespace fs = std::filesystem;

static std::string mib(uint64_t bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
  return buf;
}

uint64_t check_input_file(const std::string& path, const InputPolicy& policy) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);  // follows symbolic links
  if (ec || st.type() == fs::file_type::not_found) throw Error(path + ": cannot open file for reading (no such file)");
  if (st.type() == fs::file_type::directory) throw Error(path + ": is a folder, not a file");
  if (st.type() != fs::file_type::regular)
    throw Error(path + ": is not a regular file (a device, pipe or socket); only regular files are read");
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) throw Error(path + ": cannot read its size");
  if (size > policy.max_bytes)
    throw Error(path + ": is " + mib(size) + ", above the input limit of " + mib(policy.max_bytes) +
                " (raise it with --max-input-mb or the caller's input limit)");
  return size;
}

std::string read_input_file(const std::string& path, const InputPolicy& policy) {
  const uint64_t size = check_input_file(path, policy);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open file for reading");
  // Read in chunks, checking the limit as it goes: a file that grows while read stays bounded.
  std::string data;
  data.reserve(static_cast<size_t>(size));
  char chunk[65536];
  while (in.read(chunk, sizeof chunk) || in.gcount() > 0) {
    if (data.size() + static_cast<size_t>(in.gcount()) > policy.max_bytes)
      throw Error(path + ": grew above the input limit of " + mib(policy.max_bytes) + " while being read");
    data.append(chunk, static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) throw Error(path + ": read error");
  return data;
}

static bool inside(const fs::path& root, const fs::path& p) {
  auto r = root.begin(), q = p.begin();
  for (; r != root.end(); ++r, ++q) {
    if (r->empty()) continue;  // a trailing separator of the root
    if (q == p.end() || *r != *q) return false;
  }
  return true;
}

std::string confined_path(const std::string& root, const std::string& dir, const std::string& name,
                          const InputPolicy& policy, const std::string& what) {
  if (name.empty()) throw Error((what.empty() ? "" : what + ": ") + "empty file name");
  const std::string path = name[0] == '/' ? name : (dir.empty() ? name : dir + "/" + name);
  if (policy.allow_outside_paths) return path;
  std::error_code ec1, ec2;
  const fs::path real_root = fs::weakly_canonical(fs::absolute(root.empty() ? "." : root), ec1);
  const fs::path real = fs::weakly_canonical(fs::absolute(path), ec2);
  if (ec1 || ec2 || !inside(real_root, real))
    throw Error((what.empty() ? "" : what + ": ") + "'" + name + "' lies outside the folder " + (root.empty() ? "." : root) +
                " of the file given; paths named inside a file must stay in its folder (allow others with "
                "--allow-outside-paths or the caller's allow_outside_paths)");
  return path;
}

std::string resolve_path(const std::string& base, const std::string& p) {
  if (base.empty() || p.empty() || p[0] == '/') return p;
  return base + "/" + p;
}

}  // namespace crowdmpm
