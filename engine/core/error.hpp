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

// A simulation whose state became non-finite (too stiff a material for the time step, too strong
// a drive): the one failure training may survive by leaving that window out.
class UnstableError : public Error {
 public:
  explicit UnstableError(const std::string& what) : Error(what) {}
};

}  // namespace crowdmpm
