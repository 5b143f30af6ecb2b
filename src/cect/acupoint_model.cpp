// CECT step 5: the acupoint model (see acupoint_model.h).
//
// Landmarks from the left view's silhouette only (mask + contour):
//   rows      per image row, the back's left and right edges: the outermost
//             crossings of the contour with the row (cv::findContours
//             convention: the contour runs through the boundary pixels'
//             centres, so the edges are half a pixel further out), or the
//             first / last mask pixel when there is no contour;
//   midline   the middle of each row's extent, fitted by a robust (Huber
//             IRLS) quadratic x(y) over the torso rows (shoulder line .. just
//             above the bottom), so the neck / shoulder corners and the
//             tapering end of the back do not pull it; continued linearly
//             beyond the fitted rows;
//   top       where the midline leaves the silhouette at the head end: the
//             neck base seen from above;
//   shoulder  the widest (smoothed) row in the upper 35 % of the back;
//   waist     the narrowest row between the shoulders and the hips (middle of
//             the run of rows within 3 % of the waist-to-hip range of the
//             minimum: the minimum of a waist is broad and flat);
//   C7, L4    from the top and the waist with two calibrated fractions of
//             the C7 -> L4 distance L (c = c7_below_top, q = waist_fraction):
//               C7 = top + c L,  waist = C7 + q L
//             =>  L = (waist - top) / (c + q).
//             Cues tried for the iliac line over the simulator's 28 subjects
//             (each with one constant from the mean subject; |L4 row error|
//             mean / max, 320x240 and 640x480): the waist 1.6 / 3.6 and
//             3.5 / 7.2 px (~5 mm mean at both sizes; the others measured with
//             an exploratory version on the mask's rows): the widest row below the
//             waist 1.9 / 4.0 and 4.3 / 10 px; the bottom of the silhouette
//             2.3 / 10 and 4.5 / 19 px; rows where the width has climbed 25..90 %
//             of the way from the waist to the hips 1.8..6.2 / 4.5..14 and
//             4.7..13 / 14..32 px. The waist generalises best: the hips' maximum
//             is broad and flat, and the bottom of a real silhouette is wherever
//             the clothing starts. The hips are still required (a widening
//             below the waist), so that the narrowest row is a waist and not a
//             cut-off bottom edge.
//   lateral   perpendicular to the midline, toward the subject's left (the
//             image left with the head up); cun from the shoulder width and
//             the metres per pixel there, converted back to pixels with the
//             metres per pixel on the midline at each level.
// Known limits (see the tests): the flanks' silhouette lies near table level
// while the spine is ~0.2 m higher, so with the camera off the midline (the
// left camera of a stereo pair is half a baseline off) the silhouette's centre
// line is shifted from the skin's midline by the parallax (~5.5 px at 640x480,
// ~8 mm in the cell); levels are interpolated in image rows, which ignores
// perspective along the back (~3 px around T10 at 640x480).
// All rows are handled in the body's frame: the head-up image (head_up =
// false turns the segmentation by 180 degrees first), turned about the back
// until the midline between C7 and L4 runs along the columns (a subject lying
// askew on the table: on the image's rows a turn of 10 degrees put the
// acupoints 15 mm from the anatomical ones instead of 6-7 mm). A back within
// 1 degree of the columns keeps the image's rows. BackLandmarks::to_image maps
// the frame back; levelPixel() and placeAcupoints() answer in image pixels.
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <yaml-cpp/yaml.h>
#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// --- Tunables of the landmark search (lengths as fractions of the back's rows,
// widths as fractions of widths).
constexpr double kSmoothFraction = 0.01;  // half-window of the width smoothing
constexpr double kShoulderSearch = 0.35;  // shoulder line within the upper 35 %
constexpr double kBottomMargin = 0.06;    // the midline fit ends this far above the bottom
constexpr double kHipDrop = 0.03;         // above the hips the width drops by at least this fraction
constexpr double kHipDropCut = 0.015;     // ... on a back cut by the image's bottom (no tapering end to walk past)
constexpr double kWaistPlateau = 0.03;    // waist run: within 3 % of (hips - waist) of the minimum
constexpr double kNeckNarrower = 0.85;    // something above the shoulder line narrower than this x shoulders
constexpr double kWaistNarrower = 0.95;   // waist narrower than this x shoulders
constexpr double kHipWider = 0.015;       // hips wider than the waist by this fraction (+ 0.5 px)
constexpr double kMaxOutOfView = 0.25;    // L4 at most this fraction of C7 -> L4 below a back cut by the image
constexpr double kNeckFlare = 0.1;  // the neck's base: within 10 % of the way from the neck's width to the shoulders'
constexpr double kNeckRows = 0.04;  // a neck in view spans at least this fraction of the back's rows
constexpr double kTopMismatch =
    0.12;  // C7 from the top and from the shoulder line differ by more: the top is not the neck's base
constexpr int kMinRows = 24;           // fewer rows: too small to find anything
constexpr double kScaleWindow = 0.03;  // metres-per-pixel median over +-3 % of C7->L4 along the midline

const std::vector<std::string>& standardLevels() {
  static const std::vector<std::string> levels = {"C7", "T1",  "T2",  "T3",  "T4", "T5", "T6", "T7", "T8",
                                                  "T9", "T10", "T11", "T12", "L1", "L2", "L3", "L4", "L5"};
  return levels;
}

int levelIndex(const std::string& level) {
  const auto& levels = standardLevels();
  const auto it = std::find(levels.begin(), levels.end(), level);
  return it == levels.end() ? -1 : static_cast<int>(it - levels.begin());
}

const std::set<std::string>& regions() {
  static const std::set<std::string> r = {"upper_back", "lower_back", "midline", "shoulder"};
  return r;
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !(std::isfinite(x) && x > 0.0); }), v.end());
  if (v.empty()) return kNaN;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  return m;
}

// ---------------------------------------------------------------------------
// The back's silhouette row by row (head at the image top).

struct Rows {
  int y0 = 0;                       // first image row
  std::vector<double> left, right;  // edges (pixel borders), NaN where the row has none
  int size() const { return static_cast<int>(left.size()); }
  double width(int i) const { return right[static_cast<std::size_t>(i)] - left[static_cast<std::size_t>(i)]; }
};

bool usableContour(const std::vector<cv::Point2f>& contour) { return contour.size() >= 8; }

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

// ---------------------------------------------------------------------------
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

/// Weighted least-squares quadratic; false if singular.
bool solveQuadratic(const std::vector<double>& u, const std::vector<double>& x, const std::vector<double>& w,
                    std::array<double, 3>& c) {
  double a[3][4] = {};
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double b[3] = {1.0, u[i], u[i] * u[i]};
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) a[r][k] += w[i] * b[r] * b[k];
      a[r][3] += w[i] * b[r] * x[i];
    }
  }
  for (int r = 0; r < 3; ++r) {  // Gauss-Jordan with partial pivoting
    int p = r;
    for (int q = r + 1; q < 3; ++q) {
      if (std::abs(a[q][r]) > std::abs(a[p][r])) p = q;
    }
    if (!(std::abs(a[p][r]) > 1e-12)) return false;
    for (int k = 0; k < 4; ++k) std::swap(a[r][k], a[p][k]);
    for (int q = 0; q < 3; ++q) {
      if (q == r) continue;
      const double f = a[q][r] / a[r][r];
      for (int k = 0; k < 4; ++k) a[q][k] -= f * a[r][k];
    }
  }
  for (int r = 0; r < 3; ++r) c[static_cast<std::size_t>(r)] = a[r][3] / a[r][r];
  return true;
}

