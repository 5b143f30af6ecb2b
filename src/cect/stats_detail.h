// Statistics shared by CECT's files (src/cect): the median, quantiles and the robust fit. Private to the library: not
// installed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Dense>

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

/// Which sample quantile() takes of n sorted values (0-based index; q in [0, 1]). The callers keep the convention
/// their thresholds were tuned with.
enum class QuantileIndex {
  kNearestRank,    ///< ceil(q n) - 1, within 0..n-1: the nearest rank (evaluation.h's Spread, cect_eval's p95)
  kFloorOfSpan,    ///< floor(q (n - 1)) (the depth gate's nearest surfaces)
  kRoundedOfSpan,  ///< floor(q (n - 1) + 0.5): q (n - 1) rounded half up (the skin model's second material)
};

/// The q-quantile of v's finite values, a sample chosen by `index`; NaN when none is finite.
template <typename T>
double quantile(std::vector<T> v, double q, QuantileIndex index = QuantileIndex::kNearestRank) {
  v.erase(std::remove_if(v.begin(), v.end(), [](T x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double n = static_cast<double>(v.size());
  double k = 0.0;
  switch (index) {
    case QuantileIndex::kNearestRank:
      k = std::ceil(q * n) - 1.0;
      break;
    case QuantileIndex::kFloorOfSpan:
      k = std::floor(q * (n - 1.0));
      break;
    case QuantileIndex::kRoundedOfSpan:
      k = std::floor(q * (n - 1.0) + 0.5);
      break;
  }
  const auto at = static_cast<std::size_t>(std::clamp(k, 0.0, n - 1.0));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(at), v.end());
  return static_cast<double>(v[at]);
}

// The robust fits (the body's centre line in trunk.cpp; the acupoint model's midline, parallax line and levels' cubic).

/// Iteratively reweighted least squares of A C = B, one sample a row (B's columns fitted together; a row's residual
/// is the norm of its row of A C - B): a plain fit, then `passes` refits, each with every row weighted by
/// weight(r, m), r its residual and m the median of the residuals (the upper middle one of an even count). A weight
/// multiplies its row: the square root of an IRLS weight (huberWeight). false when a fit is rank-deficient or not
/// finite; *used, when given: the weights of the last fit.
template <typename Coefficients, typename Weight>
bool robustFit(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, int passes, const Weight& weight, Coefficients* C,
               Eigen::VectorXd* used = nullptr) {
  const Eigen::Index n = A.rows();
  Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  for (int pass = 0;; ++pass) {
    const Eigen::MatrixXd Aw = w.asDiagonal() * A, Bw = w.asDiagonal() * B;
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Aw);
    if (qr.rank() < A.cols()) return false;
    *C = qr.solve(Bw);
    if (!C->allFinite()) return false;
    if (pass == passes) break;
    const Eigen::VectorXd r = (A * *C - B).rowwise().norm();
    const double m = median(std::vector<double>(r.data(), r.data() + n), EvenCount::kUpperMiddle);
    for (Eigen::Index i = 0; i < n; ++i) w(i) = weight(r(i), m);
  }
  if (used) *used = w;
  return true;
}

/// Huber's weight of a row with residual r (robustFit's: the square root of k / r beyond k).
inline double huberWeight(double r, double k) { return r <= k ? 1.0 : std::sqrt(k / r); }

}  // namespace massage_cell::cect::detail
