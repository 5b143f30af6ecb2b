// CECT: foundational correspondences on the back's contour, barycentric
// transfer inside it, three geometric constraints, triangulation
// (see cect.h). Our design where the thesis extract is silent:
//
// * Epipolar lines are rows of the rectified pair (camera::StereoModel). A left
//   contour sample's own crossing and the right view's crossings of that row
//   are zero crossings of each view's continuous skin score, interpolated
//   between pixels, so foundational correspondences are sub-pixel.
// * Several right crossings on a row: only those of the same kind (entering
//   or leaving the back walking right) with a disparity in range are
//   candidates; the k-th such left crossing of the row takes the k-th right
//   one when both rows hold the same number, otherwise the candidate closest
//   to the disparity of the unambiguous samples along the contour nearby.
//   Samples where the border runs nearly along the row are dropped: there
//   the crossing's x is ill-conditioned.
// * The contour alone cannot carry the back's relief inward (the spine lies
//   ~5 cm above the flanks: ~9 px of disparity at 0.8 m), so interior seeds on
//   a grid are matched along their epipolar line by normalised cross
//   correlation, searching only around their barycentric prediction, and
//   join the triangulation once accepted; two passes (coarse grid, wide
//   search; then the grid of `seed_step`, narrow search around the denser
//   triangulation's prediction).
// * The three geometric constraints:
//   1. candidate agreement: the transfers through the containing triangle and
//      its edge neighbours must agree within max_candidate_spread pixels;
//   2. continuity: a seed's disparity may differ from the median of its grid
//      neighbours by at most continuity_margin (the back is smooth), and a
//      query's refinement may move its prediction by at most that much;
//   3. left-right consistency: matching the right point back into the left
//      view must return within lr_tolerance pixels.
//   Epipolar consistency itself holds by construction (every vertex has
//   y_left = y_right, and barycentric combinations keep it).
#include "massage_cell/cect/cect.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  double hi = v[m];
  if (v.size() % 2 == 1) return hi;
  const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m));
  return 0.5 * (lo + hi);
}

