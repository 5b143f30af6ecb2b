// The acupoint model's placement (acupoint_model.h): every acupoint, a vertebral level and a lateral offset in cun,
// as a left-image pixel. The level's row is its fraction of C7 -> L4 (along the body in 3D when measured, else in
// rows) on the midline; lateral is perpendicular to the midline, toward the subject's left (the image left with the
// head up); the cun from the shoulder width and the metres per pixel there, converted back to pixels with the metres
// per pixel on the midline at each level. Points are placed in the body's frame and answered in image pixels.
#include "massage_cell/cect/acupoint_model.h"

#include "acupoint_model_detail.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

namespace massage_cell::cect {

namespace {

constexpr double kScaleWindow = 0.03;  // metres-per-pixel median over +-3 % of C7->L4 along the midline

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
  const double length = std::abs(l.l4.body.y - l.c7.body.y);
  const double step = std::max(1.0, kScaleWindow / 3.0 * length);
  auto window = [&](double yc) {
    std::vector<double> s;
    for (int k = -3; k <= 3; ++k) {
      // A scale of 0 or less is none (a pixel without depth): left out, as the unknown (NaN) ones are by median().
      const double v = scale(midlineAt(l, yc + k * step));
      if (v > 0.0) s.push_back(v);
    }
    return median(s);
  };
  double m = window(y);
  for (double d = step; !std::isfinite(m) && d <= kMaxOutOfView * length; d += step) {
    m = window(y - d);
    if (!std::isfinite(m)) m = window(y + d);
  }
  return m;
}

/// The body frame's row at a fraction of C7 -> L4: along the body's axis in 3D when measured (measureLevelsIn3D),
/// else in rows.
double rowAtFraction(const BackLandmarks& l, double fraction) {
  const double by_rows = l.c7.body.y + fraction * (l.l4.body.y - l.c7.body.y);
  if (l.along.size() != l.midline.size()) return by_rows;
  // along[] is increasing where finite; C7 is at 0 and L4 at its length.
  const double l4_along = interpolateAlong(l, l.l4.body.y);
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

/// Knots (the model's fraction of C7 -> L4, a value) from C7's value, one per given level between C7 and L4
/// (`at_given` of it; a level the model does not know is left out) and L4's, in the model's order.
using Knots = std::vector<std::pair<double, double>>;
template <typename AtGiven>
Knots givenKnots(const BackLandmarks& l, const AcupointModel& model, double at_c7, const AtGiven& at_given,
                 double at_l4) {
  Knots knots{{0.0, at_c7}};
  for (const Landmark& g : l.given_levels) {
    const auto it = model.level_fraction.find(g.level);
    if (it != model.level_fraction.end() && it->second > 0.0 && it->second < 1.0)
      knots.emplace_back(it->second, at_given(g));
  }
  knots.emplace_back(1.0, at_l4);
  std::sort(knots.begin(), knots.end());
  return knots;
}

/// The knots' value at `x` in [0, 1] (linear between them).
double between(const Knots& knots, double x) {
  for (std::size_t k = 0; k + 1 < knots.size(); ++k) {
    const auto [x0, y0] = knots[k];
    const auto [x1, y1] = knots[k + 1];
    if (x <= x1) return y0 + (x - x0) / (x1 - x0) * (y1 - y0);
  }
  return knots.back().second;
}

/// The body frame's row of a level (its fraction of C7 -> L4 by the model): between two given landmarks (C7, a
/// given level such as T7, L4) the model's fractions spaced between the two; beyond C7 and L4 as they are.
double levelRow(const BackLandmarks& l, const AcupointModel& model, double fraction) {
  if (l.given_levels.empty() || !(fraction > 0.0 && fraction < 1.0)) return rowAtFraction(l, fraction);
  const Knots knots = givenKnots(
      l, model, 0.0, [&l](const Landmark& g) { return fractionAtRow(l, g.body.y); }, 1.0);
  return rowAtFraction(l, between(knots, fraction));
}

/// A scale of image pixels as one of the body frame's pixels.
PixelScale bodyScale(const BackLandmarks& l, const PixelScale& image_scale) {
  if (isIdentity(l.to_image) || !image_scale) return image_scale;
  return [&l, image_scale](const cv::Point2f& q) { return image_scale(toImage(l, q)); };
}

/// C7 -> L4 in metres: along the body in 3D where measured (measureLevelsIn3D), else the rows by the midline's median
/// metres per pixel; NaN without either.
double c7ToL4Metres(const BackLandmarks& l, const PixelScale& body_scale) {
  const double along = interpolateAlong(l, l.l4.body.y);
  if (std::isfinite(along) && along > 0.0) return along;
  return (l.l4.body.y - l.c7.body.y) * midlineScale(l, 0.5 * (l.c7.body.y + l.l4.body.y), body_scale);
}

}  // namespace

namespace detail {

double fractionAtRow(const BackLandmarks& l, double row) {
  const double by_rows = (row - l.c7.body.y) / (l.l4.body.y - l.c7.body.y);
  const double along = interpolateAlong(l, row), l4_along = interpolateAlong(l, l.l4.body.y);
  return std::isfinite(along) && l4_along > 0.0 ? along / l4_along : by_rows;
}

}  // namespace detail

std::string describeLandmarks(const BackLandmarks& landmarks) {
  if (!landmarks.valid) return "none: " + landmarks.reason;
  auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return s.empty() ? std::string("-") : s;
  };
  std::vector<std::string> used;
  for (const LayoutLandmark& l : layoutLandmarks(landmarks)) used.push_back(describeLandmark(l));
  return "used: " + join(used) + "; measured: " + join(landmarks.measured) + "; inferred: " + join(landmarks.inferred);
}

