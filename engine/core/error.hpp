#pragma once
#include <stdexcept>
#include <string>

namespace crowdmpm {

// Every failure the engine reports to a user: bad input (with the JSON path or file position),
// impossible geometry, I/O problems, numerical blow-up. The message names what and where.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace crowdmpm
