// StereoGeometry: rectification maps and triangulation from two camera_info
// calibrations (see stereo_geometry.h).
#include "massage_cell/cect/stereo_geometry.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

cv::Mat mat(const double* v, int rows, int cols) { return cv::Mat(rows, cols, CV_64F, const_cast<double*>(v)).clone(); }

Eigen::Matrix3d eigen3(const std::array<double, 9>& a) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = a[static_cast<std::size_t>(3 * r + c)];
  return m;
}

bool isIdentity(const camera::CameraCalibration& c) {
  for (double d : c.D)
    if (d != 0.0) return false;
  const Eigen::Matrix3d R = eigen3(c.R);
  if (!R.isApprox(Eigen::Matrix3d::Identity(), 1e-12) && !R.isZero()) return false;
  const std::array<double, 9> k_of_p{c.P[0], c.P[1], c.P[2], c.P[4], c.P[5], c.P[6], c.P[8], c.P[9], c.P[10]};
  for (std::size_t i = 0; i < 9; ++i)
    if (std::abs(k_of_p[i] - c.K[i]) > 1e-9 * std::max(1.0, std::abs(c.K[i]))) return false;
  return true;
}

void checkOne(const camera::CameraCalibration& c, const char* which) {
  if (!c.isCalibrated())
    throw std::invalid_argument(std::string("CECT: the ") + which + " camera is not calibrated (camera_info K is zero)");
  if (c.width <= 0 || c.height <= 0)
    throw std::invalid_argument(std::string("CECT: the ") + which + " camera_info has no image size");
  const auto problems = camera::checkCalibration(c, cv::Size(c.width, c.height), which);
  if (!problems.empty()) throw std::invalid_argument("CECT: " + problems.front());
}

}  // namespace

StereoGeometry::StereoGeometry(const camera::CameraCalibration& left, const camera::CameraCalibration& right) {
  checkOne(left, "left");
  checkOne(right, "right");
  const auto problems = camera::checkStereoCalibration(left, right);
  if (!problems.empty()) throw std::invalid_argument("CECT: " + problems.front());
  size_ = cv::Size(left.width, left.height);
  fx_ = left.P[0];
  fy_ = left.P[5];
  cx_ = left.P[2];
  cy_ = left.P[6];
  cx_right_ = right.P[2];
  baseline_ = camera::baseline(right);
  if (!(baseline_ > 0.0)) throw std::invalid_argument("CECT: stereo baseline must be > 0");
  identity_ = isIdentity(left) && isIdentity(right);
  K_l_ = mat(left.K.data(), 3, 3);
  K_r_ = mat(right.K.data(), 3, 3);
  D_l_ = left.D.empty() ? cv::Mat::zeros(1, 5, CV_64F) : mat(left.D.data(), 1, static_cast<int>(left.D.size()));
  D_r_ = right.D.empty() ? cv::Mat::zeros(1, 5, CV_64F) : mat(right.D.data(), 1, static_cast<int>(right.D.size()));
  Eigen::Matrix3d Rl = eigen3(left.R), Rr = eigen3(right.R);
  if (Rl.isZero()) Rl.setIdentity();
  if (Rr.isZero()) Rr.setIdentity();
  R_l_eigen_ = Rl;
  R_r_eigen_ = Rr;
  R_l_ = cv::Mat(3, 3, CV_64F);
  R_r_ = cv::Mat(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      R_l_.at<double>(r, c) = Rl(r, c);
      R_r_.at<double>(r, c) = Rr(r, c);
    }
  P_l_ = mat(left.P.data(), 3, 4);
  P_r_ = mat(right.P.data(), 3, 4);
  if (!identity_) {
    cv::initUndistortRectifyMap(K_l_, D_l_, R_l_, P_l_(cv::Rect(0, 0, 3, 3)), size_, CV_16SC2, map_lx_, map_ly_);
    cv::initUndistortRectifyMap(K_r_, D_r_, R_r_, P_r_(cv::Rect(0, 0, 3, 3)), size_, CV_16SC2, map_rx_, map_ry_);
  }
}

