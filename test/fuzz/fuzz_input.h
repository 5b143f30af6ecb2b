// Reads typed values off a fuzz input, front to back; once the bytes run out
// every read returns zero / the low end. The fuzz targets build frames,
// images, calibrations and parameters from it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>

namespace massage_cell::fuzz {

class FuzzInput {
 public:
  FuzzInput(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  std::size_t remaining() const { return size_ - pos_; }
  const std::uint8_t* rest() const { return data_ + pos_; }

  std::uint8_t byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  bool flag() { return byte() & 1; }

  template <typename T>
  T bits() {
    T value{};
    const std::size_t n = std::min(sizeof(T), remaining());
    if (n > 0) std::memcpy(&value, data_ + pos_, n);
    pos_ += n;
    return value;
  }

  /// An integer in [lo, hi].
  long range(long lo, long hi) {
    if (hi <= lo) return lo;
    const auto span = static_cast<std::uint64_t>(hi - lo) + 1;
    return lo + static_cast<long>(bits<std::uint32_t>() % span);
  }

  /// A double in [lo, hi]; with `special`, one read in eight is instead one
  /// of the values that break arithmetic (NaN, ±Inf, 0, -0, huge, tiny).
  double real(double lo, double hi, bool special = false) {
    const std::uint8_t selector = byte();
    if (special && selector % 8 == 0) {
      static const double kSpecial[] = {std::numeric_limits<double>::quiet_NaN(),
                                        std::numeric_limits<double>::infinity(),
                                        -std::numeric_limits<double>::infinity(),
                                        0.0,
                                        -0.0,
                                        1e300,
                                        -1e300,
                                        1e-300};
      return kSpecial[(selector / 8) % 8];
    }
    return lo + (hi - lo) * (bits<std::uint16_t>() / 65535.0);
  }

  /// The remaining bytes as a string.
  std::string text() {
    std::string s(reinterpret_cast<const char*>(rest()), remaining());
    pos_ = size_;
    return s;
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

}  // namespace massage_cell::fuzz
