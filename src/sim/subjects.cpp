// Subject variety: builds (sex, BMI, stature, Fitzpatrick skin type) mapped to
// body parameters, and a wide deterministic population of them.
//
// The mapping is linear in BMI around a reference build (male BMI 24 /
// female BMI 22, stature 1.75 m) and was chosen to keep every value inside
// BodyParameters::validate() over BMI 16..42 and statures 1.40..2.05 m:
// widths and depth grow with BMI, the flanks round off, and the scapulae,
// the spine groove and the spinous processes fade; lengths scale with stature.
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "massage_cell/sim/body_model.h"

namespace massage_cell::sim {

namespace {

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double uniform(std::mt19937& rng, double lo, double hi) {
  return lo + (hi - lo) * (static_cast<double>(rng()) / 4294967296.0);
}

/// Widths and depths: the part that scales with the frame (not with fat).
struct Frame {
  double shoulder, waist, hip, neck, depth, buttock;
};

Frame referenceFrame(bool female) {
  if (female) return {0.395, 0.275, 0.385, 0.105, 0.19, 0.06};
  return {0.44, 0.31, 0.36, 0.125, 0.21, 0.045};
}

void applyWidths(const Build& b, double d_bmi, double k, BodyParameters& p) {
  const Frame f = referenceFrame(b.female);
  const double kw = std::sqrt(k);  // widths grow more slowly than lengths
  p.shoulder_width = kw * (f.shoulder + 0.003 * d_bmi);
  p.waist_width = kw * (f.waist + (b.female ? 0.0105 : 0.0115) * d_bmi);
  p.hip_width = kw * (f.hip + (b.female ? 0.009 : 0.0075) * d_bmi);
  p.neck_width = kw * (f.neck + 0.002 * d_bmi);
  p.back_height = kw * (f.depth + (b.female ? 0.005 : 0.0055) * d_bmi);
  p.buttock_height = std::clamp(f.buttock + (b.female ? 0.002 : 0.0015) * d_bmi, 0.02, 0.12);
  // An obese waist reaches the hips but stays within validate()'s relations.
  p.waist_width = std::min({p.waist_width, 1.02 * p.hip_width, 1.08 * p.shoulder_width});
}

void applyShape(const Build& b, double d_bmi, BodyParameters& p) {
  p.lateral_rounding = std::clamp(1.0 + 0.06 * d_bmi, 0.65, 2.0);
  p.thoracic_curvature = 0.025;
  p.lumbar_curvature = std::clamp((b.female ? 0.026 : 0.018) + 0.0004 * d_bmi, 0.005, 0.045);
  p.spine_depth = std::clamp(0.006 - 0.00025 * d_bmi, 0.0015, 0.010);
  p.spinous_prominence = std::clamp(0.0015 - 0.0003 * d_bmi, 0.0, 0.003);
  p.paraspinal_width = std::clamp(0.035 + 0.0008 * d_bmi, 0.026, 0.05);
  p.scapula_prominence = std::clamp(0.006 - 0.0005 * d_bmi, 0.001, 0.014);
  p.scapula_medial_offset = 0.075 * p.shoulder_width / 0.44;
  p.scapula_medial_offset = std::min(p.scapula_medial_offset, 0.5 * p.waist_width - 0.032);
  p.shoulder_slope = b.female ? 0.30 : 0.25;
}

}  // namespace

Eigen::Vector3f fitzpatrickAlbedo(int skin_type) {
  static const std::array<Eigen::Vector3f, 6> tones = {
      Eigen::Vector3f(0.87f, 0.68f, 0.60f), Eigen::Vector3f(0.80f, 0.59f, 0.49f), Eigen::Vector3f(0.67f, 0.46f, 0.34f),
      Eigen::Vector3f(0.50f, 0.32f, 0.21f), Eigen::Vector3f(0.30f, 0.17f, 0.10f), Eigen::Vector3f(0.14f, 0.08f, 0.05f)};
  if (skin_type < 1 || skin_type > 6) {
    throw std::invalid_argument("Fitzpatrick skin type " + std::to_string(skin_type) + " is not in 1..6");
  }
  return tones[static_cast<std::size_t>(skin_type - 1)];
}

void Build::validate() const {
  if (!(bmi >= 16.0 && bmi <= 42.0)) throw std::invalid_argument("Build: bmi = " + num(bmi) + " is not in 16..42");
  if (!(stature >= 1.40 && stature <= 2.05)) {
    throw std::invalid_argument("Build: stature = " + num(stature) + " is not in 1.40..2.05 m");
  }
  if (skin_type < 1 || skin_type > 6) {
    throw std::invalid_argument("Build: skin_type = " + std::to_string(skin_type) + " is not in 1..6");
  }
  if (moles < 0 || moles > 64)
    throw std::invalid_argument("Build: moles = " + std::to_string(moles) + " is not in 0..64");
}

BodyParameters bodyFromBuild(const Build& build) {
  build.validate();
  BodyParameters p = BodyParameters::mean();
  const double k = build.stature / 1.75;
  const double d_bmi = build.bmi - (build.female ? 22.0 : 24.0);
  p.torso_length = 0.50 * k;
  applyWidths(build, d_bmi, k, p);
  applyShape(build, d_bmi, p);
  p.skin_albedo = fitzpatrickAlbedo(build.skin_type);
  p.moles = build.moles;
  p.skin_seed = build.skin_seed;
  p.validate();
  return p;
}

BodyParameters BodyParameters::varied(int index, std::uint32_t seed) {
  if (index < 0) throw std::invalid_argument("varied subject index " + std::to_string(index) + " is negative");
  if (index == 0) return mean();
  std::seed_seq seq{seed, static_cast<std::uint32_t>(index), 0x76617279u};
  std::mt19937 rng(seq);
  Build b;
  b.female = index % 2 == 0;
  // Skin types in turn per sex, from a seed-dependent start.
  const int offset = static_cast<int>(seed % 6u);
  b.skin_type = 1 + ((index - 1) / 2 + offset) % 6;
  // BMI on a golden-ratio sequence over 18..38 (evenly spread for any count), jittered.
  const double golden = 0.6180339887498949;
  const double phase = std::fmod(golden * index + (seed % 1000u) / 1000.0, 1.0);
  b.bmi = std::clamp(18.0 + 20.0 * phase + uniform(rng, -0.5, 0.5), 17.5, 38.5);
  b.stature = b.female ? uniform(rng, 1.50, 1.80) : uniform(rng, 1.62, 1.95);
  b.moles = static_cast<int>(rng() % 9u);
  b.skin_seed = rng();
  BodyParameters p = bodyFromBuild(b);
  // Individual variation beyond the build.
  p.thoracic_curvature *= uniform(rng, 0.6, 1.4);
  p.lumbar_curvature *= uniform(rng, 0.7, 1.3);
  p.shoulder_slope *= uniform(rng, 0.8, 1.2);
  p.paraspinal_width *= uniform(rng, 0.9, 1.1);
  const double warm = uniform(rng, -0.04, 0.04), pink = uniform(rng, -0.03, 0.03);
  const Eigen::Vector3f hue(static_cast<float>(1.0 + pink), static_cast<float>(1.0 + warm - pink),
                            static_cast<float>(1.0 - warm));
  p.skin_albedo = p.skin_albedo.cwiseProduct(hue).cwiseMax(0.01f).cwiseMin(0.95f);
  p.validate();
  return p;
}

}  // namespace massage_cell::sim
