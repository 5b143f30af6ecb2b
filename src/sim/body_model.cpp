// Parametric prone human back: outline, height field, anatomical landmarks,
// vertebral levels, acupoints (shared/reference/back_acupoints.md) and the skin
// mesh the renderer ray-casts. Eigen + std only.
//
// Shape model (all lengths in metres, frame `table`, x cranial, y left, z up):
//   height(x, y) = E(x) * P(s; x) * T(x, y, s),   s = y / halfWidth(x) in [-1, 1]
// with
//   E(x)     end caps: 1 over the back, falling like a quarter circle to the
//            table over the last 2 cm at the neck base and 3 cm at the buttocks;
//   P(s; x)  the cross-section (1 - |s|^n)^e: flat top, rounded flanks that meet
//            the table at the outline (e = 0.5: vertical tangent); boxier over
//            the shoulders (larger n) and tapering (e -> 1) in the corner where
//            the outline turns from the neck into the shoulders;
//   T        the crest height: back_height with the thoracic kyphosis hump, the
//            lumbar lordosis dip, the neck falling toward the head, the upper
//            buttocks, plus the local features (spine groove between the
//            paraspinal ridges, the scapulae, the C7 spinous process, the
//            shoulder slope) and breathing.
// Every term is C1 (most are C2) inside the outline.
#include "massage_cell/sim/body_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include "shape_math.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kLevelCount = 18;  // C7, T1..T12, L1..L5

// Indices into the level table.
constexpr int kC7 = 0;
constexpr int kT1 = 1;
constexpr int kT2 = 2;
constexpr int kT3 = 3;
constexpr int kT4 = 4;
constexpr int kT5 = 5;
constexpr int kT6 = 6;
constexpr int kT7 = 7;
constexpr int kT8 = 8;
constexpr int kT11 = 11;
constexpr int kT12 = 12;
constexpr int kL1 = 13;
constexpr int kL2 = 14;
constexpr int kL3 = 15;
constexpr int kL4 = 16;
constexpr int kL5 = 17;

constexpr double kNeckBaseX = 0.035;  // x_max: the neck base (head side end of the model)
constexpr double kBelowL4 = 0.12;     // x_min = -(torso_length + kBelowL4): upper buttocks
constexpr double kNeckCap = 0.02;     // length of the end cap at the neck
constexpr double kButtockCap = 0.03;  // length of the end cap at the buttocks

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double softplus(double t) { return t > 30.0 ? t : std::log1p(std::exp(t)); }

/// Uniform [0, 1) from a Mersenne twister (fully specified, portable).
double unit(std::mt19937& rng) { return static_cast<double>(rng()) / 4294967296.0; }
double uniform(std::mt19937& rng, double lo, double hi) { return lo + (hi - lo) * unit(rng); }

/// Nominal distances between consecutive spinous processes (lower borders),
/// C7->T1, T1->T2, ..., L4->L5, in cm: short upper thoracic, growing down
/// the thoracic spine, ~3.5 cm lumbar. Scaled so that C7->L4 = torso_length.
const std::array<double, kLevelCount - 1>& nominalIntervals() {
  static const std::array<double, kLevelCount - 1> intervals = [] {
    std::array<double, kLevelCount - 1> a{};
    a[0] = 2.0;                                                                           // C7 -> T1
    for (int k = 1; k <= 11; ++k) a[static_cast<std::size_t>(k)] = 2.2 + 0.05 * (k - 1);  // T1 -> ... -> T12
    a[12] = 3.0;                                                                          // T12 -> L1
    a[13] = 3.4;                                                                          // L1 -> L2
    a[14] = 3.5;                                                                          // L2 -> L3
    a[15] = 3.5;                                                                          // L3 -> L4
    a[16] = 3.4;                                                                          // L4 -> L5
    return a;
  }();
  return intervals;
}

std::array<double, kLevelCount> levelPositions(double torso_length) {
  const auto& iv = nominalIntervals();
  double c7_to_l4 = 0.0;
  for (int k = 0; k < kL4; ++k) c7_to_l4 += iv[static_cast<std::size_t>(k)];
  const double scale = torso_length / c7_to_l4;
  std::array<double, kLevelCount> x{};
  x[0] = 0.0;
  for (int k = 1; k < kLevelCount; ++k) {
    x[static_cast<std::size_t>(k)] = x[static_cast<std::size_t>(k - 1)] - scale * iv[static_cast<std::size_t>(k - 1)];
  }
  x[kL4] = -torso_length;  // exact, free of rounding
  return x;
}

int levelIndex(const std::string& level) {
  const auto& names = vertebralLevels();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == level) return static_cast<int>(i);
  }
  throw std::invalid_argument("unknown vertebral level '" + level + "' (expected C7, T1..T12 or L1..L5)");
}

