// Internals of CECT (cect.h) shared by its stages' files: the matching primitives, the local fits and the
// builder that runs the stages (cect.cpp: the driver and the matching images; foundational.cpp: the contour's
// correspondences and the triangulation; seeds.cpp: interior seeds and the rim band; transfer.cpp: transfer,
// the constraints and the uncertainty of a localised point). Private to the library: not installed.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "massage_cell/cect/cect.h"
#include "stats_detail.h"  // median

namespace massage_cell::cect {

namespace detail {

using Clock = std::chrono::steady_clock;

/// Bilinear sample of a CV_32F image (clamped at the border).
inline float sample(const cv::Mat& img, float x, float y) {
  x = std::clamp(x, 0.0f, static_cast<float>(img.cols - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.rows - 1));
  const int x0 = std::min(static_cast<int>(x), img.cols - 2 < 0 ? 0 : img.cols - 2);
  const int y0 = std::min(static_cast<int>(y), img.rows - 2 < 0 ? 0 : img.rows - 2);
  const int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
  const float* r0 = img.ptr<float>(y0);
  const float* r1 = img.ptr<float>(y1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x1]);
}

/// Matching window of one point: (2r+1)^2 bilinear samples, mean removed,
/// normalised to unit length. false when the window is flat.
inline bool windowAt(const cv::Mat& img, float x, float y, int r, int ry, std::vector<float>* out) {
  const int n = (2 * r + 1) * (2 * ry + 1);
  out->resize(static_cast<std::size_t>(n));
  double sum = 0.0;
  int k = 0;
  const int xi = static_cast<int>(x), yi = static_cast<int>(y);
  if (static_cast<float>(xi) == x && static_cast<float>(yi) == y && xi - r >= 0 && yi - ry >= 0 && xi + r < img.cols &&
      yi + ry < img.rows) {
    // Whole pixels (seeds on the grid, integer disparities): no interpolation.
    for (int dy = -ry; dy <= ry; ++dy) {
      const float* row = img.ptr<float>(yi + dy) + xi;
      for (int dx = -r; dx <= r; ++dx) {
        const float v = row[dx];
        (*out)[static_cast<std::size_t>(k++)] = v;
        sum += v;
      }
    }
  } else {
    for (int dy = -ry; dy <= ry; ++dy)
      for (int dx = -r; dx <= r; ++dx) {
        const float v = sample(img, x + static_cast<float>(dx), y + static_cast<float>(dy));
        (*out)[static_cast<std::size_t>(k++)] = v;
        sum += v;
      }
  }
  const float mean = static_cast<float>(sum / n);
  double ss = 0.0;
  for (float& v : *out) {
    v -= mean;
    ss += static_cast<double>(v) * v;
  }
  if (ss < 1e-6 * n) return false;
  const float inv = static_cast<float>(1.0 / std::sqrt(ss));
  for (float& v : *out) v *= inv;
  return true;
}

struct MatchResult {
  bool ok = false;
  double disparity = 0.0;
  double ncc = -1.0;
  std::string why;
};

/// The peak of a correlation curve over the integer disparities lo, lo+1,
/// ... (scores below -1.5: no candidate there): a parabola through it and
/// its neighbours; `missing` names why a neighbour can be absent. The
/// peak's sharpness (minus the second difference) goes to *sharpness.
inline MatchResult peakOf(const std::vector<double>& score, int lo, const char* missing, double* sharpness = nullptr) {
  MatchResult res;
  const auto best = std::max_element(score.begin(), score.end());
  const int k = static_cast<int>(best - score.begin());
  res.ncc = *best;
  if (*best < -1.5) {
    res.why = missing;
    return res;
  }
  if (k == 0 || k == static_cast<int>(score.size()) - 1) {
    res.why = "correlation peak at the edge of the search range";
    return res;
  }
  const double a = score[static_cast<std::size_t>(k - 1)], b = *best, c = score[static_cast<std::size_t>(k + 1)];
  if (a < -1.5 || c < -1.5) {
    res.why = missing;
    return res;
  }
  const double denom = a - 2 * b + c;
  if (sharpness) *sharpness = -denom;
  const double off = denom < 0 ? std::clamp(0.5 * (a - c) / denom, -0.5, 0.5) : 0.0;
  res.disparity = lo + k + off;
  res.ok = true;
  return res;
}

/// Best disparity in [d_lo, d_hi] (integer steps, then a parabola through the
/// peak) for the left point (x, y): NCC of (2r+1)^2 windows along the row.
/// `to_left` searches the other way: the point is in `from` (the right view)
/// and candidates in `to` lie at x + d.
inline MatchResult matchAlongRow(const cv::Mat& from, const cv::Mat& to, float x, float y, double d_lo, double d_hi,
                                 int r, int ry, bool to_left) {
  MatchResult res;
  std::vector<float> ref, cand;
  if (!windowAt(from, x, y, r, ry, &ref)) {
    res.why = "no texture in the matching window";
    return res;
  }
  const int lo = static_cast<int>(std::floor(d_lo)), hi = static_cast<int>(std::ceil(d_hi));
  if (hi - lo < 2) {
    res.why = "search range too small";
    return res;
  }
  std::vector<double> score(static_cast<std::size_t>(hi - lo + 1), -2.0);
  const int xi = static_cast<int>(x), yi = static_cast<int>(y);
  const int strip_x = to_left ? xi + lo - r : xi - hi - r;
  const cv::Rect strip(strip_x, yi - ry, hi - lo + 2 * r + 1, 2 * ry + 1);
  if (static_cast<float>(xi) == x && static_cast<float>(yi) == y &&
      (strip & cv::Rect(0, 0, to.cols, to.rows)) == strip && xi - r >= 0 && xi + r < from.cols) {
    // Whole pixels, every candidate inside the image: the same zero-mean
    // NCC (cv::matchTemplate's TM_CCOEFF_NORMED) along the strip, directly:
    // the reference window is zero-mean and unit-length already, so each
    // candidate needs one dot product, and its sum and sum of squares slide
    // along the strip's column sums (~4x faster than matchTemplate at this size).
    const int ww = 2 * r + 1, wh = 2 * ry + 1, sw = strip.width, n = ww * wh;
    std::vector<double> cs(static_cast<std::size_t>(sw), 0.0), cs2(static_cast<std::size_t>(sw), 0.0);
    std::vector<float> dot(static_cast<std::size_t>(sw - ww + 1), 0.0f);
    for (int yy = 0; yy < wh; ++yy) {
      const float* row = to.ptr<float>(strip.y + yy) + strip.x;
      const float* rr = ref.data() + static_cast<std::size_t>(yy) * ww;
      for (int c = 0; c < sw; ++c) {
        cs[static_cast<std::size_t>(c)] += row[c];
        cs2[static_cast<std::size_t>(c)] += static_cast<double>(row[c]) * row[c];
      }
      for (int i = 0; i + ww <= sw; ++i) {
        float acc = 0.0f;
        for (int c = 0; c < ww; ++c) acc += rr[c] * row[i + c];
        dot[static_cast<std::size_t>(i)] += acc;
      }
    }
    double sum = 0.0, sum2 = 0.0;
    for (int c = 0; c < ww; ++c) {
      sum += cs[static_cast<std::size_t>(c)];
      sum2 += cs2[static_cast<std::size_t>(c)];
    }
    for (int i = 0; i + ww <= sw; ++i) {
      if (i > 0) {
        sum += cs[static_cast<std::size_t>(i + ww - 1)] - cs[static_cast<std::size_t>(i - 1)];
        sum2 += cs2[static_cast<std::size_t>(i + ww - 1)] - cs2[static_cast<std::size_t>(i - 1)];
      }
      const double var = sum2 - sum * sum / n;
      if (var > 1e-6 * n)
        score[static_cast<std::size_t>(to_left ? i : hi - lo - i)] = dot[static_cast<std::size_t>(i)] / std::sqrt(var);
    }
  } else
    for (int d = lo; d <= hi; ++d) {
      const float xc = to_left ? x + static_cast<float>(d) : x - static_cast<float>(d);
      if (xc < r || xc > to.cols - 1 - r) continue;
      if (!windowAt(to, xc, y, r, ry, &cand)) continue;
      double s = 0.0;
      for (std::size_t i = 0; i < ref.size(); ++i) s += static_cast<double>(ref[i]) * cand[i];
      score[static_cast<std::size_t>(d - lo)] = s;
    }
  return peakOf(score, lo, "matching window leaves the image");
}

/// Barycentric coordinates of p in triangle (a, b, c); false if degenerate.
inline bool barycentric(const cv::Point2f& p, const cv::Point2f& a, const cv::Point2f& b, const cv::Point2f& c,
                        double* l0, double* l1, double* l2) {
  const double det = (b.y - c.y) * (a.x - c.x) + (c.x - b.x) * (a.y - c.y);
  if (std::abs(det) < 1e-9) return false;
  *l0 = ((b.y - c.y) * (p.x - c.x) + (c.x - b.x) * (p.y - c.y)) / det;
  *l1 = ((c.y - a.y) * (p.x - c.x) + (a.x - c.x) * (p.y - c.y)) / det;
  *l2 = 1.0 - *l0 - *l1;
  return true;
}

/// A local quadratic d(x, y) fitted to vertices around `centre`: Gaussian
/// weights (sigma = radius / 2) over the vertices within `radius`, one refit
/// without the residuals beyond 3 MAD. With `quartic_x` it also has x^3 and
/// x^4 terms (across the body: the paraspinal ridges and the spine's groove
/// between them), when the neighbours span at least five columns. Returns
/// false with fewer than `min_count` neighbours or a singular fit; *value =
/// d(centre), *rms = the weighted rms residual of the points kept, *nearest =
/// the nearest used vertex's distance, *gradient = (dd/dx, dd/dy) at centre.
inline bool fitQuadratic(const std::vector<Correspondence>& V, const std::vector<int>& idx, const cv::Point2f& centre,
                         double radius, std::size_t min_count, double* value, double* rms = nullptr,
                         double* nearest = nullptr, cv::Point2d* gradient = nullptr, bool quartic_x = false) {
  using Vec = Eigen::Matrix<double, 8, 1>;
  using Mat = Eigen::Matrix<double, 8, 8>;
  const double s2 = 2.0 * (radius / 2.0) * (radius / 2.0);
  std::vector<Vec> phi;
  std::vector<double> wt, dv;
  std::set<int> columns;
  double near = std::numeric_limits<double>::infinity();
  for (int j : idx) {
    const Correspondence& v = V[static_cast<std::size_t>(j)];
    const cv::Point2f q = v.left - centre;
    const double r2 = q.x * q.x + q.y * q.y;
    if (r2 > radius * radius) continue;
    const double x = q.x / radius, y = q.y / radius;
    Vec f;
    f << 1.0, x, y, x * x, x * y, y * y, x * x * x, x * x * x * x;
    phi.push_back(f);
    wt.push_back(std::exp(-r2 / s2));
    dv.push_back(v.disparity);
    near = std::min(near, std::sqrt(r2));
    if (quartic_x) columns.insert(cvRound(v.left.x));
  }
  const std::size_t n = phi.size();
  if (n < min_count) return false;
  const int dim = quartic_x && columns.size() >= 5 ? 8 : 6;
  std::vector<bool> use(n, true);
  std::vector<double> res(n);
  Vec coef = Vec::Zero();
  for (int pass = 0; pass < 2; ++pass) {
    Mat A = Mat::Zero();
    Vec b = Vec::Zero();
    for (std::size_t k = 0; k < n; ++k) {
      if (!use[k]) continue;
      A.noalias() += wt[k] * phi[k] * phi[k].transpose();
      b.noalias() += wt[k] * dv[k] * phi[k];
    }
    coef.setZero();
    if (dim == 8) {
      coef = A.ldlt().solve(b);
    } else {
      coef.head<6>() = A.topLeftCorner<6, 6>().ldlt().solve(b.head<6>());
    }
    if (!coef.allFinite()) return false;
    for (std::size_t k = 0; k < n; ++k) res[k] = std::abs(dv[k] - coef.dot(phi[k]));
    if (pass == 1) break;
    const double mad = std::max(0.3, median(res));
    for (std::size_t k = 0; k < n; ++k) use[k] = res[k] <= 3.0 * mad;
  }
  *value = coef(0);
  if (gradient) *gradient = cv::Point2d(coef(1) / radius, coef(2) / radius);
  if (rms) {
    double ss = 0.0, ws = 0.0;
    for (std::size_t k = 0; k < n; ++k)
      if (use[k]) {
        ss += wt[k] * res[k] * res[k];
        ws += wt[k];
      }
    *rms = ws > 0 ? std::sqrt(ss / ws) : 0.0;
  }
  if (nearest) *nearest = near;
  return true;
}

}  // namespace detail

