// Cameras of the simulator: pinhole + plumb_bob distortion, placed in the
// world frame; stereo pairs (rectified or raw, with their ROS calibrations)
// and N-view sets. ROS-free (Eigen + OpenCV).
//
// Pixel convention: (0, 0) is the centre of the top-left pixel (OpenCV and
// camera_info). Camera frames are REP 103 optical frames (x right, y down,
// z forward).
#pragma once

#include <vector>

#include <Eigen/Geometry>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::sim {

struct CameraModel {
  int width = 640;
  int height = 480;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  /// plumb_bob coefficients k1 k2 p1 p2 k3; empty = no distortion.
  std::vector<double> D;
  /// Pose of the optical frame in the world frame (world <- camera).
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();

  Eigen::Vector3d centre() const { return world_from_camera.translation(); }
  /// Pixel of world point `p` (with distortion). false when p is not in front (z <= 1e-9).
  bool project(const Eigen::Vector3d& p_world, Eigen::Vector2d* pixel) const;
  /// World-frame unit direction of the ray through pixel (x, y), distortion undone.
  Eigen::Vector3d rayDirection(double x, double y) const;
  /// 3x4 projection K [R | t] mapping homogeneous world points to (undistorted) pixels.
  Eigen::Matrix<double, 3, 4> projectionMatrix() const;
  /// Throws std::invalid_argument for a bad size, K or distortion vector.
  void validate() const;
};

/// A stereo pair and the camera_info a calibrated driver would publish for it.
struct StereoPairModel {
  CameraModel left, right;
  bool rectified = true;  ///< true: ideal rectified pair (D = 0, R = I); false: raw images
  /// ROS calibrations: for a raw pair R and P come from cv::stereoRectify
  /// (alpha 0, zero disparity at infinity), right P[3] = -fx' * B.
  camera::CameraCalibration left_info, right_info;
  double baseline() const;  ///< metres, distance between the centres
};

/// Where and how the stereo camera sits above the massage table.
struct RigParameters {
  int width = 640;
  int height = 480;
  double fx = 500.0;       ///< pixels (fy = fx), principal point at the image centre
  double baseline = 0.10;  ///< metres, along the image x axis (left camera on the image left)
  /// World position of the midpoint between the two camera centres. The
  /// cameras look straight down (optical z = -world z) with the subject's head
  /// at the top of the image (optical y = -world x, optical x = -world y).
  Eigen::Vector3d centre{-0.27, 0.0, 0.95};
  /// Camera shift (the thesis's camera-shift experiment), metres, added to `centre` along world x.
  double shift = 0.0;
  bool rectified = true;
  /// Raw pairs only: lens distortion of both cameras (plumb_bob) and small
  /// rotations of each camera about its own axes (radians, roll/pitch/yaw),
  /// so that the raw pair is not row-aligned.
  std::vector<double> distortion{-0.12, 0.05, 0.0005, -0.0003, 0.0};
  Eigen::Vector3d left_rotation{0.004, -0.006, 0.003};
  Eigen::Vector3d right_rotation{-0.003, 0.008, -0.004};
  /// Raw pairs only: toe-in, radians (0 .. 0.3): each camera yawed about its
  /// image y axis toward the other, so that the optical axes converge at
  /// about baseline / (2 tan(toe_in)) in front of the rig (applied before
  /// the small rotations above). 0 = parallel axes.
  double toe_in = 0.0;
};

/// Throws std::invalid_argument for invalid parameters (size, fx, baseline <= 0, ...).
StereoPairModel makeStereoPair(const RigParameters& rig);

/// `rig` moved along world x and z (its y, orientation, size and lenses
/// kept, shift set to 0) so that the left image's top and bottom edges, at the
/// middle column, meet the horizontal plane z = surface_z at world x = x_top
/// and x = x_bottom (x_top > x_bottom: the head at the top). Lens distortion
/// and toe-in are accounted for. Throws std::invalid_argument for bad
/// parameters or a framing the rig cannot reach (camera below the plane).
RigParameters frameRig(const RigParameters& rig, double x_top, double x_bottom, double surface_z);

/// `count` cameras on an arc above `target` at `distance`, looking at it,
/// spread over `spread` radians around the world z axis (multi-view sets).
std::vector<CameraModel> makeMultiView(int count, const Eigen::Vector3d& target, double distance, double elevation,
                                       double spread, int width, int height, double fx);

/// camera_info of a single camera: K, D, R = I, P = [K | 0].
camera::CameraCalibration monoCalibration(const CameraModel& camera);

}  // namespace massage_cell::sim
