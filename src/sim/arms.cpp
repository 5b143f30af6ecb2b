// The subject's arms as swept tubes (cell_scene.h): lying along the trunk,
// touching the flank or abducted about the shoulder, or raised beside the head.
//
// An arm is one tube from inside the back's shoulder (where it starts at
// half size below the skin, so that it emerges from the trunk without a gap
// or a visible end) to the fingertips: upper arm, elbow, forearm, wrist and a
// flattened hand, radii scaled with the build, resting on the table (its
// centre at z = b). Along the trunk the centre line is put where the tube
// just touches the trunk (minus a few mm: soft tissue pressed together),
// then the whole arm is turned about the shoulder by the abduction angle
// and, if the hand would leave the table, the elbow bends it back.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/scene_builder.h"
#include "shape_math.h"

namespace massage_cell::sim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kStep = 0.005;         // metres between rings
constexpr double kPressed = 0.008;      // arm and flank pressed into each other when touching
constexpr double kTableMargin = 0.015;  // the hand stays this far inside the table's edge

struct ArmDims {
  double upper, fore, hand;  // segment lengths
  double r_upper, r_fore;    // mid radii
  double hand_a, hand_b;     // palm half width and half thickness
  double end() const { return upper + fore + hand; }
};

ArmDims armDims(const BodyParameters& b) {
  const double k = b.torso_length / 0.5;
  // Girth from the build: the waist relative to the shoulders grows with BMI.
  const double girth = std::clamp((b.waist_width / b.shoulder_width - 0.55) / 0.45, 0.0, 1.0);
  ArmDims d;
  d.upper = 0.30 * k;
  d.fore = 0.255 * k;
  d.hand = 0.18 * k;
  d.r_upper = (0.045 + 0.015 * girth) * std::sqrt(k);
  d.r_fore = (0.035 + 0.010 * girth) * std::sqrt(k);
  d.hand_a = 0.043 * std::sqrt(k);
  d.hand_b = 0.013 + 0.004 * girth;
  return d;
}

constexpr double kEmerge = 0.07;  // the arm grows from half its size inside the shoulder over this length

Eigen::Vector2d sectionKnots(const ArmDims& d, double s);

/// Semi-axes (a: half width, b: half height) of the arm at arc length s; it
/// starts at half size deep inside the shoulder so that it emerges from the
/// trunk without a visible end.
Eigen::Vector2d armSection(const ArmDims& d, double s) {
  return (0.5 + 0.5 * smooth5(0.0, kEmerge, s)) * sectionKnots(d, s);
}

Eigen::Vector2d sectionKnots(const ArmDims& d, double s) {
  const double e = d.upper, w = d.upper + d.fore;
  const double wrist_a = 0.78 * d.r_fore, wrist_b = 0.55 * d.r_fore;
  struct Knot {
    double s, a, b;
  };
  const Knot knots[] = {{0.0, 1.02 * d.r_upper, 0.98 * d.r_upper},
                        {0.45 * e, 1.04 * d.r_upper, 0.95 * d.r_upper},
                        {e - 0.03, 0.90 * d.r_upper, 0.80 * d.r_upper},
                        {e, 0.86 * d.r_upper, 0.76 * d.r_upper},
                        {e + 0.3 * d.fore, 1.06 * d.r_fore, 0.90 * d.r_fore},
                        {w, wrist_a, wrist_b},
                        {w + 0.35 * d.hand, d.hand_a, d.hand_b},
                        {w + 0.75 * d.hand, 0.92 * d.hand_a, 0.8 * d.hand_b},
                        {d.end(), 0.8 * d.hand_a, 0.7 * d.hand_b}};
  const std::size_t n = sizeof(knots) / sizeof(knots[0]);
  if (s <= knots[0].s) return {knots[0].a, knots[0].b};
  for (std::size_t i = 0; i + 1 < n; ++i) {
    if (s <= knots[i + 1].s) {
      const double t = smooth5(knots[i].s, knots[i + 1].s, s);
      return {knots[i].a + t * (knots[i + 1].a - knots[i].a), knots[i].b + t * (knots[i + 1].b - knots[i].b)};
    }
  }
  return {knots[n - 1].a, knots[n - 1].b};
}

