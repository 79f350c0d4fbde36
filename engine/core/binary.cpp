#include "engine/core/binary.hpp"

namespace crowdmpm {

uint64_t fnv1a64(const char* data, size_t size) {
  uint64_t h = 14695981039346656037ull;
  for (size_t k = 0; k < size; ++k) {
    h ^= static_cast<unsigned char>(data[k]);
    h *= 1099511628211ull;
  }
  return h;
}

}  // namespace crowdmpm