/// Robust fit of the row centres over rows [ia, ib] (indices into rows).
bool fitMidline(const Rows& rows, int ia, int ib, Midline& m) {
  m.ya = rows.y0 + ia;
  m.yb = rows.y0 + ib;
  m.yc = 0.5 * (m.ya + m.yb);
  m.h = std::max(1.0, 0.5 * (m.yb - m.ya));
  std::vector<double> u, x, w;
  for (int i = ia; i <= ib; ++i) {
    u.push_back((rows.y0 + i - m.yc) / m.h);
    x.push_back(0.5 * (rows.left[static_cast<std::size_t>(i)] + rows.right[static_cast<std::size_t>(i)]));
  }
  w.assign(u.size(), 1.0);
  if (!solveQuadratic(u, x, w, m.c)) return false;
  // Huber IRLS: rows where the sides are not mirror images (an arm, a
  // shoulder raised) get less weight.
  for (int it = 0; it < 10; ++it) {
    std::vector<double> r(u.size()), ar(u.size());
    for (std::size_t i = 0; i < u.size(); ++i) {
      r[i] = x[i] - (m.c[0] + u[i] * (m.c[1] + u[i] * m.c[2]));
      ar[i] = std::abs(r[i]);
    }
    std::vector<double> tmp = ar;
    std::nth_element(tmp.begin(), tmp.begin() + static_cast<std::ptrdiff_t>(tmp.size() / 2), tmp.end());
    const double s = std::max(0.5, 1.4826 * tmp[tmp.size() / 2]);
    for (std::size_t i = 0; i < u.size(); ++i) w[i] = ar[i] <= 1.5 * s ? 1.0 : 1.5 * s / ar[i];
    if (!solveQuadratic(u, x, w, m.c)) return false;
  }
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

// ---------------------------------------------------------------------------
// findLandmarks with the head at the image top.

BackLandmarks invalid(const std::string& reason) {
  BackLandmarks l;
  l.valid = false;
  l.reason = reason;
  return l;
}

/// Where the body's frame lies in the (head-up) image: findLandmarksHeadUp
/// needs the image's bottom edge, which is slanted in a turned frame.
struct ImageEdge {
  bool cut_at_bottom = false;                              ///< the back reaches the image's last row
  bool cut_at_top = false;                                 ///< the back reaches the image's first row
  int rows = 0;                                            ///< image rows
  cv::Matx23d to_head_up = cv::Matx23d(1, 0, 0, 0, 1, 0);  ///< body frame -> head-up image
};

cv::Point2f apply(const cv::Matx23d& a, const cv::Point2f& p) {
  return {static_cast<float>(a(0, 0) * p.x + a(0, 1) * p.y + a(0, 2)),
          static_cast<float>(a(1, 0) * p.x + a(1, 1) * p.y + a(1, 2))};
}

/// a after b (both affine).
cv::Matx23d compose(const cv::Matx23d& a, const cv::Matx23d& b) {
  const cv::Matx33d A(a(0, 0), a(0, 1), a(0, 2), a(1, 0), a(1, 1), a(1, 2), 0, 0, 1);
  const cv::Matx33d B(b(0, 0), b(0, 1), b(0, 2), b(1, 0), b(1, 1), b(1, 2), 0, 0, 1);
  const cv::Matx33d C = A * B;
  return cv::Matx23d(C(0, 0), C(0, 1), C(0, 2), C(1, 0), C(1, 1), C(1, 2));
}

cv::Matx23d inverse(const cv::Matx23d& a) {
  cv::Matx23d b;
  cv::invertAffineTransform(a, b);
  return b;
}

bool isIdentity(const cv::Matx23d& a) { return a == cv::Matx23d(1, 0, 0, 0, 1, 0); }

/// The neck's base (row index into the smoothed widths `w`): a neck in view
/// above the shoulder line `ish` is a run of narrow rows at the top; its base
/// is the lowest of them, where the width starts to flare toward the
/// shoulders (within kNeckFlare of the way from the neck's width to the
/// shoulders'). -1 when the narrow rows are fewer than kNeckRows of the back
/// (the back's own top: no neck in view).
int neckBase(const std::vector<double>& w, int ish, int n) {
  double neck = w[static_cast<std::size_t>(ish)];
  for (int i = 0; i < ish; ++i) neck = std::min(neck, w[static_cast<std::size_t>(i)]);
  const double limit = neck + kNeckFlare * (w[static_cast<std::size_t>(ish)] - neck);
  int base = -1, narrow = 0;
  for (int i = ish; i >= 0; --i) {
    if (w[static_cast<std::size_t>(i)] > limit) continue;
    if (base < 0) base = i;
    ++narrow;
  }
  return narrow >= kNeckRows * n ? base : -1;
}

/// The back's widths per row, smoothed over kSmoothFraction of its rows.
std::vector<double> smoothedWidths(const Rows& rows) {
  const int n = rows.size();
  const int half = std::max(1, static_cast<int>(std::lround(kSmoothFraction * n)));
  std::vector<double> w(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    double acc = 0.0;
    int cnt = 0;
    for (int j = std::max(0, i - half); j <= std::min(n - 1, i + half); ++j, ++cnt) acc += rows.width(j);
    w[static_cast<std::size_t>(i)] = acc / cnt;
  }
  return w;
}

/// What the width profile shows (row indices from the back's top): the shoulder line, the neck's base, the hips,
/// the waist - or why the silhouette is not a back.
struct WidthProfile {
  std::string problem;   ///< non-empty: not a back, and why
  int ish = 0;           ///< shoulder line: widest row of the upper part
  int ineck = -1;        ///< the neck's base (-1: none in view)
  bool no_neck = false;  ///< no widening from a neck to the shoulders
  std::string no_waist;  ///< why no waist is measured (empty: it is)
  double waist_row = kNaN;
  int iend = 0;  ///< end of the midline fit
};

WidthProfile widthProfile(const Rows& rows, const std::vector<double>& w, const Segmentation& seg,
                          const ImageEdge& edge) {
  const int n = rows.size();
  auto W = [&](int i) { return w[static_cast<std::size_t>(i)]; };
  WidthProfile p;
  // Shoulder line: widest row of the upper part; the neck above it must be narrower.
  const int shoulder_end = std::max(1, static_cast<int>(kShoulderSearch * n));
  for (int i = 0; i <= shoulder_end; ++i) {
    if (W(i) > W(p.ish)) p.ish = i;
  }
  const int ish = p.ish;
  double above = W(ish);
  for (int i = 0; i < ish; ++i) above = std::min(above, W(i));
  // C7: at the neck's base when a neck is in view, else from the back's top;
  // a back cut by the image's top edge with no neck has C7 above the image.
  p.no_neck = ish == 0 || above > kNeckNarrower * W(ish);
  if (p.no_neck && !edge.cut_at_top) {
    p.problem = "not a back: no widening from the neck to the shoulders";
    return p;
  }
  p.ineck = p.no_neck ? -1 : neckBase(w, ish, n);
  // Hips: walking up from the bottom, the widest row before the width has
  // dropped kHipDrop below the widest so far (past the tapering end, the first
  // clear maximum); waist: narrowest row between the shoulders and the hips.
  // A back cut by the image's bottom (camera shifted toward the head) ends in
  // the hips' start, not in a tapering end: a smaller drop marks the waist.
  const double hip_drop = edge.cut_at_bottom ? kHipDropCut : kHipDrop;
  int ih = n - 1;
  int up = n - 1;
  for (; up > ish; --up) {
    if (W(up) > W(ih)) ih = up;
    if (W(up) < (1.0 - hip_drop) * W(ih)) break;
  }
  int iw = ish;
  for (int k = ish; k <= ih; ++k) {
    if (W(k) < W(iw)) iw = k;
  }
  // No waist in view: a back cut by the image's bottom above its hips has
  // its levels from C7 and the shoulder width instead; so has a trunk whose
  // flanks are the creases of arms lying along it (the silhouette's waist is
  // then where the arms touch, not the trunk's).
  const bool creased = seg.trunk.arm_left || seg.trunk.arm_right;
  if (up == ish)
    p.no_waist = "no waist (no narrowing between the shoulders and the bottom)";
  else if (W(iw) > kWaistNarrower * W(ish))
    p.no_waist = "no narrowing at the waist";
  else if (W(ih) < (1.0 + kHipWider) * W(iw) + 0.5)
    p.no_waist = "no widening below the waist (hips out of view?)";
  if (!p.no_waist.empty() && (!edge.cut_at_bottom || p.no_neck) && !creased) {
    p.problem = "not a back: " + p.no_waist;
    return p;
  }
  if (creased && !p.no_neck && p.no_waist.empty()) p.no_waist = "the flanks are the arms' creases";
  if (!p.no_waist.empty() && p.no_neck) {
    p.problem = "not a back: neither the neck nor the waist in view (" + p.no_waist + ")";
    return p;
  }
  p.iend = n - 1 - std::max(1, static_cast<int>(kBottomMargin * n));
  if (p.iend < ish + 3) {
    p.problem = "not a back: too short below the shoulders";
    return p;
  }
  if (p.no_waist.empty()) {
    const double threshold = W(iw) + kWaistPlateau * (W(ih) - W(iw));
    int wa = iw, wb = iw;
    while (wa > ish && W(wa - 1) <= threshold) --wa;
    while (wb < ih && W(wb + 1) <= threshold) ++wb;
    p.waist_row = rows.y0 + 0.5 * (wa + wb);
  }
  return p;
}

/// C7 and L4 (image rows) from what is in view: the anchor (the neck's base or the back's top) and the waist; else
/// one of them and the model's proportions.
struct Levels {
  std::string problem;  ///< non-empty: why there are none
  double c7_row = kNaN, l4_row = kNaN, waist_row = kNaN;
  double length = kNaN;  ///< C7 to L4, rows
  bool c7_from_shoulders = false;
};

Levels levelsOf(const WidthProfile& p, double shoulder_row, double shoulder_width, double anchor,
                const AcupointModel& model) {
  Levels out;
  const double c = model.c7_below_top, q = model.waist_fraction;
  double length = kNaN;
  if (!p.no_neck && p.no_waist.empty())
    length = (p.waist_row - anchor) / (c + q);
  else if (!p.no_neck)
    length = model.length_per_shoulder_width * shoulder_width;
  else
    length = (p.waist_row - shoulder_row) / (q - model.shoulder_below_c7);
  if (!(length > 0.0)) {
    out.problem = "the waist is not below the top of the back";
    return out;
  }
  // Without a neck in view the back's top may not be the neck's base (hair
  // over the nape, hands or a cradle above it): when the shoulder line puts
  // C7 elsewhere, it is taken from the shoulder line.
  out.c7_from_shoulders = p.no_neck;
  if (!p.no_neck && p.ineck < 0) {
    const double prop = model.length_per_shoulder_width * shoulder_width;
    if (std::abs(anchor + c * length - (shoulder_row - model.shoulder_below_c7 * prop)) > kTopMismatch * prop) {
      out.c7_from_shoulders = true;
      length = p.no_waist.empty() ? (p.waist_row - shoulder_row) / (q - model.shoulder_below_c7) : prop;
      if (!(length > 0.0)) {
        out.problem = "the waist is not below the shoulder line";
        return out;
      }
    }
  }
  out.c7_row = out.c7_from_shoulders ? shoulder_row - model.shoulder_below_c7 * length : anchor + c * length;
  out.l4_row = out.c7_row + length;
  out.length = length;
  out.waist_row = p.no_waist.empty() ? p.waist_row : out.c7_row + q * length;  // else where the model puts it
  return out;
}

/// The landmarks: the midline from `top` to `bottom` with its lateral direction, C7, L4 and what was measured.
BackLandmarks landmarksOf(const Midline& mid, double top, double bottom, const WidthProfile& p, const Levels& lv,
                          double shoulder_row, double shoulder_width, double anchor) {
  BackLandmarks l;
  l.valid = true;
  for (int y = static_cast<int>(std::ceil(top)); y <= static_cast<int>(std::floor(bottom)); ++y) {
    l.midline.emplace_back(static_cast<float>(mid.x(y)), static_cast<float>(y));
    const double s = mid.slope(y), norm = std::hypot(1.0, s);
    // Caudal tangent (s, 1); the subject's left is the tangent turned by +90 deg in image coordinates.
    l.lateral.emplace_back(static_cast<float>(-1.0 / norm), static_cast<float>(s / norm));
  }
  l.c7 = cv::Point2f(static_cast<float>(mid.x(lv.c7_row)), static_cast<float>(lv.c7_row));
  l.l4 = cv::Point2f(static_cast<float>(mid.x(lv.l4_row)), static_cast<float>(lv.l4_row));
  l.shoulder_row = shoulder_row;
  l.shoulder_width = shoulder_width;
  l.waist_row = lv.waist_row;
  l.iliac_row = lv.l4_row;
  l.top_row = anchor;
  l.c7_measured = !lv.c7_from_shoulders;
  l.waist_measured = p.no_waist.empty();
  l.measured.push_back(p.ineck >= 0           ? "C7 at the neck's base"
                       : lv.c7_from_shoulders ? "the shoulder line"
                                              : "C7 at the back's top");
  if (l.waist_measured) l.measured.push_back("the waist");
  if (!l.c7_measured)
    l.inferred.push_back(
        p.no_neck ? "C7 from the shoulder line (the neck is out of view)"
                  : "C7 from the shoulder line (the back's top is not the neck's base: hair or something over it)");
  if (!l.waist_measured) l.inferred.push_back("L4 from C7 and the shoulder width (" + p.no_waist + ")");
  return l;
}

BackLandmarks findLandmarksHeadUp(const Segmentation& seg, const AcupointModel& model, const ImageEdge& edge) {
  Rows rows = usableContour(seg.contour) ? rowsFromContour(seg.contour) : rowsFromMask(seg.mask);
  tidyRows(rows);
  const int n = rows.size();
  if (n < kMinRows) {
    return invalid("back too small: " + std::to_string(n) + " rows (need at least " + std::to_string(kMinRows) + ")");
  }
  const std::vector<double> w = smoothedWidths(rows);
  const WidthProfile p = widthProfile(rows, w, seg, edge);
  if (!p.problem.empty()) return invalid(p.problem);

  // Midline over the torso rows, then the top and bottom where it meets the outline.
  Midline mid;
  if (!fitMidline(rows, p.ish, p.iend, mid)) return invalid("midline fit failed");
  double top = 0.0, bottom = 0.0;
  if (!midlineCrossings(seg, mid, &top, &bottom)) return invalid("the midline does not cross the back's outline");
  top -= 0.5;  // pixel centre of the boundary -> its outer edge
  bottom += 0.5;
  const double shoulder_row = rows.y0 + p.ish;
  const double shoulder_width = w[static_cast<std::size_t>(p.ish)];
  const double anchor = p.ineck >= 0 ? rows.y0 + p.ineck : top;  // C7 lies c * length below it
  const Levels lv = levelsOf(p, shoulder_row, shoulder_width, anchor, model);
  if (!lv.problem.empty()) return invalid(lv.problem);

  // A back that leaves the image at its bottom (the camera shifted toward the
  // head) may have its iliac-crest line out of view: the levels still follow
  // from C7 and the waist, and the points beyond the image are reported
  // invalid by the placement and the localisation, each with its reason.
  // Its own silhouette ending above L4 is not a back, or not this model's.
  const double length = lv.length;
  const cv::Point2f bottom_point(static_cast<float>(mid.x(bottom)), static_cast<float>(bottom));
  const bool cut_by_image = apply(edge.to_head_up, bottom_point).y >= static_cast<double>(edge.rows) - 1.0;
  if (!(lv.l4_row < bottom) && !(cut_by_image && lv.l4_row < bottom + kMaxOutOfView * length)) {
    return invalid("the iliac-crest line (row " + num(lv.l4_row) + ") is below the back's bottom (row " + num(bottom) +
                   ")");
  }
  return landmarksOf(mid, top, bottom, p, lv, shoulder_row, shoulder_width, anchor);
}

/// The 180-degree turn of an image of `cols` x `rows` (its own inverse).
cv::Matx23d halfTurn(int cols, int rows) { return cv::Matx23d(-1, 0, cols - 1.0, 0, -1, rows - 1.0); }

/// A segmentation in the frame `to` maps it into (only what findLandmarks
/// uses): the contour exactly, the mask resampled (nearest) on a canvas that
/// holds the whole back.
Segmentation turnedBy(const Segmentation& seg, const cv::Matx23d& to, cv::Size canvas) {
  Segmentation t;
  t.valid = seg.valid;
  t.reason = seg.reason;
  t.trunk = seg.trunk;
  t.contour.reserve(seg.contour.size());
  for (const auto& p : seg.contour) t.contour.push_back(apply(to, p));
  cv::warpAffine(seg.mask, t.mask, to, canvas, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  return t;
}

/// The turn of the frame a contour is in by `angle` (radians) about its
/// centroid, shifted so that the turned contour starts `margin` pixels from
/// the frame's origin; *canvas: a size that holds it.
cv::Matx23d turnAbout(const std::vector<cv::Point2f>& contour, double angle, cv::Size* canvas) {
  cv::Point2d c(0, 0);
  for (const auto& p : contour) c += cv::Point2d(p.x, p.y);
  c *= 1.0 / static_cast<double>(contour.size());
  const double co = std::cos(angle), si = std::sin(angle);
  cv::Matx23d r(co, -si, c.x - co * c.x + si * c.y, si, co, c.y - si * c.x - co * c.y);
  float x0 = std::numeric_limits<float>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const auto& p : contour) {
    const cv::Point2f q = apply(r, p);
    x0 = std::min(x0, q.x);
    y0 = std::min(y0, q.y);
    x1 = std::max(x1, q.x);
    y1 = std::max(y1, q.y);
  }
  constexpr double margin = 8.0;
  r(0, 2) += margin - std::floor(x0);
  r(1, 2) += margin - std::floor(y0);
  *canvas = cv::Size(static_cast<int>(std::ceil(x1 - std::floor(x0) + 2 * margin)),
                     static_cast<int>(std::ceil(y1 - std::floor(y0) + 2 * margin)));
  return r;
}

/// The midline's tilt between C7 and L4 (radians; + when it runs toward the
/// frame's right going down): the turn that would bring it onto the columns.
double midlineTilt(const BackLandmarks& l) {
  const double dy = static_cast<double>(l.l4.y) - l.c7.y;
  return dy > 0 ? std::atan2(static_cast<double>(l.l4.x) - l.c7.x, dy) : 0.0;
}

/// The tilt of the mask's long axis against the columns (radians, as
/// midlineTilt) from its second moments; NaN when the mask is not clearly
/// longer than wide or lies across the columns. The first turn's guess: the
/// row-by-row midline of a turned back leans more than the back (30 degrees
/// read as 42-48 on the simulator's subjects), and the image's own rows find
/// no waist on a back turned by ~20 degrees or more; the moments were within
/// 0.2 degree of the turn there.
double momentsTilt(const cv::Mat& mask) {
  const cv::Moments m = cv::moments(mask, true);
  const double a = m.mu20, c = m.mu02, b = m.mu11;
  const double root = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  const double major = 0.5 * (a + c) + root, minor = 0.5 * (a + c) - root;
  if (!(minor > 0.0) || major < 1.1 * minor) return kNaN;
  const double theta = 0.5 * std::atan2(2.0 * b, a - c);  // the long axis against the image's x
  double dx = std::cos(theta), dy = std::sin(theta);
  if (dy < 0) {
    dx = -dx;
    dy = -dy;
  }
  const double tilt = std::atan2(dx, dy);
  return std::abs(tilt) <= CV_PI / 4.0 ? tilt : kNaN;
}

/// The first and last back pixel of mask row y (-1 when the row has none).
void rowExtent(const cv::Mat& mask, int y, int* first, int* last) {
  *first = *last = -1;
  const std::uint8_t* row = mask.ptr<std::uint8_t>(y);
  for (int x = 0; x < mask.cols; ++x)
    if (row[x]) {
      if (*first < 0) *first = x;
      *last = x;
    }
}

/// The image's mask in the body's frame (for the landmarks' rows).
cv::Mat maskInBodyFrame(const BackLandmarks& l, const cv::Mat& mask) {
  if (isIdentity(l.to_image)) return mask;
  const cv::Matx23d to_body = inverse(l.to_image);
  float x1 = 0.0f, y1 = 0.0f;
  for (const cv::Point2f corner :
       {cv::Point2f(0, 0), cv::Point2f(static_cast<float>(mask.cols), 0), cv::Point2f(0, static_cast<float>(mask.rows)),
        cv::Point2f(static_cast<float>(mask.cols), static_cast<float>(mask.rows))}) {
    const cv::Point2f q = apply(to_body, corner);
    x1 = std::max(x1, q.x);
    y1 = std::max(y1, q.y);
  }
  cv::Mat out;
  cv::warpAffine(mask, out, to_body, cv::Size(static_cast<int>(std::ceil(x1)) + 1, static_cast<int>(std::ceil(y1)) + 1),
                 cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  return out;
}

// ---------------------------------------------------------------------------
// Along the midline.

/// The midline's point at row y (linear between its rows, extrapolated beyond its ends).
cv::Point2f midlineAt(const BackLandmarks& l, double y) {
  const auto& m = l.midline;
  if (m.size() == 1) return {m[0].x, static_cast<float>(y)};
  const double t = y - m.front().y;
  const std::size_t i = static_cast<std::size_t>(std::clamp(std::floor(t), 0.0, double(m.size() - 2)));
  const double f = t - double(i);  // may be < 0 or > 1 beyond the ends: linear extrapolation
  return {static_cast<float>(m[i].x + f * (m[i + 1].x - m[i].x)), static_cast<float>(y)};
}

cv::Point2f lateralAt(const BackLandmarks& l, double y) {
  const auto& v = l.lateral;
  const double t = std::clamp(y - l.midline.front().y, 0.0, double(v.size() - 1));
  return v[static_cast<std::size_t>(std::lround(t))];
}

/// along[] at row y of the body frame (linear between midline points); NaN
/// where not measured.
double interpolateAlong(const BackLandmarks& l, double y) {
  if (l.along.size() != l.midline.size() || l.midline.empty()) return kNaN;
  const double t = y - l.midline.front().y;
  if (t < 0.0 || t > double(l.midline.size() - 1)) return kNaN;
  const std::size_t i = std::min(static_cast<std::size_t>(t), l.midline.size() - 2);
  const double f = t - double(i);
  return (1.0 - f) * l.along[i] + f * l.along[i + 1];
}

/// Median metres-per-pixel along the midline within +-kScaleWindow of C7->L4
/// around row y. A level out of view (a back cut by the image) takes the
/// nearest window along the midline that has a scale, at most
/// kMaxOutOfView of C7->L4 away: the scale varies slowly along the back, and
/// the point is then placed (off the image, where the localisation reports it).
double midlineScale(const BackLandmarks& l, double y, const PixelScale& scale) {
  const double length = std::abs(l.l4.y - l.c7.y);
  const double step = std::max(1.0, kScaleWindow / 3.0 * length);
  auto window = [&](double yc) {
    std::vector<double> s;
    for (int k = -3; k <= 3; ++k) s.push_back(scale(midlineAt(l, yc + k * step)));
    return median(s);
  };
  double m = window(y);
  for (double d = step; !std::isfinite(m) && d <= kMaxOutOfView * length; d += step) {
    m = window(y - d);
    if (!std::isfinite(m)) m = window(y + d);
  }
  return m;
}

/// The body frame's row of a level (its fraction of C7 -> L4): along the
/// body's axis in 3D when measured (measureLevelsIn3D), else in rows.
double levelRow(const BackLandmarks& l, double fraction) {
  const double by_rows = l.c7.y + fraction * (l.l4.y - l.c7.y);
  if (l.along.size() != l.midline.size()) return by_rows;
  // along[] is increasing where finite; C7 is at 0 and L4 at its length.
  const double l4_along = interpolateAlong(l, l.l4.y);
  if (!(l4_along > 0.0)) return by_rows;
  const double target = fraction * l4_along;
  std::size_t prev = l.along.size();
  for (std::size_t i = 0; i < l.along.size(); ++i) {
    if (!std::isfinite(l.along[i])) continue;
    if (prev < l.along.size() && l.along[prev] <= target && target <= l.along[i]) {
      const double t = (target - l.along[prev]) / std::max(1e-12, l.along[i] - l.along[prev]);
      return l.midline[prev].y + t * (l.midline[i].y - l.midline[prev].y);
    }
    prev = i;
  }
  return by_rows;  // beyond the measured stretch
}

/// A scale of image pixels as one of the body frame's pixels.
PixelScale bodyScale(const BackLandmarks& l, const PixelScale& image_scale) {
  if (isIdentity(l.to_image) || !image_scale) return image_scale;
  return [&l, image_scale](const cv::Point2f& q) { return image_scale(toImage(l, q)); };
}

// --- YAML helpers: errors name the key.

template <typename T>
T get(const YAML::Node& node, const std::string& key, const std::string& where) {
  const YAML::Node v = node[key];
  if (!v) throw std::runtime_error(where + ": missing key '" + key + "'");
  try {
    return v.as<T>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(where + ": key '" + key + "' has the wrong type");
  }
}

}  // namespace

double correctMidlineParallax(BackLandmarks* landmarks, const Segmentation& left, const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || left.mask.empty() || !image_point) return kNaN;
  // Rows of the body's frame.
  const cv::Mat mask = maskInBodyFrame(l, left.mask);
  PointLookup point = image_point;
  if (!isIdentity(l.to_image)) {
    point = [&l, &image_point](const cv::Point2f& q, cv::Point3d* p) { return image_point(toImage(l, q), p); };
  }
  auto dot = [](const cv::Point3d& a, const cv::Point3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; };
  std::vector<double> ys, shifts;
  const double y0 = std::min(l.c7.y, l.l4.y), y1 = std::max(l.c7.y, l.l4.y);
  for (const cv::Point2f& m : l.midline) {
    if (m.y < y0 || m.y > y1) continue;  // the torso between C7 and L4
    const int y = cvRound(m.y);
    if (y < 0 || y >= mask.rows) continue;
    int xl = -1, xr = -1;
    rowExtent(mask, y, &xl, &xr);
    if (xl < 0 || xr - xl < 20) continue;
    cv::Point3d pl, pr;
    const float fy = static_cast<float>(y);
    // The rims themselves (the outermost back pixels): points further in
    // are not symmetric (each view sees one flank more face-on).
    if (!point(cv::Point2f(static_cast<float>(xl), fy), &pl) || !point(cv::Point2f(static_cast<float>(xr), fy), &pr))
      continue;
    // Across the body parallel to the image plane (the table, seen from
    // above): the rims themselves lie at different heights (each is where
    // the view ray grazes the flank), so the chord between them tilts.
    const cv::Point3d mid = 0.5 * (pl + pr), across(pr.x - pl.x, pr.y - pl.y, 0.0);
    const double len = std::sqrt(dot(across, across));
    if (!(len > 0.0)) continue;
    const cv::Point3d n = across / len;
    double x = m.x;
    bool ok = true;
    for (int it = 0; it < 3 && ok; ++it) {
      cv::Point3d p, pa, pb;
      ok = point(cv::Point2f(static_cast<float>(x), fy), &p) &&
           point(cv::Point2f(static_cast<float>(x - 2), fy), &pa) &&
           point(cv::Point2f(static_cast<float>(x + 2), fy), &pb);
      if (!ok) break;
      const double slope = dot(pb - pa, n) / 4.0;  // metres along n per pixel
      if (!(slope > 0.0)) {
        ok = false;
        break;
      }
      x -= dot(p - mid, n) / slope;
      ok = x > xl && x < xr;
    }
    if (!ok) continue;
    ys.push_back(m.y);
    shifts.push_back(x - m.x);
  }
  if (ys.size() < 10) return kNaN;
  // shift(y) = a + b y, least squares, once more without the residuals beyond 3 MAD.
  std::vector<bool> use(ys.size(), true);
  double a = 0.0, b = 0.0;
  for (int pass = 0; pass < 2; ++pass) {
    double n = 0, sy = 0, ss = 0, syy = 0, sys = 0;
    for (std::size_t i = 0; i < ys.size(); ++i)
      if (use[i]) {
        n += 1;
        sy += ys[i];
        ss += shifts[i];
        syy += ys[i] * ys[i];
        sys += ys[i] * shifts[i];
      }
    const double det = n * syy - sy * sy;
    if (n < 10 || std::abs(det) < 1e-9) return kNaN;
    b = (n * sys - sy * ss) / det;
    a = (ss - b * sy) / n;
    std::vector<double> res;
    for (std::size_t i = 0; i < ys.size(); ++i) res.push_back(std::abs(shifts[i] - a - b * ys[i]));
    std::vector<double> sorted = res;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double mad = std::max(0.1, sorted[sorted.size() / 2]);
    for (std::size_t i = 0; i < ys.size(); ++i) use[i] = res[i] <= 3.0 * mad;
  }
  auto shiftAt = [&](double y) { return static_cast<float>(a + b * y); };
  double mean = 0.0;
  for (cv::Point2f& m : l.midline) {
    m.x += shiftAt(m.y);
    mean += shiftAt(m.y);
  }
  l.c7.x += shiftAt(l.c7.y);
  l.l4.x += shiftAt(l.l4.y);
  return mean / static_cast<double>(l.midline.size());
}