/// What the arm lies against: the trunk, but above the chest (T8) only its
/// rib cage, inside the back's outline: that outline holds the deltoids (the
/// arm's top) and the latissimus over the arm's inner side.
struct ArmRest {
  const TrunkSurface& trunk;
  double chest_x, chest_hw;
  static constexpr double kInset = 0.015;  // the rib cage inside the back's outline at T8 and above
  double halfWidth(double x) const {
    const double hw = trunk.halfWidth(x);
    const double inset = kInset * smooth5(chest_x - 0.08, chest_x, x);  // continuous below T8
    return (x > chest_x ? std::min(hw, chest_hw) : hw) - inset;
  }
};

/// Lateral distance from the midline (|y|) at which a tube with semi-axes
/// (a, b) centred at height zc just touches the arm's rest at x; NaN where
/// the trunk does not reach x.
double touchingLateral(const ArmRest& rest, int side, double x, double a, double b, double zc) {
  const TrunkSurface& trunk = rest.trunk;
  const double hw = rest.halfWidth(x);
  if (!(hw > 0.0)) return kNaN;
  // At least beside the outline: the trunk's flank meets the table there
  // (steeply), where a tube lower than the sampled profile still touches it.
  double best = hw + a;
  constexpr int kSamples = 40;
  for (int j = 0; j <= kSamples; ++j) {
    const double l = hw * (0.35 + 0.65 * j / kSamples);
    const double z = j == kSamples ? 0.0 : trunk.height(x, side * l);
    const double dz = (z - zc) / b;
    if (std::abs(dz) < 1.0) best = std::max(best, l + a * std::sqrt(1.0 - dz * dz));
  }
  return best;
}

/// Where the arm's tube starts: inside the back's shoulder, a little medial
/// and caudal of the acromion, below the skin.
Eigen::Vector3d shoulderJoint(const BackModel& back, const TrunkSurface& trunk, int side, double b0) {
  const Eigen::Vector3d acromion = back.landmarks().at(side > 0 ? "acromion_L" : "acromion_R");
  Eigen::Vector3d s(acromion.x() - 0.04, acromion.y() - side * 0.02, 0.0);
  s.z() = std::max(b0, trunk.height(s.x(), s.y()) - b0 - 0.006);
  return s;
}

double centreHeight(const ArmDims& d, const Eigen::Vector3d& shoulder, double b0, double s) {
  const double b = sectionKnots(d, s).y();
  return b + (shoulder.z() - b0) * (1.0 - smooth5(0.0, 0.55 * d.upper, s));
}

/// Path in the table plane touching the trunk: marches caudally from the
/// shoulder, steering (at most 35 degrees off -x) toward the touching line.
std::vector<Eigen::Vector2d> touchingPath(const ArmDims& d, const ArmRest& rest, int side,
                                          const Eigen::Vector3d& shoulder, double b0) {
  std::vector<Eigen::Vector2d> path{shoulder.head<2>()};
  const int steps = static_cast<int>(std::ceil(d.end() / kStep));
  double lateral = side * shoulder.y();
  for (int i = 1; i <= steps; ++i) {
    const double s = std::min(i * kStep, d.end());
    const Eigen::Vector2d p = path.back();
    const Eigen::Vector2d ab = armSection(d, s);
    const double touch = touchingLateral(rest, side, p.x() - kStep, ab.x(), ab.y(), centreHeight(d, shoulder, b0, s));
    if (std::isfinite(touch)) {
      const double w = smooth5(0.0, 0.45 * d.upper, s);
      lateral = (1.0 - w) * side * shoulder.y() + w * (touch - kPressed);
    }
    const double dl = std::clamp(lateral - side * p.y(), -0.7 * kStep, 0.7 * kStep);
    const Eigen::Vector2d dir = Eigen::Vector2d(-kStep, side * dl).normalized();
    path.push_back(p + (s - (i - 1) * kStep) * dir);
  }
  return path;
}

