// StereoModel: rectification maps, raw <-> rectified pixels, triangulation, depth and point clouds from two
// camera_info calibrations (see stereo_model.h).
#include "massage_cell/camera/stereo_model.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::camera {

namespace {

cv::Mat mat(const double* v, int rows, int cols) { return cv::Mat(rows, cols, CV_64F, const_cast<double*>(v)).clone(); }

Eigen::Matrix3d eigen3(const std::array<double, 9>& a) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = a[static_cast<std::size_t>(3 * r + c)];
  return m;
}

/// OpenCV's iterative inverse of the distortion, run to a hundredth of a pixel's thousandth (its default of five
/// iterations leaves a few hundredths of a pixel in strongly distorted corners).
cv::TermCriteria undistortCriteria() {
  return cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-10);
}

bool fisheye(const CameraCalibration& c) { return c.distortion_model == "equidistant"; }

/// Already rectified: no distortion, R = I and K = the left 3x3 of P.
bool isRectified(const CameraCalibration& c) {
  for (double d : c.D)
    if (d != 0.0) return false;
  if (!eigen3(c.R).isApprox(Eigen::Matrix3d::Identity(), 1e-12)) return false;
  const std::array<double, 9> k_of_p{c.P[0], c.P[1], c.P[2], c.P[4], c.P[5], c.P[6], c.P[8], c.P[9], c.P[10]};
  for (std::size_t i = 0; i < 9; ++i)
    if (std::abs(k_of_p[i] - c.K[i]) > 1e-9 * std::max(1.0, std::abs(c.K[i]))) return false;
  return true;
}

void checkOne(const CameraCalibration& c, const char* which) {
  if (!c.isCalibrated()) {
    throw std::invalid_argument(std::string("the ") + which +
                                " camera is not calibrated (uncalibrated camera_info: K is all zero)");
  }
  if (c.width <= 0 || c.height <= 0) throw std::invalid_argument(std::string(which) + " camera_info has no image size");
  const auto problems = checkCalibration(c, cv::Size(c.width, c.height), which);
  if (!problems.empty()) throw std::invalid_argument(problems.front());
}

/// The distortion coefficients as OpenCV takes them: 4 for equidistant, else 5 zeros when there are none.
cv::Mat distortion(const CameraCalibration& c) {
  if (c.D.empty()) return cv::Mat::zeros(1, fisheye(c) ? 4 : 5, CV_64F);
  return mat(c.D.data(), 1, static_cast<int>(c.D.size()));
}

void rectificationMaps(const cv::Mat& K, const cv::Mat& D, const cv::Mat& R, const cv::Mat& P, bool is_fisheye,
                       cv::Size size, cv::Mat* map1, cv::Mat* map2) {
  if (is_fisheye) {
    cv::fisheye::initUndistortRectifyMap(K, D, R, P, size, CV_16SC2, *map1, *map2);
  } else {
    cv::initUndistortRectifyMap(K, D, R, P, size, CV_16SC2, *map1, *map2);
  }
}

CameraCalibration rectifiedCalibration(const CameraCalibration& c) {
  CameraCalibration out = c;
  out.distortion_model = "plumb_bob";
  out.D.assign(5, 0.0);
  out.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  out.K = {c.P[0], c.P[1], c.P[2], c.P[4], c.P[5], c.P[6], c.P[8], c.P[9], c.P[10]};
  return out;
}

}  // namespace

