// Statistics shared by CECT's files (src/cect). Private to the library: not installed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace massage_cell::cect::detail {

/// How median() takes the middle of an even count.
enum class EvenCount {
  kMeanOfMiddle,  ///< the mean of the middle two
  kUpperMiddle,   ///< the upper of the middle two: a sample (the robust fits' scales, the skin model's chroma)
};

/// The median of v's finite values; NaN when none is finite.
template <typename T>
double median(std::vector<T> v, EvenCount even = EvenCount::kMeanOfMiddle) {
  v.erase(std::remove_if(v.begin(), v.end(), [](T x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double hi = v[mid];
  if (v.size() % 2 == 1 || even == EvenCount::kUpperMiddle) return hi;
  const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lo + hi);
}

}  // namespace massage_cell::cect::detail
