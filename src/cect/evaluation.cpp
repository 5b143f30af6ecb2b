// Scoring the acupoint chain against the anatomy (see evaluation.h).
//
// The body's directions come from the truth: `along` is the unit chord from
// the true C7 to the true L4, `view` the left camera's optical axis made
// perpendicular to it (the camera looks down on the back), `across` =
// view x along (toward the subject's left for a prone subject seen from
// above). A level's error is its pixel's surface point minus the true level
// point in those directions; the spine line's is the distance, across, from
// CECT's midline points to the true midline, both seen along `view`.
#include "massage_cell/cect/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "stats_detail.h"  // median, quantile

namespace massage_cell::cect {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct BodyAxes {
  Eigen::Vector3d along, across, view;
};

bool bodyAxes(const BackTruth& truth, BodyAxes* axes) {
  const auto c7 = truth.levels.find("C7"), l4 = truth.levels.find("L4");
  if (c7 == truth.levels.end() || l4 == truth.levels.end()) return false;
  const Eigen::Vector3d chord = l4->second - c7->second;
  if (!(chord.norm() > 0.0)) return false;
  axes->along = chord.normalized();
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ() - axes->along.z() * axes->along;
  if (!(view.norm() > 1e-6)) return false;  // the body along the optical axis: no view from above
  axes->view = view.normalized();
  // The camera's z points down at the back, the image's y toward the feet (head up): view x along points to the
  // subject's left (the image's left). Turned views keep the handedness.
  axes->across = axes->view.cross(axes->along);
  return true;
}

/// The 3D point a rectified pixel stands for: the true surface there, else its ray where it meets the plane through
/// `reference` facing the camera (a pixel off the body: the error it makes is still measured).
Eigen::Vector3d pointAt(const cv::Point2f& pixel, const Eigen::Vector3d& reference, const camera::StereoModel& geometry,
                        const BackTruth& truth, const BodyAxes& axes) {
  Eigen::Vector3d p;
  if (truth.surface && truth.surface(pixel, &p)) return p;
  const Eigen::Vector3d ray = geometry.triangulate(pixel.x, pixel.y, geometry.disparityAtDepth(1.0));
  const double denom = ray.dot(axes.view);
  if (!(std::abs(denom) > 1e-9)) return Eigen::Vector3d::Constant(kNaN);
  return ray * (reference.dot(axes.view) / denom);
}

/// Signed distance across the body from `p` to the polyline `line`, both seen along `view`.
double acrossDistance(const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& line, const BodyAxes& axes) {
  auto flat = [&](const Eigen::Vector3d& q) { return Eigen::Vector2d(q.dot(axes.along), q.dot(axes.across)); };
  const Eigen::Vector2d x = flat(p);
  double best = kNaN, best_d2 = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d a = flat(line[i]), b = flat(line[i + 1]);
    const Eigen::Vector2d ab = b - a;
    const double t = ab.squaredNorm() > 0.0 ? std::clamp((x - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const Eigen::Vector2d q = a + t * ab;
    const double d2 = (x - q).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = x.y() - q.y();
    }
  }
  return best;
}

std::vector<LevelError> scoreLevels(const LocatedAcupoints& result, const AcupointModel& model,
                                    const camera::StereoModel& geometry, const BackTruth& truth, const BodyAxes& axes) {
  std::vector<LevelError> out;
  for (const std::string& level : scoredLevels()) {
    LevelError e;
    e.level = level;
    const auto t = truth.levels.find(level);
    if (result.landmarks.valid && t != truth.levels.end() && model.level_fraction.count(level)) {
      const Eigen::Vector3d p = pointAt(levelPixel(result.landmarks, model, level), t->second, geometry, truth, axes);
      if (p.allFinite()) {
        e.scored = true;
        e.along_mm = 1000.0 * (p - t->second).dot(axes.along);
        e.across_mm = 1000.0 * (p - t->second).dot(axes.across);
      }
    }
    out.push_back(e);
  }
  return out;
}

double scoreMidline(const BackLandmarks& lm, const camera::StereoModel& geometry, const BackTruth& truth,
                    const BodyAxes& axes) {
  if (!lm.valid || truth.midline.size() < 2) return kNaN;
  const Eigen::Vector3d reference = truth.levels.at("C7");
  double sum = 0.0;
  int n = 0;
  for (const cv::Point2f& m : lm.midline) {
    if (m.y < lm.c7.body.y || m.y > lm.l4.body.y) continue;
    const Eigen::Vector3d p = pointAt(toImage(lm, m), reference, geometry, truth, axes);
    const double d = p.allFinite() ? acrossDistance(p, truth.midline, axes) : kNaN;
    if (!std::isfinite(d)) continue;
    sum += std::abs(d);
    ++n;
  }
  return n ? 1000.0 * sum / n : kNaN;
}

}  // namespace

