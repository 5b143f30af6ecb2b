// Rigid camera <- arm base fit (Eigen::umeyama, no scaling), degeneracy and
// residual checks. The YAML I/O is in hand_eye_io.cpp.
#include "massage_cell/calib/hand_eye.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <sstream>
#include <stdexcept>

#include <Eigen/SVD>

#include "massage_cell/camera/point_spread.h"

namespace massage_cell::calib {
namespace {

std::string num(double v, int precision = 4) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

void validate(const std::vector<Correspondence>& pairs, const FitOptions& o) {
  if (pairs.size() < 4) {
    throw std::invalid_argument("hand-eye fit: need at least 4 poses, got " + std::to_string(pairs.size()));
  }
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!pairs[i].in_base.allFinite() || !pairs[i].in_camera.allFinite()) {
      throw std::invalid_argument("hand-eye fit: pose " + std::to_string(i) + " has a non-finite coordinate");
    }
  }
  if (!(o.warn_rms_mm > 0.0) || !std::isfinite(o.warn_rms_mm)) {
    throw std::invalid_argument("hand-eye fit: warn_rms_mm must be finite and > 0, got " + num(o.warn_rms_mm));
  }
  if (!(o.min_singular_ratio >= 0.0 && o.min_singular_ratio < 1.0) || !(o.min_spread >= 0.0) ||
      !std::isfinite(o.min_spread) || !(o.warn_singular_ratio >= o.min_singular_ratio && o.warn_singular_ratio < 1.0)) {
    throw std::invalid_argument(
        "hand-eye fit: need 0 <= min_singular_ratio <= warn_singular_ratio < 1 and a finite min_spread >= 0");
  }
}

/// Singular values (descending) of the 3xN matrix of centred points.
Eigen::Vector3d spreadOf(const Eigen::Matrix3Xd& points) {
  const Eigen::Matrix3Xd centred = points.colwise() - points.rowwise().mean();
  return camera::principalAxes(centred).spread;
}

/// Throws for collinear / coplanar base points; adds a warning for weak spread.
void checkSpread(const Eigen::Vector3d& s, std::size_t n, const FitOptions& o, std::vector<std::string>* warnings) {
  const std::string values = "singular values of the centred poses " + num(s(0) * 1e3) + ", " + num(s(1) * 1e3) + ", " +
                             num(s(2) * 1e3) + " mm";
  if (!(s(0) > 0.0)) throw std::invalid_argument("hand-eye fit: degenerate poses: all poses are the same point");
  const double rms_weakest = s(2) / std::sqrt(static_cast<double>(n));
  if (s(1) / s(0) < o.min_singular_ratio) {
    throw std::invalid_argument("hand-eye fit: degenerate poses: they lie on a line (" + values +
                                "); spread them over all three axes of the gantry");
  }
  if (s(2) / s(0) < o.min_singular_ratio || rms_weakest < o.min_spread) {
    throw std::invalid_argument("hand-eye fit: degenerate poses: they lie in a plane (" + values +
                                "); vary the third axis too (e.g. Z heights as well as X and Y)");
  }
  if (s(2) / s(0) < o.warn_singular_ratio) {
    warnings->push_back("poses poorly spread along one direction (" + values + ")");
  }
}

}  // namespace

double rotationAngle(const Eigen::Matrix3d& rotation) { return Eigen::AngleAxisd(rotation).angle(); }

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

HandEyeResult fitHandEye(const std::vector<Correspondence>& pairs, const FitOptions& options) {
  validate(pairs, options);
  const auto n = static_cast<Eigen::Index>(pairs.size());
  Eigen::Matrix3Xd base(3, n), camera(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    base.col(i) = pairs[i].in_base;
    camera.col(i) = pairs[i].in_camera;
  }
  HandEyeResult r;
  r.singular_values = spreadOf(base);
  checkSpread(r.singular_values, pairs.size(), options, &r.warnings);

  const Eigen::Matrix4d m = Eigen::umeyama(base, camera, false);
  r.camera_from_base.matrix() = m;
  double sum2 = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double e = (r.camera_from_base * base.col(i) - camera.col(i)).norm() * 1e3;
    r.residuals_mm.push_back(e);
    sum2 += e * e;
    r.max_mm = std::max(r.max_mm, e);
  }
  r.rms_mm = std::sqrt(sum2 / static_cast<double>(n));
  if (r.rms_mm > options.warn_rms_mm) {
    r.warnings.push_back("RMS residual " + num(r.rms_mm, 3) + " mm exceeds " + num(options.warn_rms_mm, 3) +
                         " mm: check the marker mount offset, the camera calibration and the detections");
  }
  r.date = utcNow();
  return r;
}

}  // namespace massage_cell::calib