double correctWaistParallax(BackLandmarks* landmarks, const AcupointModel& model, const Segmentation& left,
                            const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || left.mask.empty() || !image_point) return kNaN;
  if (!l.c7_measured || !l.waist_measured) return kNaN;  // C7 and L4 do not hang on the top and the waist
  const double c = model.c7_below_top, q = model.waist_fraction;
  if (!(c + q > 0.0)) return kNaN;
  const cv::Mat mask = maskInBodyFrame(l, left.mask);
  auto point = [&](const cv::Point2f& body, Eigen::Vector3d* out) {
    cv::Point3d p;
    if (!image_point(toImage(l, body), &p)) return false;
    *out = Eigen::Vector3d(p.x, p.y, p.z);
    return true;
  };
  // The waist's rims in 3D: the mean of the midpoints between the outermost
  // back pixels of the rows around the waist.
  Eigen::Vector3d rims = Eigen::Vector3d::Zero();
  int n = 0;
  const int wy = static_cast<int>(std::lround(l.waist_row));
  for (int y = wy - 3; y <= wy + 3; ++y) {
    if (y < 0 || y >= mask.rows) continue;
    int xl = -1, xr = -1;
    rowExtent(mask, y, &xl, &xr);
    Eigen::Vector3d pl, pr;
    const float fy = static_cast<float>(y);
    if (xl < 0 || xr - xl < 20 || !point(cv::Point2f(static_cast<float>(xl), fy), &pl) ||
        !point(cv::Point2f(static_cast<float>(xr), fy), &pr))
      continue;
    rims += 0.5 * (pl + pr);
    ++n;
  }
  if (n < 3) return kNaN;
  rims /= n;
  // Along the body parallel to the image plane (the camera looks down at the
  // table: the rims and the spine differ in height, so a chord that tilts
  // with the spine would pair them at different places): the body frame's
  // columns in the image.
  const Eigen::Vector3d axis = Eigen::Vector3d(l.to_image(0, 1), l.to_image(1, 1), 0.0).normalized();
  // The midline row at the rims' position along the axis (a sign change of
  // the distance along it, between C7 and L4).
  double spine_row = kNaN, prev_d = kNaN, prev_y = kNaN;
  for (const cv::Point2f& m : l.midline) {
    if (m.y < l.c7.y || m.y > l.l4.y) continue;
    Eigen::Vector3d p;
    if (!point(m, &p)) continue;
    const double d = (p - rims).dot(axis);
    if (std::isfinite(prev_d) && prev_d < 0.0 && d >= 0.0) {
      spine_row = prev_y + (m.y - prev_y) * (-prev_d) / (d - prev_d);
      break;
    }
    prev_d = d;
    prev_y = m.y;
  }
  if (!std::isfinite(spine_row)) return kNaN;
  const double length = static_cast<double>(l.l4.y) - l.c7.y;
  const double move = (spine_row - l.waist_row) - model.waist_rim_offset * length;
  const double waist = l.waist_row + move;
  const double new_length = (waist - l.top_row) / (c + q);
  if (!(new_length > 0.0)) return kNaN;
  const double c7_row = l.top_row + c * new_length, l4_row = c7_row + new_length;
  l.c7 = midlineAt(l, c7_row);
  l.l4 = midlineAt(l, l4_row);
  l.waist_row = waist;
  l.iliac_row = l4_row;
  l.along.clear();  // measured from the old C7: measureLevelsIn3D again
  return move;
}