/// Bilinear sample of a CV_32F image (clamped at the border).
float sample(const cv::Mat& img, float x, float y) {
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
bool windowAt(const cv::Mat& img, float x, float y, int r, int ry, std::vector<float>* out) {
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
MatchResult peakOf(const std::vector<double>& score, int lo, const char* missing, double* sharpness = nullptr) {
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
MatchResult matchAlongRow(const cv::Mat& from, const cv::Mat& to, float x, float y, double d_lo, double d_hi, int r,
                          int ry, bool to_left) {
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

/// matchAlongRow for a window that may cross the back's border: only the
/// window's pixels on `from_mask` whose candidate lies on `to_mask` count
/// (at least a third of the window). Whole pixels (x, y rounded). Also
/// returns the peak's sharpness (minus the second difference of the NCC).
MatchResult maskedMatchAlongRow(const cv::Mat& from, const cv::Mat& to, const cv::Mat& from_mask,
                                const cv::Mat& to_mask, float x, float y, double d_lo, double d_hi, int r, int ry,
                                bool to_left, double* sharpness) {
  MatchResult res;
  *sharpness = 0.0;
  const int xi = cvRound(x), yi = cvRound(y);
  const int lo = static_cast<int>(std::floor(d_lo)), hi = static_cast<int>(std::ceil(d_hi));
  if (hi - lo < 2) {
    res.why = "search range too small";
    return res;
  }
  const int min_count = (2 * r + 1) * (2 * ry + 1) / 3;
  std::vector<double> score(static_cast<std::size_t>(hi - lo + 1), -2.0);
  for (int d = lo; d <= hi; ++d) {
    const int dx = to_left ? d : -d;
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    int n = 0;
    for (int v = yi - ry; v <= yi + ry; ++v) {
      if (v < 0 || v >= from.rows) continue;
      const float* a = from.ptr<float>(v);
      const float* b = to.ptr<float>(v);
      const std::uint8_t* ma = from_mask.ptr<std::uint8_t>(v);
      const std::uint8_t* mb = to_mask.ptr<std::uint8_t>(v);
      for (int u = xi - r; u <= xi + r; ++u) {
        const int uc = u + dx;
        if (u < 0 || u >= from.cols || uc < 0 || uc >= to.cols || !ma[u] || !mb[uc]) continue;
        sa += a[u];
        sb += b[uc];
        saa += static_cast<double>(a[u]) * a[u];
        sbb += static_cast<double>(b[uc]) * b[uc];
        sab += static_cast<double>(a[u]) * b[uc];
        ++n;
      }
    }
    if (n < min_count) continue;
    const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
    if (va <= 1e-9 || vb <= 1e-9) continue;
    score[static_cast<std::size_t>(d - lo)] = (sab - sa * sb / n) / std::sqrt(va * vb);
  }
  return peakOf(score, lo, "too little of the window on the back", sharpness);
}

/// matchAlongRow with a slanted window: the left window's pixel (x+u, y+v)
/// is compared with the right view at x+u - (d + g.x u + g.y v), the
/// disparity plane through d with gradient g (bilinear samples), for
/// d = d0 - range .. d0 + range in whole pixels, then a parabola. A
/// fronto-parallel window on a slanted surface compares pixels whose
/// disparities differ by g.x r + g.y ry at its edges (~1.5 px at the
/// shoulders' top), and its peak follows wherever the window's texture is
/// strongest rather than its centre.
MatchResult slantedMatch(const cv::Mat& left, const cv::Mat& right, int x, int y, double d0, const cv::Point2d& g,
                         int range, int r, int ry) {
  MatchResult res;
  if (x - r < 0 || y - ry < 0 || x + r >= left.cols || y + ry >= left.rows) {
    res.why = "matching window leaves the image";
    return res;
  }
  std::vector<float> ref;
  if (!windowAt(left, static_cast<float>(x), static_cast<float>(y), r, ry, &ref)) {
    res.why = "no texture in the matching window";
    return res;
  }
  const int n = static_cast<int>(ref.size());
  std::vector<double> score(static_cast<std::size_t>(2 * range + 1), -2.0);
  std::vector<float> cand(ref.size());
  for (int k = -range; k <= range; ++k) {
    const double d = d0 + k;
    double sum = 0.0;
    int i = 0;
    bool inside = true;
    for (int v = -ry; v <= ry && inside; ++v)
      for (int u = -r; u <= r; ++u) {
        const double xr = x + u - (d + g.x * u + g.y * v);
        if (xr < 0.0 || xr > right.cols - 1.0) {
          inside = false;
          break;
        }
        const float c = sample(right, static_cast<float>(xr), static_cast<float>(y + v));
        cand[static_cast<std::size_t>(i++)] = c;
        sum += c;
      }
    if (!inside) continue;
    const double mean = sum / n;
    double ss = 0.0, dot = 0.0;
    for (int j = 0; j < n; ++j) {
      const double c = cand[static_cast<std::size_t>(j)] - mean;
      ss += c * c;
      dot += c * ref[static_cast<std::size_t>(j)];
    }
    if (ss < 1e-6 * n) continue;
    score[static_cast<std::size_t>(k + range)] = dot / std::sqrt(ss);
  }
  MatchResult m = peakOf(score, 0, "matching window leaves the image");
  if (m.ok) m.disparity += d0 - range;
  return m;
}

/// Barycentric coordinates of p in triangle (a, b, c); false if degenerate.
bool barycentric(const cv::Point2f& p, const cv::Point2f& a, const cv::Point2f& b, const cv::Point2f& c, double* l0,
                 double* l1, double* l2) {
  const double det = (b.y - c.y) * (a.x - c.x) + (c.x - b.x) * (a.y - c.y);
  if (std::abs(det) < 1e-9) return false;
  *l0 = ((b.y - c.y) * (p.x - c.x) + (c.x - b.x) * (p.y - c.y)) / det;
  *l1 = ((c.y - a.y) * (p.x - c.x) + (a.x - c.x) * (p.y - c.y)) / det;
  *l2 = 1.0 - *l0 - *l1;
  return true;
}

/// Gaussian blur of `img` (CV_32F) over the pixels of weight `w` (CV_32F in
/// [0, 1]) only: blur(img w) / blur(w), normalised convolution. Blurs with
/// sigma >= 3 run at half resolution (their result is smooth; 8x fewer
/// operations).
cv::Mat maskedBlur(const cv::Mat& img, const cv::Mat& w, double sigma) {
  cv::Mat both, b;
  cv::merge(std::vector<cv::Mat>{img.mul(w), w}, both);
  if (sigma >= 3.0 && both.cols >= 8 && both.rows >= 8) {
    cv::Mat half;
    cv::resize(both, half, cv::Size((both.cols + 1) / 2, (both.rows + 1) / 2), 0, 0, cv::INTER_AREA);
    cv::GaussianBlur(half, half, cv::Size(0, 0), sigma / 2.0);
    cv::resize(half, b, both.size(), 0, 0, cv::INTER_LINEAR);
  } else {
    cv::GaussianBlur(both, b, cv::Size(0, 0), sigma);
  }
  cv::Mat ch[2];
  cv::split(b, ch);
  return ch[0] / cv::max(ch[1], 1e-3);
}

/// A local quadratic d(x, y) fitted to vertices around `centre`: Gaussian
/// weights (sigma = radius / 2) over the vertices within `radius`, one refit
/// without the residuals beyond 3 MAD. With `quartic_x` it also has x^3 and
/// x^4 terms (across the body: the paraspinal ridges and the spine's groove
/// between them), when the neighbours span at least five columns. Returns
/// false with fewer than `min_count` neighbours or a singular fit; *value =
/// d(centre), *rms = the weighted rms residual of the points kept, *nearest =
/// the nearest used vertex's distance, *gradient = (dd/dx, dd/dy) at centre.
bool fitQuadratic(const std::vector<Correspondence>& V, const std::vector<int>& idx, const cv::Point2f& centre,
                  double radius, std::size_t min_count, double* value, double* rms = nullptr, double* nearest = nullptr,
                  cv::Point2d* gradient = nullptr, bool quartic_x = false) {
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

/// s rounded to the nearest power of 2^(1/4).
double quantisedScale(double s) { return std::exp2(std::round(4.0 * std::log2(s)) / 4.0); }

/// One seed beside a rim vertex: u along the rim's inward normal, t across
/// it (pixels), its disparity, its index among the vertices.
struct RimObservation {
  double u, t, d;
  int vertex;
};

/// The rim profile d(u, t) = k0 + k1 sqrt(u / step) + k2 u / step + k3 t / step.
double rimProfileAt(const Eigen::Vector4d& k, double u, double t, double step) {
  return k(0) + k(1) * std::sqrt(u / step) + k(2) * u / step + k(3) * t / step;
}

/// Least-squares rim profile through the rim's own disparity (at u = 0,
/// weight `rim_weight`) and the seeds `obs`; while its rms exceeds `max_rms`
/// the seed farthest from it goes to `outliers` and the fit is repeated,
/// as long as five seeds remain. False when it never holds.
bool fitRimProfile(double rim_disparity, double rim_weight, double step, double max_rms,
                   std::vector<RimObservation>* obs, Eigen::Vector4d* k, std::vector<int>* outliers) {
  while (obs->size() >= 5) {
    Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
    Eigen::Vector4d b = Eigen::Vector4d::Zero();
    auto add = [&](double u, double t, double d, double w) {
      const Eigen::Vector4d phi(1.0, std::sqrt(u / step), u / step, t / step);
      A += w * phi * phi.transpose();
      b += w * d * phi;
    };
    add(0.0, 0.0, rim_disparity, rim_weight);
    for (const RimObservation& o : *obs) add(o.u, o.t, o.d, 1.0);
    *k = A.ldlt().solve(b);
    if (!k->allFinite()) return false;
    double ss = rim_weight * std::pow(rim_disparity - rimProfileAt(*k, 0.0, 0.0, step), 2), worst_res = -1.0;
    std::size_t worst = 0;
    for (std::size_t o = 0; o < obs->size(); ++o) {
      const RimObservation& r = (*obs)[o];
      const double res = std::abs(r.d - rimProfileAt(*k, r.u, r.t, step));
      ss += res * res;
      if (res > worst_res) {
        worst_res = res;
        worst = o;
      }
    }
    if (std::sqrt(ss / (static_cast<double>(obs->size()) + rim_weight)) <= max_rms) return true;
    outliers->push_back((*obs)[worst].vertex);
    obs->erase(obs->begin() + static_cast<std::ptrdiff_t>(worst));
  }
  return false;
}

}  // namespace

double viewScale(double median_disparity, double baseline) {
  if (!(median_disparity > 0) || !(baseline > 0) || !std::isfinite(median_disparity / baseline)) return 1.0;
  return quantisedScale(median_disparity / baseline / kReferencePixelsPerMetre);
}

cv::Vec2d disparityRange(const CectParams& p, const camera::StereoModel& geometry) {
  const double width = geometry.size().width;
  double lo = p.min_disparity, hi = p.max_disparity;
  if (!(lo > 0)) lo = std::max(0.5, geometry.disparityAtDepth(p.max_depth));
  if (!(hi > 0)) hi = std::min(width - 1.0, geometry.disparityAtDepth(p.min_depth));
  if (!std::isfinite(lo) || !std::isfinite(hi)) return cv::Vec2d(0.0, 0.0);
  return cv::Vec2d(lo, hi);
}

CectParams scaledParams(const CectParams& p, double scale) {
  CectParams q = p;
  if (scale == 1.0 || !(scale > 0)) return q;
  const double s = scale;
  // A window's extent 2r + 1 scales (23 px -> 11.5 -> r = 5 at half size).
  auto radius = [s](int r) { return std::max(1, static_cast<int>(std::lround(((2 * r + 1) * s - 1.0) / 2.0))); };
  auto step = [s](int n) { return n > 0 ? std::max(2, static_cast<int>(std::lround(n * s))) : n; };
  q.sample_spacing = p.sample_spacing * s;
  q.edge_window = p.edge_window * s;
  q.seed_step = step(p.seed_step);
  q.seed_column_step = step(p.seed_column_step);
  q.ncc_radius = radius(p.ncc_radius);
  q.ncc_half_height = p.ncc_half_height > 0 ? radius(p.ncc_half_height) : 0;
  q.bandpass_low = p.bandpass_low * s;
  q.bandpass_high = p.bandpass_high * s;
  q.sheen_sigma = p.sheen_sigma * s;
  q.seed_margin = p.seed_margin >= 0 ? p.seed_margin * s : p.seed_margin;
  q.direct_min_sharpness = p.direct_min_sharpness / (s * s);
  q.seed_search = p.seed_search * s;
  q.query_search = p.query_search * s;
  q.max_candidate_spread = p.max_candidate_spread * s;
  q.continuity_margin = p.continuity_margin * s;
  q.min_slant = p.min_slant * s;
  q.border_sigma = p.border_sigma * s;
  q.slope_sigma = p.slope_sigma * s;
  SegmentationParams& g = q.segmentation;
  g.blur_sigma = p.segmentation.blur_sigma * s;
  g.open_radius = std::max(1, static_cast<int>(std::lround(p.segmentation.open_radius * s)));
  g.close_radius = std::max(1, static_cast<int>(std::lround(p.segmentation.close_radius * s)));
  g.contour_spacing = p.segmentation.contour_spacing * s;
  return q;  // (the trunk's pixel sizes scale with the body itself: trunk.h)
}

/// Builds a CectFrame step by step (friend of CectFrame).
class CectFrameBuilder {
 public:
  CectFrameBuilder(CectFrame& f) : f_(f) {}

  void run(const cv::Mat& left, const cv::Mat& right) {
    const auto t0 = Clock::now();
    f_.geometry_.rectify(left, right, &f_.left_rect_, &f_.right_rect_);
    f_.timings_.rectify_ms = msSince(t0);
    f_.disparity_range_ = disparityRange(f_.params_, f_.geometry_);
    if (!(f_.disparity_range_[1] > f_.disparity_range_[0]))
      return fail("empty disparity range " + std::to_string(f_.disparity_range_[0]) + ".." +
                      std::to_string(f_.disparity_range_[1]) + " px (min_depth / max_depth or min / max_disparity)",
                  t0);

    // With auto_scale the segmentation and the contour's sampling scale with
    // the image's width first (a prior); once the contour is matched, its
    // median disparity gives the view's scale for everything after it.
    const CectParams given = f_.params_;
    if (given.auto_scale) {
      const double s0 = quantisedScale(f_.left_rect_.cols / 640.0);
      f_.params_ = scaledParams(given, s0);
      f_.scale_ = s0;
    }

    auto t = Clock::now();
    f_.background_ = farBackground(f_.left_rect_, f_.right_rect_, f_.geometry_, f_.disparity_range_, given.background);
    // The two views are independent until matching: one core each.
    cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& views) {
      for (int v = views.start; v < views.end; ++v)
        (v == 0 ? f_.left_seg_ : f_.right_seg_) =
            segmentBack(v == 0 ? f_.left_rect_ : f_.right_rect_, f_.params_.segmentation,
                        v == 0 ? f_.background_.left_far : f_.background_.right_far,
                        v == 0 ? f_.background_.left_depth : f_.background_.right_depth);
    });
    retryWithoutTheTable(given.background.table_margin);
    f_.timings_.segment_ms = msSince(t);
    if (!f_.left_seg_.valid) return fail("left view: " + f_.left_seg_.reason, t0);
    if (!f_.right_seg_.valid) return fail("right view: " + f_.right_seg_.reason, t0);

    t = Clock::now();
    foundational();
    f_.timings_.foundational_ms = msSince(t);
    if (f_.vertices_.size() < 8)
      return fail("only " + std::to_string(f_.vertices_.size()) +
                      " foundational correspondences (the contours' epipolar lines found no consistent crossings)",
                  t0);
    if (given.auto_scale) {
      std::vector<double> d;
      d.reserve(f_.vertices_.size());
      for (const auto& v : f_.vertices_) d.push_back(v.disparity);
      const double s = viewScale(median(d), f_.geometry_.baseline());
      CectParams scaled = scaledParams(given, s);
      // What the segmentation and the contour's matching used stays.
      scaled.segmentation = f_.params_.segmentation;
      scaled.sample_spacing = f_.params_.sample_spacing;
      scaled.edge_window = f_.params_.edge_window;
      f_.params_ = scaled;
      f_.scale_ = s;
    }

    t = Clock::now();
    cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& views) {
      for (int v = views.start; v < views.end; ++v)
        (v == 0 ? f_.left_grey_ : f_.right_grey_) =
            matchingImage(v == 0 ? f_.left_rect_ : f_.right_rect_, v == 0 ? f_.left_seg_.mask : f_.right_seg_.mask);
    });
    f_.timings_.segment_ms += msSince(t);
    const cv::Mat k3 = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7));
    cv::erode(f_.left_seg_.mask, f_.left_inner_, k3);
    cv::erode(f_.right_seg_.mask, f_.right_inner_, k3);
    const int margin = f_.params_.seed_margin >= 0 ? cvRound(f_.params_.seed_margin) : f_.params_.ncc_radius + 2;
    f_.seed_margin_ = margin;
    cv::erode(f_.left_seg_.mask, f_.seed_region_,
              cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * margin + 1, 2 * margin + 1)));
    cv::distanceTransform(f_.left_seg_.mask, f_.border_distance_, cv::DIST_L2, 3);

    t = Clock::now();
    triangulate();
    if (f_.params_.seed_step > 0) {
      seeds(2 * f_.params_.seed_step, f_.params_.seed_search);
      triangulate();
      seeds(f_.params_.seed_step, std::max(2.0, 0.5 * f_.params_.seed_search),
            f_.params_.seed_column_step > 0 ? f_.params_.seed_column_step : f_.params_.seed_step);
      if (f_.params_.slanted_windows && f_.params_.smooth_radius > 0)
        slantSeeds(f_.params_.smooth_radius * f_.params_.seed_step);
      if (f_.params_.smooth_radius > 0) smoothSeeds(f_.params_.smooth_radius * f_.params_.seed_step);
      if (f_.params_.rim_profile) rimProfiles();
      triangulate(f_.params_.max_triangle_edge * f_.params_.seed_step);
    }
    f_.timings_.interior_ms = msSince(t);
    if (f_.triangles_.empty()) return fail("no triangles over the foundational correspondences", t0);
    f_.valid_ = true;
    f_.timings_.total_ms = msSince(t0);
  }

 private:
  /// A view whose segmentation failed (a sheet or towel of skin's colour
  /// joined to the back: "multi-coloured") is segmented again with the
  /// table's pixels (tablePixels) left out as well; kept when that works.
  /// Only then: the coarse depth is too rough at the body's foot to leave
  /// the table out everywhere.
  void retryWithoutTheTable(double margin) {
    DepthGate& g = f_.background_;
    for (int v = 0; v < 2; ++v) {
      Segmentation& seg = v == 0 ? f_.left_seg_ : f_.right_seg_;
      const cv::Mat& depth = v == 0 ? g.left_depth : g.right_depth;
      if (seg.valid || !(margin > 0.0) || depth.empty()) continue;
      const cv::Mat& far = v == 0 ? g.left_far : g.right_far;
      const cv::Mat table = tablePixels(depth, far, f_.geometry_, margin);
      if (table.empty()) continue;
      Segmentation retry = segmentBack(v == 0 ? f_.left_rect_ : f_.right_rect_, f_.params_.segmentation,
                                       far.empty() ? table : (far | table), depth);
      if (!retry.valid) continue;
      seg = std::move(retry);
      (v == 0 ? g.left_table : g.right_table) = table;
    }
  }

  void fail(const std::string& why, Clock::time_point t0) {
    f_.valid_ = false;
    f_.reason_ = why;
    f_.timings_.total_ms = msSince(t0);
  }

  /// Grey without the specular sheen, by the dichromatic reflection model:
  /// in linear RGB (sRGB decoded) every back pixel is I = D c + S (1,1,1),
  /// a diffuse part of the skin's own chromaticity c (the median over the
  /// back) plus a specular part of the light's colour (white). D and S are
  /// solved per pixel (least squares, 3 channels); S, noisy, is smoothed
  /// (Gaussian, sheen_sigma; with sheen_twicing 2 G*S - G*G*S, which keeps
  /// the highlights' peaks) and taken off every channel; the grey of the
  /// rest is returned, scaled back to 0..255. Outside the back: plain grey.
  cv::Mat diffuseGrey(const cv::Mat& bgr, const cv::Mat& mask) const {
    static const std::array<float, 256> lut = [] {
      std::array<float, 256> t{};
      for (int i = 0; i < 256; ++i) {
        const double v = i / 255.0;
        t[static_cast<std::size_t>(i)] =
            static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
      }
      return t;
    }();
    cv::Mat lin(bgr.size(), CV_32FC3);
    for (int y = 0; y < bgr.rows; ++y) {
      const cv::Vec3b* src = bgr.ptr<cv::Vec3b>(y);
      cv::Vec3f* dst = lin.ptr<cv::Vec3f>(y);
      for (int x = 0; x < bgr.cols; ++x) dst[x] = cv::Vec3f(lut[src[x][0]], lut[src[x][1]], lut[src[x][2]]);
    }
    // The skin's chromaticity: per-channel medians of the normalised colour
    // over the more saturated half of the back (the sheen whitens the rest).
    std::vector<cv::Vec3f> chroma;
    for (int y = 0; y < bgr.rows; y += 3) {
      const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
      const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < bgr.cols; x += 3) {
        const float sum = l[x][0] + l[x][1] + l[x][2];
        if (m[x] && sum > 1e-3f) chroma.push_back(l[x] / sum);
      }
    }
    cv::Mat S = cv::Mat::zeros(bgr.size(), CV_32F);
    if (chroma.size() >= 32) {
      auto whiteness = [](const cv::Vec3f& v) { return std::min({v[0], v[1], v[2]}); };
      auto half = chroma.begin() + static_cast<std::ptrdiff_t>(chroma.size() / 2);
      std::nth_element(chroma.begin(), half, chroma.end(),
                       [&](const cv::Vec3f& a, const cv::Vec3f& b) { return whiteness(a) < whiteness(b); });
      Eigen::Vector3d c;
      for (int k = 0; k < 3; ++k) {
        std::vector<float> v;
        v.reserve(chroma.size() / 2);
        for (auto it = chroma.begin(); it != half; ++it) v.push_back((*it)[k]);
        auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
        std::nth_element(v.begin(), mid, v.end());
        c(k) = *mid;
      }
      // Normal equations of min |I - D c - S 1|^2: [c.c c.1; c.1 3] [D S]' = [c.I 1.I]'.
      const double cc = c.squaredNorm(), c1 = c.sum();
      const double det = 3.0 * cc - c1 * c1;
      if (std::abs(det) > 1e-9) {
        const float a = static_cast<float>(-c1 / det), b = static_cast<float>(cc / det);
        const cv::Vec3f cf(static_cast<float>(c(0)), static_cast<float>(c(1)), static_cast<float>(c(2)));
        for (int y = 0; y < bgr.rows; ++y) {
          const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
          float* s = S.ptr<float>(y);
          for (int x = 0; x < bgr.cols; ++x) {
            const float ci = cf[0] * l[x][0] + cf[1] * l[x][1] + cf[2] * l[x][2];
            const float oi = l[x][0] + l[x][1] + l[x][2];
            s[x] = a * ci + b * oi;
          }
        }
        cv::Mat m;
        mask.convertTo(m, CV_32F, 1.0 / 255.0);
        const cv::Mat smooth = maskedBlur(S, m, f_.params_.sheen_sigma);
        S = f_.params_.sheen_twicing ? cv::Mat(2.0 * smooth - maskedBlur(smooth, m, f_.params_.sheen_sigma)) : smooth;
        S.setTo(0, mask == 0);
      }
    }
    cv::Mat out(bgr.size(), CV_32F);
    for (int y = 0; y < bgr.rows; ++y) {
      const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
      const float* s = S.ptr<float>(y);
      float* o = out.ptr<float>(y);
      for (int x = 0; x < bgr.cols; ++x)
        o[x] = 255.0f * (0.114f * l[x][0] + 0.587f * l[x][1] + 0.299f * l[x][2] - s[x]);
    }
    return out;
  }

  /// Matching image band-passed: a difference of Gaussians keeps
  /// the skin's mottling and the relief's edges and drops the broad shading
  /// and the specular sheen, which move with the viewpoint.
  cv::Mat matchingImage(const cv::Mat& bgr, const cv::Mat& mask) const {
    const CectParams& p = f_.params_;
    auto grey = [&](const cv::Mat& img, const cv::Mat& m) {
      if (p.sheen_sigma > 0) return diffuseGrey(img, m);
      cv::Mat g, f;
      cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
      g.convertTo(f, CV_32F);
      return f;
    };
    if (p.bandpass_high <= 0) return grey(bgr, mask);
    // Normalised convolution inside the back: the step to the background at
    // the contour would otherwise ring ~2 sigma into the skin, and that
    // step is the occluding rim, a different surface line in each view.
    // Only the back's bounding box (plus the matching windows' reach) is needed.
    const int margin = 2 * (std::max(p.ncc_radius, p.ncc_half_height) + 2);
    const cv::Rect roi = (cv::boundingRect(mask) + cv::Size(2 * margin, 2 * margin) - cv::Point(margin, margin)) &
                         cv::Rect(0, 0, bgr.cols, bgr.rows);
    cv::Mat out = cv::Mat::zeros(bgr.size(), CV_32F);
    if (roi.empty()) return out;
    const cv::Mat f = grey(bgr(roi), mask(roi));
    cv::Mat m;
    mask(roi).convertTo(m, CV_32F, 1.0 / 255.0);
    const cv::Mat lo = p.bandpass_low > 0 ? maskedBlur(f, m, p.bandpass_low) : f;
    cv::Mat band = lo - maskedBlur(f, m, p.bandpass_high);
    band.setTo(0, mask(roi) == 0);
    band.copyTo(out(roi));
    return out;
  }

  double minDisparity() const { return f_.disparity_range_[0]; }
  double maxDisparity() const { return f_.disparity_range_[1]; }

  /// Step 2: contour samples -> row crossings in the right view.
  void foundational() {
    const CectParams& p = f_.params_;
    const auto& contour = f_.left_seg_.contour;
    const int n = static_cast<int>(contour.size());
    const double min_sin = std::sin(p.min_crossing_angle * M_PI / 180.0);
    struct Sample {
      cv::Point2f left;
      std::vector<double> cands;  ///< candidate disparities
      int unique = -1;            ///< index into cands chosen by the order rule, -1 none
      cv::Point2f normal;         ///< the contour's inward unit normal
    };
    std::vector<Sample> samples;
    samples.reserve(static_cast<std::size_t>(n));
    std::vector<EdgeSample> edge;
    double last_y = -1e9;
    for (int i = 0; i < n; ++i) {
      const cv::Point2f& a = contour[static_cast<std::size_t>((i + n - 1) % n)];
      const cv::Point2f& b = contour[static_cast<std::size_t>((i + 1) % n)];
      const cv::Point2f tan = b - a;
      const double len = std::hypot(tan.x, tan.y);
      if (len < 1e-6) continue;
      if (std::abs(tan.y) / len < min_sin) {
        // Along the epipolar lines: left to edge registration (below).
        edge.push_back({contour[static_cast<std::size_t>(i)],
                        cv::Point2f(static_cast<float>(tan.y / len), static_cast<float>(-tan.x / len))});
        continue;
      }
      const cv::Point2f& c = contour[static_cast<std::size_t>(i)];
      (void)last_y;
      const double y = c.y;
      std::vector<bool> lr, rr;
      const std::vector<double> lx = rowCrossings(f_.left_seg_.score, y, &lr);
      const std::vector<double> rx = rowCrossings(f_.right_seg_.score, y, &rr);
      // The left crossing this sample stands for: the nearest one.
      int li = -1;
      double best = 3.0;
      for (std::size_t k = 0; k < lx.size(); ++k)
        if (std::abs(lx[k] - c.x) < best) {
          best = std::abs(lx[k] - c.x);
          li = static_cast<int>(k);
        }
      if (li < 0) continue;
      const bool rising = lr[static_cast<std::size_t>(li)];
      Sample s;
      s.left = cv::Point2f(static_cast<float>(lx[static_cast<std::size_t>(li)]), static_cast<float>(y));
      s.normal = cv::Point2f(static_cast<float>(tan.y / len), static_cast<float>(-tan.x / len));  // inward
      // Order among the crossings of the same kind on both rows.
      int rank = 0, left_same = 0, right_same = 0;
      for (std::size_t k = 0; k < lx.size(); ++k)
        if (lr[k] == rising) {
          if (static_cast<int>(k) < li) ++rank;
          ++left_same;
        }
      int r_rank = 0;
      for (std::size_t k = 0; k < rx.size(); ++k) {
        if (rr[k] != rising) continue;
        ++right_same;
        const double d = s.left.x - rx[k];
        if (d >= minDisparity() && d <= maxDisparity()) {
          if (r_rank == rank) s.unique = static_cast<int>(s.cands.size());
          s.cands.push_back(d);
        }
        ++r_rank;
      }
      if (left_same != right_same) s.unique = -1;
      if (s.cands.size() == 1 && left_same == right_same) s.unique = 0;
      if (!s.cands.empty()) samples.push_back(std::move(s));
    }
    // Resolve ambiguous samples by continuity along the contour with the
    // unambiguous ones (order in `samples` follows the contour).
    const int m = static_cast<int>(samples.size());
    // Up to 8 samples either side, each counted once on a short contour.
    const int reach = std::min(8, (m - 1) / 2);
    for (int i = 0; i < m; ++i) {
      Sample& s = samples[static_cast<std::size_t>(i)];
      std::vector<double> near;
      for (int k = -reach; k <= reach; ++k) {
        if (k == 0) continue;
        const Sample& o = samples[static_cast<std::size_t>(((i + k) % m + m) % m)];
        if (o.unique >= 0) near.push_back(o.cands[static_cast<std::size_t>(o.unique)]);
      }
      double d = std::numeric_limits<double>::quiet_NaN();
      if (near.size() >= 3) {
        const double ref = median(near);
        double bestd = std::numeric_limits<double>::infinity();
        for (double c : s.cands)
          if (std::abs(c - ref) < bestd) {
            bestd = std::abs(c - ref);
            d = c;
          }
        // A sample disagreeing with its neighbours is more likely a wrong
        // crossing (or a rim seen differently) than a real jump.
        if (bestd > 3.0 * f_.params_.continuity_margin) d = std::numeric_limits<double>::quiet_NaN();
      } else if (s.unique >= 0) {
        d = s.cands[static_cast<std::size_t>(s.unique)];
      }
      if (!std::isfinite(d)) continue;
      Correspondence c;
      c.left = s.left;
      c.disparity = static_cast<float>(d);
      c.sigma = static_cast<float>(p.pixel_sigma * std::sqrt(2.0));
      c.source = Correspondence::Source::kContour;
      f_.vertices_.push_back(c);
      rim_normals_.push_back(s.normal);
    }
    if (p.edge_window > 0 && !edge.empty()) registerEdges(edge);
  }

  struct EdgeSample {
    cv::Point2f left;    ///< contour sample
    cv::Point2f normal;  ///< inward unit normal
  };

  /// Row (sub-pixel) of the back's border in each column of a view, along
  /// an edge that runs across the columns: tracked column by column from
  /// (x0, y0) in direction `dir` (+-1) over `count` columns, each time the
  /// score's zero crossing nearest the last row (within 3 px; 6 px at the
  /// start) whose sign change matches the edge's side (`down_into_back`:
  /// the back lies below the edge). NaN where the edge turns too steep.
  static void trackEdge(const std::vector<std::vector<double>>& ys, const std::vector<std::vector<bool>>& rising,
                        int x0, double y0, int dir, int count, bool down_into_back, std::vector<double>* out,
                        int out_x0) {
    double last = y0;
    for (int k = 0; k < count; ++k) {
      const int x = x0 + dir * k;
      if (x < 0 || x >= static_cast<int>(ys.size())) break;
      const double reach = k == 0 ? 6.0 : 3.0;
      double best = std::numeric_limits<double>::quiet_NaN(), best_dist = reach;
      for (std::size_t j = 0; j < ys[static_cast<std::size_t>(x)].size(); ++j) {
        if (rising[static_cast<std::size_t>(x)][j] != down_into_back) continue;
        const double dist = std::abs(ys[static_cast<std::size_t>(x)][j] - last);
        if (dist <= best_dist) {
          best_dist = dist;
          best = ys[static_cast<std::size_t>(x)][j];
        }
      }
      if (!std::isfinite(best)) break;
      (*out)[static_cast<std::size_t>(x - out_x0)] = best;
      last = best;
    }
  }

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
  void registerEdges(const std::vector<EdgeSample>& edge) {
    const CectParams& p = f_.params_;
    const int W = static_cast<int>(std::lround(p.edge_window));
    // Zero crossings of every column, per view (the transposed score's rows).
    auto columns = [](const cv::Mat& score, std::vector<std::vector<double>>* ys,
                      std::vector<std::vector<bool>>* rising) {
      const cv::Mat t = score.t();
      ys->resize(static_cast<std::size_t>(t.rows));
      rising->resize(static_cast<std::size_t>(t.rows));
      for (int x = 0; x < t.rows; ++x)
        (*ys)[static_cast<std::size_t>(x)] = rowCrossings(t, x, &(*rising)[static_cast<std::size_t>(x)]);
    };
    std::vector<std::vector<double>> lys, rys;
    std::vector<std::vector<bool>> lrise, rrise;
    columns(f_.left_seg_.score, &lys, &lrise);
    columns(f_.right_seg_.score, &rys, &rrise);
    const std::size_t n_crossing = f_.vertices_.size();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double sw2 = 2.0 * (0.5 * W) * (0.5 * W);
    for (std::size_t e = 0; e < edge.size(); e += 2) {  // every other sample, as the rim profile
      const EdgeSample& es = edge[e];
      const bool down = es.normal.y > 0.0f;
      const int xi = cvRound(es.left.x);
      // Disparity range from the row-crossing correspondences nearby.
      double d_lo = std::numeric_limits<double>::infinity(), d_hi = -d_lo;
      for (std::size_t v = 0; v < n_crossing; ++v) {
        const cv::Point2f q = f_.vertices_[v].left - es.left;
        if (q.x * q.x + q.y * q.y > 9.0 * W * W) continue;
        d_lo = std::min(d_lo, static_cast<double>(f_.vertices_[v].disparity));
        d_hi = std::max(d_hi, static_cast<double>(f_.vertices_[v].disparity));
      }
      if (!std::isfinite(d_lo)) continue;  // no prior nearby: too risky on a flat edge
      d_lo = std::max(minDisparity(), d_lo - 4.0);
      d_hi = std::min(maxDisparity(), d_hi + 4.0);
      // The left curve over [xi - W, xi + W], the right one over the
      // columns those can shift to.
      std::vector<double> yl(static_cast<std::size_t>(2 * W + 1), nan);
      trackEdge(lys, lrise, xi, es.left.y, +1, W + 1, down, &yl, xi - W);
      trackEdge(lys, lrise, xi, es.left.y, -1, W + 1, down, &yl, xi - W);
      // Only the parts of the edge that run along the rows: where it turns
      // steeper it becomes a flank's rim, a different line in each view.
      const double max_slope = std::tan(p.min_crossing_angle * M_PI / 180.0);
      {
        std::vector<double> along(yl.size(), nan);
        for (std::size_t k = 1; k + 1 < yl.size(); ++k)
          if (std::abs(0.5 * (yl[k + 1] - yl[k - 1])) <= max_slope) along[k] = yl[k];  // NaN compares false
        yl.swap(along);
      }
      const int rx0 = static_cast<int>(std::floor(xi - W - d_hi)) - 1;
      const int rx1 = static_cast<int>(std::ceil(xi + W - d_lo)) + 1;
      std::vector<double> yr(static_cast<std::size_t>(rx1 - rx0 + 1), nan);
      const int rstart = cvRound(xi - 0.5 * (d_lo + d_hi));
      trackEdge(rys, rrise, rstart, es.left.y, +1, rx1 - rstart + 1, down, &yr, rx0);
      trackEdge(rys, rrise, rstart, es.left.y, -1, rstart - rx0 + 1, down, &yr, rx0);
      auto rightAt = [&](double x) {
        const double u = x - rx0;
        const int k = static_cast<int>(std::floor(u));
        if (k < 0 || k + 1 >= static_cast<int>(yr.size())) return nan;
        const double f = u - k;
        return (1.0 - f) * yr[static_cast<std::size_t>(k)] + f * yr[static_cast<std::size_t>(k + 1)];
      };
      double w_all = 0.0;
      for (int k = -W; k <= W; ++k) w_all += std::exp(-k * k / sw2);
      auto cost = [&](double d) {
        double c = 0.0, ws = 0.0;
        for (int k = -W; k <= W; ++k) {
          const double a = yl[static_cast<std::size_t>(k + W)];
          if (!std::isfinite(a)) continue;
          const double b = rightAt(xi + k - d);
          if (!std::isfinite(b)) continue;
          const double w = std::exp(-k * k / sw2);
          c += w * (a - b) * (a - b);
          ws += w;
        }
        return ws >= 0.6 * w_all ? c / ws : nan;
      };
      const double step = 0.25;
      std::vector<double> ds, cs;
      for (double d = d_lo; d <= d_hi + 1e-9; d += step) {
        ds.push_back(d);
        cs.push_back(cost(d));
      }
      int best = -1;
      for (std::size_t k = 0; k < cs.size(); ++k)
        if (std::isfinite(cs[k]) && (best < 0 || cs[k] < cs[static_cast<std::size_t>(best)]))
          best = static_cast<int>(k);
      if (best <= 0 || best + 1 >= static_cast<int>(cs.size())) continue;
      const double a = cs[static_cast<std::size_t>(best - 1)], b = cs[static_cast<std::size_t>(best)],
                   c = cs[static_cast<std::size_t>(best + 1)];
      if (!std::isfinite(a) || !std::isfinite(c)) continue;
      const double denom = a - 2.0 * b + c;
      const double d =
          ds[static_cast<std::size_t>(best)] + (denom > 0 ? std::clamp(0.5 * (a - c) / denom, -0.5, 0.5) * step : 0.0);
      const double c0 = cost(d), cm = cost(d - 2.0), cp = cost(d + 2.0);
      if (!std::isfinite(c0) || !std::isfinite(cm) || !std::isfinite(cp)) continue;
      const double bend = std::min(cm, cp) - c0;
      if (c0 > 1.0 || bend < p.edge_min_bend) continue;
      // Unique: every shift more than 2 px away is clearly worse.
      bool unique = true;
      for (std::size_t k = 0; k < cs.size() && unique; ++k)
        if (std::abs(ds[k] - d) > 2.0 && std::isfinite(cs[k]) && cs[k] < c0 + 0.5 * bend) unique = false;
      if (!unique) continue;
      const double y = yl[static_cast<std::size_t>(W)];
      if (!std::isfinite(y)) continue;
      Correspondence v;
      v.left = cv::Point2f(static_cast<float>(xi), static_cast<float>(y));
      v.disparity = static_cast<float>(d);
      // Weaker bends fix the shift less well.
      v.sigma = static_cast<float>(p.pixel_sigma * std::sqrt(2.0) * std::max(1.0, 1.0 / std::sqrt(bend)));
      v.source = Correspondence::Source::kEdge;
      f_.vertices_.push_back(v);
      rim_normals_.push_back(es.normal);
    }
  }

  /// Delaunay triangulation of the vertices, the triangle index map and the
  /// triangles around each vertex.
  void triangulate(double max_edge = 0.0) {
    auto& V = f_.vertices_;
    f_.triangles_.clear();
    const cv::Rect rect(-1, -1, f_.left_rect_.cols + 2, f_.left_rect_.rows + 2);
    cv::Subdiv2D subdiv(rect);
    // getTriangleList returns the inserted coordinates exactly: look the
    // vertices up by them (the first of coincident vertices wins).
    std::unordered_map<std::uint64_t, int> vertex_at;
    auto key = [](float x, float y) {
      std::uint32_t bx, by;
      std::memcpy(&bx, &x, sizeof bx);
      std::memcpy(&by, &y, sizeof by);
      return (static_cast<std::uint64_t>(bx) << 32) | by;
    };
    for (std::size_t i = 0; i < V.size(); ++i) {
      subdiv.insert(V[i].left);
      vertex_at.emplace(key(V[i].left.x, V[i].left.y), static_cast<int>(i));
    }
    std::vector<cv::Vec6f> tris;
    subdiv.getTriangleList(tris);
    auto indexOf = [&](float x, float y) -> int {
      const auto it = vertex_at.find(key(x, y));
      return it == vertex_at.end() ? -1 : it->second;
    };
    const cv::Mat& mask = f_.left_seg_.mask;
    // Edge midpoints of border triangles sit on the border itself: they may
    // fall up to 1.5 px outside the mask.
    if (near_mask_.empty()) cv::dilate(mask, near_mask_, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    for (const auto& t : tris) {
      const int a = indexOf(t[0], t[1]), b = indexOf(t[2], t[3]), c = indexOf(t[4], t[5]);
      if (a < 0 || b < 0 || c < 0) continue;
      // Only triangles inside the back: the centroid and the edge midpoints
      // must lie on the mask (the contour is concave at the neck and waist).
      const cv::Point2f pa = V[static_cast<std::size_t>(a)].left, pb = V[static_cast<std::size_t>(b)].left,
                        pc = V[static_cast<std::size_t>(c)].left;
      bool inside = true;
      for (const cv::Point2f& q : {(pa + pb + pc) / 3.0f, (pa + pb) * 0.5f, (pb + pc) * 0.5f, (pa + pc) * 0.5f}) {
        const int x = cvRound(q.x), y = cvRound(q.y);
        if (!(x >= 0 && y >= 0 && x < mask.cols && y < mask.rows && near_mask_.at<std::uint8_t>(y, x))) {
          inside = false;
          break;
        }
      }
      const double area = std::abs((pb.x - pa.x) * (pc.y - pa.y) - (pc.x - pa.x) * (pb.y - pa.y)) * 0.5;
      // Long edges bridge a gap in the correspondences (an unmatched edge
      // along the rows, a patch without seeds): a plane over it is a poor
      // guess; such pixels are better extrapolated from the seeds.
      if (max_edge > 0.0 && std::max({cv::norm(pa - pb), cv::norm(pb - pc), cv::norm(pa - pc)}) > max_edge)
        inside = false;
      if (inside && area > 0.5) f_.triangles_.emplace_back(a, b, c);
    }
    f_.vertex_triangles_.assign(V.size(), {});
    f_.triangle_index_.create(f_.left_rect_.size(), CV_32S);
    f_.triangle_index_.setTo(-1);
    for (std::size_t k = 0; k < f_.triangles_.size(); ++k) {
      const cv::Vec3i& t = f_.triangles_[k];
      for (int j = 0; j < 3; ++j) f_.vertex_triangles_[static_cast<std::size_t>(t[j])].push_back(static_cast<int>(k));
      // Rasterise with a small margin so that points on shared edges find a triangle.
      const cv::Point pts[3] = {cv::Point(cvRound(V[t[0]].left.x * 16), cvRound(V[t[0]].left.y * 16)),
                                cv::Point(cvRound(V[t[1]].left.x * 16), cvRound(V[t[1]].left.y * 16)),
                                cv::Point(cvRound(V[t[2]].left.x * 16), cvRound(V[t[2]].left.y * 16))};
      cv::fillConvexPoly(f_.triangle_index_, pts, 3, cv::Scalar(static_cast<int>(k)), cv::LINE_8, 4);
    }
  }

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
  void rimProfiles() {
    auto& V = f_.vertices_;
    const double step = f_.params_.seed_step;
    const double band = 0.75 * step, reach = 5.0 * step;
    const double rim_weight = 2.0;  // the rim's own crossing counts as two seeds
    std::vector<int> seeds;
    for (std::size_t i = 0; i < V.size(); ++i)
      if (V[i].source == Correspondence::Source::kSeed) seeds.push_back(static_cast<int>(i));
    const cv::Mat& mask = f_.left_seg_.mask;
    std::vector<Correspondence> added;
    std::vector<int> drop;
    const std::size_t n_rim = std::min(rim_normals_.size(), V.size());
    for (std::size_t i = 0; i < n_rim; i += 2) {
      const Correspondence& rim = V[i];
      if (!rim.foundational()) continue;
      const cv::Point2f n = rim_normals_[i];
      const cv::Point2f t(-n.y, n.x);
      std::vector<RimObservation> obs;
      for (int j : seeds) {
        const cv::Point2f q = V[static_cast<std::size_t>(j)].left - rim.left;
        const double u = q.dot(n), tt = q.dot(t);
        if (u <= 0.0 || u > reach || std::abs(tt) > band) continue;
        obs.push_back({u, tt, V[static_cast<std::size_t>(j)].disparity, j});
      }
      Eigen::Vector4d k;
      std::vector<int> outliers;
      if (!fitRimProfile(rim.disparity, rim_weight, step, 2.0 * f_.params_.pixel_sigma, &obs, &k, &outliers)) continue;
      double u_min = reach;
      for (const RimObservation& o : obs) u_min = std::min(u_min, o.u);
      if (u_min > 3.0 * step) continue;
      drop.insert(drop.end(), outliers.begin(), outliers.end());
      // The profile interpolates between the rim and the seeds: a value
      // outside their range (beyond the continuity margin) is an
      // extrapolation of a fit the seeds do not hold, e.g. next to the
      // image's edge, where the back is cut and the seeds lie to one side.
      double lo = rim.disparity, hi = rim.disparity;
      for (const RimObservation& o : obs) {
        lo = std::min(lo, o.d);
        hi = std::max(hi, o.d);
      }
      lo -= f_.params_.continuity_margin;
      hi += f_.params_.continuity_margin;
      for (double u : {2.0, 5.0, 9.0, 14.0, 20.0, 27.0, 35.0, 44.0}) {
        if (u > u_min - 0.5 * step) break;
        const double d = rimProfileAt(k, u, 0.0, step);
        if (d < lo || d > hi) break;
        const cv::Point2f q = rim.left + static_cast<float>(u) * n;
        const int x = cvRound(q.x), y = cvRound(q.y);
        if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows || !mask.at<std::uint8_t>(y, x)) break;
        Correspondence c;
        c.left = q;
        c.disparity = static_cast<float>(d);
        c.sigma = static_cast<float>(f_.params_.pixel_sigma);
        c.source = Correspondence::Source::kRimProfile;
        added.push_back(c);
      }
    }
    std::sort(drop.begin(), drop.end());
    drop.erase(std::unique(drop.begin(), drop.end()), drop.end());
    for (auto it = drop.rbegin(); it != drop.rend(); ++it) V.erase(V.begin() + *it);
    f_.seed_stats_.rim_outliers += static_cast<int>(drop.size());
    V.insert(V.end(), added.begin(), added.end());
  }

  /// True when a border running along the rows lies within `reach` pixels
  /// above or below (x, y) while the back continues `reach` pixels to
  /// either side along the row (the shoulders' top, the neck base).
  bool nearRowBorder(int x, int y, int reach) const {
    const cv::Mat& mask = f_.left_seg_.mask;
    auto on = [&](int xx, int yy) {
      return xx >= 0 && yy >= 0 && xx < mask.cols && yy < mask.rows && mask.at<std::uint8_t>(yy, xx) != 0;
    };
    return (!on(x, y - reach) || !on(x, y + reach)) && on(x - reach, y) && on(x + reach, y);
  }

  /// Each interior seed on a slanted part of the back (or within 2 seed
  /// steps of a border along the rows) is matched again with a slanted
  /// window: the disparity plane of the seeds' local quadratic around it
  /// (its gradient at the seed), searched +-2 px around the seed's first
  /// match. Kept when the peak is found, strong enough (min_ncc) and
  /// within continuity_margin of the first match; otherwise the first match
  /// stays.
  void slantSeeds(double radius) {
    auto& V = f_.vertices_;
    const CectParams& p = f_.params_;
    const int r = p.ncc_radius;
    const int ry = p.ncc_half_height > 0 ? p.ncc_half_height : r;
    std::vector<int> idx;
    for (std::size_t i = 0; i < V.size(); ++i)
      if (V[i].source == Correspondence::Source::kSeed) idx.push_back(static_cast<int>(i));
    std::vector<float> refined(V.size(), std::numeric_limits<float>::quiet_NaN());
    cv::parallel_for_(cv::Range(0, static_cast<int>(idx.size())), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) {
        const std::size_t i = static_cast<std::size_t>(idx[static_cast<std::size_t>(k)]);
        double fit = 0.0;
        cv::Point2d g;
        if (!fitQuadratic(V, idx, V[i].left, radius, 8, &fit, nullptr, nullptr, &g)) continue;
        // Nearly fronto-parallel: the first match stands (a re-match there
        // only trades one noisy peak for another, with the right window
        // interpolated). But next to a border along the rows (the
        // shoulders' top) the skin rolls over toward the head, and the
        // quadratic, fitted from one side only, underestimates that slope:
        // those seeds are re-matched in any case.
        const bool ledge = nearRowBorder(cvRound(V[i].left.x), cvRound(V[i].left.y), 2 * p.seed_step);
        if (!ledge && std::abs(g.x) * r + std::abs(g.y) * ry < p.min_slant) continue;
        const MatchResult m = slantedMatch(f_.left_grey_, f_.right_grey_, cvRound(V[i].left.x), cvRound(V[i].left.y),
                                           std::round(V[i].disparity), g, 2, r, ry);
        if (m.ok && m.ncc >= p.min_ncc && std::abs(m.disparity - V[i].disparity) <= p.continuity_margin)
          refined[i] = static_cast<float>(m.disparity);
      }
    });
    for (int i : idx) {
      const float d = refined[static_cast<std::size_t>(i)];
      if (std::isfinite(d)) V[static_cast<std::size_t>(i)].disparity = d;
    }
  }

  /// Each interior seed's disparity becomes the value at the seed of a
  /// weighted quadratic (with quartic_across: quartic across the body)
  /// fitted to the seeds within `radius` pixels (Gaussian weights, sigma =
  /// radius / 2; one refit without the residuals beyond 3 MAD): single
  /// matches on skin are noisy (~0.6 px), the back is smooth.
  /// A seed farther than continuity_margin from its fit is dropped
  /// (constraint 2).
  void smoothSeeds(double radius) {
    auto& V = f_.vertices_;
    std::vector<int> idx;
    for (std::size_t i = 0; i < V.size(); ++i)
      if (V[i].source == Correspondence::Source::kSeed) idx.push_back(static_cast<int>(i));
    std::vector<float> smoothed(V.size(), std::numeric_limits<float>::quiet_NaN());
    const bool quartic = f_.params_.quartic_across;
    cv::parallel_for_(cv::Range(0, static_cast<int>(idx.size())), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) {
        const std::size_t i = static_cast<std::size_t>(idx[static_cast<std::size_t>(k)]);
        double fit = 0.0;
        // Too few neighbours to fit: the seed stays as matched.
        if (fitQuadratic(V, idx, V[i].left, radius, 8, &fit, nullptr, nullptr, nullptr, quartic))
          smoothed[i] = static_cast<float>(fit);
      }
    });
    std::vector<Correspondence> kept;
    kept.reserve(V.size());
    for (std::size_t i = 0; i < V.size(); ++i) {
      Correspondence v = V[i];
      if (v.source == Correspondence::Source::kSeed && std::isfinite(smoothed[i])) {
        if (std::abs(v.disparity - smoothed[i]) > f_.params_.continuity_margin) {
          ++f_.seed_stats_.smoothing;
          continue;
        }
        v.disparity = smoothed[i];
      }
      kept.push_back(v);
    }
    V.swap(kept);
  }

  /// Interior seeds on a grid of `step` pixels (rows; columns every
  /// `column_step`, 0: `step`), matched within `search` of their barycentric
  /// prediction, kept when they pass the constraints.
  void seeds(int step, double search, int column_step = 0) {
    const int cstep = column_step > 0 ? column_step : step;
    const CectParams& p = f_.params_;
    const int r = p.ncc_radius;
    const int ry = p.ncc_half_height > 0 ? p.ncc_half_height : r;
    const cv::Mat& inner = f_.seed_region_;
    struct Seed {
      cv::Point2f left;
      double d;
      int gx, gy;
    };
    std::vector<Seed> found;
    const bool contour_only = f_.foundationalCount() == f_.vertices_.size();
    const double fxb = f_.geometry_.fx() * f_.geometry_.baseline();
    const int w = f_.left_rect_.cols, h = f_.left_rect_.rows;
    // Skip grid points already close to a vertex.
    cv::Mat taken = cv::Mat::zeros(h, w, CV_8U);
    for (const auto& v : f_.vertices_)
      cv::circle(taken, cv::Point(cvRound(v.left.x), cvRound(v.left.y)), std::max(2, step / 3), cv::Scalar(255), -1);
    struct Job {
      cv::Point2f q;
      double lo, hi;
      int gx, gy;
      enum { kNoPeak, kWeak, kLeftRight, kFound } outcome = kNoPeak;
      double d = 0.0;
    };
    std::vector<Job> jobs;
    for (int y = step / 2; y < h; y += step)
      for (int x = (step / 2) % cstep; x < w; x += cstep) {
        if (!inner.at<std::uint8_t>(y, x) || taken.at<std::uint8_t>(y, x)) continue;
        const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
        double spread = 0;
        int count = 0;
        const double d0 = f_.transfer(q, &spread, &count);
        if (!std::isfinite(d0)) continue;
        const double reach = search + 0.5 * spread;
        // The back rises above its contour (it rests on the table there), so
        // while the triangulation holds only the contour the search reaches
        // up to max_relief metres nearer than the prediction.
        double hi = d0 + reach;
        if (contour_only) {
          const double z0 = fxb / std::max(d0, 1e-3);
          hi = z0 > p.max_relief ? fxb / (z0 - p.max_relief) + reach : maxDisparity();
        }
        jobs.push_back({q, std::max(minDisparity(), d0 - reach), std::min(maxDisparity(), hi), x / cstep, y / step});
      }
    // Matching, the bulk of the work, on every core (each seed on its own).
    cv::parallel_for_(cv::Range(0, static_cast<int>(jobs.size())), [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i) {
        Job& j = jobs[static_cast<std::size_t>(i)];
        const MatchResult m = matchAlongRow(f_.left_grey_, f_.right_grey_, j.q.x, j.q.y, j.lo, j.hi, r, ry, false);
        if (!m.ok) continue;  // kNoPeak
        if (m.ncc < p.min_ncc) {
          j.outcome = Job::kWeak;
          continue;
        }
        // Constraint 3: back from the right view, from the whole pixel
        // nearest the match (its own disparity to the seed is q.x - xr).
        const float xr = std::round(static_cast<float>(j.q.x - m.disparity));
        const double d_back = j.q.x - xr;
        const MatchResult back = matchAlongRow(f_.right_grey_, f_.left_grey_, xr, j.q.y, d_back - 2.0 - p.lr_tolerance,
                                               d_back + 2.0 + p.lr_tolerance, r, ry, true);
        if (!back.ok || std::abs(back.disparity - d_back) > p.lr_tolerance) {
          j.outcome = Job::kLeftRight;
          continue;
        }
        j.outcome = Job::kFound;
        j.d = m.disparity;
      }
    });
    for (const Job& j : jobs) {
      ++f_.seed_stats_.tried;
      switch (j.outcome) {
        case Job::kNoPeak:
          ++f_.seed_stats_.no_peak;
          break;
        case Job::kWeak:
          ++f_.seed_stats_.weak;
          break;
        case Job::kLeftRight:
          ++f_.seed_stats_.left_right;
          break;
        case Job::kFound:
          found.push_back({j.q, j.d, j.gx, j.gy});
          break;
      }
    }
    // Constraint 2: continuity with the grid neighbours.
    std::map<std::pair<int, int>, double> grid;
    for (const auto& s : found) grid[{s.gx, s.gy}] = s.d;
    for (const auto& s : found) {
      std::vector<double> nb;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy) continue;
          const auto it = grid.find({s.gx + dx, s.gy + dy});
          if (it != grid.end()) nb.push_back(it->second);
        }
      if ((nb.size() >= 2 && std::abs(s.d - median(nb)) > p.continuity_margin) ||
          (nb.size() < 2 && step > p.seed_step)) {  // isolated coarse seeds are not trusted
        ++f_.seed_stats_.continuity;
        continue;
      }
      ++f_.seed_stats_.accepted;
      Correspondence c;
      c.left = s.left;
      c.disparity = static_cast<float>(s.d);
      c.sigma = static_cast<float>(p.pixel_sigma);
      c.source = Correspondence::Source::kSeed;
      f_.vertices_.push_back(c);
    }
  }

  CectFrame& f_;
  std::vector<cv::Point2f> rim_normals_;  ///< inward contour normal of each foundational vertex (same index)
  cv::Mat near_mask_;                     ///< the left mask dilated by 2 px
};