std::string sourceName(LandmarkSource source) {
  switch (source) {
    case LandmarkSource::kMeasured:
      return "measured";
    case LandmarkSource::kInferred:
      return "inferred";
    default:
      return "given";
  }
}

std::string givenHowName(LandmarkSource source) {
  switch (source) {
    case LandmarkSource::kGivenService:
      return "service";
    case LandmarkSource::kGivenClick:
      return "clicked";
    case LandmarkSource::kGivenMarker:
      return "marker";
    case LandmarkSource::kGivenOption:
      return "--landmark";
    default:
      return {};
  }
}

double layoutSigma(const AcupointModel& model, const std::string& level, LandmarkSource source) {
  const AcupointModel::LayoutSigma& s = model.layout_sigma;
  const bool given = isGiven(source);
  if (level == "C7") return given ? s.c7_given : source == LandmarkSource::kMeasured ? s.c7_measured : s.c7_inferred;
  if (level == "L4") return given ? s.l4_given : source == LandmarkSource::kMeasured ? s.l4_measured : s.l4_inferred;
  return given ? s.level_given : kNaN;
}

std::vector<LayoutLandmark> layoutLandmarks(const BackLandmarks& l) {
  if (!l.valid) return {};
  std::vector<LayoutLandmark> out{{l.c7, toImage(l, l.c7.body)}};
  for (const Landmark& g : l.given_levels) out.push_back({g, toImage(l, midlineAt(l, g.body.y))});
  out.push_back({l.l4, toImage(l, l.l4.body)});
  return out;
}

std::string landmarkDetail(const Landmark& l) { return l.given() ? givenHowName(l.source) : l.detail; }

std::string describeLandmark(const Landmark& l) {
  const std::string source = sourceName(l.source), detail = landmarkDetail(l);
  return l.level + " " + source + (detail.empty() || detail == source ? "" : " (" + detail + ")");
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
  return toImage(landmarks, midlineAt(landmarks, levelRow(landmarks, model, it->second)));
}

Eigen::Matrix3d layoutCovariance(const BackLandmarks& landmarks, const AcupointModel& model, const std::string& level,
                                 double metres_per_pixel) {
  const auto it = model.level_fraction.find(level);
  if (it == model.level_fraction.end() || !landmarks.valid || !(metres_per_pixel > 0.0)) return Eigen::Matrix3d::Zero();
  const cv::Point2f c7 = toImage(landmarks, landmarks.c7.body), l4 = toImage(landmarks, landmarks.l4.body);
  const double length_px = std::hypot(l4.x - c7.x, l4.y - c7.y);
  if (!(length_px > 0.0)) return Eigen::Matrix3d::Zero();
  const AcupointModel::LayoutSigma& ls = model.layout_sigma;
  // Linear in the level between two of C7, a given level and L4 (beyond C7 and L4, the nearer one's).
  const Knots knots = givenKnots(
      landmarks, model, layoutSigma(model, landmarks.c7), [&model](const Landmark& g) { return layoutSigma(model, g); },
      layoutSigma(model, landmarks.l4));
  const double sigma = between(knots, std::clamp(it->second, 0.0, 1.0));
  const double length = length_px * metres_per_pixel;
  const double along = sigma * length, across = ls.across * length;
  const Eigen::Vector3d a((l4.x - c7.x) / length_px, (l4.y - c7.y) / length_px, 0.0);
  const Eigen::Vector3d c(-a.y(), a.x(), 0.0);
  return along * along * a * a.transpose() + across * across * c * c.transpose();
}

double cunMetres(const BackLandmarks& landmarks, const AcupointModel& model, const PixelScale& image_scale) {
  if (!landmarks.valid || landmarks.midline.empty() || !image_scale) return kNaN;
  const PixelScale scale = bodyScale(landmarks, image_scale);
  if (landmarks.c7.given() && landmarks.l4.given()) {
    // The therapist's C7 and L4 fix the back's length, and the cun follows from it by the model's proportions; the
    // silhouette's widest row is misread where arms, hands or the cradle join the shoulders.
    const double length = c7ToL4Metres(landmarks, scale);
    if (std::isfinite(length)) return model.cun_per_shoulder_width / model.length_per_shoulder_width * length;
  }
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
      // A scale of 0 or less is none (a pixel without depth): left out, as the unknown (NaN) ones are by median().
      const double v = scale(centre + static_cast<float>(t) * lat);
      if (v > 0.0) s.push_back(v);
    }
    return median(s);
  };
  const double length = std::abs(landmarks.l4.body.y - landmarks.c7.body.y);
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
    const cv::Point2f p0 = midlineAt(landmarks, levelRow(landmarks, model, level->second + spec.level_offset));
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