StereoModel::StereoModel(const CameraCalibration& left, const CameraCalibration& right) {
  checkOne(left, "left");
  checkOne(right, "right");
  const auto problems = checkStereoCalibration(left, right);
  if (!problems.empty()) throw std::invalid_argument(problems.front());
  left_ = left;
  right_ = right;
  size_ = cv::Size(left.width, left.height);
  fx_ = left.P[0];
  fy_ = left.P[5];
  cx_ = left.P[2];
  cy_ = left.P[6];
  cx_right_ = right.P[2];
  baseline_ = camera::baseline(right);
  identity_ = isRectified(left) && isRectified(right);
  K_l_ = mat(left.K.data(), 3, 3);
  K_r_ = mat(right.K.data(), 3, 3);
  D_l_ = distortion(left);
  D_r_ = distortion(right);
  R_l_eigen_ = eigen3(left.R);
  R_r_eigen_ = eigen3(right.R);
  to_optical_ = R_l_eigen_.transpose();
  R_l_ = mat(left.R.data(), 3, 3);
  R_r_ = mat(right.R.data(), 3, 3);
  P_l_ = mat(left.P.data(), 3, 4)(cv::Rect(0, 0, 3, 3)).clone();
  P_r_ = mat(right.P.data(), 3, 4)(cv::Rect(0, 0, 3, 3)).clone();
  if (!identity_) {
    rectificationMaps(K_l_, D_l_, R_l_, P_l_, fisheye(left), size_, &map_l1_, &map_l2_);
    rectificationMaps(K_r_, D_r_, R_r_, P_r_, fisheye(right), size_, &map_r1_, &map_r2_);
  }
}