/// Monotone piecewise cubic Hermite interpolation (Fritsch-Carlson), C1.
class Pchip {
 public:
  void set(std::vector<double> x, std::vector<double> y) {
    x_ = std::move(x);
    y_ = std::move(y);
    const std::size_t n = x_.size();
    d_.assign(n, 0.0);
    std::vector<double> h(n - 1), delta(n - 1);
    for (std::size_t i = 0; i + 1 < n; ++i) {
      h[i] = x_[i + 1] - x_[i];
      delta[i] = (y_[i + 1] - y_[i]) / h[i];
    }
    for (std::size_t i = 1; i + 1 < n; ++i) {
      if (delta[i - 1] * delta[i] <= 0.0) {
        d_[i] = 0.0;
      } else {
        const double w1 = 2.0 * h[i] + h[i - 1], w2 = h[i] + 2.0 * h[i - 1];
        d_[i] = (w1 + w2) / (w1 / delta[i - 1] + w2 / delta[i]);
      }
    }
    auto endSlope = [](double h0, double h1, double d0, double d1) {
      double d = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
      if (d * d0 <= 0.0) return 0.0;
      if (d0 * d1 <= 0.0 && std::abs(d) > std::abs(3.0 * d0)) return 3.0 * d0;
      return d;
    };
    d_[0] = endSlope(h[0], h[1], delta[0], delta[1]);
    d_[n - 1] = endSlope(h[n - 2], h[n - 3], delta[n - 2], delta[n - 3]);
  }

  double operator()(double x) const {
    const auto it = std::upper_bound(x_.begin(), x_.end(), x);
    std::size_t i = it == x_.begin() ? 0 : static_cast<std::size_t>(it - x_.begin()) - 1;
    i = std::min(i, x_.size() - 2);
    const double h = x_[i + 1] - x_[i];
    const double t = (x - x_[i]) / h;
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * y_[i] + (t3 - 2 * t2 + t) * h * d_[i] + (-2 * t3 + 3 * t2) * y_[i + 1] +
           (t3 - t2) * h * d_[i + 1];
  }

 private:
  std::vector<double> x_, y_, d_;
};

/// The x-only terms of the height at one x (one mesh row).
struct Row {
  double x = 0.0;
  double hw = 0.0;          // half-width of the outline
  double cap = 0.0;         // E(x)
  double n = 2.0, e = 0.5;  // cross-section exponents
  double crest = 0.0;       // Hc(x): crest height without the local features
  double buttock = 0.0;     // buttock rise (lateral modulation applied per y)
  double spine = 0.0;       // weight of the spine groove / paraspinal ridges
  double shoulder = 0.0;    // weight of the shoulder slope
  double breath = 0.0;      // breathing rise (metres) at the midline
  double c7 = 0.0;          // C7 spinous process bump (x part)
  double spinous = 0.0;     // spinous process bumps T1..L5 (x part)
  double scap_x = 0.0;      // scapula plate, x part (between superior border and inferior angle)
  bool inside = false;
};

/// Everything derived from the body parameters, evaluated many times.
class Shape {
 public:
  Shape(const BodyParameters& b, double breathing_phase, double breathing_amplitude)
      : b_(b), lx_(levelPositions(b.torso_length)) {
    x_min_ = lx_[kL4] - kBelowL4;
    x_max_ = kNeckBaseX;
    breath_ = breathing_amplitude * 0.5 * (1.0 - std::cos(2.0 * kPi * breathing_phase));

    // Outline knots (ascending x).
    const double neck = 0.5 * b.neck_width;
    shoulder_hw_ = 0.5 * b.shoulder_width + 0.03;  // acromion + deltoid
    const double waist = 0.5 * b.waist_width, hip = 0.5 * b.hip_width;
    const double chest = waist + 0.3 * (shoulder_hw_ - waist);
    outline_.set({x_min_, lx_[kL4], lx_[kL2], lx_[kT8], lx_[kT5], lx_[kT1] - 0.008, 0.0, x_max_ - 0.012, x_max_},
                 {1.02 * hip, 0.98 * hip, waist, chest, chest + 0.35 * (shoulder_hw_ - chest), shoulder_hw_,
                  neck + 0.55 * (shoulder_hw_ - neck), neck + 0.006, neck});

    const double lr = b.lateral_rounding;
    n_body_ = std::clamp(3.6 + 2.0 * (lr - 1.0), 2.6, 5.0);
    e_body_ = std::clamp(0.75 - 0.2 * (lr - 1.0), 0.65, 0.9);

    acromion_x_ = lx_[kT1];
    acromion_y_ = 0.5 * b.shoulder_width - 0.01;

    // Spine groove profile normalised so that ridge(p) - groove(0) = spine_depth.
    groove_norm_ = groove(b.paraspinal_width) - groove(0.0);

    // Scapula geometry (subject's left; mirrored): medial border at |y| = m,
    // superior angle ~T2, inferior angle at T7, lateral border toward the axilla.
    const double m = b.scapula_medial_offset;
    lat0_ = Eigen::Vector2d(lx_[kT7], m + 0.01);
    const Eigen::Vector2d lat1(lx_[kT1], 0.5 * b.shoulder_width - 0.035);
    Eigen::Vector2d dir = (lat1 - lat0_).normalized();
    lat_normal_ = Eigen::Vector2d(dir.y(), -dir.x());  // points medially/caudally
    if (lat_normal_.y() > 0.0) lat_normal_ = -lat_normal_;
    spine0_ = Eigen::Vector2d(lx_[kT3], m + 0.005);
    spine1_ = Eigen::Vector2d(acromion_x_ + 0.005, acromion_y_ - 0.01);
  }