void rotateAbout(std::vector<Eigen::Vector2d>& path, std::size_t from, const Eigen::Vector2d& pivot, double angle) {
  const Eigen::Rotation2Dd r(angle);
  for (std::size_t i = from; i < path.size(); ++i) path[i] = pivot + r * (path[i] - pivot);
}

/// Bends the forearm and hand about the elbow toward the trunk until the hand lies on the table.
void keepHandOnTable(std::vector<Eigen::Vector2d>& path, const ArmDims& d, int side) {
  const std::size_t elbow = std::min(path.size() - 1, static_cast<std::size_t>(d.upper / kStep));
  auto overhang = [&](const std::vector<Eigen::Vector2d>& p) {
    double worst = -1.0;
    for (std::size_t i = elbow; i < p.size(); ++i) {
      const double a = armSection(d, static_cast<double>(i) * kStep).x();
      worst = std::max(worst, std::abs(p[i].y()) + a - (kTableHalfWidth - kTableMargin));
    }
    return worst;
  };
  if (overhang(path) <= 0.0) return;
  double lo = 0.0, hi = 1.5;
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    std::vector<Eigen::Vector2d> trial = path;
    rotateAbout(trial, elbow + 1, path[elbow], side * mid);
    (overhang(trial) > 0.0 ? lo : hi) = mid;
  }
  rotateAbout(path, elbow + 1, path[elbow], side * hi);
}

std::vector<Eigen::Vector2d> alongTrunkPath(const ArmDims& d, const ArmRest& rest, int side,
                                            const Eigen::Vector3d& shoulder, double b0, double abduction) {
  std::vector<Eigen::Vector2d> path = touchingPath(d, rest, side, shoulder, b0);
  rotateAbout(path, 1, shoulder.head<2>(), -side * abduction);
  keepHandOnTable(path, d, side);
  // Never into the trunk: push out to the touching line where the arm rests.
  for (std::size_t i = 1; i < path.size(); ++i) {
    const double s = static_cast<double>(i) * kStep;
    if (s < 0.45 * d.upper) continue;
    const Eigen::Vector2d ab = armSection(d, s);
    const double touch = touchingLateral(rest, side, path[i].x(), ab.x(), ab.y(), centreHeight(d, shoulder, b0, s));
    if (std::isfinite(touch) && side * path[i].y() < touch - kPressed) path[i].y() = side * (touch - kPressed);
  }
  return path;
}

/// Points every `step` metres of arc length along a polyline (its first point kept).
std::vector<Eigen::Vector2d> resampled(const std::vector<Eigen::Vector2d>& points, double step) {
  std::vector<Eigen::Vector2d> out{points.front()};
  double need = step;  // arc length still to go to the next output point
  for (std::size_t i = 1; i < points.size(); ++i) {
    Eigen::Vector2d a = points[i - 1];
    const Eigen::Vector2d& b = points[i];
    double len = (b - a).norm();
    while (len >= need && len > 0.0) {
      a += (b - a) * (need / len);
      out.push_back(a);
      len = (b - a).norm();
      need = step;
    }
    need -= len;
  }
  return out;
}