double measureLevelsIn3D(BackLandmarks* landmarks, const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || !image_point) return kNaN;
  const double length_rows = static_cast<double>(l.l4.y) - l.c7.y;
  if (!(length_rows > 10.0)) return kNaN;
  // The 3D points of the midline from just above C7 to a quarter of C7 -> L4
  // below L4 (the model's lowest levels), as functions of u = 0 at C7, 1 at L4.
  const double u_lo = -0.05, u_hi = 1.25;
  std::vector<double> us;
  std::vector<Eigen::Vector3d> ps;
  int near_c7 = 0, near_l4 = 0;
  for (const cv::Point2f& m : l.midline) {
    const double u = (m.y - l.c7.y) / length_rows;
    if (u < u_lo || u > u_hi) continue;
    cv::Point3d p;
    if (!image_point(toImage(l, m), &p)) continue;
    us.push_back(u);
    ps.emplace_back(p.x, p.y, p.z);
    near_c7 += std::abs(u) < 0.1 ? 1 : 0;
    near_l4 += std::abs(u - 1.0) < 0.1 ? 1 : 0;
  }
  if (us.size() < 30 || near_c7 < 5 || near_l4 < 5) return kNaN;
  // Each coordinate a cubic in u (least squares, Eigen), refitted twice with
  // Huber weights on the 3D residual (a hole or a wrong point in the surface).
  const Eigen::Index n = static_cast<Eigen::Index>(us.size());
  Eigen::MatrixXd A(n, 4), B(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double u = us[static_cast<std::size_t>(i)];
    A.row(i) << 1.0, u, u * u, u * u * u;
    B.row(i) = ps[static_cast<std::size_t>(i)].transpose();
  }
  Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  Eigen::Matrix<double, 4, 3> C;
  for (int pass = 0; pass < 3; ++pass) {
    const Eigen::MatrixXd Aw = w.asDiagonal() * A, Bw = w.asDiagonal() * B;
    C = Aw.colPivHouseholderQr().solve(Bw);
    if (!C.allFinite()) return kNaN;
    Eigen::VectorXd r = (A * C - B).rowwise().norm();
    std::vector<double> sorted(r.data(), r.data() + n);
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    const double k = 1.5 * std::max(1e-3, 1.4826 * sorted[static_cast<std::size_t>(n / 2)]);
    for (Eigen::Index i = 0; i < n; ++i) w(i) = r(i) <= k ? 1.0 : std::sqrt(k / r(i));
  }
  auto P = [&](double u) { return Eigen::Vector3d((Eigen::RowVector4d(1.0, u, u * u, u * u * u) * C).transpose()); };
  const Eigen::Vector3d c7 = P(0.0), chord = P(1.0) - c7;
  const double length = chord.norm();
  if (!(length > 0.0)) return kNaN;
  const Eigen::Vector3d axis = chord / length;
  const double u_min = *std::min_element(us.begin(), us.end()), u_max = *std::max_element(us.begin(), us.end());
  std::vector<double> along(l.midline.size(), kNaN);
  double last = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < l.midline.size(); ++i) {
    const double u = (l.midline[i].y - l.c7.y) / length_rows;
    if (u < u_min || u > u_max) continue;
    along[i] = (P(u) - c7).dot(axis);
    if (!(along[i] > last)) return kNaN;  // not monotonic: not a back lying along its axis
    last = along[i];
  }
  l.along = std::move(along);
  return length;
}