  double xMin() const { return x_min_; }
  double xMax() const { return x_max_; }
  const std::array<double, kLevelCount>& levels() const { return lx_; }
  double acromionX() const { return acromion_x_; }
  double acromionY() const { return acromion_y_; }

  double halfWidth(double x) const {
    if (!(x >= x_min_ && x <= x_max_)) return 0.0;
    return std::max(0.0, outline_(x));
  }

  Row row(double x) const {
    Row r;
    r.x = x;
    if (!(x >= x_min_ && x <= x_max_)) return r;
    r.inside = true;
    r.hw = halfWidth(x);
    const auto& l = lx_;
    // End caps.
    r.cap = 1.0;
    const double t_top = (x - (x_max_ - kNeckCap)) / kNeckCap;
    if (t_top > 0.0) r.cap *= std::max(0.0, 1.0 - t_top * t_top);
    const double t_bot = ((x_min_ + kButtockCap) - x) / kButtockCap;
    if (t_bot > 0.0) r.cap *= std::max(0.0, 1.0 - t_bot * t_bot);
    // Cross-section: boxy over the shoulders, tapering into the neck/shoulder corner.
    r.n = n_body_ + 2.5 * smooth5(l[kT6], l[kT1], x);
    r.e = e_body_ + (1.0 - e_body_) * smooth5(-0.025, 0.005, x);
    // Crest height along x.
    const double kyphosis = smooth5(x_max_, l[kT4], x) * (1.0 - smooth5(l[kT8], l[kL1], x));
    const double lordosis = smooth5(l[kT11], l[kL3], x) * (1.0 - smooth5(l[kL3], x_min_ + 0.02, x));
    const double neck_drop = 0.14 * b_.back_height * smooth5(-0.01, x_max_, x);
    r.crest = b_.back_height + b_.thoracic_curvature * (kyphosis - 1.0) - b_.lumbar_curvature * lordosis - neck_drop;
    r.buttock = b_.buttock_height * smooth5(l[kL5] + 0.01, x_min_ + kButtockCap, x);
    r.spine = smooth5(0.0, l[kT1], x) * (1.0 - smooth5(l[kL5], l[kL5] - 0.04, x));
    r.shoulder = std::tan(b_.shoulder_slope) * smooth5(l[kT5], l[kT1], x);
    r.breath = breath_ * smooth5(0.0, l[kT4], x) * (1.0 - smooth5(l[kT7], l[kL1], x));
    r.c7 = 0.0035 * gauss((x - 0.003) / 0.01);
    if (b_.spinous_prominence > 0.0) {
      for (int k = kT1; k < kLevelCount; ++k) r.spinous += gauss((x - l[static_cast<std::size_t>(k)] - 0.006) / 0.009);
    }
    r.scap_x = smooth5(l[kT7] - 0.015, l[kT7] + 0.015, x) * (1.0 - smooth5(l[kT2] - 0.015, l[kT2] + 0.015, x));
    return r;
  }

  /// Height at lateral coordinate y (s = y / hw) of a row; NaN outside.
  double height(const Row& r, double y) const {
    if (!r.inside || !(std::abs(y) <= r.hw) || r.hw <= 0.0) return kNaN;
    return heightS(r, y / r.hw);
  }

  /// Height at normalised lateral coordinate s in [-1, 1] of a row.
  double heightS(const Row& r, double s) const {
    s = std::clamp(s, -1.0, 1.0);
    const double a = std::abs(s);
    const double base = 1.0 - std::pow(a, r.n);
    if (base <= 0.0 || r.cap <= 0.0) return 0.0;
    const double profile = std::pow(base, r.e);
    return r.cap * profile * top(r, s * r.hw, s);
  }

  double height(double x, double y) const { return height(row(x), y); }

  /// Outward (upward) unit normal at the parametric point (x, s).
  Eigen::Vector3d normal(const Row& r, const Row& r_lo, const Row& r_hi, double s) const {
    const double hs = 1e-6;
    const double s_lo = std::max(-1.0, s - hs), s_hi = std::min(1.0, s + hs);
    const double z_s = (heightS(r, s_hi) - heightS(r, s_lo)) / (s_hi - s_lo);
    const double dx = r_hi.x - r_lo.x;
    const double y_x = s * (r_hi.hw - r_lo.hw) / dx;
    const double z_x = (heightS(r_hi, s) - heightS(r_lo, s)) / dx;
    const Eigen::Vector3d t_x(1.0, y_x, z_x), t_s(0.0, r.hw, z_s);
    Eigen::Vector3d n = t_x.cross(t_s);
    const double len = n.norm();
    if (!(len > 0.0) || !std::isfinite(len)) return Eigen::Vector3d::UnitZ();
    return n / len;
  }

 private:
  double groove(double y) const {
    const double p = b_.paraspinal_width;
    return -gauss(y / (0.5 * p)) + 0.35 * (gauss((y - p) / (0.8 * p)) + gauss((y + p) / (0.8 * p)));
  }

