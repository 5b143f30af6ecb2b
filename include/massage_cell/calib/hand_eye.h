// Hand-eye calibration of the massage cell's fixed stereo camera against the
// three-axis Cartesian gantry: the rigid transform camera <- arm base from
// point correspondences, its quality figures, and its YAML file. ROS-free
// (Eigen + yaml-cpp).
//
// The gantry has no rotation, so one pose gives one point pair: the marker's
// reference point in the arm base frame (commanded tool tip + the marker's
// known mount offset from the tip, arm_base_link axes) and the same point
// triangulated by the stereo camera (left optical frame, REP 103). The fit is
// Eigen::umeyama without scaling (Arun / Umeyama least squares). Lengths are
// metres unless a name ends in _mm.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace massage_cell::calib {

/// One pose of the gantry: the marker's reference point in both frames.
struct Correspondence {
  Eigen::Vector3d in_base = Eigen::Vector3d::Zero();    ///< arm base frame (tip + mount offset), metres
  Eigen::Vector3d in_camera = Eigen::Vector3d::Zero();  ///< left optical frame, metres
};

/// The marker's reference point in the arm base frame: tool tip + mount offset
/// (the gantry does not rotate, so the offset is constant in the base frame).
inline Eigen::Vector3d markerInBase(const Eigen::Vector3d& tool_tip, const Eigen::Vector3d& mount_offset) {
  return tool_tip + mount_offset;
}

struct FitOptions {
  /// RMS residual above which the result carries a warning, millimetres.
  double warn_rms_mm = 1.0;
  /// The poses are refused as degenerate when the smallest singular value of
  /// the centred base points, divided by the largest, is below this (all
  /// points on one line or in one plane) ...
  double min_singular_ratio = 0.02;
  /// ... or when the RMS spread along the weakest direction (smallest singular
  /// value / sqrt(N)) is below this, metres.
  double min_spread = 0.005;
  /// A ratio below this (but above the refusal) gives a warning: the rotation
  /// about the well-spread directions is poorly determined.
  double warn_singular_ratio = 0.1;
};

/// Result of a fit; also what the calibration YAML holds.
struct HandEyeResult {
  std::string parent_frame = "stereo_left_optical_frame";
  std::string child_frame = "arm_base_link";
  /// Pose of the child (arm base) in the parent (camera): p_camera = camera_from_base * p_base.
  Eigen::Isometry3d camera_from_base = Eigen::Isometry3d::Identity();
  std::vector<double> residuals_mm;  ///< per pose: |camera_from_base * in_base - in_camera|
  double rms_mm = 0.0;
  double max_mm = 0.0;
  /// Singular values of the centred base points (metres, descending).
  Eigen::Vector3d singular_values = Eigen::Vector3d::Zero();
  std::vector<std::string> warnings;  ///< empty: no warning
  std::string date;                   ///< ISO 8601 UTC time of the fit
  bool warning() const { return !warnings.empty(); }
};

/// Fits camera <- base to `pairs` (N >= 4). Throws std::invalid_argument for
/// too few pairs, non-finite coordinates, invalid options, or degenerate
/// poses (collinear / coplanar: the message gives the singular values and
/// what to change).
HandEyeResult fitHandEye(const std::vector<Correspondence>& pairs, const FitOptions& options = {});

/// Rotation angle of a rotation matrix, radians in [0, pi].
double rotationAngle(const Eigen::Matrix3d& rotation);

/// Current UTC time as "YYYY-MM-DDTHH:MM:SSZ".
std::string utcNow();

/// Writes `result` as YAML (parent_frame, child_frame, translation {x y z},
/// rotation {x y z w} quaternion, residuals_mm, rms_mm, max_mm, warnings,
/// date). Throws std::runtime_error naming the file when it cannot be written.
void writeHandEyeYaml(const std::string& path, const HandEyeResult& result);

/// Reads a file written by writeHandEyeYaml. Throws std::runtime_error naming
/// the file and the missing or malformed field (a quaternion whose norm is
/// not within 1e-3 of 1 included).
HandEyeResult readHandEyeYaml(const std::string& path);

}  // namespace massage_cell::calib
