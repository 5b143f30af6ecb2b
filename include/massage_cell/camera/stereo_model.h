// The stereo camera model: the two cameras' calibrations (sensor_msgs/CameraInfo's fields, calibration.h) as one
// rectified pair. Raw (distorted, unrectified) pairs with plumb_bob, rational_polynomial or equidistant (fisheye)
// distortion and already-rectified pairs alike. ROS-free; every node, library and tool that maps pixels between the
// raw and the rectified images or turns disparities into metres goes through it (the hbds node, CECT, the tools).
//
// In the rectified frame the calibration defines (R, P of each camera) the epipolar line of a left pixel is the
// image row with the same y. Disparities here are rectified x_left - x_right; the principal points' difference
// (offset()) is taken out when triangulating. 3D points are in the (raw) left camera's optical frame (REP 103).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::camera {

class StereoModel {
 public:
  StereoModel() = default;
  /// Throws std::invalid_argument naming the problem: an uncalibrated camera, a calibration without image size,
  /// any problem of checkCalibration (non-finite or zero values in K, D, R, P with the field named, the distortion
  /// model, R not a rotation) or checkStereoCalibration (not a horizontal pair rectified together).
  StereoModel(const CameraCalibration& left, const CameraCalibration& right);

  bool empty() const { return size_.width == 0; }
  cv::Size size() const { return size_; }  ///< the images' size, raw and rectified
  /// true when both calibrations already describe rectified images (D = 0, R = I, K = P).
  bool identity() const { return identity_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double cxRight() const { return cx_right_; }
  double baseline() const { return baseline_; }  ///< metres
  /// The principal points' difference cx_left - cx_right: a stereo_msgs/DisparityImage holds (x_l - x_r) - offset().
  double offset() const { return cx_ - cx_right_; }
  const CameraCalibration& left() const { return left_; }
  const CameraCalibration& right() const { return right_; }

  /// Rectified images (remapped with cached maps; the same Mats when identity()). Throws std::invalid_argument
  /// when an image's size is not size().
  void rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect, cv::Mat* right_rect) const;
  /// Raw left pixel -> rectified left pixel, and back (each camera's distortion model).
  cv::Point2f toRectified(const cv::Point2f& left_raw) const;
  cv::Point2f toRaw(const cv::Point2f& left_rect) const;
  /// 3D point in the left camera's optical frame, metres, from a rectified left pixel and its disparity
  /// (x_l - x_r, > offset()). `jacobian` receives d(X, Y, Z) / d(x, y, disparity).
  Eigen::Vector3d triangulate(double x_rect, double y_rect, double disparity,
                              Eigen::Matrix3d* jacobian = nullptr) const;
  /// Rectified left pixel (x, y) and disparity of a 3D point in the left optical frame.
  Eigen::Vector3d project(const Eigen::Vector3d& p_left) const;
  /// Rectified disparity of a point at depth z (metres, > 0) along the rectified optical axis.
  double disparityAtDepth(double z) const { return fx_ * baseline_ / z + offset(); }
  /// Fundamental matrix of the raw pair for undistorted pixels: x_r^T F x_l = 0.
  Eigen::Matrix3d fundamental() const;

  /// The rectified left / right camera's calibration: D = 0, R = I, K = the left 3x3 of P (depth/camera_info).
  CameraCalibration rectifiedLeft() const;
  CameraCalibration rectifiedRight() const;
  /// The rectified pair at 1/factor resolution, as Decimation shrinks images (area averaging, pixel centres kept):
  /// an identity() model whose 3D points are still in the left camera's optical frame. Throws
  /// std::invalid_argument when factor < 1 or the images would be empty.
  StereoModel downsampled(int factor) const;

  /// Depth along the rectified optical axis (REP 118: CV_32F metres, NaN where unknown) of a rectified disparity
  /// map (CV_32F, x_l - x_r); disparities that are not finite or put the point at or beyond infinity give NaN.
  cv::Mat depth(const cv::Mat& disparity) const;
  /// Organised point cloud (CV_32FC3: X, Y, Z in the left camera's optical frame, metres; NaN where the depth is)
  /// of a depth map from depth().
  cv::Mat points(const cv::Mat& depth) const;

 private:
  CameraCalibration left_, right_;
  cv::Size size_;
  bool identity_ = true;
  double fx_ = 0, fy_ = 0, cx_ = 0, cy_ = 0, cx_right_ = 0, baseline_ = 0;
  cv::Mat K_l_, D_l_, R_l_, K_r_, D_r_, R_r_, P_l_, P_r_;  ///< CV_64F; P as its left 3x3
  cv::Mat map_l1_, map_l2_, map_r1_, map_r2_;
  Eigen::Matrix3d R_l_eigen_ = Eigen::Matrix3d::Identity();  ///< rectified <- raw, left
  Eigen::Matrix3d R_r_eigen_ = Eigen::Matrix3d::Identity();  ///< rectified <- raw, right
  Eigen::Matrix3d to_optical_ =
      Eigen::Matrix3d::Identity();  ///< left optical frame <- rectified left (kept when downsampled)
};

}  // namespace massage_cell::camera
