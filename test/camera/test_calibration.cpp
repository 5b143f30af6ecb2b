// Unit tests of the calibration checks, the rectified declaration, the stereo
// geometry (massage_cell/camera/calibration.h) and the camera_info YAML files
// (massage_cell/camera/calibration_io.h). main() is in test_frame_sources.cpp.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/calibration_io.h"

namespace fs = std::filesystem;
using namespace massage_cell::camera;

namespace {

constexpr double kFx = 500.0;
constexpr double kBaseline = 0.12;

/// A calibrated, rectified camera of 640x480 images; `tx` is P[3].
CameraCalibration makeCamera(double tx = 0.0) {
  CameraCalibration c;
  c.width = 640;
  c.height = 480;
  c.distortion_model = "plumb_bob";
  c.D = {-0.1, 0.05, 0.001, -0.002, 0.0};
  c.K = {510.0, 0.0, 318.0, 0.0, 512.0, 242.0, 0.0, 0.0, 1.0};
  c.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.P = {kFx, 0.0, 320.0, tx, 0.0, kFx, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  return c;
}

CameraCalibration makeLeft() { return makeCamera(0.0); }
CameraCalibration makeRight() { return makeCamera(-kFx * kBaseline); }

std::array<double, 9> rowMajor(const Eigen::Matrix3d& m) {
  return {m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1), m(2, 2)};
}

Eigen::Matrix3d rotation(double angle, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

::testing::AssertionResult anyContains(const std::vector<std::string>& problems, const std::string& part) {
  for (const auto& p : problems)
    if (p.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  auto failure = ::testing::AssertionFailure() << "no problem mentions '" << part << "'; problems:";
  for (const auto& p : problems) failure << "\n  " << p;
  return failure;
}

std::string joined(const std::vector<std::string>& problems) {
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  return all;
}

// -------------------------------------------------------------- checkCalibration --

TEST(CheckCalibrationTest, ConsistentCalibrationHasNoProblems) {
  EXPECT_TRUE(checkCalibration(makeLeft(), {640, 480}, "left").empty())
      << joined(checkCalibration(makeLeft(), {640, 480}, "left"));
  CameraCalibration no_distortion = makeLeft();
  no_distortion.D.clear();  // plumb_bob with no coefficients: no distortion
  EXPECT_TRUE(checkCalibration(no_distortion, {640, 480}, "left").empty());
  CameraCalibration rational = makeLeft();
  rational.distortion_model = "rational_polynomial";
  rational.D = {0.1, 0.01, 0.0, 0.0, 0.001, 0.2, 0.02, 0.002};
  EXPECT_TRUE(checkCalibration(rational, {640, 480}, "left").empty());
  CameraCalibration fisheye = makeLeft();
  fisheye.distortion_model = "equidistant";
  fisheye.D = {0.1, 0.01, 0.001, 0.0001};
  EXPECT_TRUE(checkCalibration(fisheye, {640, 480}, "left").empty());
}

TEST(CheckCalibrationTest, UncalibratedHasNoProblems) {
  const CameraCalibration uncalibrated;  // K all zero, as camera_info_manager's default
  EXPECT_FALSE(uncalibrated.isCalibrated());
  EXPECT_TRUE(checkCalibration(uncalibrated, {640, 480}, "left").empty());
  EXPECT_TRUE(checkCalibration(uncalibrated, {1280, 720}, "left").empty());
}

TEST(CheckCalibrationTest, SizeMismatchNamesBothSizes) {
  const auto problems = checkCalibration(makeLeft(), {1280, 720}, "right camera");
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "640x480"));
  EXPECT_TRUE(anyContains(problems, "1280x720"));
  EXPECT_TRUE(anyContains(problems, "right camera"));
}

TEST(CheckCalibrationTest, NonRotationR) {
  CameraCalibration c = makeLeft();
  c.R = {2, 0, 0, 0, 2, 0, 0, 0, 2};  // scaled
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "rectification_matrix"));
  c.R = {1, 0, 0, 0, 1, 0, 0, 0, -1};  // a reflection: orthogonal but det = -1
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "rectification_matrix"));
  c.R = {};  // all zero
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "rectification_matrix"));
  c.R = rowMajor(rotation(0.3, {1, 2, 3}));  // a real rotation is fine
  EXPECT_TRUE(checkCalibration(c, {640, 480}, "left").empty());
}

