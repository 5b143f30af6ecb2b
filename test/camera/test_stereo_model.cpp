// Unit tests of the stereo camera model (massage_cell/camera/stereo_model.h): the three distortion models against
// OpenCV's own functions, triangulation, the downsampled model, depth and point clouds, and bad calibrations named.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/stereo_model.h"

using massage_cell::camera::CameraCalibration;
using massage_cell::camera::StereoModel;

namespace {

constexpr double kFx = 420.0;
constexpr double kBaseline = 0.1;

std::array<double, 9> rowMajor(const Eigen::Matrix3d& m) {
  return {m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1), m(2, 2)};
}

/// One camera of a raw 640x480 pair: its own K and distortion, a small rectification rotation, the common P.
CameraCalibration rawCamera(const std::string& model, bool right) {
  CameraCalibration c;
  c.width = 640;
  c.height = 480;
  c.distortion_model = model;
  if (model == "plumb_bob") c.D = {-0.28, 0.09, 0.0012, -0.0008, 0.0};
  if (model == "rational_polynomial") c.D = {-0.25, 0.07, 0.001, -0.0005, 0.01, 0.02, -0.01, 0.005};
  if (model == "equidistant") c.D = {0.05, -0.02, 0.004, -0.001};
  c.K = {430.0, 0.0, right ? 322.0 : 316.0, 0.0, 431.0, right ? 238.0 : 243.0, 0.0, 0.0, 1.0};
  const double angle = right ? -0.02 : 0.015;
  c.R = rowMajor(Eigen::AngleAxisd(angle, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix());
  c.P = {kFx, 0.0, 318.0, right ? -kFx * kBaseline : 0.0, 0.0, kFx, 241.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  return c;
}

/// An already-rectified pair (D = 0, R = I, K = P), the right principal point 6 px further right.
CameraCalibration rectifiedCamera(bool right) {
  CameraCalibration c;
  c.width = 320;
  c.height = 240;
  c.D.assign(5, 0.0);
  c.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double cx = right ? 166.0 : 160.0;
  c.P = {kFx / 2, 0.0, cx, right ? -kFx / 2 * kBaseline : 0.0, 0.0, kFx / 2, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  c.K = {c.P[0], 0.0, cx, 0.0, c.P[5], 120.0, 0.0, 0.0, 1.0};
  return c;
}

cv::Mat K(const CameraCalibration& c) { return cv::Mat(3, 3, CV_64F, const_cast<double*>(c.K.data())).clone(); }
cv::Mat R(const CameraCalibration& c) { return cv::Mat(3, 3, CV_64F, const_cast<double*>(c.R.data())).clone(); }
cv::Mat D(const CameraCalibration& c) { return cv::Mat(c.D, true).reshape(1, 1); }
cv::Mat P3(const CameraCalibration& c) {
  return cv::Mat(3, 4, CV_64F, const_cast<double*>(c.P.data()))(cv::Rect(0, 0, 3, 3)).clone();
}

const std::vector<cv::Point2f> kRawPixels{
    {600.0f, 450.0f}, {20.0f, 15.0f}, {320.0f, 240.0f}, {100.0f, 400.0f}, {500.0f, 60.0f}};

std::string whatOf(const CameraCalibration& left, const CameraCalibration& right) {
  try {
    StereoModel model(left, right);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// ------------------------------------------------------------ distortion models --

class DistortionModel : public ::testing::TestWithParam<std::string> {};

TEST_P(DistortionModel, RectifiedPixelsAreOpenCvs) {
  const CameraCalibration l = rawCamera(GetParam(), false), r = rawCamera(GetParam(), true);
  const StereoModel model(l, r);
  EXPECT_FALSE(model.identity());
  std::vector<cv::Point2f> expected;
  if (GetParam() == "equidistant") {
    cv::fisheye::undistortPoints(kRawPixels, expected, K(l), D(l), R(l), P3(l));
  } else {
    cv::undistortPoints(kRawPixels, expected, K(l), D(l), R(l), P3(l),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-10));
  }
  for (std::size_t i = 0; i < kRawPixels.size(); ++i) {
    const cv::Point2f got = model.toRectified(kRawPixels[i]);
    EXPECT_NEAR(got.x, expected[i].x, 1e-3) << GetParam() << " pixel " << i;
    EXPECT_NEAR(got.y, expected[i].y, 1e-3) << GetParam() << " pixel " << i;
    const cv::Point2f back = model.toRaw(got);  // and back through the distortion
    EXPECT_NEAR(back.x, kRawPixels[i].x, 0.005) << GetParam() << " pixel " << i;
    EXPECT_NEAR(back.y, kRawPixels[i].y, 0.005) << GetParam() << " pixel " << i;
  }
}

TEST_P(DistortionModel, RectifiedImagesAreOpenCvs) {
  const CameraCalibration l = rawCamera(GetParam(), false), r = rawCamera(GetParam(), true);
  const StereoModel model(l, r);
  cv::Mat left(480, 640, CV_8UC3), right(480, 640, CV_8UC3);
  cv::randu(left, 0, 255);
  cv::randu(right, 0, 255);
  cv::Mat left_rect, right_rect;
  model.rectify(left, right, &left_rect, &right_rect);
  for (const auto& [calib, raw, rect] : {std::tuple(l, left, left_rect), std::tuple(r, right, right_rect)}) {
    cv::Mat map1, map2, expected;
    if (GetParam() == "equidistant") {
      cv::fisheye::initUndistortRectifyMap(K(calib), D(calib), R(calib), P3(calib), raw.size(), CV_16SC2, map1, map2);
    } else {
      cv::initUndistortRectifyMap(K(calib), D(calib), R(calib), P3(calib), raw.size(), CV_16SC2, map1, map2);
    }
    cv::remap(raw, expected, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    EXPECT_EQ(cv::norm(rect, expected, cv::NORM_INF), 0.0) << GetParam();
  }
}

INSTANTIATE_TEST_SUITE_P(StereoModel, DistortionModel,
                         ::testing::Values("plumb_bob", "rational_polynomial", "equidistant"));

TEST(StereoModel, AFisheyeIsNotRectifiedAsAPinhole) {
  // The pinhole formulas with a fisheye's four coefficients land pixels elsewhere: the model must not use them.
  const CameraCalibration l = rawCamera("equidistant", false), r = rawCamera("equidistant", true);
  const StereoModel model(l, r);
  std::vector<cv::Point2f> pinhole;
  cv::undistortPoints(std::vector<cv::Point2f>{kRawPixels[0]}, pinhole, K(l), D(l), R(l), P3(l));
  const cv::Point2f got = model.toRectified(kRawPixels[0]);
  EXPECT_GT(cv::norm(got - pinhole[0]), 2.0) << got << " vs the pinhole model's " << pinhole[0];
}

// ------------------------------------------------------------------- geometry --

TEST(StereoModel, TriangulatesAndProjectsInTheLeftOpticalFrame) {
  const StereoModel model(rawCamera("plumb_bob", false), rawCamera("plumb_bob", true));
  EXPECT_DOUBLE_EQ(model.baseline(), kBaseline);
  const Eigen::Vector3d p(0.12, -0.05, 0.9);
  const Eigen::Vector3d pixel = model.project(p);
  EXPECT_NEAR((model.triangulate(pixel.x(), pixel.y(), pixel.z()) - p).norm(), 0.0, 1e-9);
  // The raw left camera sees p where toRaw puts the rectified pixel.
  std::vector<cv::Point2d> raw;
  const CameraCalibration l = model.left();
  cv::projectPoints(std::vector<cv::Point3d>{{p.x(), p.y(), p.z()}}, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K(l), D(l),
                    raw);
  const cv::Point2f to_raw = model.toRaw(cv::Point2f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y())));
  EXPECT_NEAR(to_raw.x, raw[0].x, 1e-3);
  EXPECT_NEAR(to_raw.y, raw[0].y, 1e-3);
  // The Jacobian against central differences.
  Eigen::Matrix3d J;
  model.triangulate(pixel.x(), pixel.y(), pixel.z(), &J);
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d step = Eigen::Vector3d::Zero();
    step[k] = 1e-4;
    const Eigen::Vector3d a = pixel + step, b = pixel - step;
    const Eigen::Vector3d numeric =
        (model.triangulate(a.x(), a.y(), a.z()) - model.triangulate(b.x(), b.y(), b.z())) / 2e-4;
    EXPECT_NEAR((J.col(k) - numeric).norm(), 0.0, 1e-6) << "column " << k;
  }
}

TEST(StereoModel, AnAlreadyRectifiedPairIsUsedAsItIs) {
  const StereoModel model(rectifiedCamera(false), rectifiedCamera(true));
  EXPECT_TRUE(model.identity());
  EXPECT_DOUBLE_EQ(model.offset(), -6.0);
  const cv::Point2f p(33.5f, 77.25f);
  EXPECT_EQ(model.toRectified(p), p);
  EXPECT_EQ(model.toRaw(p), p);
  cv::Mat left(240, 320, CV_8U, cv::Scalar(7)), right(240, 320, CV_8U, cv::Scalar(9)), l2, r2;
  model.rectify(left, right, &l2, &r2);
  EXPECT_EQ(l2.data, left.data);
  EXPECT_THROW(model.rectify(left, cv::Mat(120, 160, CV_8U), &l2, &r2), std::invalid_argument);
}

TEST(StereoModel, DownsampledModelKeepsEveryPointWhereItWas) {
  const StereoModel full(rawCamera("rational_polynomial", false), rawCamera("rational_polynomial", true));
  const StereoModel half = full.downsampled(2);
  EXPECT_TRUE(half.identity());
  EXPECT_EQ(half.size(), cv::Size(320, 240));
  EXPECT_DOUBLE_EQ(half.fx(), kFx / 2);
  EXPECT_DOUBLE_EQ(half.cx(), (318.0 + 0.5) / 2 - 0.5);  // pixel centres kept, as cv::resize(INTER_AREA)
  EXPECT_DOUBLE_EQ(half.baseline(), kBaseline);
  const Eigen::Vector3d p(-0.2, 0.1, 1.1);
  const Eigen::Vector3d a = full.project(p), b = half.project(p);
  EXPECT_NEAR(b.x(), (a.x() + 0.5) / 2 - 0.5, 1e-9);
  EXPECT_NEAR(b.z(), a.z() / 2, 1e-9);
  EXPECT_NEAR((half.triangulate(b.x(), b.y(), b.z()) - p).norm(), 0.0, 1e-9);  // the same optical frame
  EXPECT_THROW(full.downsampled(0), std::invalid_argument);
  EXPECT_THROW(full.downsampled(1000), std::invalid_argument);
}

TEST(StereoModel, DepthAndPointsAreTheTriangulatedOnes) {
  const StereoModel model = StereoModel(rawCamera("plumb_bob", false), rawCamera("plumb_bob", true)).downsampled(4);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat disparity(120, 160, CV_32F, cv::Scalar(12.5f));
  disparity.at<float>(3, 4) = nan;
  disparity.at<float>(5, 6) = static_cast<float>(model.offset());         // at infinity
  disparity.at<float>(7, 8) = static_cast<float>(model.offset()) - 1.0f;  // beyond it
  const cv::Mat depth = model.depth(disparity);
  EXPECT_NEAR(depth.at<float>(0, 0), kFx / 4 * kBaseline / (12.5 - model.offset()), 1e-5);
  EXPECT_TRUE(std::isnan(depth.at<float>(3, 4)));
  EXPECT_TRUE(std::isnan(depth.at<float>(5, 6)));
  EXPECT_TRUE(std::isnan(depth.at<float>(7, 8)));
  const cv::Mat cloud = model.points(depth);
  for (const cv::Point& q : {cv::Point(0, 0), cv::Point(150, 20), cv::Point(80, 110)}) {
    const Eigen::Vector3d expected = model.triangulate(q.x, q.y, 12.5);
    const cv::Vec3f got = cloud.at<cv::Vec3f>(q);
    EXPECT_NEAR((Eigen::Vector3d(got[0], got[1], got[2]) - expected).norm(), 0.0, 1e-5) << q;
  }
  EXPECT_TRUE(std::isnan(cloud.at<cv::Vec3f>(3, 4)[0]));
  EXPECT_THROW(model.depth(cv::Mat(4, 4, CV_8U)), std::invalid_argument);
}

// --------------------------------------------------------------- bad calibrations --

TEST(StereoModel, EveryNonFiniteValueIsNamed) {
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    for (std::size_t i = 0; i < 9; ++i) {
      CameraCalibration l = rawCamera("plumb_bob", false);
      l.K[i] = bad;
      EXPECT_NE(whatOf(l, rawCamera("plumb_bob", true)).find("K"), std::string::npos) << "K[" << i << "] " << bad;
      l = rawCamera("plumb_bob", false);
      l.R[i] = bad;
      EXPECT_NE(whatOf(l, rawCamera("plumb_bob", true)).find("R"), std::string::npos) << "R[" << i << "] " << bad;
    }
    for (std::size_t i = 0; i < 12; ++i) {
      CameraCalibration r = rawCamera("plumb_bob", true);
      r.P[i] = bad;
      EXPECT_NE(whatOf(rawCamera("plumb_bob", false), r).find("P"), std::string::npos) << "P[" << i << "] " << bad;
    }
    for (const std::string model : {"plumb_bob", "rational_polynomial", "equidistant"}) {
      for (std::size_t i = 0; i < rawCamera(model, true).D.size(); ++i) {
        CameraCalibration r = rawCamera(model, true);
        r.D[i] = bad;
        const std::string what = whatOf(rawCamera(model, false), r);
        EXPECT_NE(what.find("right"), std::string::npos) << what;
        EXPECT_NE(what.find("D holds a non-finite value"), std::string::npos) << model << " D[" << i << "]: " << what;
      }
    }
  }
}

TEST(StereoModel, ZerosWhereTheyCannotBeAreNamed) {
  const CameraCalibration good = rawCamera("plumb_bob", false), right = rawCamera("plumb_bob", true);
  CameraCalibration c = good;
  c.K.fill(0.0);
  EXPECT_NE(whatOf(c, right).find("left camera is not calibrated"), std::string::npos) << whatOf(c, right);
  c = good;
  c.K[0] = 0.0;  // K[0] is what tells a calibrated camera (camera_info_manager's rule)
  EXPECT_NE(whatOf(c, right).find("left camera is not calibrated"), std::string::npos) << whatOf(c, right);
  c = good;
  c.K[4] = 0.0;
  EXPECT_NE(whatOf(c, right).find("K[0], K[4]"), std::string::npos) << whatOf(c, right);
  for (const std::size_t i : {0u, 5u}) {
    c = good;
    c.P[i] = 0.0;
    EXPECT_NE(whatOf(c, right).find("P[0], P[5]"), std::string::npos) << whatOf(c, right);
  }
  c = good;
  c.P[10] = 0.0;
  EXPECT_NE(whatOf(c, right).find("P[10]"), std::string::npos) << whatOf(c, right);
  c = good;
  c.R.fill(0.0);
  EXPECT_NE(whatOf(c, right).find("R is not a rotation"), std::string::npos) << whatOf(c, right);
  c = good;
  c.width = 0;
  EXPECT_NE(whatOf(c, right).find("no image size"), std::string::npos) << whatOf(c, right);
}

TEST(StereoModel, APairThatIsNotHorizontalAndRectifiedTogetherIsRefused) {
  const CameraCalibration l = rawCamera("plumb_bob", false), good_right = rawCamera("plumb_bob", true);
  CameraCalibration r = good_right;
  r.P[7] = r.P[3];  // vertical: the baseline in Ty
  r.P[3] = 0.0;
  EXPECT_NE(whatOf(l, r).find("-fx * baseline"), std::string::npos) << whatOf(l, r);
  r = good_right;
  r.P[7] = -5.0;  // both
  EXPECT_NE(whatOf(l, r).find("P[7]"), std::string::npos) << whatOf(l, r);
  r = good_right;
  r.P[5] *= 1.1;
  EXPECT_NE(whatOf(l, r).find("not rectified together"), std::string::npos) << whatOf(l, r);
  r = good_right;
  r.width = 320;
  EXPECT_NE(whatOf(l, r).find("different image sizes"), std::string::npos) << whatOf(l, r);
  r = good_right;
  r.distortion_model = "kannala_brandt";
  EXPECT_NE(whatOf(l, r).find("unknown distortion model 'kannala_brandt'"), std::string::npos) << whatOf(l, r);
  EXPECT_TRUE(whatOf(l, good_right).empty()) << whatOf(l, good_right);
}