  double top(const Row& r, double y, double s) const {
    double t = r.crest;
    if (r.buttock > 0.0) t += r.buttock * (0.72 + 0.28 * (gauss((s - 0.45) / 0.22) + gauss((s + 0.45) / 0.22)));
    if (r.spine > 0.0 && b_.spine_depth > 0.0) t += b_.spine_depth / groove_norm_ * r.spine * groove(y);
    if (r.c7 > 0.0) t += r.c7 * gauss(y / 0.012);
    if (r.spinous > 0.0) t += b_.spinous_prominence * r.spine * r.spinous * gauss(y / 0.008);
    const double ay = std::abs(y);
    if (r.shoulder > 0.0) {
      const double w = 0.015;
      const double radial = std::sqrt(y * y + 1e-6);
      t -= r.shoulder * w * softplus((radial - 0.5 * b_.neck_width) / w);
    }
    if (r.scap_x > 0.0 && b_.scapula_prominence > 0.0) {
      const double m = b_.scapula_medial_offset;
      const Eigen::Vector2d q(r.x, ay);
      const double medial = smooth5(m - 0.012, m + 0.012, ay);
      const double lateral = smooth5(-0.015, 0.015, (q - lat0_).dot(lat_normal_));
      const double slope = 1.0 - 0.4 * smooth5(m, m + 0.09, ay);
      t += b_.scapula_prominence * r.scap_x * medial * lateral * slope;
    }
    if (b_.scapula_prominence > 0.0) {
      // Spine of the scapula: a low ridge from its root (~T3) toward the acromion.
      const Eigen::Vector2d q(r.x, ay), d = spine1_ - spine0_;
      const double u = std::clamp((q - spine0_).dot(d) / d.squaredNorm(), 0.0, 1.0);
      const double dist = (q - (spine0_ + u * d)).norm();
      t += 0.5 * b_.scapula_prominence * gauss(dist / 0.012);
    }
    if (r.breath != 0.0) t += r.breath * (1.0 - s * s);
    return t;
  }

  BodyParameters b_;
  std::array<double, kLevelCount> lx_;
  double x_min_ = 0.0, x_max_ = 0.0;
  double breath_ = 0.0;
  Pchip outline_;
  double shoulder_hw_ = 0.0;
  double n_body_ = 2.6, e_body_ = 0.5;
  double acromion_x_ = 0.0, acromion_y_ = 0.0;
  double groove_norm_ = 1.0;
  Eigen::Vector2d lat0_, lat_normal_, spine0_, spine1_;
};

}  // namespace

// ---------------------------------------------------------------------------
// BodyParameters

BodyParameters BodyParameters::mean() { return BodyParameters{}; }

BodyParameters BodyParameters::subject(int index, std::uint32_t seed) {
  if (index < 0 || index > 28) {
    throw std::invalid_argument("subject index " + std::to_string(index) + " is not in 0..28");
  }
  BodyParameters p = mean();
  if (index == 0) return p;

  // Skin tones: a permutation of 28 strata over the light..dark range, so the
  // 28 subjects cover it evenly; which subject gets which tone depends on seed.
  std::array<int, 28> strata{};
  for (int i = 0; i < 28; ++i) strata[static_cast<std::size_t>(i)] = i;
  {
    std::seed_seq seq{seed, 0x746f6e65u};
    std::mt19937 perm(seq);
    for (int i = 27; i > 0; --i) {
      const int j = static_cast<int>(perm() % static_cast<std::uint32_t>(i + 1));
      std::swap(strata[static_cast<std::size_t>(i)], strata[static_cast<std::size_t>(j)]);
    }
  }

  std::seed_seq seq{seed, static_cast<std::uint32_t>(index), 0x626f6479u};
  std::mt19937 rng(seq);
  const double size = uniform(rng, -1.0, 1.0);  // shared: big people are big all over
  auto vary = [&](double mean_value, double fraction) {
    const double v = std::clamp(0.5 * size + 0.5 * uniform(rng, -1.0, 1.0), -1.0, 1.0);
    return mean_value * (1.0 + fraction * v);
  };
  p.shoulder_width = vary(p.shoulder_width, 0.12);
  p.waist_width = vary(p.waist_width, 0.12);
  p.hip_width = vary(p.hip_width, 0.12);
  p.waist_width = std::min({p.waist_width, 0.97 * p.hip_width, 0.8 * p.shoulder_width});
  p.neck_width = vary(p.neck_width, 0.10);
  p.torso_length = vary(p.torso_length, 0.10);
  p.back_height = p.back_height * (1.0 + 0.15 * uniform(rng, -1.0, 1.0));
  p.lateral_rounding = uniform(rng, 0.7, 1.45);
  p.thoracic_curvature = p.thoracic_curvature * uniform(rng, 0.5, 1.5);
  p.lumbar_curvature = p.lumbar_curvature * uniform(rng, 0.5, 1.6);
  p.spine_depth = uniform(rng, 0.003, 0.010);
  p.paraspinal_width = uniform(rng, 0.028, 0.043);
  p.scapula_prominence = uniform(rng, 0.002, 0.011);
  p.scapula_medial_offset = 0.075 * (p.shoulder_width / 0.44) * (1.0 + 0.05 * uniform(rng, -1.0, 1.0));
  p.shoulder_slope = uniform(rng, 0.15, 0.35);
  p.buttock_height = uniform(rng, 0.03, 0.075);

  // Linear-RGB skin albedos from very light to very dark.
  static const std::array<Eigen::Vector3d, 7> tones = {
      Eigen::Vector3d(0.84, 0.64, 0.54), Eigen::Vector3d(0.78, 0.57, 0.47), Eigen::Vector3d(0.66, 0.45, 0.34),
      Eigen::Vector3d(0.52, 0.33, 0.23), Eigen::Vector3d(0.37, 0.22, 0.14), Eigen::Vector3d(0.23, 0.13, 0.085),
      Eigen::Vector3d(0.12, 0.07, 0.05)};
  const double t = (strata[static_cast<std::size_t>(index - 1)] + unit(rng)) / 28.0 * (tones.size() - 1);
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(t), tones.size() - 2);
  const double f = t - static_cast<double>(k);
  Eigen::Vector3d albedo = (1.0 - f) * tones[k] + f * tones[k + 1];
  // Hue jitter: a little more red/yellow or more pink, same brightness.
  const double warm = uniform(rng, -0.06, 0.06), pink = uniform(rng, -0.05, 0.05);
  albedo = albedo.cwiseProduct(Eigen::Vector3d(1.0 + pink, 1.0 + warm - pink, 1.0 - warm));
  p.skin_albedo = albedo.cwiseMax(0.01).cwiseMin(0.95).cast<float>();

  p.moles = static_cast<int>(rng() % 9u);
  p.skin_seed = rng();
  p.validate();
  return p;
}