void StereoGeometry::rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect,
                             cv::Mat* right_rect) const {
  if (empty()) throw std::logic_error("StereoGeometry::rectify on an empty geometry");
  if (left_raw.size() != size_ || right_raw.size() != size_)
    throw std::invalid_argument("CECT: images are " + std::to_string(left_raw.cols) + "x" +
                                std::to_string(left_raw.rows) + " / " + std::to_string(right_raw.cols) + "x" +
                                std::to_string(right_raw.rows) + " but the calibration is for " +
                                std::to_string(size_.width) + "x" + std::to_string(size_.height));
  if (identity_) {
    *left_rect = left_raw;
    *right_rect = right_raw;
    return;
  }
  cv::remap(left_raw, *left_rect, map_lx_, map_ly_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(right_raw, *right_rect, map_rx_, map_ry_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

cv::Point2f StereoGeometry::toRectified(const cv::Point2f& left_raw) const {
  if (identity_) return left_raw;
  std::vector<cv::Point2f> in{left_raw}, out;
  cv::undistortPoints(in, out, K_l_, D_l_, R_l_, P_l_(cv::Rect(0, 0, 3, 3)));
  return out[0];
}

cv::Point2f StereoGeometry::toRaw(const cv::Point2f& left_rect) const {
  if (identity_) return left_rect;
  // Ray in the rectified frame -> raw camera frame -> distorted pixel.
  const Eigen::Vector3d ray_rect((left_rect.x - cx_) / fx_, (left_rect.y - cy_) / fy_, 1.0);
  const Eigen::Vector3d ray_raw = R_l_eigen_.transpose() * ray_rect;
  std::vector<cv::Point3f> obj{cv::Point3f(static_cast<float>(ray_raw.x()), static_cast<float>(ray_raw.y()),
                                           static_cast<float>(ray_raw.z()))};
  std::vector<cv::Point2f> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K_l_, D_l_, img);
  return img[0];
}

Eigen::Vector3d StereoGeometry::triangulate(double x, double y, double disparity, Eigen::Matrix3d* jacobian) const {
  // Rectified frame: Z = fx B / d', X = (x - cx) Z / fx, Y = (y - cy) Z / fy,
  // d' = d - (cx_l - cx_r) (principal points may differ after rectification).
  const double d = disparity - (cx_ - cx_right_);
  const double Z = fx_ * baseline_ / d;
  const double X = (x - cx_) * Z / fx_;
  const double Y = (y - cy_) * Z / fy_;
  const Eigen::Vector3d p_rect(X, Y, Z);
  if (jacobian) {
    Eigen::Matrix3d J;  // d(X, Y, Z) / d(x, y, disparity) in the rectified frame
    const double dZ = -Z / d;
    J << Z / fx_, 0.0, (x - cx_) / fx_ * dZ,  //
        0.0, Z / fy_, (y - cy_) / fy_ * dZ,   //
        0.0, 0.0, dZ;
    *jacobian = R_l_eigen_.transpose() * J;
  }
  return R_l_eigen_.transpose() * p_rect;
}

Eigen::Vector3d StereoGeometry::project(const Eigen::Vector3d& p_left) const {
  const Eigen::Vector3d p = R_l_eigen_ * p_left;
  const double x = fx_ * p.x() / p.z() + cx_;
  const double y = fy_ * p.y() / p.z() + cy_;
  const double d = fx_ * baseline_ / p.z() + (cx_ - cx_right_);
  return {x, y, d};
}

Eigen::Matrix3d StereoGeometry::fundamental() const {
  // Undistorted raw pixels: x_l ~ K_l X, x_r ~ K_r (R X + t) with the right
  // camera's pose from the rectification rotations: raw right <- raw left is
  // R = R_r^T R_l, t = -R_r^T (B, 0, 0).
  Eigen::Matrix3d Kl, Kr;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      Kl(r, c) = K_l_.at<double>(r, c);
      Kr(r, c) = K_r_.at<double>(r, c);
    }
  const Eigen::Matrix3d R = R_r_eigen_.transpose() * R_l_eigen_;
  const Eigen::Vector3d t = -(R_r_eigen_.transpose() * Eigen::Vector3d(baseline_, 0.0, 0.0));
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return Kr.inverse().transpose() * tx * R * Kl.inverse();
}

}  // namespace massage_cell::cect