PixelScale frameScale(const CectFrame& frame) {
  return [&frame](const cv::Point2f& q) {
    const LocalizedPoint p = frame.localizeRectified(q);
    return p.valid ? p.position.z() / frame.geometry().fx() : kNaN;
  };
}

PointLookup framePoints(const CectFrame& frame) {
  return [&frame](const cv::Point2f& q, cv::Point3d* out) {
    const LocalizedPoint p = frame.localizeRectified(q);
    if (!p.valid) return false;
    *out = cv::Point3d(p.position.x(), p.position.y(), p.position.z());
    return true;
  };
}

// ---------------------------------------------------------------------------
// AcupointModel

std::vector<std::string> AcupointModel::names() const {
  std::vector<std::string> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(p.name);
  return out;
}

const AcupointSpec* AcupointModel::find(const std::string& name) const {
  for (const auto& p : points) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

void AcupointModel::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("acupoint model: " + what); };
  if (level_fraction.empty()) fail("level_fraction is empty");
  for (const auto& [level, f] : level_fraction) {
    if (levelIndex(level) < 0) {
      fail("unknown vertebral level '" + level + "' in level_fraction (expected C7, T1..T12, L1..L5)");
    }
    if (!std::isfinite(f)) fail("level_fraction of " + level + " is not finite");
  }
  const auto c7 = level_fraction.find("C7"), l4 = level_fraction.find("L4");
  if (c7 == level_fraction.end() || c7->second != 0.0) fail("level_fraction must list C7 = 0");
  if (l4 == level_fraction.end() || l4->second != 1.0) fail("level_fraction must list L4 = 1");
  // Increasing in the spine's order.
  std::string prev;
  double prev_f = -std::numeric_limits<double>::infinity();
  for (const auto& level : standardLevels()) {
    const auto it = level_fraction.find(level);
    if (it == level_fraction.end()) continue;
    if (!(it->second > prev_f)) {
      fail("level_fraction must increase from C7 to L5: " + level + " = " + num(it->second) + " is not below " + prev +
           " = " + num(prev_f));
    }
    prev = level;
    prev_f = it->second;
  }
  if (!(cun_per_shoulder_width > 0.0 && cun_per_shoulder_width < 0.5)) {
    fail("cun_per_shoulder_width = " + num(cun_per_shoulder_width) + " is not in (0, 0.5)");
  }
  if (!(c7_below_top >= 0.0 && c7_below_top < 0.5)) fail("c7_below_top = " + num(c7_below_top) + " is not in [0, 0.5)");
  if (!(std::abs(waist_rim_offset) < 0.2))
    fail("waist_rim_offset = " + num(waist_rim_offset) + " is not in (-0.2, 0.2)");
  if (!(shoulder_below_c7 >= 0.0 && shoulder_below_c7 < 0.5))
    fail("shoulder_below_c7 = " + num(shoulder_below_c7) + " is not in [0, 0.5)");
  if (!(length_per_shoulder_width > 0.3 && length_per_shoulder_width < 3.0))
    fail("length_per_shoulder_width = " + num(length_per_shoulder_width) + " is not in (0.3, 3)");
  for (const double v : {layout_sigma.c7_measured, layout_sigma.c7_inferred, layout_sigma.l4_measured,
                         layout_sigma.l4_inferred, layout_sigma.across})
    if (!(v >= 0.0 && v < 1.0)) fail("layout_sigma: " + num(v) + " is not in [0, 1)");
  if (!(waist_fraction > 0.0 && waist_fraction < 1.5)) {
    fail("waist_fraction = " + num(waist_fraction) + " is not in (0, 1.5)");
  }
  if (points.empty()) fail("no points");
  std::set<std::string> seen;
  for (const auto& p : points) {
    if (p.name.empty()) fail("a point has an empty name");
    if (!seen.insert(p.name).second) fail("duplicate point name '" + p.name + "'");
    if (!level_fraction.count(p.level)) {
      fail("point '" + p.name + "': unknown level '" + p.level + "' (not in level_fraction)");
    }
    if (!(std::abs(p.lateral_cun) <= 10.0)) {
      fail("point '" + p.name + "': lateral_cun = " + num(p.lateral_cun) + " is not in -10 .. 10");
    }
    if (!regions().count(p.region)) {
      fail("point '" + p.name + "': unknown region '" + p.region +
           "' (expected upper_back, lower_back, midline or shoulder)");
    }
  }
}