CectFrame CectFrame::analyse(const cv::Mat& left, const cv::Mat& right, const camera::StereoModel& geometry,
                             const CectParams& params) {
  if (geometry.empty()) throw std::invalid_argument("CECT: no stereo geometry (calibration) given");
  if (left.empty() || right.empty()) throw std::invalid_argument("CECT: empty image");
  if (left.type() != CV_8UC3 || right.type() != CV_8UC3)
    throw std::invalid_argument("CECT: images must be 8-bit BGR (CV_8UC3)");
  if (params.ncc_radius < 1) throw std::invalid_argument("CECT: ncc_radius must be >= 1");
  if (params.seed_step < 0) throw std::invalid_argument("CECT: seed_step must be >= 0");
  if (params.seed_column_step < 0) throw std::invalid_argument("CECT: seed_column_step must be >= 0");
  if (!(params.sample_spacing > 0)) throw std::invalid_argument("CECT: sample_spacing must be > 0");
  if (!(params.min_depth > 0) || !(params.max_depth > params.min_depth) || !std::isfinite(params.max_depth))
    throw std::invalid_argument("CECT: the depth range must satisfy 0 < min_depth < max_depth (finite), got " +
                                std::to_string(params.min_depth) + ".." + std::to_string(params.max_depth) + " m");
  if (!(params.min_disparity >= 0) || !(params.max_disparity >= 0) ||
      (params.max_disparity > 0 && params.max_disparity <= params.min_disparity))
    throw std::invalid_argument("CECT: min_disparity / max_disparity must be >= 0 and max > min unless 0");
  CectFrame f;
  f.geometry_ = geometry;
  f.params_ = params;
  f.params_.segmentation.contour_spacing = params.sample_spacing;
  CectFrameBuilder(f).run(left, right);
  return f;
}