TEST(CheckCalibrationTest, WrongDistortionCount) {
  CameraCalibration c = makeLeft();
  c.D = {0.1, 0.2, 0.3, 0.4};
  auto problems = checkCalibration(c, {640, 480}, "left");
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "plumb_bob"));
  EXPECT_TRUE(anyContains(problems, "got 4"));

  c.distortion_model = "rational_polynomial";
  c.D = {0.1, 0.2, 0.3, 0.4, 0.5};
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "rational_polynomial"));
  c.distortion_model = "equidistant";
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "equidistant"));
}

TEST(CheckCalibrationTest, UnknownModel) {
  CameraCalibration c = makeLeft();
  c.distortion_model = "fisheye_xyz";
  const auto problems = checkCalibration(c, {640, 480}, "left");
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "fisheye_xyz"));
}

TEST(CheckCalibrationTest, NonPositiveFocalLengths) {
  CameraCalibration c = makeLeft();
  c.K[4] = -512.0;
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "K[4]"));
  c = makeLeft();
  c.P[5] = 0.0;
  EXPECT_TRUE(anyContains(checkCalibration(c, {640, 480}, "left"), "P[5]"));
}

// ------------------------------------------------------- checkStereoCalibration --

TEST(CheckStereoCalibrationTest, ConsistentPairHasNoProblems) {
  const auto problems = checkStereoCalibration(makeLeft(), makeRight());
  EXPECT_TRUE(problems.empty()) << joined(problems);
}

TEST(CheckStereoCalibrationTest, UncalibratedPairIsNotChecked) {
  EXPECT_TRUE(checkStereoCalibration(CameraCalibration{}, CameraCalibration{}).empty());
  EXPECT_TRUE(checkStereoCalibration(makeLeft(), CameraCalibration{}).empty());
}

TEST(CheckStereoCalibrationTest, RightTxMustBeNegative) {
  CameraCalibration right = makeRight();
  right.P[3] = 0.0;
  EXPECT_TRUE(anyContains(checkStereoCalibration(makeLeft(), right), "P[3]"));
  right.P[3] = kFx * kBaseline;  // right camera on the left
  const auto problems = checkStereoCalibration(makeLeft(), right);
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "right projection"));
}

TEST(CheckStereoCalibrationTest, FocalLengthMismatch) {
  CameraCalibration right = makeRight();
  right.P[0] = 520.0;
  right.P[3] = -520.0 * kBaseline;
  const auto problems = checkStereoCalibration(makeLeft(), right);
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "fx"));
  // cy mismatch: also not rectified together.
  right = makeRight();
  right.P[6] = 250.0;
  EXPECT_EQ(checkStereoCalibration(makeLeft(), right).size(), 1u);
}

TEST(CheckStereoCalibrationTest, LeftTxMustBeZero) {
  CameraCalibration left = makeLeft();
  left.P[3] = 5.0;
  const auto problems = checkStereoCalibration(left, makeRight());
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_TRUE(anyContains(problems, "left projection P[3]"));
}

TEST(CheckStereoCalibrationTest, SizeMismatch) {
  CameraCalibration right = makeRight();
  right.width = 1280;
  EXPECT_TRUE(anyContains(checkStereoCalibration(makeLeft(), right), "image sizes"));
}

// -------------------------------------------------------------- declareRectified --