void BodyParameters::validate() const {
  auto check = [](const char* name, double v, double lo, double hi, const char* unit_text) {
    if (!(v >= lo && v <= hi)) {
      throw std::invalid_argument(std::string("BodyParameters: ") + name + " = " + num(v) +
                                  " is implausible (expected " + num(lo) + " .. " + num(hi) + unit_text + ")");
    }
  };
  check("shoulder_width", shoulder_width, 0.25, 0.75, " m");
  check("waist_width", waist_width, 0.15, 0.70, " m");
  check("hip_width", hip_width, 0.18, 1.0, " m");
  check("torso_length", torso_length, 0.30, 0.80, " m");
  check("neck_width", neck_width, 0.06, 0.25, " m");
  check("back_height", back_height, 0.08, 0.45, " m");
  check("lateral_rounding", lateral_rounding, 0.3, 2.5, "");
  check("thoracic_curvature", thoracic_curvature, 0.0, 0.08, " m");
  check("lumbar_curvature", lumbar_curvature, 0.0, 0.08, " m");
  check("spine_depth", spine_depth, 0.0, 0.03, " m");
  check("paraspinal_width", paraspinal_width, 0.01, 0.08, " m");
  check("scapula_prominence", scapula_prominence, 0.0, 0.03, " m");
  check("scapula_medial_offset", scapula_medial_offset, 0.03, 0.15, " m");
  check("shoulder_slope", shoulder_slope, 0.0, 0.7, " rad");
  check("buttock_height", buttock_height, 0.0, 0.15, " m");
  check("spinous_prominence", spinous_prominence, 0.0, 0.015, " m");
  for (int c = 0; c < 3; ++c) check("skin_albedo", skin_albedo[c], 0.0, 1.0, "");
  check("moles", moles, 0, 64, "");
  // Relations between the values.
  // Obese builds may be a little wider at the waist than across the acromions.
  if (!(waist_width <= 1.1 * shoulder_width)) {
    throw std::invalid_argument("BodyParameters: waist_width = " + num(waist_width) +
                                " is implausible (more than 1.1 * shoulder_width = " + num(1.1 * shoulder_width) + ")");
  }
  if (!(neck_width <= 0.6 * shoulder_width)) {
    throw std::invalid_argument("BodyParameters: neck_width = " + num(neck_width) +
                                " is implausible (more than 0.6 * shoulder_width)");
  }
  if (!(scapula_medial_offset <= 0.5 * shoulder_width - 0.06)) {
    throw std::invalid_argument("BodyParameters: scapula_medial_offset = " + num(scapula_medial_offset) +
                                " is implausible (scapula would not fit in shoulder_width = " + num(shoulder_width) +
                                ")");
  }
  if (!(scapula_medial_offset <= 0.5 * waist_width - 0.03)) {
    throw std::invalid_argument(
        "BodyParameters: scapula_medial_offset = " + num(scapula_medial_offset) +
        " is implausible (3 cun lateral points would leave the waist_width = " + num(waist_width) + ")");
  }
  if (!(thoracic_curvature + lumbar_curvature + spine_depth <= 0.5 * back_height)) {
    throw std::invalid_argument("BodyParameters: thoracic_curvature + lumbar_curvature + spine_depth = " +
                                num(thoracic_curvature + lumbar_curvature + spine_depth) +
                                " is implausible for back_height = " + num(back_height));
  }
}