using namespace detail;  // (the stages' files are all in namespace cect)

/// Builds a CectFrame step by step (friend of CectFrame).
class CectFrameBuilder {
 public:
  CectFrameBuilder(CectFrame& f) : f_(f) {}

  void run(const cv::Mat& left, const cv::Mat& right);

 private:
  /// A view whose segmentation failed (a sheet or towel of skin's colour
  /// joined to the back: "multi-coloured") is segmented again with the
  /// table's pixels (tablePixels) left out as well; kept when that works.
  /// Only then: the coarse depth is too rough at the body's foot to leave
  /// the table out everywhere.
  void retryWithoutTheTable(double margin);

  void fail(const std::string& why, Clock::time_point t0);

  /// Grey without the specular sheen, by the dichromatic reflection model:
  /// in linear RGB (sRGB decoded) every back pixel is I = D c + S (1,1,1),
  /// a diffuse part of the skin's own chromaticity c (the median over the
  /// back) plus a specular part of the light's colour (white). D and S are
  /// solved per pixel (least squares, 3 channels); S, noisy, is smoothed
  /// (Gaussian, sheen_sigma; with sheen_twicing 2 G*S - G*G*S, which keeps
  /// the highlights' peaks) and taken off every channel; the grey of the
  /// rest is returned, scaled back to 0..255. Outside the back: plain grey.
  cv::Mat diffuseGrey(const cv::Mat& bgr, const cv::Mat& mask) const;