/// Upper arm cranially and outward, elbow bent, forearm and hand cranially
/// and a little inward beside the face cradle; corners rounded.
std::vector<Eigen::Vector2d> raisedPath(const ArmDims& d, int side, const Eigen::Vector3d& shoulder) {
  const Eigen::Vector2d s0 = shoulder.head<2>();
  const Eigen::Vector2d e = s0 + d.upper * Eigen::Vector2d(std::cos(0.85), side * std::sin(0.85));
  const Eigen::Vector2d w = e + d.fore * Eigen::Vector2d(std::cos(0.42), -side * std::sin(0.42));
  const Eigen::Vector2d t = w + d.hand * Eigen::Vector2d(std::cos(0.30), -side * std::sin(0.30));
  std::vector<Eigen::Vector2d> raw;
  const Eigen::Vector2d corners[] = {s0, e, w, t};
  for (int k = 0; k < 3; ++k) {
    const int n = std::max(1, static_cast<int>(std::ceil((corners[k + 1] - corners[k]).norm() / 0.002)));
    for (int i = 0; i < n; ++i)
      raw.push_back(corners[k] + (corners[k + 1] - corners[k]) * (static_cast<double>(i) / n));
  }
  raw.push_back(t);
  // Round the elbow and wrist: moving average over +-3 cm (ends kept).
  std::vector<Eigen::Vector2d> smooth = raw;
  const int half = 15;
  for (int i = 0; i < static_cast<int>(raw.size()); ++i) {
    const int h = std::min({half, i, static_cast<int>(raw.size()) - 1 - i});
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    for (int j = i - h; j <= i + h; ++j) sum += raw[static_cast<std::size_t>(j)];
    smooth[static_cast<std::size_t>(i)] = sum / (2 * h + 1);
  }
  return resampled(smooth, kStep);
}

}  // namespace

std::vector<TubeRing> armRings(const BackModel& back, const TrunkSurface& trunk, ArmPose pose, int side,
                               double abduction) {
  if (side != 1 && side != -1) throw std::invalid_argument("armRings: side must be +1 (left) or -1 (right)");
  if (pose == ArmPose::kNone) return {};
  const ArmDims d = armDims(back.body());
  const double b0 = sectionKnots(d, 0.0).y();  // full size: the tube's top stays below the shoulder's skin
  const Eigen::Vector3d shoulder = shoulderJoint(back, trunk, side, b0);
  const double chest_x = back.levelX("T8");
  const ArmRest rest{trunk, chest_x, trunk.halfWidth(chest_x)};
  const std::vector<Eigen::Vector2d> path =
      pose == ArmPose::kRaised ? raisedPath(d, side, shoulder) : alongTrunkPath(d, rest, side, shoulder, b0, abduction);
  std::vector<TubeRing> rings;
  const double last = d.end() - 0.45 * armSection(d, d.end()).sum();  // the end cap reaches the fingertips
  for (std::size_t i = 0; i < path.size(); ++i) {
    const double s = static_cast<double>(i) * kStep;
    if (s > last) break;
    const Eigen::Vector2d ab = armSection(d, s);
    rings.push_back({Eigen::Vector3d(path[i].x(), path[i].y(), centreHeight(d, shoulder, b0, s)), ab.x(), ab.y()});
  }
  return rings;
}

double tubeTopAt(const std::vector<TubeRing>& rings, double x, double y) {
  double top = -std::numeric_limits<double>::infinity();
  const Eigen::Vector2d q(x, y);
  for (std::size_t i = 0; i + 1 < rings.size(); ++i) {
    const Eigen::Vector2d p0 = rings[i].centre.head<2>(), p1 = rings[i + 1].centre.head<2>();
    const Eigen::Vector2d d = p1 - p0;
    const double len2 = d.squaredNorm();
    if (!(len2 > 0.0)) continue;
    const double t = (q - p0).dot(d) / len2;
    if (t < 0.0 || t > 1.0) continue;
    const double dist = (q - (p0 + t * d)).norm();
    const double a = rings[i].a + t * (rings[i + 1].a - rings[i].a);
    if (dist >= a) continue;
    const double b = rings[i].b + t * (rings[i + 1].b - rings[i].b);
    const double z = rings[i].centre.z() + t * (rings[i + 1].centre.z() - rings[i].centre.z());
    top = std::max(top, z + b * std::sqrt(1.0 - (dist / a) * (dist / a)));
  }
  return top;
}

}  // namespace massage_cell::sim
