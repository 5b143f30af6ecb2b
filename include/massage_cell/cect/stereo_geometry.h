// The stereo geometry CECT works in, from the two cameras' calibrations
// (sensor_msgs/CameraInfo fields): raw (distorted, unrectified) pairs and
// already-rectified pairs alike. ROS-free.
//
// CECT applies the epipolar constraint in the rectified frame the calibration
// defines (R, P of each camera): there the epipolar line of a left point is
// the image row with the same y, which turns "intersect the epipolar line
// with the right contour" into exact, sub-pixel row crossings and handles
// lens distortion exactly. For raw images this is the same constraint as the
// fundamental matrix of the raw pair (fundamental()), applied to undistorted
// pixels.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::cect {

class StereoGeometry {
 public:
  StereoGeometry() = default;
  /// Throws std::invalid_argument naming the problem: uncalibrated camera,
  /// different image sizes, not a horizontal pair (checkStereoCalibration).
  /// Disparities are left.x - right.x in the rectified images (the principal
  /// points' difference is taken out when triangulating).
  StereoGeometry(const camera::CameraCalibration& left, const camera::CameraCalibration& right);

  bool empty() const { return size_.width == 0; }
  cv::Size size() const { return size_; }
  /// true when both calibrations already describe rectified images (D = 0, R = I, K = P).
  bool identity() const { return identity_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double baseline() const { return baseline_; }  ///< metres
  /// Rectified disparity of a point at depth z (metres, > 0) in the left optical frame.
  double disparityAtDepth(double z) const { return fx_ * baseline_ / z + (cx_ - cx_right_); }

  /// Rectified images (copies, or remapped with cached maps).
  void rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect, cv::Mat* right_rect) const;
  /// Raw left pixel -> rectified left pixel, and back.
  cv::Point2f toRectified(const cv::Point2f& left_raw) const;
  cv::Point2f toRaw(const cv::Point2f& left_rect) const;
  /// 3D point in the (raw) left camera's optical frame, metres, from a
  /// rectified left pixel and its disparity (> 0). J receives d(X,Y,Z)/d(x,y,d).
  Eigen::Vector3d triangulate(double x_rect, double y_rect, double disparity,
                              Eigen::Matrix3d* jacobian = nullptr) const;
  /// Rectified left pixel (x, y) and disparity of a 3D point in the left optical frame.
  Eigen::Vector3d project(const Eigen::Vector3d& p_left) const;
  /// Fundamental matrix of the raw pair for undistorted pixels: x_r^T F x_l = 0.
  Eigen::Matrix3d fundamental() const;

 private:
  cv::Size size_;
  bool identity_ = true;
  double fx_ = 0, fy_ = 0, cx_ = 0, cy_ = 0, baseline_ = 0;
  double cx_right_ = 0;  ///< principal point x of the right rectified view
  cv::Mat K_l_, D_l_, R_l_, P_l_, K_r_, D_r_, R_r_, P_r_;
  cv::Mat map_lx_, map_ly_, map_rx_, map_ry_;
  Eigen::Matrix3d R_l_eigen_ = Eigen::Matrix3d::Identity();  ///< rectified <- raw, left
  Eigen::Matrix3d R_r_eigen_ = Eigen::Matrix3d::Identity();  ///< rectified <- raw, right
};

}  // namespace massage_cell::cect