namespace {

AcupointModel acupointModel(const std::string& path) {
  const std::string where = "acupoint model '" + path + "'";
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(where + ": cannot open the file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(where + ": not valid YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error(where + ": expected a mapping at the top level");
  AcupointModel m;
  m.head_up = root["head_up"] ? get<bool>(root, "head_up", where) : true;
  m.cun_per_shoulder_width = get<double>(root, "cun_per_shoulder_width", where);
  m.c7_below_top = get<double>(root, "c7_below_top", where);
  m.waist_fraction = get<double>(root, "waist_fraction", where);
  if (root["waist_rim_offset"]) m.waist_rim_offset = get<double>(root, "waist_rim_offset", where);
  if (root["shoulder_below_c7"]) m.shoulder_below_c7 = get<double>(root, "shoulder_below_c7", where);
  if (root["length_per_shoulder_width"])
    m.length_per_shoulder_width = get<double>(root, "length_per_shoulder_width", where);
  if (const YAML::Node ls = root["layout_sigma"]) {
    if (!ls.IsMap()) throw std::runtime_error(where + ": 'layout_sigma' must be a mapping");
    const std::string at = where + ", layout_sigma";
    AcupointModel::LayoutSigma& l = m.layout_sigma;
    for (const auto& kv : ls) {
      const std::string key = kv.first.as<std::string>();
      double* field = key == "c7_measured"   ? &l.c7_measured
                      : key == "c7_inferred" ? &l.c7_inferred
                      : key == "l4_measured" ? &l.l4_measured
                      : key == "l4_inferred" ? &l.l4_inferred
                      : key == "across"      ? &l.across
                                             : nullptr;
      if (!field)
        throw std::runtime_error(at + ": unknown key '" + key +
                                 "' (c7_measured, c7_inferred, l4_measured, l4_inferred, across)");
      *field = get<double>(ls, key, at);
    }
  }
  const YAML::Node levels = root["level_fraction"];
  if (!levels || !levels.IsMap()) throw std::runtime_error(where + ": missing mapping 'level_fraction'");
  for (const auto& kv : levels) {
    const std::string level = kv.first.as<std::string>();
    if (m.level_fraction.count(level)) throw std::runtime_error(where + ": level '" + level + "' listed twice");
    try {
      m.level_fraction[level] = kv.second.as<double>();
    } catch (const YAML::Exception&) {
      throw std::runtime_error(where + ": level_fraction of '" + level + "' is not a number");
    }
  }
  const YAML::Node points = root["points"];
  if (!points || !points.IsSequence()) throw std::runtime_error(where + ": missing sequence 'points'");
  for (std::size_t i = 0; i < points.size(); ++i) {
    const YAML::Node p = points[i];
    const std::string at = where + ", points[" + std::to_string(i) + "]";
    if (!p.IsMap()) throw std::runtime_error(at + ": expected a mapping");
    AcupointSpec s;
    s.name = get<std::string>(p, "name", at);
    s.level = get<std::string>(p, "level", at);
    s.lateral_cun = get<double>(p, "lateral_cun", at);
    s.region = get<std::string>(p, "region", at);
    m.points.push_back(s);
  }
  try {
    m.validate();
  } catch (const std::invalid_argument& e) {
    std::string what = e.what();
    const std::string prefix = "acupoint model: ";
    if (what.rfind(prefix, 0) == 0) what = what.substr(prefix.size());
    throw std::runtime_error(where + ": " + what);
  }
  return m;
}

}  // namespace

// A yaml-cpp error the field readers did not name still names the file and its line.
AcupointModel loadAcupointModel(const std::string& path) {
  try {
    return acupointModel(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("acupoint model '" + path + "': " + e.what());
  }
}

// ---------------------------------------------------------------------------
// Landmarks and points

BackLandmarks findLandmarks(const Segmentation& left, const AcupointModel& model) {
  if (!left.valid) return invalid("segmentation not valid: " + left.reason);
  if (left.mask.empty()) return invalid("mask is empty");
  if (left.mask.type() != CV_8UC1) return invalid("mask is not CV_8UC1");
  if (cv::countNonZero(left.mask) == 0) return invalid("mask is empty (no back)");
  if (!(model.c7_below_top + model.waist_fraction > 0.0)) return invalid("model constants not set");
  // The head-up image: the image itself, or turned by 180 degrees.
  const cv::Matx23d image_from_up =
      model.head_up ? cv::Matx23d(1, 0, 0, 0, 1, 0) : halfTurn(left.mask.cols, left.mask.rows);
  const Segmentation up = model.head_up ? left : turnedBy(left, image_from_up, left.mask.size());
  ImageEdge edge;
  edge.rows = up.mask.rows;
  edge.cut_at_bottom = cv::countNonZero(up.mask.row(up.mask.rows - 1)) > 0;
  edge.cut_at_top = cv::countNonZero(up.mask.row(0)) > 0;
  BackLandmarks l = findLandmarksHeadUp(up, model, edge);
  l.to_image = image_from_up;
  // A body turned on the table: the rows of the head-up image cut it
  // slantwise (wider, and the levels sheared across the body). Turn the
  // frame until the midline between C7 and L4 runs along its columns; the
  // row-by-row midline of a turned back leans less than the back itself, so
  // this takes a few turns. Within kMinTurn the image's own rows are kept.
  constexpr double kMinTurn = 1.0 * CV_PI / 180.0, kTolerance = 0.1 * CV_PI / 180.0, kMaxTurn = 45.0 * CV_PI / 180.0;
  constexpr int kMaxTurns = 6;
  if (!usableContour(up.contour)) return l;
  if (l.valid && std::abs(midlineTilt(l)) < kMinTurn) return l;
  // A turn that loses the landmarks, or runs past 45 degrees, is not the
  // body's: the silhouette's own axis misleads (arms, head, a one-sided cut);
  // the head-up frame's landmarks stand then.
  const BackLandmarks upright = l;
  // First turn: the mask's long axis (the row-by-row midline of a turned
  // back can lean more than the back), else the midline.
  const double moments = momentsTilt(up.mask);
  double tilt = std::isfinite(moments) ? moments : l.valid ? midlineTilt(l) : kNaN, total = 0.0;
  if (!(std::abs(tilt) >= kMinTurn)) return l;  // also NaN: no axis to turn to
  cv::Matx23d body_from_up(1, 0, 0, 0, 1, 0);
  Segmentation body = up;
  for (int turn = 0; turn < kMaxTurns && std::abs(tilt) >= kTolerance; ++turn) {
    total += tilt;
    if (std::abs(total) > kMaxTurn) {
      if (upright.valid) return upright;
      return invalid("the body lies turned by more than 45 degrees against the image's columns (" +
                     num(std::round(-total * 180.0 / CV_PI)) + " degrees): not this model's view of a back");
    }
    cv::Size canvas;
    const cv::Matx23d step = turnAbout(body.contour, tilt, &canvas);
    body_from_up = compose(step, body_from_up);
    body = turnedBy(up, body_from_up, canvas);
    edge.to_head_up = inverse(body_from_up);
    BackLandmarks turned = findLandmarksHeadUp(body, model, edge);
    if (!turned.valid) {
      if (upright.valid) return upright;
      turned.reason = "body turned by " + num(std::round(-total * 180.0 / CV_PI)) + " degrees: " + turned.reason;
      return turned;
    }
    l = turned;
    l.to_image = compose(image_from_up, edge.to_head_up);
    l.body_angle_deg = -total * 180.0 / CV_PI;  // the midline's tilt is + with the head toward the left
    tilt = midlineTilt(l);
  }
  return l;
}

std::string describeLandmarks(const BackLandmarks& landmarks) {
  if (!landmarks.valid) return "none: " + landmarks.reason;
  auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return s.empty() ? std::string("-") : s;
  };
  return "measured: " + join(landmarks.measured) + "; inferred: " + join(landmarks.inferred);
}

cv::Point2f toImage(const BackLandmarks& landmarks, const cv::Point2f& body_pixel) {
  return apply(landmarks.to_image, body_pixel);
}

cv::Point2f levelPixel(const BackLandmarks& landmarks, const AcupointModel& model, const std::string& level) {
  const auto it = model.level_fraction.find(level);
  if (it == model.level_fraction.end()) throw std::invalid_argument("levelPixel: unknown level '" + level + "'");
  if (!landmarks.valid || landmarks.midline.empty()) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    return {nan, nan};
  }
  return toImage(landmarks, midlineAt(landmarks, levelRow(landmarks, it->second)));
}