const std::vector<std::string>& vertebralLevels() {
  static const std::vector<std::string> names = {"C7", "T1",  "T2",  "T3",  "T4", "T5", "T6", "T7", "T8",
                                                 "T9", "T10", "T11", "T12", "L1", "L2", "L3", "L4", "L5"};
  return names;
}

// ---------------------------------------------------------------------------
// BackModel

BackModel::BackModel(const BodyParameters& body, double breathing_phase, double breathing_amplitude)
    : body_(body), breathing_phase_(breathing_phase), breathing_amplitude_(breathing_amplitude) {
  body_.validate();
  if (!std::isfinite(breathing_phase)) throw std::invalid_argument("BackModel: breathing_phase must be finite");
  if (!(breathing_amplitude >= 0.0 && breathing_amplitude <= 0.05)) {
    throw std::invalid_argument("BackModel: breathing_amplitude = " + num(breathing_amplitude) +
                                " is not in 0 .. 0.05 m");
  }
}

double BackModel::height(double x, double y) const {
  if (!std::isfinite(x) || !std::isfinite(y)) return kNaN;
  return Shape(body_, breathing_phase_, breathing_amplitude_).height(x, y);
}

double BackModel::halfWidth(double x) const {
  return Shape(body_, breathing_phase_, breathing_amplitude_).halfWidth(x);
}

Eigen::Vector2d BackModel::extent() const {
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  return {shape.xMin(), shape.xMax()};
}

Eigen::Vector2d BackModel::fullHeightExtent() const {
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  return {shape.xMin() + kButtockCap, shape.xMax() - kNeckCap};
}

double BackModel::levelX(const std::string& level) const {
  const int i = levelIndex(level);
  return levelPositions(body_.torso_length)[static_cast<std::size_t>(i)];
}

double BackModel::cun() const { return body_.scapula_medial_offset / 3.0; }

Eigen::Vector3d BackModel::surfacePoint(const std::string& level, double lateral_cun) const {
  const double x = levelX(level);
  const double y = lateral_cun * cun();
  const double z = height(x, y);
  if (!std::isfinite(z)) {
    throw std::invalid_argument("surfacePoint: " + num(lateral_cun) + " cun at " + level + " is off the back");
  }
  return {x, y, z};
}

std::map<std::string, Eigen::Vector3d> BackModel::landmarks() const {
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  std::map<std::string, Eigen::Vector3d> out;
  auto put = [&](const std::string& name, double x, double y) { out[name] = {x, y, shape.height(x, y)}; };
  const auto& names = vertebralLevels();
  const auto& lx = shape.levels();
  for (std::size_t i = 0; i < names.size(); ++i) put(names[i], lx[i], 0.0);
  const double inferior_y = body_.scapula_medial_offset + 0.01;
  put("scapula_inferior_angle_L", lx[kT7], inferior_y);
  put("scapula_inferior_angle_R", lx[kT7], -inferior_y);
  const double crest_y = 0.8 * shape.halfWidth(lx[kL4]);
  put("iliac_crest_L", lx[kL4], crest_y);
  put("iliac_crest_R", lx[kL4], -crest_y);
  put("acromion_L", shape.acromionX(), shape.acromionY());
  put("acromion_R", shape.acromionX(), -shape.acromionY());
  return out;
}

std::map<std::string, Eigen::Vector3d> BackModel::acupoints() const {
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  const double cun_m = cun();
  const auto& lx = shape.levels();
  std::map<std::string, Eigen::Vector3d> out;
  auto put = [&](const std::string& name, double x, double y) {
    const double z = shape.height(x, y);
    if (!std::isfinite(z)) throw std::logic_error("acupoint " + name + " is off the back");
    out[name] = {x, y, z};
  };
  auto bilateral = [&](const std::string& name, int level, double lateral_cun) {
    put(name + "_L", lx[static_cast<std::size_t>(level)], lateral_cun * cun_m);
    put(name + "_R", lx[static_cast<std::size_t>(level)], -lateral_cun * cun_m);
  };
  // The table of back_acupoints.md: level, midline GV, 1.5 cun BL, 3 cun.
  struct RowSpec {
    int level;
    const char* midline;
    const char* inner;
    const char* outer;
  };
  static const RowSpec table[] = {
      {kC7, "GV14", nullptr, nullptr}, {kT1, "GV13", "BL11", "SI14"},  {kT2, nullptr, "BL12", "BL41"},
      {kT3, "GV12", "BL13", "BL42"},   {kT4, nullptr, "BL14", "BL43"}, {kT5, "GV11", "BL15", "BL44"},
      {kT6, "GV10", "BL16", "BL45"},   {kT7, "GV9", "BL17", "BL46"},   {9, "GV8", "BL18", "BL47"},
      {10, "GV7", "BL19", "BL48"},     {kT11, "GV6", "BL20", "BL49"},  {kT12, nullptr, "BL21", "BL50"},
      {kL1, "GV5", "BL22", "BL51"},    {kL2, "GV4", "BL23", "BL52"},   {kL3, nullptr, "BL24", nullptr},
      {kL4, "GV3", "BL25", nullptr},   {kL5, nullptr, "BL26", nullptr}};
  for (const RowSpec& r : table) {
    if (r.midline) put(r.midline, lx[static_cast<std::size_t>(r.level)], 0.0);
    if (r.inner) bilateral(r.inner, r.level, 1.5);
    if (r.outer) bilateral(r.outer, r.level, 3.0);
  }
  bilateral("SI15", kC7, 2.0);
  const auto& names = vertebralLevels();
  for (int level = kT1; level <= kL5; ++level) {
    bilateral("EX_B2_" + names[static_cast<std::size_t>(level)], level, 0.5);
  }
  // GB21: midpoint of GV14 .. acromion (in x, y), on the skin there.
  const double gx = 0.5 * (lx[kC7] + shape.acromionX()), gy = 0.5 * shape.acromionY();
  put("GB21_L", gx, gy);
  put("GB21_R", gx, -gy);
  return out;
}

