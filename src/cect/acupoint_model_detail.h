// Internals of the acupoint model (acupoint_model.h) shared by its stages' files: silhouette.cpp (the back's rows
// and the midline fit), landmarks.cpp (the landmark search in the body's frame), landmarks_3d.cpp (the corrections
// with the back in 3D), placement.cpp (the acupoints' pixels) and acupoint_model.cpp (the model's file). Private to
// the library: not installed.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "massage_cell/cect/acupoint_model.h"
#include "stats_detail.h"  // median; robustFit, huberWeight (the midline, the parallax's line, the levels' cubic)

namespace massage_cell::cect {

namespace detail {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

constexpr double kMaxOutOfView = 0.25;  // L4 at most this fraction of C7 -> L4 below a back cut by the image

inline std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// ---------------------------------------------------------------------------
// Affine maps between the image and the body's frame.

inline cv::Point2f apply(const cv::Matx23d& a, const cv::Point2f& p) {
  return {static_cast<float>(a(0, 0) * p.x + a(0, 1) * p.y + a(0, 2)),
          static_cast<float>(a(1, 0) * p.x + a(1, 1) * p.y + a(1, 2))};
}

/// a after b (both affine).
inline cv::Matx23d compose(const cv::Matx23d& a, const cv::Matx23d& b) {
  const cv::Matx33d A(a(0, 0), a(0, 1), a(0, 2), a(1, 0), a(1, 1), a(1, 2), 0, 0, 1);
  const cv::Matx33d B(b(0, 0), b(0, 1), b(0, 2), b(1, 0), b(1, 1), b(1, 2), 0, 0, 1);
  const cv::Matx33d C = A * B;
  return cv::Matx23d(C(0, 0), C(0, 1), C(0, 2), C(1, 0), C(1, 1), C(1, 2));
}

inline cv::Matx23d inverse(const cv::Matx23d& a) {
  cv::Matx23d b;
  cv::invertAffineTransform(a, b);
  return b;
}

inline bool isIdentity(const cv::Matx23d& a) { return a == cv::Matx23d(1, 0, 0, 0, 1, 0); }

// ---------------------------------------------------------------------------
// The back's silhouette row by row (head at the image top): silhouette.cpp.

struct Rows {
  int y0 = 0;                       // first image row
  std::vector<double> left, right;  // edges (pixel borders), NaN where the row has none
  int size() const { return static_cast<int>(left.size()); }
  double width(int i) const { return right[static_cast<std::size_t>(i)] - left[static_cast<std::size_t>(i)]; }
};

inline bool usableContour(const std::vector<cv::Point2f>& contour) { return contour.size() >= 8; }

Rows rowsFromContour(const std::vector<cv::Point2f>& contour);
Rows rowsFromMask(const cv::Mat& mask);
/// Drops rows without edges at both ends (the contour's extreme rows can have
/// none under the half-open crossing rule) and fills gaps from their neighbours.
void tidyRows(Rows& rows);

// Midline: x(y) = quadratic over the fitted rows, linear beyond them.

struct Midline {
  double ya = 0.0, yb = 1.0;  // fitted rows
  double yc = 0.0, h = 1.0;   // normalisation u = (y - yc) / h
  std::array<double, 3> c{};  // x = c0 + c1 u + c2 u^2

  double fit(double y) const {
    const double u = (y - yc) / h;
    return c[0] + u * (c[1] + u * c[2]);
  }
  double fitSlope(double y) const {  // dx/dy
    const double u = (y - yc) / h;
    return (c[1] + 2.0 * c[2] * u) / h;
  }
  double x(double y) const {
    if (y < ya) return fit(ya) + fitSlope(ya) * (y - ya);
    if (y > yb) return fit(yb) + fitSlope(yb) * (y - yb);
    return fit(y);
  }
  double slope(double y) const { return fitSlope(std::clamp(y, ya, yb)); }
};

/// Robust fit of the row centres over rows [ia, ib] (indices into rows).
bool fitMidline(const Rows& rows, int ia, int ib, Midline& m);

/// Rows (sub-pixel, pixel-centre coordinates) where the midline crosses the
/// back's outline: the first and last ones give the top and the bottom.
bool midlineCrossings(const Segmentation& seg, const Midline& m, double* top, double* bottom);

// ---------------------------------------------------------------------------
// Along the midline.

/// What midlineAt gives beyond the midline's ends.
enum class Beyond {
  kExtrapolate,  ///< the end segment continued: the point at row y
  kClamp,        ///< the end point itself: the row clamped to the midline's rows
};

/// The midline's point at row y of the body frame: linear between its points (one a row), beyond its ends as `beyond`
/// says. The midline must not be empty.
inline cv::Point2f midlineAt(const BackLandmarks& l, double y, Beyond beyond = Beyond::kExtrapolate) {
  const auto& m = l.midline;
  const double last = static_cast<double>(m.size() - 1);
  double t = y - m.front().y;
  if (beyond == Beyond::kClamp && t < 0.0) return m.front();
  if (beyond == Beyond::kClamp && t > last) return m.back();
  if (m.size() == 1) return {m[0].x, static_cast<float>(y)};
  const std::size_t i = static_cast<std::size_t>(std::clamp(std::floor(t), 0.0, last - 1.0));
  const double f = t - double(i);  // < 0 or > 1 beyond the ends (kExtrapolate): linear extrapolation
  return {static_cast<float>(m[i].x + f * (m[i + 1].x - m[i].x)), static_cast<float>(y)};
}

// ---------------------------------------------------------------------------
// The placement (placement.cpp).

/// The fraction of C7 -> L4 at a row of the body frame: along the body in 3D when measured, else in rows.
double fractionAtRow(const BackLandmarks& l, double row);

}  // namespace detail

using namespace detail;  // (the model's files are all in namespace cect)

}  // namespace massage_cell::cect