void StereoModel::rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect,
                          cv::Mat* right_rect) const {
  if (empty()) throw std::logic_error("StereoModel::rectify on an empty model");
  if (left_raw.size() != size_ || right_raw.size() != size_) {
    throw std::invalid_argument("the images are " + std::to_string(left_raw.cols) + "x" +
                                std::to_string(left_raw.rows) + " / " + std::to_string(right_raw.cols) + "x" +
                                std::to_string(right_raw.rows) + " but the calibration is for " +
                                std::to_string(size_.width) + "x" + std::to_string(size_.height));
  }
  if (identity_) {
    *left_rect = left_raw;
    *right_rect = right_raw;
    return;
  }
  cv::remap(left_raw, *left_rect, map_l1_, map_l2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(right_raw, *right_rect, map_r1_, map_r2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

cv::Point2f StereoModel::toRectified(const cv::Point2f& left_raw) const {
  if (identity_) return left_raw;
  std::vector<cv::Point2f> in{left_raw}, out;
  if (fisheye(left_)) {
    cv::fisheye::undistortPoints(in, out, K_l_, D_l_, R_l_, P_l_);
  } else {
    cv::undistortPoints(in, out, K_l_, D_l_, R_l_, P_l_, undistortCriteria());
  }
  return out[0];
}

cv::Point2f StereoModel::toRaw(const cv::Point2f& left_rect) const {
  if (identity_) return left_rect;
  // Ray in the rectified frame -> raw camera frame -> distorted pixel.
  const Eigen::Vector3d ray_rect((left_rect.x - cx_) / fx_, (left_rect.y - cy_) / fy_, 1.0);
  const Eigen::Vector3d ray_raw = R_l_eigen_.transpose() * ray_rect;
  const std::vector<cv::Point3d> object{cv::Point3d(ray_raw.x(), ray_raw.y(), ray_raw.z())};
  std::vector<cv::Point2d> image;
  const cv::Vec3d zero(0, 0, 0);
  if (fisheye(left_)) {
    cv::fisheye::projectPoints(object, image, zero, zero, K_l_, D_l_);
  } else {
    cv::projectPoints(object, zero, zero, K_l_, D_l_, image);
  }
  return cv::Point2f(static_cast<float>(image[0].x), static_cast<float>(image[0].y));
}

Eigen::Vector3d StereoModel::triangulate(double x, double y, double disparity, Eigen::Matrix3d* jacobian) const {
  // Rectified frame: Z = fx B / d', X = (x - cx) Z / fx, Y = (y - cy) Z / fy, d' = disparity - offset().
  const double d = disparity - offset();
  const double Z = fx_ * baseline_ / d;
  const double X = (x - cx_) * Z / fx_;
  const double Y = (y - cy_) * Z / fy_;
  if (jacobian) {
    Eigen::Matrix3d J;  // d(X, Y, Z) / d(x, y, disparity) in the rectified frame
    const double dZ = -Z / d;
    J << Z / fx_, 0.0, (x - cx_) / fx_ * dZ,  //
        0.0, Z / fy_, (y - cy_) / fy_ * dZ,   //
        0.0, 0.0, dZ;
    *jacobian = to_optical_ * J;
  }
  return to_optical_ * Eigen::Vector3d(X, Y, Z);
}

Eigen::Vector3d StereoModel::project(const Eigen::Vector3d& p_left) const {
  const Eigen::Vector3d p = to_optical_.transpose() * p_left;
  return {fx_ * p.x() / p.z() + cx_, fy_ * p.y() / p.z() + cy_, disparityAtDepth(p.z())};
}

Eigen::Matrix3d StereoModel::fundamental() const {
  // Undistorted raw pixels: x_l ~ K_l X, x_r ~ K_r (R X + t) with the right camera's pose from the rectification
  // rotations: raw right <- raw left is R = R_r^T R_l, t = -R_r^T (B, 0, 0).
  const Eigen::Matrix3d Kl = eigen3(left_.K), Kr = eigen3(right_.K);
  const Eigen::Matrix3d R = R_r_eigen_.transpose() * R_l_eigen_;
  const Eigen::Vector3d t = -(R_r_eigen_.transpose() * Eigen::Vector3d(baseline_, 0.0, 0.0));
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return Kr.inverse().transpose() * tx * R * Kl.inverse();
}

CameraCalibration StereoModel::rectifiedLeft() const { return rectifiedCalibration(left_); }

CameraCalibration StereoModel::rectifiedRight() const { return rectifiedCalibration(right_); }

StereoModel StereoModel::downsampled(int factor) const {
  if (empty()) throw std::logic_error("StereoModel::downsampled on an empty model");
  const Decimation decimation(size_, factor);
  StereoModel small(decimation.apply(rectifiedLeft()), decimation.apply(rectifiedRight()));
  small.to_optical_ = to_optical_;  // its images are rectified; its 3D points stay in the left optical frame
  return small;
}

cv::Mat StereoModel::depth(const cv::Mat& disparity) const {
  if (disparity.type() != CV_32F) throw std::invalid_argument("StereoModel::depth: the disparity map must be CV_32F");
  const float fB = static_cast<float>(fx_ * baseline_);
  const float off = static_cast<float>(offset());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat z(disparity.size(), CV_32F);
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    float* out = z.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      const float dd = d[x] - off;
      out[x] = std::isfinite(dd) && dd > 0.0f ? fB / dd : nan;
    }
  }
  return z;
}

cv::Mat StereoModel::points(const cv::Mat& depth) const {
  if (depth.type() != CV_32F) throw std::invalid_argument("StereoModel::points: the depth map must be CV_32F");
  const Eigen::Matrix3f to_left = to_optical_.cast<float>();
  const bool rotate = !to_optical_.isIdentity(1e-12);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat cloud(depth.size(), CV_32FC3);
  for (int y = 0; y < depth.rows; ++y) {
    const float* z = depth.ptr<float>(y);
    cv::Vec3f* out = cloud.ptr<cv::Vec3f>(y);
    const float ny = static_cast<float>((y - cy_) / fy_);
    for (int x = 0; x < depth.cols; ++x) {
      if (!std::isfinite(z[x])) {
        out[x] = cv::Vec3f(nan, nan, nan);
        continue;
      }
      Eigen::Vector3f p(static_cast<float>((x - cx_) / fx_) * z[x], ny * z[x], z[x]);
      if (rotate) p = to_left * p;
      out[x] = cv::Vec3f(p.x(), p.y(), p.z());
    }
  }
  return cloud;
}

}  // namespace massage_cell::camera