std::vector<Eigen::Vector3d> BackModel::midline(int count) const {
  if (count < 2) throw std::invalid_argument("midline: count must be at least 2, got " + std::to_string(count));
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  const double x0 = shape.levels()[kC7], x1 = shape.levels()[kL5];
  std::vector<Eigen::Vector3d> out;
  out.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    const double x = x0 + (x1 - x0) * i / (count - 1);
    out.emplace_back(x, 0.0, shape.height(x, 0.0));
  }
  return out;
}

// ---------------------------------------------------------------------------
// Mesh

namespace {

/// Vertical error, at the middle of the mesh edge between rows xa and xb along
/// the column s, of the linear interpolation against the true surface.
double rowError(const Shape& shape, const Row& a, const Row& b, const std::vector<double>& probes) {
  const Row m = shape.row(0.5 * (a.x + b.x));
  double err = 0.0;
  for (double s : probes) {
    const double za = shape.heightS(a, s), zb = shape.heightS(b, s);
    double zt = shape.height(m, s * 0.5 * (a.hw + b.hw));
    if (!std::isfinite(zt)) zt = 0.0;
    err = std::max(err, std::abs(zt - 0.5 * (za + zb)));
  }
  return err;
}

void refineRows(const Shape& shape, const Row& a, const Row& b, double tol, double max_dy, int depth,
                std::vector<Row>& out) {
  if (depth > 0 && (b.x - a.x) > 2e-5) {
    static const std::vector<double> probes = {0.0,  0.2,  0.4,   0.55,  0.7,   0.8,   0.88,
                                               0.94, 0.97, 0.985, 0.993, 0.997, 0.999, 0.9997};
    const Row m = shape.row(0.5 * (a.x + b.x));
    // Chord of the outline vs the outline: the mesh border misses the true
    // outline by dy there; the surface within dy of the outline must be low.
    const double dy = std::abs(m.hw - 0.5 * (a.hw + b.hw));
    const double z_edge = m.hw > 0.0 ? shape.heightS(m, 1.0 - std::min(1.0, dy / m.hw)) : 0.0;
    if (std::abs(b.hw - a.hw) > max_dy || z_edge > tol || rowError(shape, a, b, probes) > tol) {
      refineRows(shape, a, m, tol, max_dy, depth - 1, out);
      refineRows(shape, m, b, tol, max_dy, depth - 1, out);
      return;
    }
  }
  out.push_back(b);
}

double columnError(const Shape& shape, const std::vector<Row>& rows, double sa, double sb) {
  double err = 0.0;
  const double sm = 0.5 * (sa + sb);
  for (const Row& r : rows) {
    const double e = std::abs(shape.heightS(r, sm) - 0.5 * (shape.heightS(r, sa) + shape.heightS(r, sb)));
    err = std::max(err, e);
  }
  return err;
}

void refineColumns(const Shape& shape, const std::vector<Row>& rows, double sa, double sb, double tol, int depth,
                   std::vector<double>& out) {
  if (depth > 0 && sb - sa > 1e-7 && columnError(shape, rows, sa, sb) > tol) {
    const double sm = 0.5 * (sa + sb);
    refineColumns(shape, rows, sa, sm, tol, depth - 1, out);
    refineColumns(shape, rows, sm, sb, tol, depth - 1, out);
    return;
  }
  out.push_back(sb);
}

}  // namespace