  /// Matching image band-passed: a difference of Gaussians keeps
  /// the skin's mottling and the relief's edges and drops the broad shading
  /// and the specular sheen, which move with the viewpoint.
  cv::Mat matchingImage(const cv::Mat& bgr, const cv::Mat& mask) const;

  double minDisparity() const { return f_.disparity_range_[0]; }
  double maxDisparity() const { return f_.disparity_range_[1]; }

  /// Step 2: contour samples -> row crossings in the right view.
  void foundational();

  struct EdgeSample {
    cv::Point2f left;    ///< contour sample
    cv::Point2f normal;  ///< inward unit normal
  };

  /// Step 2b: contour parts that run along the epipolar lines (the neck
  /// base, a bottom edge) have no usable row crossings. Where an edge runs
  /// parallel to the baseline both cameras see the same rim line (the
  /// baseline lies in its tangent plane), so the edge's row as a function of
  /// the column, y(x), is the same curve in both views shifted by the
  /// disparity. Each such contour sample gets the shift that best aligns the
  /// left curve with the right one over +-edge_window px, using only the
  /// columns where the edge stays within min_crossing_angle of the rows
  /// (where it turns steeper it is a flank's rim, a different line in each
  /// view) (Gaussian weights;
  /// quarter-pixel grid, then a parabola), within the disparities of the
  /// row-crossing correspondences nearby (+-4 px), and is kept only where
  /// the edge bends enough to fix it: the mean squared misalignment must
  /// grow by edge_min_bend px^2 or more 2 px either side of the best shift,
  /// and no other shift may come close (an ambiguous edge stays unmatched).
  void registerEdges(const std::vector<EdgeSample>& edge);

