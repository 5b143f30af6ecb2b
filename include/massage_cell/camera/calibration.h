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
/// non-positive focal lengths (K, P), P[10] not 1, a non-finite value in K,
/// D, R or P (the field named), R not a rotation, an unknown distortion model
/// or the wrong number of coefficients for it. Empty when usable (or when
/// uncalibrated: K[0] = 0). `which` names the camera in messages. The one
/// validator of calibrations: the drivers, StereoModel and the nodes use it.
std::vector<std::string> checkCalibration(const CameraCalibration& calib, cv::Size image_size,
                                          const std::string& which);

/// Problems of a stereo pair's calibrations: one image size, the two
/// rectified projections must share fx, fy and cy, the left P must have
/// Tx = 0 and the right one Tx = -fx * B with B > 0 (right camera to the
/// right of the left one) and Ty = P[7] = 0 (a horizontal pair).
std::vector<std::string> checkStereoCalibration(const CameraCalibration& left, const CameraCalibration& right);

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

/// Processing a camera's images at a lower resolution (as image_proc's
/// crop_decimate, without the crop): the images are shrunk by area averaging,
/// the calibration's K and P rows are scaled by the same factors (pixel
/// centres kept: c' = (c + 0.5) s - 0.5), D and R stay. Pixels map between
/// the two sizes exactly; 3D results are unchanged in metres.
class Decimation {
 public:
  Decimation() = default;
  /// The smallest integer factor that brings `full.width` to at most
  /// `max_width` (max_width <= 0 or a narrower image: factor 1, nothing done).
  static Decimation toWidth(cv::Size full, int max_width);
  /// Throws std::invalid_argument when factor < 1 or the size is empty.
  Decimation(cv::Size full, int factor);

  int factor() const { return factor_; }
  bool identity() const { return factor_ == 1; }
  cv::Size fullSize() const { return full_; }
  cv::Size size() const { return size_; }  ///< the decimated images' size
  /// The image shrunk to size() (INTER_AREA); the same Mat when identity().
  /// Throws std::invalid_argument when its size is not fullSize().
  cv::Mat apply(const cv::Mat& image) const;
  /// The calibration of the decimated images (a copy when identity()).
  /// Throws std::invalid_argument when it is for another size than fullSize().
  CameraCalibration apply(const CameraCalibration& calib) const;
  cv::Point2f toDecimated(const cv::Point2f& full_pixel) const;
  cv::Point2f toFull(const cv::Point2f& decimated_pixel) const;

 private:
  cv::Size full_{0, 0}, size_{0, 0};
  int factor_ = 1;
  double sx_ = 1.0, sy_ = 1.0;  ///< decimated / full, per axis
};

}  // namespace massage_cell::camera