Mesh BackModel::mesh(double spacing) const {
  if (!(spacing >= 0.0005 && spacing <= 0.05)) {
    throw std::invalid_argument("BackModel::mesh: spacing = " + num(spacing) + " is not in 0.0005 .. 0.05 m");
  }
  const Shape shape(body_, breathing_phase_, breathing_amplitude_);
  const double tol = std::min(2.5e-4, 0.0625 * spacing);  // vertical interpolation tolerance

  // Rows: uniform in x, refined where the surface or the outline bends.
  const double x0 = shape.xMin(), x1 = shape.xMax();
  const int n_rows = std::max(2, static_cast<int>(std::ceil((x1 - x0) / spacing)));
  std::vector<Row> rows;
  rows.push_back(shape.row(x0));
  for (int i = 1; i <= n_rows; ++i) {
    const Row next = shape.row(i == n_rows ? x1 : x0 + (x1 - x0) * i / n_rows);
    const Row prev = rows.back();
    refineRows(shape, prev, next, tol, spacing, 10, rows);
  }

  // Columns s in [0, 1] (mirrored): s = sin(pi/2 u), refined toward the outline.
  double max_hw = 0.0;
  for (const Row& r : rows) max_hw = std::max(max_hw, r.hw);
  const int n_u = std::max(2, static_cast<int>(std::ceil(max_hw * kPi / 2.0 / spacing)));
  std::vector<Row> probe_rows;
  for (std::size_t i = 0; i < rows.size(); i += 4) probe_rows.push_back(rows[i]);
  std::vector<double> half{0.0};
  for (int j = 1; j <= n_u; ++j) {
    const double sb = j == n_u ? 1.0 : std::sin(kPi / 2.0 * j / n_u);
    refineColumns(shape, probe_rows, half.back(), sb, tol, 16, half);
  }
  std::vector<double> cols;
  cols.reserve(2 * half.size() - 1);
  for (std::size_t j = half.size(); j-- > 1;) cols.push_back(-half[j]);
  for (double s : half) cols.push_back(s);

  const std::size_t nr = rows.size(), nc = cols.size();
  Mesh mesh;
  mesh.name = "back";
  mesh.label = kLabelBack;
  mesh.vertices.resize(nr * nc);
  mesh.normals.resize(nr * nc);
  mesh.uv.resize(nr * nc);
  const double hx = 1e-5;
  for (std::size_t i = 0; i < nr; ++i) {
    const Row& r = rows[i];
    const Row r_lo = shape.row(std::max(x0, r.x - hx)), r_hi = shape.row(std::min(x1, r.x + hx));
    for (std::size_t j = 0; j < nc; ++j) {
      const double s = cols[j];
      const bool border = i == 0 || i + 1 == nr || j == 0 || j + 1 == nc;
      const double y = s * r.hw;
      const double z = border ? 0.0 : shape.heightS(r, s);
      const std::size_t k = i * nc + j;
      mesh.vertices[k] = Eigen::Vector3f(static_cast<float>(r.x), static_cast<float>(y), static_cast<float>(z));
      mesh.uv[k] = Eigen::Vector2f(static_cast<float>(r.x), static_cast<float>(y));
      mesh.normals[k] = shape.normal(r, r_lo, r_hi, s).cast<float>();
    }
  }
  // Two triangles per cell, counter-clockwise seen from above; the diagonal
  // that better follows the surface.
  mesh.triangles.reserve(2 * (nr - 1) * (nc - 1));
  for (std::size_t i = 0; i + 1 < nr; ++i) {
    const Row mid = shape.row(0.5 * (rows[i].x + rows[i + 1].x));
    for (std::size_t j = 0; j + 1 < nc; ++j) {
      const int a = static_cast<int>(i * nc + j), b = static_cast<int>(i * nc + j + 1);
      const int c = static_cast<int>((i + 1) * nc + j), d = static_cast<int>((i + 1) * nc + j + 1);
      const Eigen::Vector3f &va = mesh.vertices[static_cast<std::size_t>(a)],
                            &vb = mesh.vertices[static_cast<std::size_t>(b)],
                            &vc = mesh.vertices[static_cast<std::size_t>(c)],
                            &vd = mesh.vertices[static_cast<std::size_t>(d)];
      // Diagonal a-d vs b-c: compare each diagonal's midpoint with the surface.
      const Eigen::Vector3f m_ad = 0.5f * (va + vd), m_bc = 0.5f * (vb + vc);
      double e_ad = std::abs(shape.height(mid, m_ad.y()) - m_ad.z());
      double e_bc = std::abs(shape.height(mid, m_bc.y()) - m_bc.z());
      if (!std::isfinite(e_ad)) e_ad = std::abs(m_ad.z());
      if (!std::isfinite(e_bc)) e_bc = std::abs(m_bc.z());
      if (e_ad <= e_bc) {
        mesh.triangles.emplace_back(a, c, d);
        mesh.triangles.emplace_back(a, d, b);
      } else {
        mesh.triangles.emplace_back(a, c, b);
        mesh.triangles.emplace_back(c, d, b);
      }
    }
  }

  Material& mat = mesh.material;
  mat.pattern = Material::Pattern::kSkin;
  mat.albedo = body_.skin_albedo;
  mat.specular = 0.08f;
  mat.shininess = 25.0f;
  mat.feature_size = 0.02f;
  mat.contrast = 0.03f;
  mat.seed = body_.skin_seed;
  std::mt19937 rng(body_.skin_seed);
  const auto& lx = shape.levels();
  for (int i = 0; i < body_.moles; ++i) {
    const double x = uniform(rng, lx[kL5], lx[kT1]);
    const double y = uniform(rng, -0.8, 0.8) * shape.halfWidth(x);
    Spot spot;
    spot.centre = Eigen::Vector2f(static_cast<float>(x), static_cast<float>(y));
    spot.radius = static_cast<float>(uniform(rng, 0.0015, 0.003));
    spot.albedo = 0.45f * body_.skin_albedo;
    mat.spots.push_back(spot);
  }
  return mesh;
}

}  // namespace massage_cell::sim