const std::vector<std::string>& scoredLevels() {
  static const std::vector<std::string> levels{"C7", "T7", "L4"};
  return levels;
}

bool PairScore::farOff(double limit_mm) const { return worst_level_mm > limit_mm || midline_across_mm > limit_mm; }

bool PairScore::wronglyTrusted(double limit_mm) const { return published && farOff(limit_mm); }

PairScore scorePair(const LocatedAcupoints& result, const AcupointModel& model, const camera::StereoModel& geometry,
                    const BackTruth& truth) {
  PairScore s;
  s.landmarks = result.landmarks.valid;
  s.published = result.valid;
  s.reason = result.reason;
  s.worst_level_mm = s.midline_across_mm = kNaN;
  BodyAxes axes;
  const bool have_axes = bodyAxes(truth, &axes);
  if (have_axes) {
    s.levels = scoreLevels(result, model, geometry, truth, axes);
    for (const LevelError& e : s.levels)
      if (e.scored)
        s.worst_level_mm =
            std::isnan(s.worst_level_mm) ? std::abs(e.along_mm) : std::max(s.worst_level_mm, std::abs(e.along_mm));
    s.midline_across_mm = scoreMidline(result.landmarks, geometry, truth, axes);
  }
  for (const LocatedAcupoint& a : result.points) {
    const auto t = truth.acupoints_in_view.find(a.name);
    if (t == truth.acupoints_in_view.end()) {
      s.valid_out_of_view += a.valid ? 1 : 0;
      continue;
    }
    ++s.in_view;
    s.valid_in_view += a.valid ? 1 : 0;
    if (!a.placed || !have_axes) continue;
    const Eigen::Vector3d p = pointAt(a.rectified, t->second, geometry, truth, axes);
    if (p.allFinite()) s.layout_mm[a.name] = 1000.0 * (p - t->second).norm();
  }
  return s;
}

Spread spreadOf(const std::vector<double>& values) {
  Spread s;
  std::vector<double> v;
  for (double x : values)
    if (std::isfinite(x)) v.push_back(std::abs(x));
  s.count = static_cast<int>(v.size());
  if (v.empty()) {
    s.mean = s.p95 = s.max = s.median = kNaN;
    return s;
  }
  double sum = 0.0;
  for (double x : v) sum += x;
  s.mean = sum / static_cast<double>(v.size());
  s.p95 = detail::quantile(v, 0.95, detail::QuantileIndex::kNearestRank);
  s.max = *std::max_element(v.begin(), v.end());
  s.median = detail::median(v, detail::EvenCount::kUpperMiddle);
  return s;
}

double ScoreSummary::placedShare() const { return in_view ? static_cast<double>(valid_in_view) / in_view : 0.0; }

ScoreSummary summarise(const std::vector<PairScore>& pairs) {
  ScoreSummary out;
  std::map<std::string, std::vector<double>> levels;
  std::vector<double> worst, midline, layout;
  for (const PairScore& p : pairs) {
    ++out.pairs;
    if (!p.published) {
      ++out.refused;
      out.refused_wrong += p.farOff() ? 1 : 0;
      continue;
    }
    ++out.published;
    out.wrongly_trusted += p.wronglyTrusted() ? 1 : 0;
    for (const LevelError& e : p.levels)
      if (e.scored) levels[e.level].push_back(e.along_mm);
    worst.push_back(p.worst_level_mm);
    midline.push_back(p.midline_across_mm);
    for (const auto& [name, mm] : p.layout_mm) layout.push_back(mm);
    out.in_view += p.in_view;
    out.valid_in_view += p.valid_in_view;
    out.valid_out_of_view += p.valid_out_of_view;
  }
  for (const std::string& level : scoredLevels()) out.levels[level] = spreadOf(levels[level]);
  out.worst_level = spreadOf(worst);
  out.midline_across = spreadOf(midline);
  out.layout = spreadOf(layout);
  return out;
}

}  // namespace massage_cell::cect