Eigen::Matrix3d layoutCovariance(const BackLandmarks& landmarks, const AcupointModel& model, const std::string& level,
                                 double metres_per_pixel) {
  const auto it = model.level_fraction.find(level);
  if (it == model.level_fraction.end() || !landmarks.valid || !(metres_per_pixel > 0.0)) return Eigen::Matrix3d::Zero();
  const cv::Point2f c7 = toImage(landmarks, landmarks.c7), l4 = toImage(landmarks, landmarks.l4);
  const double length_px = std::hypot(l4.x - c7.x, l4.y - c7.y);
  if (!(length_px > 0.0)) return Eigen::Matrix3d::Zero();
  const AcupointModel::LayoutSigma& ls = model.layout_sigma;
  const double at_c7 = landmarks.c7_measured ? ls.c7_measured : ls.c7_inferred;
  const double at_l4 = landmarks.waist_measured ? ls.l4_measured : ls.l4_inferred;
  // Linear in the level between C7 and L4 (beyond them, the nearer one's).
  const double t = std::clamp(it->second, 0.0, 1.0);
  const double length = length_px * metres_per_pixel;
  const double along = ((1.0 - t) * at_c7 + t * at_l4) * length, across = ls.across * length;
  const Eigen::Vector3d a((l4.x - c7.x) / length_px, (l4.y - c7.y) / length_px, 0.0);
  const Eigen::Vector3d c(-a.y(), a.x(), 0.0);
  return along * along * a * a.transpose() + across * across * c * c.transpose();
}

