// The acupoint model's silhouette (acupoint_model.h): per image row, the back's left and right edges (the outermost
// crossings of the contour with the row, which runs through the boundary pixels' centres, so the edges are half a
// pixel further out; the first / last mask pixel without a contour), and the midline: the middle of each row's
// extent fitted by a robust (Huber IRLS) quadratic x(y) over the torso rows (shoulder line .. just above the
// bottom), so the neck / shoulder corners and the tapering end of the back do not pull it, continued linearly
// beyond them. Where it leaves the outline at the head end is the back's top: the neck's base seen from above.
#include "massage_cell/cect/acupoint_model.h"

#include "acupoint_model_detail.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

namespace massage_cell::cect::detail {

Rows rowsFromContour(const std::vector<cv::Point2f>& contour) {
  float lo = contour[0].y, hi = contour[0].y;
  for (const auto& p : contour) {
    lo = std::min(lo, p.y);
    hi = std::max(hi, p.y);
  }
  Rows rows;
  rows.y0 = static_cast<int>(std::ceil(lo));
  const int y1 = static_cast<int>(std::floor(hi));
  const int n = std::max(0, y1 - rows.y0 + 1);
  rows.left.assign(static_cast<std::size_t>(n), kNaN);
  rows.right.assign(static_cast<std::size_t>(n), kNaN);
  const std::size_t m = contour.size();
  for (std::size_t k = 0; k < m; ++k) {
    const cv::Point2f a = contour[k], b = contour[(k + 1) % m];
    // Rows y with a.y <= y < b.y or b.y <= y < a.y (half-open: each crossing counted once).
    const double ylo = std::min(a.y, b.y), yhi = std::max(a.y, b.y);
    if (!(yhi > ylo)) continue;
    for (int y = static_cast<int>(std::ceil(ylo)); y < yhi && y <= y1; ++y) {
      if (y < rows.y0) continue;
      const double x = a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
      auto& l = rows.left[static_cast<std::size_t>(y - rows.y0)];
      auto& r = rows.right[static_cast<std::size_t>(y - rows.y0)];
      if (!(x - 0.5 >= l)) l = x - 0.5;  // NaN-safe min
      if (!(x + 0.5 <= r)) r = x + 0.5;
    }
  }
  return rows;
}

Rows rowsFromMask(const cv::Mat& mask) {
  Rows rows;
  int first = -1, last = -1;
  std::vector<double> l(static_cast<std::size_t>(mask.rows), kNaN), r(static_cast<std::size_t>(mask.rows), kNaN);
  for (int y = 0; y < mask.rows; ++y) {
    const unsigned char* p = mask.ptr<unsigned char>(y);
    int a = -1, b = -1;
    for (int x = 0; x < mask.cols; ++x) {
      if (p[x]) {
        if (a < 0) a = x;
        b = x;
      }
    }
    if (a < 0) continue;
    l[static_cast<std::size_t>(y)] = a - 0.5;
    r[static_cast<std::size_t>(y)] = b + 0.5;
    if (first < 0) first = y;
    last = y;
  }
  if (first < 0) return rows;
  rows.y0 = first;
  rows.left.assign(l.begin() + first, l.begin() + last + 1);
  rows.right.assign(r.begin() + first, r.begin() + last + 1);
  return rows;
}

/// Drops rows without edges at both ends (the contour's extreme rows can have
/// none under the half-open crossing rule) and fills gaps from their neighbours.
void tidyRows(Rows& rows) {
  int a = 0, b = rows.size() - 1;
  while (a <= b && !std::isfinite(rows.left[static_cast<std::size_t>(a)])) ++a;
  while (b >= a && !std::isfinite(rows.left[static_cast<std::size_t>(b)])) --b;
  rows.left = std::vector<double>(rows.left.begin() + a, rows.left.begin() + b + 1);
  rows.right = std::vector<double>(rows.right.begin() + a, rows.right.begin() + b + 1);
  rows.y0 += a;
  const int n = rows.size();
  int prev = -1;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(rows.left[static_cast<std::size_t>(i)])) continue;
    if (prev >= 0 && i - prev > 1) {
      for (int j = prev + 1; j < i; ++j) {
        const double t = double(j - prev) / (i - prev);
        auto lerp = [&](const std::vector<double>& v) {
          return (1 - t) * v[static_cast<std::size_t>(prev)] + t * v[static_cast<std::size_t>(i)];
        };
        rows.left[static_cast<std::size_t>(j)] = lerp(rows.left);
        rows.right[static_cast<std::size_t>(j)] = lerp(rows.right);
      }
    }
    prev = i;
  }
}

/// Robust fit of the row centres over rows [ia, ib] (indices into rows).
bool fitMidline(const Rows& rows, int ia, int ib, Midline& m) {
  m.ya = rows.y0 + ia;
  m.yb = rows.y0 + ib;
  m.yc = 0.5 * (m.ya + m.yb);
  m.h = std::max(1.0, 0.5 * (m.yb - m.ya));
  const Eigen::Index n = ib - ia + 1;
  Eigen::MatrixXd A(n, 3), B(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) {
    const int i = ia + static_cast<int>(k);
    const double u = (rows.y0 + i - m.yc) / m.h;
    A.row(k) << 1.0, u, u * u;
    B(k, 0) = 0.5 * (rows.left[static_cast<std::size_t>(i)] + rows.right[static_cast<std::size_t>(i)]);
  }
  // Huber IRLS: rows where the sides are not mirror images (an arm, a
  // shoulder raised) get less weight.
  auto huber = [](double r, double median) { return huberWeight(r, 1.5 * std::max(0.5, 1.4826 * median)); };
  Eigen::Vector3d c;
  if (!robustFit(A, B, 10, huber, &c)) return false;
  m.c = {c(0), c(1), c(2)};
  return true;
}

/// Rows (sub-pixel, pixel-centre coordinates) where the midline crosses the
/// back's outline: the first and last ones give the top and the bottom.
bool midlineCrossings(const Segmentation& seg, const Midline& m, double* top, double* bottom) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  if (usableContour(seg.contour)) {
    const auto& c = seg.contour;
    const std::size_t n = c.size();
    for (std::size_t k = 0; k < n; ++k) {
      const cv::Point2f a = c[k], b = c[(k + 1) % n];
      const double ga = a.x - m.x(a.y), gb = b.x - m.x(b.y);
      if ((ga < 0.0) == (gb < 0.0)) continue;
      const double t = ga / (ga - gb);
      const double y = a.y + t * (b.y - a.y);
      lo = std::min(lo, y);
      hi = std::max(hi, y);
    }
  } else {
    for (int y = 0; y < seg.mask.rows; ++y) {
      const int x = static_cast<int>(std::lround(m.x(y)));
      if (x < 0 || x >= seg.mask.cols || !seg.mask.at<unsigned char>(y, x)) continue;
      lo = std::min(lo, double(y));
      hi = std::max(hi, double(y));
    }
  }
  if (!(hi >= lo)) return false;
  *top = lo;
  *bottom = hi;
  return true;
}

}  // namespace massage_cell::cect::detail
