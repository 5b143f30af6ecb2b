// Ray-cast rendering of a textured plane for an ideal rectified stereo pair.
#include "massage_cell/sim/textured_plane.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>
#include <opencv2/core/utility.hpp>

namespace massage_cell::sim {

namespace {

// ---------------------------------------------------------------------------
// Input validation

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void validateRig(const StereoRig& rig) {
  if (rig.width <= 0 || rig.height <= 0) {
    throw std::invalid_argument("StereoRig: image size must be positive, got " + std::to_string(rig.width) + "x" +
                                std::to_string(rig.height));
  }
  if (!(rig.fx > 0.0) || !(rig.fy > 0.0) || !std::isfinite(rig.fx) || !std::isfinite(rig.fy)) {
    throw std::invalid_argument("StereoRig: focal lengths must be positive and finite, got fx=" + num(rig.fx) +
                                " fy=" + num(rig.fy));
  }
  if (!std::isfinite(rig.cx) || !std::isfinite(rig.cy)) {
    throw std::invalid_argument("StereoRig: principal point must be finite, got cx=" + num(rig.cx) +
                                " cy=" + num(rig.cy));
  }
  if (!(rig.baseline > 0.0) || !std::isfinite(rig.baseline)) {
    throw std::invalid_argument("StereoRig: baseline must be positive and finite, got " + num(rig.baseline));
  }
}

void validatePlane(const TexturedPlane& plane) {
  if (!plane.point.allFinite()) throw std::invalid_argument("TexturedPlane: point must be finite");
  if (!plane.normal.allFinite() || plane.normal.cwiseAbs().maxCoeff() == 0.0) {
    throw std::invalid_argument("TexturedPlane: normal must be finite and non-zero");
  }
  if (!(plane.feature_size > 0.0) || !std::isfinite(plane.feature_size)) {
    throw std::invalid_argument("TexturedPlane: feature_size must be positive and finite, got " +
                                num(plane.feature_size));
  }
  if (!plane.texture_offset.allFinite()) throw std::invalid_argument("TexturedPlane: texture_offset must be finite");
}

// ---------------------------------------------------------------------------
// Procedural texture: multi-octave value noise mapped to warm colours.

/// A well-mixed 64-bit hash of the seed and an integer lattice point
/// (SplitMix64 finaliser), as a double uniform in [0, 1).
double latticeValue(std::uint64_t seed, std::int64_t ix, std::int64_t iy) {
  std::uint64_t h = seed * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<std::uint64_t>(ix) * 0xC2B2AE3D27D4EB4Full;
  h ^= static_cast<std::uint64_t>(iy) * 0x165667B19E3779F9ull;
  h ^= h >> 30;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 27;
  h *= 0x94D049BB133111EBull;
  h ^= h >> 31;
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

/// Quintic smoothstep: C2-continuous interpolation weight.
double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

/// Beyond this (in lattice cells) coordinates no longer fit the integer
/// lattice; such far-away texture is far below pixel size and shows its mean.
constexpr double kMaxLatticeCoord = 0x1.0p52;

/// Smooth value noise in [0, 1] with unit lattice spacing.
double valueNoise(std::uint64_t seed, double x, double y) {
  if (!(std::abs(x) < kMaxLatticeCoord && std::abs(y) < kMaxLatticeCoord)) return 0.5;
  // floor() by truncation and correction: much faster than std::floor without SSE4.1.
  auto ix = static_cast<std::int64_t>(x), iy = static_cast<std::int64_t>(y);
  ix -= x < static_cast<double>(ix);
  iy -= y < static_cast<double>(iy);
  const double tx = fade(x - static_cast<double>(ix)), ty = fade(y - static_cast<double>(iy));
  const double v00 = latticeValue(seed, ix, iy), v10 = latticeValue(seed, ix + 1, iy);
  const double v01 = latticeValue(seed, ix, iy + 1), v11 = latticeValue(seed, ix + 1, iy + 1);
  const double a = v00 + (v10 - v00) * tx;
  const double b = v01 + (v11 - v01) * tx;
  return a + (b - a) * ty;
}

/// One octave of the brightness field: its weight (the weights sum to 1) and
/// the map from plane coordinates (feature sizes) to its lattice, a rotation
/// (so that the octaves' lattices do not line up) scaled by 1 / lattice
/// spacing: x = a u - b v, y = b u + a v.
struct Octave {
  double weight, a, b;
};

/// Lattice spacings from 8 feature sizes down to a quarter of a feature size,
/// with slowly decreasing weights so that fine detail keeps good contrast.
const std::array<Octave, 6>& brightnessOctaves() {
  static const std::array<Octave, 6> octaves = [] {
    std::array<Octave, 6> o{};
    double spacing = 8.0, weight = 1.0, total_weight = 0.0;
    for (std::size_t k = 0; k < o.size(); ++k) {
      const double angle = 2.39996 * static_cast<double>(k + 1);  // golden angle steps
      o[k] = {weight, std::cos(angle) / spacing, std::sin(angle) / spacing};
      spacing *= 0.5;
      total_weight += weight;
      weight *= 0.85;
    }
    for (Octave& octave : o) octave.weight /= total_weight;
    return o;
  }();
  return octaves;
}

/// Warm palette (BGR, 0..255) indexed by the hue field: umber, terracotta,
/// ochre, sand.
constexpr std::array<std::array<float, 3>, 4> kPalette{{
    {45.f, 72.f, 120.f},
    {60.f, 98.f, 196.f},
    {80.f, 160.f, 214.f},
    {160.f, 205.f, 230.f},
}};

/// Texture colour (BGR, 0..255) at plane coordinates (u, v) in units of the
/// feature size.
cv::Vec3f textureColour(std::uint64_t seed, double u, double v) {
  // Brightness: normalised fractal sum, contrast-stretched around its mean
  // with a soft clip, so that no region saturates into a flat patch.
  double sum = 0.0;
  std::uint64_t octave_seed = seed * 4 + 1;
  for (const Octave& o : brightnessOctaves()) {
    sum += o.weight * valueNoise(octave_seed, o.a * u - o.b * v, o.b * u + o.a * v);
    octave_seed += 0x632BE59BD9B4E019ull;
  }
  const double stretched = 3.5 * (sum - 0.5);
  const double brightness = 0.5 + 0.5 * stretched / std::sqrt(1.0 + stretched * stretched);

  // Hue: a coarse, independent field choosing a colour along the palette.
  const std::uint64_t hue_seed = seed * 4 + 3;
  const double hue_noise = (2.0 * valueNoise(hue_seed, u * (1.0 / 12.0) + 17.3, v * (1.0 / 12.0) - 5.1) +
                            valueNoise(hue_seed, v * 0.2, -u * 0.2)) *
                           (1.0 / 3.0);
  const double hue = std::clamp(2.0 * (hue_noise - 0.5) + 0.5, 0.0, 1.0) * (kPalette.size() - 1);
  const auto i = std::min(static_cast<std::size_t>(hue), kPalette.size() - 2);
  const float t = static_cast<float>(hue - static_cast<double>(i));

  const float shade = static_cast<float>(0.3 + brightness);
  cv::Vec3f colour;
  for (int c = 0; c < 3; ++c) {
    const float base = kPalette[i][c] + (kPalette[i + 1][c] - kPalette[i][c]) * t;
    colour[c] = std::min(255.f, base * shade);
  }
  return colour;
}

// ---------------------------------------------------------------------------
// Geometry

/// The plane in the left optical frame with its deterministic in-plane basis.
struct PlaneFrame {
  Eigen::Vector3d point, n, e1, e2;
};

Eigen::Vector3d reject(const Eigen::Vector3d& v, const Eigen::Vector3d& unit) { return v - v.dot(unit) * unit; }

PlaneFrame planeFrame(const TexturedPlane& plane) {
  constexpr double kDegenerate = 1e-3;
  PlaneFrame f;
  f.point = plane.point;
  f.n = (plane.normal / plane.normal.cwiseAbs().maxCoeff()).normalized();  // pre-scaled: no under/overflow
  f.e1 = reject(Eigen::Vector3d::UnitX(), f.n);
  if (f.e1.norm() < kDegenerate) f.e1 = reject(Eigen::Vector3d::UnitY(), f.n);
  f.e1.normalize();
  f.e2 = reject(reject(Eigen::Vector3d::UnitY(), f.n), f.e1);
  if (f.e2.norm() < kDegenerate) f.e2 = reject(reject(Eigen::Vector3d::UnitZ(), f.n), f.e1);
  f.e2.normalize();
  return f;
}

/// Renders one view (camera centre `origin`, left-frame axes) as CV_32FC3.
cv::Mat renderView(const StereoRig& rig, const TexturedPlane& plane, const PlaneFrame& frame,
                   const Eigen::Vector3d& origin, int supersample) {
  cv::Mat image(rig.height, rig.width, CV_32FC3);
  const double numerator = frame.n.dot(frame.point - origin);  // ray parameter t = numerator / (n . d)
  const Eigen::Vector3d rel = origin - frame.point;
  const double inv_size = 1.0 / plane.feature_size;
  const double u0 = (rel.dot(frame.e1) + plane.texture_offset.x()) * inv_size;
  const double v0 = (rel.dot(frame.e2) + plane.texture_offset.y()) * inv_size;
  const std::uint64_t seed = plane.seed;
  const float inv_samples = 1.0f / static_cast<float>(supersample * supersample);

  cv::parallel_for_(cv::Range(0, rig.height), [&](const cv::Range& rows) {
    for (int r = rows.start; r < rows.end; ++r) {
      auto* out = image.ptr<cv::Vec3f>(r);
      for (int c = 0; c < rig.width; ++c) {
        cv::Vec3f acc(0.f, 0.f, 0.f);
        for (int sy = 0; sy < supersample; ++sy) {
          const double py = r + (sy + 0.5) / supersample - 0.5;
          const double dy = (py - rig.cy) / rig.fy;
          for (int sx = 0; sx < supersample; ++sx) {
            const double px = c + (sx + 0.5) / supersample - 0.5;
            const Eigen::Vector3d d((px - rig.cx) / rig.fx, dy, 1.0);
            const double t = numerator / frame.n.dot(d);
            if (!(t > 0.0) || !std::isfinite(t)) continue;  // behind the camera, edge-on or parallel
            acc += textureColour(seed, u0 + t * d.dot(frame.e1) * inv_size, v0 + t * d.dot(frame.e2) * inv_size);
          }
        }
        out[c] = acc * inv_samples;
      }
    }
  });
  return image;
}

/// Adds Gaussian noise (if any) and converts to CV_8UC3 with rounding and saturation.
cv::Mat finish(cv::Mat image, double noise_sigma, cv::RNG& rng) {
  if (noise_sigma > 0.0) {
    cv::Mat noise(image.size(), image.type());
    rng.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0.0), cv::Scalar::all(noise_sigma));
    image += noise;
  }
  cv::Mat out;
  image.convertTo(out, CV_8UC3);
  return out;
}

massage_cell::camera::CameraCalibration calibration(const StereoRig& rig, double tx) {
  validateRig(rig);
  massage_cell::camera::CameraCalibration c;
  c.width = rig.width;
  c.height = rig.height;
  c.distortion_model = "plumb_bob";
  c.D.assign(5, 0.0);
  c.K = {rig.fx, 0.0, rig.cx, 0.0, rig.fy, rig.cy, 0.0, 0.0, 1.0};
  c.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  c.P = {rig.fx, 0.0, rig.cx, tx, 0.0, rig.fy, rig.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return c;
}

}  // namespace

StereoRender renderStereo(const StereoRig& rig, const TexturedPlane& plane, int supersample, double noise_sigma,
                          std::uint32_t noise_seed) {
  validateRig(rig);
  validatePlane(plane);
  if (supersample < 1)
    throw std::invalid_argument("renderStereo: supersample must be >= 1, got " + std::to_string(supersample));
  if (!(noise_sigma >= 0.0) || !std::isfinite(noise_sigma)) {
    throw std::invalid_argument("renderStereo: noise_sigma must be >= 0 and finite, got " + num(noise_sigma));
  }

  const PlaneFrame frame = planeFrame(plane);
  StereoRender result;

  // Exact depth and disparity at the left pixel centres: the left ray
  // d = ((c - cx)/fx, (r - cy)/fy, 1) meets the plane at t, and z = t.
  result.left_depth.create(rig.height, rig.width, CV_32F);
  result.left_disparity.create(rig.height, rig.width, CV_32F);
  const double numerator = frame.n.dot(frame.point);
  const double fb = rig.fx * rig.baseline;
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (int r = 0; r < rig.height; ++r) {
    auto* depth = result.left_depth.ptr<float>(r);
    auto* disparity = result.left_disparity.ptr<float>(r);
    const double dy = (r - rig.cy) / rig.fy;
    for (int c = 0; c < rig.width; ++c) {
      const double t = numerator / frame.n.dot(Eigen::Vector3d((c - rig.cx) / rig.fx, dy, 1.0));
      const bool hit = t > 0.0 && std::isfinite(t);
      depth[c] = hit ? static_cast<float>(t) : kNaN;
      disparity[c] = hit ? static_cast<float>(fb / t) : kNaN;
    }
  }

  cv::RNG rng(noise_seed);
  result.left = finish(renderView(rig, plane, frame, Eigen::Vector3d::Zero(), supersample), noise_sigma, rng);
  result.right =
      finish(renderView(rig, plane, frame, Eigen::Vector3d(rig.baseline, 0.0, 0.0), supersample), noise_sigma, rng);
  return result;
}

massage_cell::camera::CameraCalibration leftCalibration(const StereoRig& rig) { return calibration(rig, 0.0); }

massage_cell::camera::CameraCalibration rightCalibration(const StereoRig& rig) {
  return calibration(rig, -rig.fx * rig.baseline);
}

}  // namespace massage_cell::sim