std::size_t CectFrame::foundationalCount() const {
  return static_cast<std::size_t>(
      std::count_if(vertices_.begin(), vertices_.end(), [](const Correspondence& c) { return c.foundational(); }));
}

double CectFrame::transfer(const cv::Point2f& q, double* spread, int* count, cv::Point2d* gradient) const {
  *spread = 0.0;
  *count = 0;
  if (gradient) *gradient = cv::Point2d(0.0, 0.0);
  const int x = cvRound(q.x), y = cvRound(q.y);
  if (x < 0 || y < 0 || x >= triangle_index_.cols || y >= triangle_index_.rows)
    return std::numeric_limits<double>::quiet_NaN();
  const int t = triangle_index_.at<int>(y, x);
  if (t < 0) return std::numeric_limits<double>::quiet_NaN();
  // The containing triangle and every triangle sharing an edge with it.
  std::vector<int> tris{t};
  const cv::Vec3i& T = triangles_[static_cast<std::size_t>(t)];
  for (int j = 0; j < 3; ++j)
    for (int o : vertex_triangles_[static_cast<std::size_t>(T[j])]) {
      if (o == t || std::find(tris.begin(), tris.end(), o) != tris.end()) continue;
      const cv::Vec3i& O = triangles_[static_cast<std::size_t>(o)];
      int shared = 0;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shared += T[a] == O[b];
      if (shared == 2) tris.push_back(o);
    }
  double own = std::numeric_limits<double>::quiet_NaN();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::vector<double> cands;
  for (int k : tris) {
    const cv::Vec3i& K = triangles_[static_cast<std::size_t>(k)];
    const Correspondence &a = vertices_[static_cast<std::size_t>(K[0])], &b = vertices_[static_cast<std::size_t>(K[1])],
                         &c = vertices_[static_cast<std::size_t>(K[2])];
    double l0, l1, l2;
    if (!barycentric(q, a.left, b.left, c.left, &l0, &l1, &l2)) continue;
    // The right point is the same barycentric combination of the right
    // vertices; on a common row its x gives the disparity directly.
    const double d = l0 * a.disparity + l1 * b.disparity + l2 * c.disparity;
    if (k == t) {
      own = d;
      if (gradient) {
        // The plane through the three vertices: [ab ac]^T g = [d_b - d_a, d_c - d_a].
        const double ux = b.left.x - a.left.x, uy = b.left.y - a.left.y;
        const double vx = c.left.x - a.left.x, vy = c.left.y - a.left.y;
        const double det = ux * vy - uy * vx;
        const double du = b.disparity - a.disparity, dv = c.disparity - a.disparity;
        if (std::abs(det) > 1e-9) *gradient = cv::Point2d((du * vy - dv * uy) / det, (dv * ux - du * vx) / det);
      }
    }
    cands.push_back(d);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  if (cands.empty()) return std::numeric_limits<double>::quiet_NaN();
  *spread = hi - lo;
  *count = static_cast<int>(cands.size());
  // The containing triangle interpolates; its neighbours extrapolate: the
  // median of all keeps one bad neighbour from dragging the estimate.
  return cands.size() >= 3 ? median(cands) : (std::isfinite(own) ? own : cands.front());
}

LocalizedPoint CectFrame::localize(const cv::Point2f& left_raw_pixel) const {
  LocalizedPoint out;
  out.pixel = left_raw_pixel;
  if (!valid_) {
    out.reason = "no valid frame: " + reason_;
    return out;
  }
  if (!(left_raw_pixel.x >= 0 && left_raw_pixel.y >= 0 && left_raw_pixel.x <= geometry_.size().width - 1 &&
        left_raw_pixel.y <= geometry_.size().height - 1)) {
    out.reason = "pixel outside the image";
    return out;
  }
  out = localizeRectified(geometry_.toRectified(left_raw_pixel));
  out.pixel = left_raw_pixel;
  return out;
}

LocalizedPoint CectFrame::localizeRectified(const cv::Point2f& q) const {
  LocalizedPoint out;
  out.rectified = q;
  out.pixel = valid_ ? geometry_.toRaw(q) : q;
  if (!valid_) {
    out.reason = "no valid frame: " + reason_;
    return out;
  }
  const int x = cvRound(q.x), y = cvRound(q.y);
  if (!(q.x >= 0 && q.y >= 0) || x >= left_seg_.mask.cols || y >= left_seg_.mask.rows) {
    out.reason = "pixel outside the image";
    return out;
  }
  if (!left_seg_.mask.at<std::uint8_t>(y, x)) {
    out.reason = "pixel is not on the back";
    return out;
  }
  double spread = 0;
  int count = 0;
  cv::Point2d gradient;
  const double d0 = transfer(q, &spread, &count, &gradient);
  if (!std::isfinite(d0)) return extrapolate(q, out);
  out.spread = spread;
  out.candidates = count;
  // Constraint 1.
  if (spread > params_.max_candidate_spread) {
    out.reason = "candidate triangles disagree by " + std::to_string(spread) + " px";
    return out;
  }
  double d = d0;
  double sigma = std::hypot(matchingSigma(), 0.25 * spread);
  if (params_.direct_min_sharpness > 0 && inRowBorderBand(x, y)) {
    // Next to a border running along the rows (the shoulders' top, the neck
    // base, the waist) the transfer leans on the first seeds, whose windows
    // reach across the band's steep relief (the shoulders' top is a ledge
    // behind the back): the transfer there is ~0.6 px too near. The pixel's
    // own window, wide along the border and short across it, is unbiased but
    // noisy (~0.7 px); their mean halves both.
    double dm = 0.0;
    const int r = params_.ncc_radius;
    if (directMatch(q, d0, cvRound(1.4 * r), std::max(2, r / 2), &dm)) d = 0.5 * (d0 + dm);
  }
  if (params_.query_search > 0) {
    const int ry = params_.ncc_half_height > 0 ? params_.ncc_half_height : params_.ncc_radius;
    const double reach = std::min(params_.query_search, params_.continuity_margin);  // constraint 2
    const MatchResult m = matchAlongRow(left_grey_, right_grey_, q.x, q.y, d0 - reach - 1.0, d0 + reach + 1.0,
                                        params_.ncc_radius, ry, false);
    if (m.ok && m.ncc >= params_.min_ncc && std::abs(m.disparity - d0) <= reach) {
      const MatchResult back = matchAlongRow(right_grey_, left_grey_, static_cast<float>(q.x - m.disparity), q.y,
                                             m.disparity - 2.0 - params_.lr_tolerance,
                                             m.disparity + 2.0 + params_.lr_tolerance, params_.ncc_radius, ry, true);
      if (back.ok && std::abs(back.disparity - m.disparity) <= params_.lr_tolerance) {  // constraint 3
        d = m.disparity;
        sigma = matchingSigma();
      }
    }
  }
  // A query_search match keeps the border's part: single windows on skin are
  // noisier than pixel_sigma (cect_eval --param query_search=2: 78 % of the
  // acupoints' errors within 2 sigma with it, 75 % without).
  return triangulated(q, d, structuralSigma(q, sigma, gradient), std::move(out));
}

double CectFrame::structuralSigma(const cv::Point2f& q, double sigma, const cv::Point2d& gradient,
                                  bool interpolated) const {
  double var = sigma * sigma;
  const int x = cvRound(q.x), y = cvRound(q.y);
  const double reach = params_.border_sigma_reach * std::max(1, params_.seed_step);
  if (interpolated && params_.border_sigma > 0 && reach > 0 && !border_distance_.empty() && x >= 0 && y >= 0 &&
      x < border_distance_.cols && y < border_distance_.rows) {
    const double ramp = std::max(0.0, 1.0 - border_distance_.at<float>(y, x) / reach);
    var += std::pow(params_.border_sigma * ramp, 2);
  }
  if (params_.slope_sigma > 0) var += std::pow(params_.slope_sigma * std::hypot(gradient.x, gradient.y), 2);
  return std::sqrt(var);
}

bool CectFrame::directMatch(const cv::Point2f& q, double d, int rx, int ry, double* disparity) const {
  const double reach = params_.continuity_margin;
  double sharp = 0.0, sharp_back = 0.0;
  const MatchResult m = maskedMatchAlongRow(left_grey_, right_grey_, left_inner_, right_inner_, q.x, q.y,
                                            d - reach - 1.0, d + reach + 1.0, rx, ry, false, &sharp);
  if (!m.ok || m.ncc < params_.min_ncc || sharp < params_.direct_min_sharpness || std::abs(m.disparity - d) > reach)
    return false;
  const float xr = static_cast<float>(cvRound(q.x) - std::round(m.disparity));
  const double d_back = cvRound(q.x) - xr;
  const MatchResult back = maskedMatchAlongRow(right_grey_, left_grey_, right_inner_, left_inner_, xr, q.y,
                                               d_back - 2.0 - params_.lr_tolerance, d_back + 2.0 + params_.lr_tolerance,
                                               rx, ry, true, &sharp_back);
  if (!back.ok || std::abs(back.disparity - d_back) > params_.lr_tolerance) return false;  // constraint 3
  *disparity = m.disparity;
  return true;
}

bool CectFrame::inRowBorderBand(int x, int y) const {
  if (seed_region_.at<std::uint8_t>(y, x)) return false;
  const cv::Mat& mask = left_seg_.mask;
  auto on = [&](int xx, int yy) {
    return xx >= 0 && yy >= 0 && xx < mask.cols && yy < mask.rows && mask.at<std::uint8_t>(yy, xx) != 0;
  };
  const int m = seed_margin_;
  return (!on(x, y - m) || !on(x, y + m)) && on(x - m, y) && on(x + m, y);
}

LocalizedPoint CectFrame::extrapolate(const cv::Point2f& q, LocalizedPoint out) const {
  // A back pixel between the contour and the triangulation where the
  // contour gives no foundational correspondences (it runs along the
  // epipolar lines: the neck base, the waist band): the local quadratic of
  // the seeds around it, evaluated at most max_extrapolation seed steps
  // beyond the nearest seed, with the fit's rms and the distance in its
  // uncertainty.
  const double step = std::max(1, params_.seed_step);
  double d = 0.0, rms = 0.0, nearest = 0.0;
  cv::Point2d gradient;
  std::vector<int> idx;
  for (std::size_t i = 0; i < vertices_.size(); ++i)
    if (!vertices_[i].foundational()) idx.push_back(static_cast<int>(i));
  if (params_.max_extrapolation <= 0 || params_.seed_step <= 0 ||
      !fitQuadratic(vertices_, idx, q, 4.0 * step, 12, &d, &rms, &nearest, &gradient) ||
      nearest > params_.max_extrapolation * step) {
    out.reason = "pixel outside the triangulated back (too close to its border)";
    return out;
  }
  // Seeds that scatter beyond three times their matching noise around
  // their own quadratic do not describe a smooth surface here.
  if (rms > 3.0 * params_.pixel_sigma) {
    out.reason = "pixel outside the triangulated back, and the seeds around it do not fit a smooth surface (rms " +
                 std::to_string(rms) + " px)";
    return out;
  }
  if (params_.direct_min_sharpness > 0 && !seed_region_.at<std::uint8_t>(cvRound(q.y), cvRound(q.x))) {
    // In the border band: a direct match where the pixel's own window holds
    // enough texture.
    const int ry = params_.ncc_half_height > 0 ? params_.ncc_half_height : params_.ncc_radius;
    double dm = 0.0;
    if (directMatch(q, d, params_.ncc_radius, ry, &dm))
      // Its own measurement: no interpolation across the band.
      return triangulated(q, dm, structuralSigma(q, matchingSigma(), gradient, false), std::move(out));
  }
  const double sigma = std::hypot(matchingSigma(), rms) * (1.0 + nearest / step);
  out.extrapolated = true;
  return triangulated(q, d, structuralSigma(q, sigma, gradient), std::move(out));
}

LocalizedPoint CectFrame::triangulated(const cv::Point2f& q, double d, double sigma, LocalizedPoint out) const {
  // Covariance: pixel_sigma across the image, the disparity's sigma along
  // it, through the triangulation's Jacobian.
  Eigen::Matrix3d J;
  out.position = geometry_.triangulate(q.x, q.y, d, &J);
  if (!(out.position.z() > 0.0) || !out.position.allFinite()) {
    out.reason = "point behind the camera";
    return out;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  S(0, 0) = S(1, 1) = matchingSigma() * matchingSigma();
  S(2, 2) = sigma * sigma;
  out.covariance = J * S * J.transpose();
  out.disparity = d;
  out.disparity_sigma = sigma;
  out.valid = true;
  return out;
}

cv::Mat CectFrame::drawDebug() const {
  cv::Mat img = left_rect_.empty() ? cv::Mat() : left_rect_.clone();
  if (img.empty()) return img;
  for (const auto& t : triangles_) {
    const cv::Point pts[3] = {vertices_[static_cast<std::size_t>(t[0])].left,
                              vertices_[static_cast<std::size_t>(t[1])].left,
                              vertices_[static_cast<std::size_t>(t[2])].left};
    for (int j = 0; j < 3; ++j) cv::line(img, pts[j], pts[(j + 1) % 3], cv::Scalar(200, 200, 0), 1, cv::LINE_AA);
  }
  if (!left_seg_.contour.empty()) {
    std::vector<cv::Point> c;
    for (const auto& p : left_seg_.contour) c.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, c, true, cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  }
  for (const auto& v : vertices_)
    cv::circle(img, cv::Point(cvRound(v.left.x), cvRound(v.left.y)), 2,
               v.foundational()                                  ? cv::Scalar(0, 0, 255)
               : v.source == Correspondence::Source::kRimProfile ? cv::Scalar(0, 200, 255)
                                                                 : cv::Scalar(0, 255, 0),
               -1, cv::LINE_AA);
  if (!valid_)
    cv::putText(img, reason_, cv::Point(10, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
  return img;
}

}  // namespace massage_cell::cect
