// The acupoint model's landmarks (acupoint_model.h), from the left view's silhouette only (the rows and the midline
// of silhouette.cpp): the shoulder line is the widest (smoothed) row in the upper 35 % of the back; the waist the
// narrowest row between the shoulders and the hips (the middle of the run of rows within 3 % of the waist-to-hip
// range of the minimum: a waist's minimum is broad and flat); C7 and L4 from the top and the waist with two
// calibrated fractions of C7 -> L4 = L (c = c7_below_top, q = waist_fraction): C7 = top + c L, waist = C7 + q L,
// so L = (waist - top) / (c + q). All rows are the body's frame: the head-up image (head_up = false turns it by 180
// degrees), turned about the back until the midline between C7 and L4 runs along the columns (within 1 degree the
// image's rows stay); BackLandmarks::to_image maps it back. Figures: docs/cect.md, "Acupoint model: design notes".
#include "massage_cell/cect/acupoint_model.h"

#include "acupoint_model_detail.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

// --- Tunables of the landmark search (lengths as fractions of the back's rows,
// widths as fractions of widths; kMaxOutOfView, shared with the placement: acupoint_model_detail.h).
constexpr double kSmoothFraction = 0.01;  // half-window of the width smoothing
constexpr double kShoulderSearch = 0.35;  // shoulder line within the upper 35 %
constexpr double kBottomMargin = 0.06;    // the midline fit ends this far above the bottom
constexpr double kHipDrop = 0.03;         // above the hips the width drops by at least this fraction
constexpr double kHipDropCut = 0.015;     // ... on a back cut by the image's bottom (no tapering end to walk past)
constexpr double kWaistPlateau = 0.03;    // waist run: within 3 % of (hips - waist) of the minimum
constexpr double kNeckNarrower = 0.85;    // something above the shoulder line narrower than this x shoulders
constexpr double kWaistNarrower = 0.95;   // waist narrower than this x shoulders
constexpr double kHipWider = 0.015;       // hips wider than the waist by this fraction (+ 0.5 px)
constexpr double kNeckFlare = 0.1;  // the neck's base: within 10 % of the way from the neck's width to the shoulders'
constexpr double kNeckRows = 0.04;  // a neck in view spans at least this fraction of the back's rows
constexpr double kTopMismatch =
    0.12;  // C7 from the top and from the shoulder line differ by more: the top is not the neck's base
constexpr int kMinRows = 24;  // fewer rows: too small to find anything

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
  bool l4_given = false;  ///< L4 will be given (findLandmarks): an inferred one beyond the back's bottom is no failure
};

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
  l.c7.body = cv::Point2f(static_cast<float>(mid.x(lv.c7_row)), static_cast<float>(lv.c7_row));
  l.l4.body = cv::Point2f(static_cast<float>(mid.x(lv.l4_row)), static_cast<float>(lv.l4_row));
  l.shoulder_row = shoulder_row;
  l.shoulder_width = shoulder_width;
  l.waist_row = lv.waist_row;
  l.iliac_row = lv.l4_row;
  l.top_row = anchor;
  // C7 at a neck's base is always measured: c7_from_shoulders only where no neck's base was found.
  l.c7.source = lv.c7_from_shoulders ? LandmarkSource::kInferred : LandmarkSource::kMeasured;
  l.c7.detail = lv.c7_from_shoulders ? kFromShoulderLine : p.ineck >= 0 ? kFromNeckBase : kFromBackTop;
  const bool waist = p.no_waist.empty();
  l.l4.source = waist ? LandmarkSource::kMeasured : LandmarkSource::kInferred;
  l.l4.detail = waist ? kFromWaist : kFromShoulderWidth;
  l.measured.push_back(p.ineck >= 0           ? "C7 at the neck's base"
                       : lv.c7_from_shoulders ? "the shoulder line"
                                              : "C7 at the back's top");
  if (waist) l.measured.push_back("the waist");
  if (lv.c7_from_shoulders)
    l.inferred.push_back(
        p.no_neck ? "C7 from the shoulder line (the neck is out of view)"
                  : "C7 from the shoulder line (the back's top is not the neck's base: hair or something over it)");
  if (!waist) l.inferred.push_back("L4 from C7 and the shoulder width (" + p.no_waist + ")");
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
  if (!edge.l4_given && !(lv.l4_row < bottom) && !(cut_by_image && lv.l4_row < bottom + kMaxOutOfView * length)) {
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
  const double dy = static_cast<double>(l.l4.body.y) - l.c7.body.y;
  return dy > 0 ? std::atan2(static_cast<double>(l.l4.body.x) - l.c7.body.x, dy) : 0.0;
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

}  // namespace

BackLandmarks findLandmarks(const Segmentation& left, const AcupointModel& model, bool l4_given) {
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
  edge.l4_given = l4_given;
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

}  // namespace massage_cell::cect