TEST(DeclareRectifiedTest, IdentityRectificationFromP) {
  CameraCalibration c = makeRight();
  c.R = rowMajor(rotation(0.05, {0, 1, 0}));
  c.P = {480.0, 0.5, 321.0, -57.6, 0.0, 481.0, 239.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  const CameraCalibration out = declareRectified(c);
  EXPECT_EQ(out.width, c.width);
  EXPECT_EQ(out.height, c.height);
  EXPECT_EQ(out.distortion_model, "plumb_bob");
  ASSERT_EQ(out.D.size(), 5u);
  for (double d : out.D) EXPECT_EQ(d, 0.0);
  EXPECT_EQ(out.R, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(out.K, (std::array<double, 9>{480.0, 0.5, 321.0, 0.0, 481.0, 239.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(out.P, c.P);
  EXPECT_TRUE(checkCalibration(out, {640, 480}, "right").empty());
}

TEST(DeclareRectifiedTest, KeepsTheDistortionModelsCount) {
  CameraCalibration c = makeLeft();
  c.distortion_model = "rational_polynomial";
  c.D = {0.1, 0.01, 0.0, 0.0, 0.001, 0.2, 0.02, 0.002};
  const CameraCalibration out = declareRectified(c);
  ASSERT_EQ(out.D.size(), 8u);
  for (double d : out.D) EXPECT_EQ(d, 0.0);
}

TEST(DeclareRectifiedTest, UncalibratedIsUnchanged) {
  CameraCalibration c;
  c.width = 320;
  c.height = 240;
  c.D = {0.3};
  c.R = {0, 1, 0, 1, 0, 0, 0, 0, 1};
  c.P[0] = 400.0;  // K[0] = 0: uncalibrated all the same
  const CameraCalibration out = declareRectified(c);
  EXPECT_EQ(out.D, c.D);
  EXPECT_EQ(out.K, c.K);
  EXPECT_EQ(out.R, c.R);
  EXPECT_EQ(out.P, c.P);
  EXPECT_EQ(out.width, 320);
}

// ------------------------------------------------------------- stereo geometry --

TEST(BaselineTest, FromRightProjection) {
  EXPECT_NEAR(baseline(makeRight()), kBaseline, 1e-12);
  CameraCalibration right = makeRight();
  right.P[0] = 800.0;
  right.P[3] = -800.0 * 0.065;
  EXPECT_NEAR(baseline(right), 0.065, 1e-12);
  EXPECT_EQ(baseline(CameraCalibration{}), 0.0);
}

TEST(RightCameraInLeftTest, IdentityRectification) {
  const Eigen::Isometry3d pose = rightCameraInLeft(makeLeft(), makeRight());
  EXPECT_TRUE(pose.linear().isIdentity(1e-12)) << pose.linear();
  EXPECT_TRUE(pose.translation().isApprox(Eigen::Vector3d(kBaseline, 0, 0), 1e-12)) << pose.translation().transpose();
}

TEST(RightCameraInLeftTest, RotatedRectification) {
  const Eigen::Matrix3d Rl = rotation(0.1, {0.3, 1.0, 0.2});
  const Eigen::Matrix3d Rr = rotation(-0.07, {0.1, 0.9, -0.3});
  CameraCalibration left = makeLeft();
  CameraCalibration right = makeRight();
  left.R = rowMajor(Rl);
  right.R = rowMajor(Rr);
  const Eigen::Isometry3d pose = rightCameraInLeft(left, right);
  const Eigen::Vector3d expected_t = Rl.transpose() * Eigen::Vector3d(kBaseline, 0, 0);
  EXPECT_TRUE(pose.translation().isApprox(expected_t, 1e-12)) << pose.translation().transpose();
  EXPECT_TRUE(pose.linear().isApprox(Rl.transpose() * Rr, 1e-12)) << pose.linear();
  EXPECT_GT((pose.translation() - Eigen::Vector3d(kBaseline, 0, 0)).norm(), 1e-3);  // the rotation matters

  // Independent check: a point X in the left raw frame is R_l X in the shared
  // rectified frame, R_l X - (B,0,0) in the right rectified frame and
  // R_r^T (R_l X - (B,0,0)) in the right raw frame; the pose maps it back.
  const Eigen::Vector3d X(0.3, -0.2, 1.5);
  const Eigen::Vector3d x_right = Rr.transpose() * (Rl * X - Eigen::Vector3d(kBaseline, 0, 0));
  EXPECT_TRUE((pose * x_right).isApprox(X, 1e-12)) << (pose * x_right).transpose();
}

// ------------------------------------------------------------------- YAML files --

class CameraInfoYamlTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("massage_cell_test_calibration_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    ASSERT_TRUE(fs::create_directories(dir_)) << dir_;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  void writeText(const std::string& name, const std::string& text) const {
    std::ofstream file(path(name));
    file << text;
    ASSERT_TRUE(file.good());
  }

  /// Expects readCameraInfoYaml(file) to throw std::runtime_error; returns the message.
  static std::string readError(const std::string& file) {
    try {
      readCameraInfoYaml(file);
    } catch (const std::runtime_error& e) {
      return e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "expected std::runtime_error, got: " << e.what();
      return "";
    }
    ADD_FAILURE() << "reading " << file << " did not throw";
    return "";
  }

  /// A valid camera_info file, with `projection` as the projection_matrix
  /// block ("" leaves it out).
  static std::string cameraInfoText(const std::string& projection) {
    return "image_width: 640\n"
           "image_height: 480\n"
           "camera_name: left\n"
           "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"
           "distortion_model: plumb_bob\n"
           "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
           "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n" +
           projection;
  }

  fs::path dir_;
};

void expectNearArray(const double* a, const double* b, std::size_t n, const char* what) {
  for (std::size_t i = 0; i < n; ++i)
    EXPECT_NEAR(a[i], b[i], 1e-9 * std::max(1.0, std::abs(b[i]))) << what << "[" << i << "]";
}

TEST_F(CameraInfoYamlTest, RoundTripKeepsAllFields) {
  CameraCalibration c;
  c.width = 1280;
  c.height = 720;
  c.distortion_model = "rational_polynomial";
  c.D = {-0.312345678, 0.123456789, 0.000123, -0.000456, 0.0789, 0.25, -0.0125, 0.003};
  c.K = {912.345678, 0.0, 641.25, 0.0, 913.5, 359.875, 0.0, 0.0, 1.0};
  c.R = rowMajor(rotation(0.0123, {0.2, 1.0, -0.1}));
  c.P = {900.125, 0.0, 640.5, -108.015, 0.0, 900.125, 360.25, 0.0, 0.0, 0.0, 1.0, 0.0};

  const std::string file = path("left.yaml");
  writeCameraInfoYaml(file, c, "stereo_left");
  std::string name;
  const CameraCalibration back = readCameraInfoYaml(file, &name);
  EXPECT_EQ(name, "stereo_left");
  EXPECT_EQ(back.width, 1280);
  EXPECT_EQ(back.height, 720);
  EXPECT_EQ(back.distortion_model, "rational_polynomial");
  ASSERT_EQ(back.D.size(), c.D.size());
  expectNearArray(back.D.data(), c.D.data(), c.D.size(), "D");
  expectNearArray(back.K.data(), c.K.data(), 9, "K");
  expectNearArray(back.R.data(), c.R.data(), 9, "R");
  expectNearArray(back.P.data(), c.P.data(), 12, "P");
  EXPECT_TRUE(back.isCalibrated());

  // Without a name pointer it reads all the same.
  EXPECT_EQ(readCameraInfoYaml(file).width, 1280);
}

TEST_F(CameraInfoYamlTest, RoundTripWithoutDistortion) {
  CameraCalibration c = makeRight();
  c.D.clear();
  const std::string file = path("right.yaml");
  writeCameraInfoYaml(file, c, "right");
  const CameraCalibration back = readCameraInfoYaml(file);
  EXPECT_TRUE(back.D.empty());
  EXPECT_EQ(back.distortion_model, "plumb_bob");
  expectNearArray(back.P.data(), c.P.data(), 12, "P");
  EXPECT_NEAR(baseline(back), kBaseline, 1e-12);
}

TEST_F(CameraInfoYamlTest, ReadsHandWrittenFile) {
  writeText("hand.yaml", cameraInfoText("projection_matrix:\n  rows: 3\n  cols: 4\n"
                                        "  data: [500, 0, 320, -60, 0, 500, 240, 0, 0, 0, 1, 0]\n"));
  std::string name;
  const CameraCalibration c = readCameraInfoYaml(path("hand.yaml"), &name);
  EXPECT_EQ(name, "left");
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.D.size(), 5u);
  EXPECT_DOUBLE_EQ(c.P[3], -60.0);
  EXPECT_DOUBLE_EQ(c.K[0], 500.0);
}

TEST_F(CameraInfoYamlTest, WriteToMissingFolderThrows) {
  const std::string file = path("no_such_folder/left.yaml");
  try {
    writeCameraInfoYaml(file, makeLeft(), "left");
    FAIL() << "writing " << file << " did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
  }
}

TEST_F(CameraInfoYamlTest, MissingFile) {
  const std::string file = path("missing.yaml");
  EXPECT_NE(readError(file).find(file), std::string::npos);
}

TEST_F(CameraInfoYamlTest, InvalidYaml) {
  writeText("broken.yaml", "image_width: [640, 480\ncamera_matrix: {rows: 3\n");
  EXPECT_NE(readError(path("broken.yaml")).find(path("broken.yaml")), std::string::npos);
}

TEST_F(CameraInfoYamlTest, NotAMap) {
  writeText("list.yaml", "- 1\n- 2\n");
  EXPECT_NE(readError(path("list.yaml")).find(path("list.yaml")), std::string::npos);
}

TEST_F(CameraInfoYamlTest, MissingProjectionMatrix) {
  writeText("no_p.yaml", cameraInfoText(""));
  const std::string message = readError(path("no_p.yaml"));
  EXPECT_NE(message.find(path("no_p.yaml")), std::string::npos) << message;
  EXPECT_NE(message.find("projection_matrix"), std::string::npos) << message;
}

TEST_F(CameraInfoYamlTest, WrongNumberOfValues) {
  writeText("short_p.yaml", cameraInfoText("projection_matrix:\n  rows: 3\n  cols: 4\n"
                                           "  data: [500, 0, 320, -60, 0, 500, 240, 0, 0, 0, 1]\n"));
  std::string message = readError(path("short_p.yaml"));
  EXPECT_NE(message.find(path("short_p.yaml")), std::string::npos) << message;
  EXPECT_NE(message.find("projection_matrix"), std::string::npos) << message;
  // The counts (12 needed, 11 given), apart from digits of the temporary path.
  for (auto at = message.find(dir_.string()); at != std::string::npos; at = message.find(dir_.string())) {
    message.erase(at, dir_.string().size());
  }
  EXPECT_NE(message.find("12"), std::string::npos) << message;
  EXPECT_NE(message.find("11"), std::string::npos) << message;
}

TEST_F(CameraInfoYamlTest, NonNumericValue) {
  writeText("text_p.yaml", cameraInfoText("projection_matrix:\n  rows: 3\n  cols: 4\n"
                                          "  data: [500, 0, 320, abc, 0, 500, 240, 0, 0, 0, 1, 0]\n"));
  EXPECT_NE(readError(path("text_p.yaml")).find(path("text_p.yaml")), std::string::npos);
}

// ------------------------------------------------------------------- Decimation --

TEST(DecimationTest, FactorFromTheWidthBudget) {
  EXPECT_EQ(Decimation::toWidth({640, 480}, 480).factor(), 2);
  EXPECT_EQ(Decimation::toWidth({640, 480}, 320).factor(), 2);
  EXPECT_EQ(Decimation::toWidth({1280, 960}, 480).factor(), 3);
  EXPECT_TRUE(Decimation::toWidth({320, 240}, 480).identity());
  EXPECT_TRUE(Decimation::toWidth({1280, 960}, 0).identity()) << "0: full resolution";
  const Decimation d = Decimation::toWidth({641, 481}, 480);
  EXPECT_EQ(d.size(), cv::Size(320, 240));
  EXPECT_THROW(Decimation({640, 480}, 0), std::invalid_argument);
  EXPECT_THROW(Decimation({0, 0}, 2), std::invalid_argument);
}

TEST(DecimationTest, CalibrationAndPixelsAgreeWithTheProjection) {
  const Decimation d({640, 480}, 2);
  const CameraCalibration full = makeRight();
  const CameraCalibration half = d.apply(full);
  EXPECT_EQ(half.width, 320);
  EXPECT_EQ(half.height, 240);
  EXPECT_EQ(half.D, full.D);
  EXPECT_NEAR(baseline(half), kBaseline, 1e-12) << "metres do not change";
  EXPECT_TRUE(checkCalibration(half, d.size(), "half").empty()) << joined(checkCalibration(half, d.size(), "half"));
  // A point projected with each P lands on pixels that toDecimated / toFull map onto each other.
  const Eigen::Vector4d X(0.13, -0.07, 0.9, 1.0);
  auto project = [&](const CameraCalibration& c) {
    const Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> P(c.P.data());
    const Eigen::Vector3d x = P * X;
    return cv::Point2f(static_cast<float>(x.x() / x.z()), static_cast<float>(x.y() / x.z()));
  };
  const cv::Point2f p_full = project(full), p_half = project(half);
  EXPECT_NEAR(d.toDecimated(p_full).x, p_half.x, 1e-3);
  EXPECT_NEAR(d.toDecimated(p_full).y, p_half.y, 1e-3);
  EXPECT_NEAR(d.toFull(p_half).x, p_full.x, 1e-3);
  EXPECT_NEAR(d.toFull(p_half).y, p_full.y, 1e-3);
  EXPECT_NEAR(half.K[2], (full.K[2] + 0.5) / 2 - 0.5, 1e-12) << "the principal point keeps its pixel centre";
  // A calibration for another size is refused, not silently given the decimated size (found by fuzz_cect).
  CameraCalibration other = full;
  other.width = 641;
  EXPECT_THROW(d.apply(other), std::invalid_argument);
  EXPECT_THROW(Decimation({640, 480}, 1).apply(other), std::invalid_argument);
}

TEST(DecimationTest, ImagesShrinkByAreaAndKeepTheirContentInPlace) {
  cv::Mat image(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  image(cv::Rect(100, 200, 40, 20)).setTo(cv::Scalar(255, 255, 255));
  const Decimation d({640, 480}, 2);
  const cv::Mat small = d.apply(image);
  ASSERT_EQ(small.size(), cv::Size(320, 240));
  cv::Mat grey;
  cv::cvtColor(small, grey, cv::COLOR_BGR2GRAY);
  const cv::Moments m = cv::moments(grey);
  const cv::Point2f centre_full(119.5f, 209.5f);  // the square's centre, full-size pixels
  const cv::Point2f centre = d.toDecimated(centre_full);
  EXPECT_NEAR(m.m10 / m.m00, centre.x, 1e-3);
  EXPECT_NEAR(m.m01 / m.m00, centre.y, 1e-3);
  EXPECT_EQ(Decimation({640, 480}, 1).apply(image).data, image.data) << "factor 1: the same image";
  EXPECT_THROW(d.apply(cv::Mat(100, 100, CV_8UC1)), std::invalid_argument);
}

}  // namespace
