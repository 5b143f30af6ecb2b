#include "massage_cell/camera/calibration.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

namespace massage_cell::camera {

namespace {

Eigen::Matrix3d mat3(const std::array<double, 9>& a) {
  Eigen::Matrix3d m;
  m << a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8];
  return m;
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

bool near(double a, double b, double rel) { return std::abs(a - b) <= rel * std::max(1.0, std::abs(a)); }

}  // namespace

std::vector<std::string> checkCalibration(const CameraCalibration& c, cv::Size image, const std::string& which) {
  std::vector<std::string> problems;
  if (!c.isCalibrated()) return problems;  // uncalibrated: nothing to check
  if (c.width != image.width || c.height != image.height) {
    problems.push_back(which + " calibration is for " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                       " images but the camera delivers " + std::to_string(image.width) + "x" +
                       std::to_string(image.height));
  }
  if (!(c.K[0] > 0.0) || !(c.K[4] > 0.0))
    problems.push_back(which + " calibration: focal lengths K[0], K[4] must be > 0");
  if (!(c.P[0] > 0.0) || !(c.P[5] > 0.0)) problems.push_back(which + " calibration: projection P[0], P[5] must be > 0");
  if (c.P[10] != 1.0 && std::isfinite(c.P[10])) {
    problems.push_back(which + " calibration: projection P[10] must be 1, got " + num(c.P[10]));
  }
  auto finite = [&](const auto& values, const char* name) {
    for (double v : values)
      if (!std::isfinite(v)) {
        problems.push_back(which + " calibration: " + name + " holds a non-finite value");
        return;
      }
  };
  finite(c.K, "K");
  finite(c.D, "D");
  finite(c.R, "R");
  finite(c.P, "P");
  const Eigen::Matrix3d R = mat3(c.R);
  if (!(R.transpose() * R).isIdentity(1e-3) || std::abs(R.determinant() - 1.0) > 1e-3) {
    problems.push_back(which + " calibration: rectification_matrix R is not a rotation");
  }
  const std::size_t n = c.D.size();
  if (c.distortion_model == "plumb_bob" && n != 5 && n != 0) {
    problems.push_back(which + " calibration: plumb_bob needs 5 distortion coefficients, got " + std::to_string(n));
  } else if (c.distortion_model == "rational_polynomial" && n != 8) {
    problems.push_back(which + " calibration: rational_polynomial needs 8 distortion coefficients, got " +
                       std::to_string(n));
  } else if (c.distortion_model == "equidistant" && n != 4) {
    problems.push_back(which + " calibration: equidistant needs 4 distortion coefficients, got " + std::to_string(n));
  } else if (c.distortion_model != "plumb_bob" && c.distortion_model != "rational_polynomial" &&
             c.distortion_model != "equidistant") {
    problems.push_back(which + " calibration: unknown distortion model '" + c.distortion_model + "'");
  }
  return problems;
}

std::vector<std::string> checkStereoCalibration(const CameraCalibration& l, const CameraCalibration& r) {
  std::vector<std::string> problems;
  if (!l.isCalibrated() || !r.isCalibrated()) return problems;
  if (l.width != r.width || l.height != r.height) {
    problems.push_back("left and right calibrations are for different image sizes");
  }
  if (!near(l.P[0], r.P[0], 1e-3) || !near(l.P[5], r.P[5], 1e-3) || !near(l.P[6], r.P[6], 1e-3)) {
    problems.push_back("left and right projections P differ in fx, fy or cy (" + num(l.P[0]) + "/" + num(r.P[0]) +
                       ", " + num(l.P[5]) + "/" + num(r.P[5]) + ", " + num(l.P[6]) + "/" + num(r.P[6]) +
                       "): the pair is not rectified together");
  }
  if (std::abs(l.P[3]) > 1e-9) problems.push_back("left projection P[3] must be 0 (Tx of the reference camera)");
  if (!(r.P[3] < 0.0)) {
    problems.push_back("right projection P[3] = " + num(r.P[3]) +
                       " must be -fx * baseline < 0 (right camera to the right of the left one); "
                       "stereo_image_proc computes no depth otherwise");
  }
  if (std::abs(r.P[7]) > 1e-9) {
    problems.push_back("right projection P[7] = " + num(r.P[7]) +
                       " must be 0: a vertical (or diagonal) pair is not supported, the cameras must be side by side");
  }
  return problems;
}

CameraCalibration declareRectified(const CameraCalibration& c) {
  CameraCalibration out = c;
  if (!c.isCalibrated()) return out;
  out.D.assign(c.distortion_model == "rational_polynomial" ? 8 : c.distortion_model == "equidistant" ? 4 : 5, 0.0);
  out.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  out.K = {c.P[0], c.P[1], c.P[2], c.P[4], c.P[5], c.P[6], c.P[8], c.P[9], c.P[10]};
  return out;
}

double baseline(const CameraCalibration& right) {
  if (!(right.P[0] > 0.0)) return 0.0;
  return -right.P[3] / right.P[0];
}

Eigen::Isometry3d rightCameraInLeft(const CameraCalibration& left, const CameraCalibration& right) {
  Eigen::Matrix3d Rl = mat3(left.R);
  Eigen::Matrix3d Rr = mat3(right.R);
  if (!left.isCalibrated() || Rl.isZero()) Rl.setIdentity();
  if (!right.isCalibrated() || Rr.isZero()) Rr.setIdentity();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Rl.transpose() * Rr;
  pose.translation() = Rl.transpose() * Eigen::Vector3d(baseline(right), 0.0, 0.0);
  return pose;
}

Decimation Decimation::toWidth(cv::Size full, int max_width) {
  if (max_width <= 0 || full.width <= max_width) return Decimation(full, 1);
  return Decimation(full, (full.width + max_width - 1) / max_width);
}

Decimation::Decimation(cv::Size full, int factor) : full_(full), factor_(factor) {
  if (factor < 1) throw std::invalid_argument("decimation factor " + std::to_string(factor) + " is below 1");
  if (full.width < factor || full.height < factor) {
    throw std::invalid_argument("cannot decimate a " + std::to_string(full.width) + "x" + std::to_string(full.height) +
                                " image by " + std::to_string(factor));
  }
  size_ = cv::Size(full.width / factor, full.height / factor);
  sx_ = static_cast<double>(size_.width) / full.width;
  sy_ = static_cast<double>(size_.height) / full.height;
}

cv::Mat Decimation::apply(const cv::Mat& image) const {
  if (image.size() != full_) {
    throw std::invalid_argument("decimation: the image is " + std::to_string(image.cols) + "x" +
                                std::to_string(image.rows) + ", expected " + std::to_string(full_.width) + "x" +
                                std::to_string(full_.height));
  }
  if (identity()) return image;
  cv::Mat out;
  cv::resize(image, out, size_, 0, 0, cv::INTER_AREA);
  return out;
}

CameraCalibration Decimation::apply(const CameraCalibration& c) const {
  if (full_.area() > 0 && (c.width != full_.width || c.height != full_.height)) {
    throw std::invalid_argument("decimation: the calibration is for " + std::to_string(c.width) + "x" +
                                std::to_string(c.height) + ", the images are " + std::to_string(full_.width) + "x" +
                                std::to_string(full_.height));
  }
  CameraCalibration out = c;
  if (identity()) return out;
  out.width = size_.width;
  out.height = size_.height;
  // Row 0 (x) scales by sx, row 1 (y) by sy; the principal point keeps its pixel centre.
  auto scaleRows = [&](double* m, int cols) {
    for (int j = 0; j < cols; ++j) {
      m[j] *= sx_;
      m[cols + j] *= sy_;
    }
    m[2] += 0.5 * (sx_ - 1.0) * m[2 * cols + 2];
    m[cols + 2] += 0.5 * (sy_ - 1.0) * m[2 * cols + 2];
  };
  scaleRows(out.K.data(), 3);
  scaleRows(out.P.data(), 4);
  return out;
}

cv::Point2f Decimation::toDecimated(const cv::Point2f& p) const {
  return {static_cast<float>((p.x + 0.5) * sx_ - 0.5), static_cast<float>((p.y + 0.5) * sy_ - 0.5)};
}

cv::Point2f Decimation::toFull(const cv::Point2f& p) const {
  return {static_cast<float>((p.x + 0.5) / sx_ - 0.5), static_cast<float>((p.y + 0.5) / sy_ - 0.5)};
}

}  // namespace massage_cell::camera
