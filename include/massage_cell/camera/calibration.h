// Camera calibration checks and the geometry a stereo driver declares.
// ROS-free: CameraCalibration mirrors sensor_msgs/CameraInfo's fields.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace massage_cell::camera {

struct CameraCalibration {
  int width = 0;
  int height = 0;
  std::string distortion_model = "plumb_bob";
  std::vector<double> D;
  std::array<double, 9> K{};   ///< row-major 3x3
  std::array<double, 9> R{};   ///< rectification rotation, row-major 3x3
  std::array<double, 12> P{};  ///< projection, row-major 3x4

  /// As camera_info_manager: calibrated when K[0] (fx) is set.
  bool isCalibrated() const { return K[0] != 0.0; }
};

/// Problems of one camera's calibration against its images: size mismatch,
/// non-positive focal lengths, non-rotation R, wrong number of distortion
/// coefficients. Empty when usable. `which` names the camera in messages.
std::vector<std::string> checkCalibration(const CameraCalibration& calib, cv::Size image_size,
                                          const std::string& which);

/// Problems of a stereo pair's calibrations: the two rectified projections
/// must share fx, fy and cy, the left P must have Tx = 0 and the right one
/// Tx = -fx * B with B > 0 (right camera to the right of the left one).
std::vector<std::string> checkStereoCalibration(const CameraCalibration& left,
                                                const CameraCalibration& right);

/// The camera_info of images that are already rectified: D = 0, R = I and
/// K = the left 3x3 block of P, so that image_proc's rectification is the
/// identity and stereo_image_proc reads the geometry from P as usual.
CameraCalibration declareRectified(const CameraCalibration& calib);

/// Stereo baseline in metres from the right camera's projection: -Tx / fx.
double baseline(const CameraCalibration& right);

/// Pose of the right camera's optical frame in the left camera's optical
/// frame. With rectification rotations R_l, R_r (rectified <- raw) the right
/// centre lies at (B, 0, 0) in the rectified frame, so the pose is
/// rotation R_l^T R_r and translation R_l^T (B, 0, 0).
Eigen::Isometry3d rightCameraInLeft(const CameraCalibration& left, const CameraCalibration& right);

}  // namespace massage_cell::camera