  /// Delaunay triangulation of the vertices, the triangle index map and the
  /// triangles around each vertex.
  void triangulate(double max_edge = 0.0);

  /// The band between the contour and the first seeds. The contour is the
  /// back's occluding rim: there the surface turns away from the camera, and
  /// across a smooth rim depth varies with the square root of the image
  /// distance u to it (a cross-section of curvature radius R seen edge-on
  /// rises by sqrt(2 R x) at a distance x from its rim). Linear interpolation
  /// between a rim vertex and the first seeds ~30 px inside undershoots that
  /// profile by up to ~4 px of disparity on a flank. So for every other rim
  /// vertex, d(u, t) = c + a sqrt(u) + b u + e t is fitted (least squares)
  /// to the seeds within a band along its inward normal (u along it, t
  /// across it) and to the rim's own disparity at u = 0; where the fit holds
  /// (rms within 2 pixel_sigma), vertices at u = 2, 5, 9, ... px are added up
  /// to half a seed step short of the nearest seed. Where it does not hold,
  /// the seed farthest from the fit is dropped and the fit repeated while
  /// five seeds remain: one bad seed on a steep flank (a window spanning a
  /// fall of several pixels of disparity) otherwise spoils both the profile
  /// and the interpolation from it.
  void rimProfiles();

  /// True when a border running along the rows lies within `reach` pixels
  /// above or below (x, y) while the back continues `reach` pixels to
  /// either side along the row (the shoulders' top, the neck base).
  bool nearRowBorder(int x, int y, int reach) const;

  /// Each interior seed on a slanted part of the back (or within 2 seed
  /// steps of a border along the rows) is matched again with a slanted
  /// window: the disparity plane of the seeds' local quadratic around it
  /// (its gradient at the seed), searched +-2 px around the seed's first
  /// match. Kept when the peak is found, strong enough (min_ncc) and
  /// within continuity_margin of the first match; otherwise the first match
  /// stays.
  void slantSeeds(double radius);

  /// Each interior seed's disparity becomes the value at the seed of a
  /// weighted quadratic (with quartic_across: quartic across the body)
  /// fitted to the seeds within `radius` pixels (Gaussian weights, sigma =
  /// radius / 2; one refit without the residuals beyond 3 MAD): single
  /// matches on skin are noisy (~0.6 px), the back is smooth.
  /// A seed farther than continuity_margin from its fit is dropped
  /// (constraint 2).
  void smoothSeeds(double radius);

  /// Interior seeds on a grid of `step` pixels (rows; columns every
  /// `column_step`, 0: `step`), matched within `search` of their barycentric
  /// prediction, kept when they pass the constraints.
  void seeds(int step, double search, int column_step = 0);

  CectFrame& f_;
  std::vector<cv::Point2f> rim_normals_;  ///< inward contour normal of each foundational vertex (same index)
  cv::Mat near_mask_;                     ///< the left mask dilated by 2 px
};

}  // namespace massage_cell::cect
