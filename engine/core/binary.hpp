#pragma once
// Little-endian binary encoding for snapshots: a writer that appends to a byte string and a
// reader that checks every read against the end of its input (a truncated or corrupted file
// gives an Error naming what was being read and where, never a read past the end).
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "engine/core/error.hpp"
#include "engine/core/vec.hpp"

namespace crowdmpm {

// FNV-1a, 64 bit.
uint64_t fnv1a64(const char* data, size_t size);

class BinaryWriter {
 public:
  void u32(uint32_t v) { put(&v, 4); }
  void u64(uint64_t v) { put(&v, 8); }
  void i64(int64_t v) { put(&v, 8); }
  void f64(double v) { put(&v, 8); }
  void raw(const char* p, size_t n) { bytes_.append(p, n); }
  void str(const std::string& s) {
    u64(s.size());
    bytes_.append(s);
  }
  void vec2(const Vec2& v) {
    f64(v.x());
    f64(v.y());
  }
  void mat2(const Mat2& m) {
    for (int k = 0; k < 4; ++k) f64(m(k % 2, k / 2));
  }
  template <class T, class F>
  void array(const std::vector<T>& a, F&& each) {
    u64(a.size());
    for (const T& x : a) each(x);
  }
  const std::string& bytes() const { return bytes_; }

 private:
  void put(const void* p, size_t n) {
    static_assert(sizeof(double) == 8, "IEEE doubles");
    // Snapshots are little-endian; every platform we build for is (x86-64, AArch64).
    bytes_.append(static_cast<const char*>(p), n);
  }
  std::string bytes_;
};

class BinaryReader {
 public:
  BinaryReader(const char* data, size_t size, std::string source) : p_(data), end_(data + size), begin_(data), source_(std::move(source)) {}
  uint32_t u32(const char* what) { uint32_t v; get(&v, 4, what); return v; }
  uint64_t u64(const char* what) { uint64_t v; get(&v, 8, what); return v; }
  int64_t i64(const char* what) { int64_t v; get(&v, 8, what); return v; }
  double f64(const char* what) { double v; get(&v, 8, what); return v; }
  std::string str(const char* what) {
    const uint64_t n = count(what, 1);
    std::string s(p_, static_cast<size_t>(n));
    p_ += n;
    return s;
  }
  Vec2 vec2(const char* what) {
    const double x = f64(what);
    return Vec2(x, f64(what));
  }
  Mat2 mat2(const char* what) {
    Mat2 m;
    for (int k = 0; k < 4; ++k) m(k % 2, k / 2) = f64(what);
    return m;
  }
  // An array length, checked against the bytes left (each element at least min_bytes long).
  uint64_t count(const char* what, size_t min_bytes) {
    const uint64_t n = u64(what);
    if (min_bytes > 0 && n > static_cast<uint64_t>(end_ - p_) / min_bytes) fail(what, "length " + std::to_string(n) + " runs past the end");
    return n;
  }
  template <class T, class F>
  void array(std::vector<T>& a, const char* what, size_t min_bytes, F&& each) {
    const uint64_t n = count(what, min_bytes);
    a.clear();
    a.reserve(static_cast<size_t>(n));
    for (uint64_t i = 0; i < n; ++i) a.push_back(each());
  }
  bool at_end() const { return p_ == end_; }
  size_t offset() const { return static_cast<size_t>(p_ - begin_); }
  [[noreturn]] void fail(const char* what, const std::string& why) const {
    throw Error(source_ + ": byte " + std::to_string(offset()) + " (" + what + "): " + why);
  }

 private:
  void get(void* v, size_t n, const char* what) {
    if (static_cast<size_t>(end_ - p_) < n) fail(what, "the file ends here (truncated)");
    std::memcpy(v, p_, n);
    p_ += n;
  }
  const char* p_;
  const char* end_;
  const char* begin_;
  std::string source_;
};

}  // namespace crowdmpm