double cunMetres(const BackLandmarks& landmarks, const AcupointModel& model, const PixelScale& image_scale) {
  if (!landmarks.valid || landmarks.midline.empty() || !image_scale) return kNaN;
  const PixelScale scale = bodyScale(landmarks, image_scale);
  // Metres per pixel on the shoulder line: median over its central half (the
  // skin there; robust to holes and outliers of a measured depth). Where
  // nothing there is localised (the line at the image's top edge), the
  // nearest row below, within kMaxOutOfView of C7 -> L4, that is.
  auto across = [&](double row) {
    const cv::Point2f centre = midlineAt(landmarks, row);
    const cv::Point2f lat = lateralAt(landmarks, row);
    std::vector<double> s;
    for (int k = -4; k <= 4; ++k) {
      const double t = 0.25 * landmarks.shoulder_width * k / 4.0;
      s.push_back(scale(centre + static_cast<float>(t) * lat));
    }
    return median(s);
  };
  const double length = std::abs(landmarks.l4.y - landmarks.c7.y);
  const double step = std::max(1.0, kScaleWindow / 3.0 * length);
  double mpp = across(landmarks.shoulder_row);
  for (double d = step; !std::isfinite(mpp) && d <= kMaxOutOfView * length; d += step)
    mpp = across(landmarks.shoulder_row + d);
  return model.cun_per_shoulder_width * landmarks.shoulder_width * mpp;
}

std::vector<AcupointPixel> placeAcupoints(const BackLandmarks& landmarks, const AcupointModel& model,
                                          const PixelScale& scale) {
  std::vector<AcupointPixel> out;
  out.reserve(model.points.size());
  const double cun = landmarks.valid ? cunMetres(landmarks, model, scale) : kNaN;
  const PixelScale body_scale = bodyScale(landmarks, scale);
  for (const auto& spec : model.points) {
    AcupointPixel a;
    a.name = spec.name;
    if (!landmarks.valid) {
      a.reason = "no landmarks: " + landmarks.reason;
      out.push_back(a);
      continue;
    }
    const auto level = model.level_fraction.find(spec.level);
    if (level == model.level_fraction.end()) {
      a.reason = "unknown level '" + spec.level + "'";
      out.push_back(a);
      continue;
    }
    // In the body's frame, then into the image.
    const cv::Point2f p0 = midlineAt(landmarks, levelRow(landmarks, level->second));
    if (spec.lateral_cun == 0.0) {
      a.pixel = toImage(landmarks, p0);
      a.valid = true;
      out.push_back(a);
      continue;
    }
    if (!std::isfinite(cun)) {
      a.reason = "cun unknown (no metres per pixel on the shoulder line)";
      out.push_back(a);
      continue;
    }
    const double mpp = midlineScale(landmarks, p0.y, body_scale);
    if (!std::isfinite(mpp)) {
      a.reason = "no metres per pixel on the midline at " + spec.level;
      out.push_back(a);
      continue;
    }
    const double offset = spec.lateral_cun * cun / mpp;  // pixels toward the subject's left
    a.pixel = toImage(landmarks, p0 + static_cast<float>(offset) * lateralAt(landmarks, p0.y));
    a.valid = true;
    out.push_back(a);
  }
  return out;
}

}  // namespace massage_cell::cect
