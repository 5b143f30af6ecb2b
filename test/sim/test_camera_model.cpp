// Tests of the simulator's camera models: projection / back-projection,
// distortion against OpenCV, rectified and raw stereo pairs against the
// project's calibration checks, rig orientation, multi-view sets, validation.
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/sim/camera_model.h"

namespace {

using massage_cell::camera::CameraCalibration;
using massage_cell::sim::CameraModel;
using massage_cell::sim::makeMultiView;
using massage_cell::sim::makeStereoPair;
using massage_cell::sim::monoCalibration;
using massage_cell::sim::RigParameters;
using massage_cell::sim::StereoPairModel;

constexpr double kPi = 3.14159265358979323846;

/// A camera with a non-trivial pose (tilted, translated) and a full-size image.
CameraModel tiltedCamera(const std::vector<double>& D) {
  CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.K << 520.0, 0.0, 322.5, 0.0, 515.0, 238.0, 0.0, 0.0, 1.0;
  cam.D = D;
  cam.world_from_camera = Eigen::Isometry3d::Identity();
  cam.world_from_camera.linear() =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(2.9, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  cam.world_from_camera.translation() = Eigen::Vector3d(-0.2, 0.05, 0.9);
  return cam;
}

std::vector<double> defaultDistortion() { return RigParameters().distortion; }

Eigen::Matrix3d mat3(const std::array<double, 9>& a) {
  Eigen::Matrix3d m;
  m << a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8];
  return m;
}

cv::Mat cvMat3(const std::array<double, 9>& a) {
  cv::Mat m(3, 3, CV_64F);
  for (int i = 0; i < 9; ++i) m.at<double>(i / 3, i % 3) = a[static_cast<std::size_t>(i)];
  return m;
}

cv::Mat cvMat34(const std::array<double, 12>& a) {
  cv::Mat m(3, 4, CV_64F);
  for (int i = 0; i < 12; ++i) m.at<double>(i / 4, i % 4) = a[static_cast<std::size_t>(i)];
  return m;
}

/// Random world points above the table under the rig (in front of both cameras).
std::vector<Eigen::Vector3d> tablePoints(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-0.55, 0.0), uy(-0.2, 0.2), uz(0.0, 0.5);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) points.emplace_back(ux(rng), uy(rng), uz(rng));
  return points;
}

bool inside(const Eigen::Vector2d& px, const CameraModel& cam) {
  return px.x() >= 0.0 && px.y() >= 0.0 && px.x() <= cam.width - 1.0 && px.y() <= cam.height - 1.0;
}

// ---------------------------------------------------------------------------
// CameraModel

void expectRoundTrip(const CameraModel& cam) {
  std::vector<double> xs, ys;
  for (int i = 0; i <= 16; ++i) xs.push_back((cam.width - 1) * i / 16.0);
  for (int i = 0; i <= 12; ++i) ys.push_back((cam.height - 1) * i / 12.0);
  xs.push_back(-0.5);  // slightly beyond the corner pixels too
  ys.push_back(cam.height - 0.5);
  double worst = 0.0;
  for (double x : xs) {
    for (double y : ys) {
      const Eigen::Vector3d ray = cam.rayDirection(x, y);
      EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
      for (double t : {0.3, 1.7}) {
        Eigen::Vector2d px;
        ASSERT_TRUE(cam.project(cam.centre() + t * ray, &px)) << x << ", " << y;
        worst = std::max(worst, (px - Eigen::Vector2d(x, y)).norm());
      }
    }
  }
  EXPECT_LT(worst, 1e-4) << "worst round-trip error " << worst << " px";
}

TEST(CameraModel, RoundTripWithoutDistortion) { expectRoundTrip(tiltedCamera({})); }

TEST(CameraModel, RoundTripWithDefaultDistortion) { expectRoundTrip(tiltedCamera(defaultDistortion())); }

TEST(CameraModel, RoundTripWithStrongDistortion) {
  // Stronger than the default: a too-short undistortion iteration fails here.
  expectRoundTrip(tiltedCamera({-0.25, 0.08, 0.002, -0.0015, 0.01}));
}

TEST(CameraModel, RoundTripOfRawRigCameras) {
  RigParameters rig;
  rig.rectified = false;
  const StereoPairModel pair = makeStereoPair(rig);
  expectRoundTrip(pair.left);
  expectRoundTrip(pair.right);
}

TEST(CameraModel, RayOfPrincipalPointIsOpticalAxis) {
  const CameraModel cam = tiltedCamera(defaultDistortion());
  const Eigen::Vector3d ray = cam.rayDirection(cam.K(0, 2), cam.K(1, 2));
  EXPECT_LT((ray - cam.world_from_camera.linear().col(2)).norm(), 1e-12);
}

TEST(CameraModel, ProjectRejectsPointsBehind) {
  const CameraModel cam = tiltedCamera({});
  Eigen::Vector2d px(-1.0, -1.0);
  EXPECT_FALSE(cam.project(cam.centre() - cam.world_from_camera.linear().col(2), &px));
  EXPECT_FALSE(cam.project(cam.centre(), &px));
  EXPECT_TRUE(cam.project(cam.centre() + cam.world_from_camera.linear().col(2), &px));
  EXPECT_NEAR(px.x(), cam.K(0, 2), 1e-9);
  EXPECT_NEAR(px.y(), cam.K(1, 2), 1e-9);
}

TEST(CameraModel, ProjectionMatrixAgreesWithProjectWithoutDistortion) {
  CameraModel cam = tiltedCamera({});
  cam.K(0, 1) = 1.5;  // a skew must be honoured by both
  const Eigen::Matrix<double, 3, 4> P = cam.projectionMatrix();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3), depth(0.2, 2.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = cam.world_from_camera * Eigen::Vector3d(u(rng), u(rng), depth(rng));
    Eigen::Vector2d px;
    ASSERT_TRUE(cam.project(p, &px));
    const Eigen::Vector3d h = P * p.homogeneous();
    EXPECT_NEAR(h.x() / h.z(), px.x(), 1e-9);
    EXPECT_NEAR(h.y() / h.z(), px.y(), 1e-9);
  }
}

TEST(CameraModel, DistortionAgreesWithOpenCV) {
  CameraModel cam = tiltedCamera({-0.25, 0.08, 0.002, -0.0015, 0.01});
  const Eigen::Isometry3d camera_from_world = cam.world_from_camera.inverse();
  cv::Mat R_cv(3, 3, CV_64F), rvec, tvec(3, 1, CV_64F), K_cv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    tvec.at<double>(r) = camera_from_world.translation()(r);
    for (int c = 0; c < 3; ++c) {
      R_cv.at<double>(r, c) = camera_from_world.linear()(r, c);
      K_cv.at<double>(r, c) = cam.K(r, c);
    }
  }
  cv::Rodrigues(R_cv, rvec);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.4, 0.4), depth(0.3, 2.0);
  std::vector<cv::Point3d> object;
  std::vector<Eigen::Vector3d> world;
  for (int i = 0; i < 300; ++i) {
    const double z = depth(rng);
    const Eigen::Vector3d p = cam.world_from_camera * Eigen::Vector3d(u(rng) * z, u(rng) * z, z);
    world.push_back(p);
    object.emplace_back(p.x(), p.y(), p.z());
  }
  std::vector<cv::Point2d> image;
  cv::projectPoints(object, rvec, tvec, K_cv, cam.D, image);
  for (std::size_t i = 0; i < world.size(); ++i) {
    Eigen::Vector2d px;
    ASSERT_TRUE(cam.project(world[i], &px));
    EXPECT_NEAR(px.x(), image[i].x, 1e-8);
    EXPECT_NEAR(px.y(), image[i].y, 1e-8);
  }
  // ... and the distortion really changes the pixels (the comparison is not vacuous).
  CameraModel ideal = cam;
  ideal.D.clear();
  Eigen::Vector2d a, b;
  ASSERT_TRUE(cam.project(cam.world_from_camera * Eigen::Vector3d(0.5, 0.4, 1.0), &a));
  ASSERT_TRUE(ideal.project(cam.world_from_camera * Eigen::Vector3d(0.5, 0.4, 1.0), &b));
  EXPECT_GT((a - b).norm(), 1.0);
}

TEST(CameraModel, ValidateRejectsBadModels) {
  const CameraModel good = tiltedCamera(defaultDistortion());
  EXPECT_NO_THROW(good.validate());
  EXPECT_NO_THROW(tiltedCamera({}).validate());
  const std::vector<std::pair<std::string, std::function<void(CameraModel&)>>> cases = {
      {"zero width", [](CameraModel& c) { c.width = 0; }},
      {"negative height", [](CameraModel& c) { c.height = -3; }},
      {"K(1,0)", [](CameraModel& c) { c.K(1, 0) = 0.1; }},
      {"K(2,0)", [](CameraModel& c) { c.K(2, 0) = 0.1; }},
      {"K(2,1)", [](CameraModel& c) { c.K(2, 1) = 0.1; }},
      {"fx = 0", [](CameraModel& c) { c.K(0, 0) = 0.0; }},
      {"fy < 0", [](CameraModel& c) { c.K(1, 1) = -500.0; }},
      {"K(2,2) = 2", [](CameraModel& c) { c.K(2, 2) = 2.0; }},
      {"NaN cx", [](CameraModel& c) { c.K(0, 2) = std::nan(""); }},
      {"inf fx", [](CameraModel& c) { c.K(0, 0) = INFINITY; }},
      {"4 coefficients",
       [](CameraModel& c) {
         c.D = {0.1, 0.0, 0.0, 0.0};
       }},
      {"8 coefficients", [](CameraModel& c) { c.D.assign(8, 0.0); }},
      {"NaN distortion", [](CameraModel& c) { c.D[1] = std::nan(""); }},
      {"NaN pose", [](CameraModel& c) { c.world_from_camera.translation().x() = std::nan(""); }},
      {"non-rigid pose", [](CameraModel& c) { c.world_from_camera.linear() *= 2.0; }},
  };
  for (const auto& [name, mutate] : cases) {
    CameraModel bad = good;
    mutate(bad);
    EXPECT_THROW(bad.validate(), std::invalid_argument) << name;
  }
}

// ---------------------------------------------------------------------------
// Stereo pairs

RigParameters rawRig() {
  RigParameters rig;
  rig.rectified = false;
  return rig;
}

TEST(StereoPair, RectifiedPairIsRowAlignedWithExactDisparity) {
  RigParameters rig;
  rig.baseline = 0.12;
  rig.shift = 0.03;
  const StereoPairModel pair = makeStereoPair(rig);
  EXPECT_TRUE(pair.rectified);
  EXPECT_TRUE(pair.left.D.empty());
  EXPECT_TRUE(pair.right.D.empty());
  EXPECT_NEAR(pair.baseline(), rig.baseline, 1e-12);
  for (const Eigen::Vector3d& p : tablePoints(300, 3)) {
    Eigen::Vector2d l, r;
    ASSERT_TRUE(pair.left.project(p, &l));
    ASSERT_TRUE(pair.right.project(p, &r));
    const double z_left = (pair.left.world_from_camera.inverse() * p).z();
    EXPECT_NEAR(l.y(), r.y(), 1e-9);
    EXPECT_NEAR(l.x() - r.x(), rig.fx * rig.baseline / z_left, 1e-9);
  }
}

TEST(StereoPair, RectifiedInfos) {
  RigParameters rig;
  rig.width = 800;
  rig.height = 600;
  rig.fx = 610.0;
  const StereoPairModel pair = makeStereoPair(rig);
  for (const CameraCalibration* info : {&pair.left_info, &pair.right_info}) {
    EXPECT_EQ(info->width, 800);
    EXPECT_EQ(info->height, 600);
    EXPECT_EQ(info->distortion_model, "plumb_bob");
    EXPECT_EQ(info->D, std::vector<double>(5, 0.0));
    EXPECT_EQ(info->K, (std::array<double, 9>{610.0, 0.0, 399.5, 0.0, 610.0, 299.5, 0.0, 0.0, 1.0}));
    EXPECT_EQ(info->R, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  }
  EXPECT_EQ(pair.left_info.P, (std::array<double, 12>{610.0, 0.0, 399.5, 0.0, 0.0, 610.0, 299.5, 0.0, 0, 0, 1, 0}));
  EXPECT_EQ(pair.right_info.P,
            (std::array<double, 12>{610.0, 0.0, 399.5, -610.0 * rig.baseline, 0.0, 610.0, 299.5, 0.0, 0, 0, 1, 0}));
  EXPECT_NEAR(massage_cell::camera::baseline(pair.right_info), rig.baseline, 1e-12);
}

TEST(StereoPair, RawPairRectifiesWithItsInfos) {
  const RigParameters rig = rawRig();
  const StereoPairModel pair = makeStereoPair(rig);
  EXPECT_FALSE(pair.rectified);
  EXPECT_EQ(pair.left.D, rig.distortion);
  EXPECT_EQ(pair.right.D, rig.distortion);
  EXPECT_EQ(pair.left_info.D, rig.distortion);
  EXPECT_EQ(pair.right_info.D, rig.distortion);
  EXPECT_NEAR(pair.baseline(), rig.baseline, 1e-12);
  EXPECT_LT(pair.right_info.P[3], 0.0);

  const cv::Mat K1 = cvMat3(pair.left_info.K), K2 = cvMat3(pair.right_info.K);
  const cv::Mat R1 = cvMat3(pair.left_info.R), R2 = cvMat3(pair.right_info.R);
  const cv::Mat P1 = cvMat34(pair.left_info.P), P2 = cvMat34(pair.right_info.P);
  const Eigen::Matrix3d R1e = mat3(pair.left_info.R);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-12);

  double worst_raw_row_difference = 0.0;
  int used = 0;
  for (const Eigen::Vector3d& p : tablePoints(400, 5)) {
    Eigen::Vector2d l, r;
    ASSERT_TRUE(pair.left.project(p, &l));
    ASSERT_TRUE(pair.right.project(p, &r));
    if (!inside(l, pair.left) || !inside(r, pair.right)) continue;
    ++used;
    worst_raw_row_difference = std::max(worst_raw_row_difference, std::abs(l.y() - r.y()));
    std::vector<cv::Point2d> lin{{l.x(), l.y()}}, rin{{r.x(), r.y()}}, lout, rout;
    cv::undistortPoints(lin, lout, K1, pair.left_info.D, R1, P1, criteria);
    cv::undistortPoints(rin, rout, K2, pair.right_info.D, R2, P2, criteria);
    const double z_rect = (R1e * (pair.left.world_from_camera.inverse() * p)).z();
    EXPECT_NEAR(lout[0].y, rout[0].y, 0.05);
    EXPECT_NEAR(lout[0].x - rout[0].x, P1.at<double>(0, 0) * rig.baseline / z_rect, 0.05);
  }
  EXPECT_GT(used, 200);
  // The raw images themselves are not row-aligned (else the test above proves nothing).
  EXPECT_GT(worst_raw_row_difference, 1.0);
}

TEST(StereoPair, InfosPassTheProjectChecks) {
  for (bool rectified : {true, false}) {
    RigParameters rig;
    rig.rectified = rectified;
    const StereoPairModel pair = makeStereoPair(rig);
    const cv::Size size(rig.width, rig.height);
    EXPECT_TRUE(massage_cell::camera::checkCalibration(pair.left_info, size, "left").empty()) << rectified;
    EXPECT_TRUE(massage_cell::camera::checkCalibration(pair.right_info, size, "right").empty()) << rectified;
    const auto problems = massage_cell::camera::checkStereoCalibration(pair.left_info, pair.right_info);
    EXPECT_TRUE(problems.empty()) << rectified << ": " << (problems.empty() ? "" : problems.front());
  }
}

TEST(StereoPair, RightCameraInLeftMatchesThePoses) {
  for (bool rectified : {true, false}) {
    RigParameters rig;
    rig.rectified = rectified;
    rig.baseline = 0.15;
    const StereoPairModel pair = makeStereoPair(rig);
    const Eigen::Isometry3d actual = pair.left.world_from_camera.inverse() * pair.right.world_from_camera;
    const Eigen::Isometry3d declared = massage_cell::camera::rightCameraInLeft(pair.left_info, pair.right_info);
    EXPECT_LT((actual.translation() - declared.translation()).norm(), 1e-6) << rectified;
    const double angle = Eigen::AngleAxisd(actual.linear().transpose() * declared.linear()).angle();
    EXPECT_LT(angle, 1e-6) << rectified;
    if (!rectified) {
      // The raw cameras are really rotated against each other.
      EXPECT_GT(Eigen::AngleAxisd(actual.linear()).angle(), 1e-3);
    }
  }
}

TEST(StereoPair, CentreRayPointsStraightDown) {
  RigParameters rig;
  rig.shift = -0.04;
  const StereoPairModel pair = makeStereoPair(rig);
  const double cx = (rig.width - 1) / 2.0, cy = (rig.height - 1) / 2.0;
  for (const CameraModel* cam : {&pair.left, &pair.right}) {
    EXPECT_LT((cam->rayDirection(cx, cy) - Eigen::Vector3d(0.0, 0.0, -1.0)).norm(), 1e-12);
  }
  // The midpoint between the centres is the rig centre plus the shift.
  const Eigen::Vector3d mid = 0.5 * (pair.left.centre() + pair.right.centre());
  EXPECT_LT((mid - (rig.centre + Eigen::Vector3d(rig.shift, 0.0, 0.0))).norm(), 1e-12);
  // A camera at the midpoint with the same orientation sees the point below it at the image centre.
  CameraModel middle = pair.left;
  middle.world_from_camera.translation() = mid;
  Eigen::Vector2d px;
  ASSERT_TRUE(middle.project(mid - Eigen::Vector3d(0.0, 0.0, 0.5), &px));
  EXPECT_NEAR(px.x(), cx, 1e-9);
  EXPECT_NEAR(px.y(), cy, 1e-9);
}

TEST(StereoPair, HeadAtTopAndSubjectsLeftOnImageLeft) {
  for (bool rectified : {true, false}) {
    RigParameters rig;
    rig.rectified = rectified;
    const StereoPairModel pair = makeStereoPair(rig);
    for (const CameraModel* cam : {&pair.left, &pair.right}) {
      const Eigen::Vector3d p(-0.27, 0.0, 0.1);
      Eigen::Vector2d base, headward, leftward;
      ASSERT_TRUE(cam->project(p, &base));
      ASSERT_TRUE(cam->project(p + Eigen::Vector3d(0.05, 0.0, 0.0), &headward));
      ASSERT_TRUE(cam->project(p + Eigen::Vector3d(0.0, 0.05, 0.0), &leftward));
      EXPECT_LT(headward.y(), base.y() - 10.0) << "head (+x) must be toward the image top";
      EXPECT_NEAR(headward.x(), base.x(), 2.0);
      EXPECT_LT(leftward.x(), base.x() - 10.0) << "subject's left (+y) must be on the image left";
      EXPECT_NEAR(leftward.y(), base.y(), 2.0);
    }
    // The left camera is on the image left, i.e. toward +y; the right camera
    // lies at +x in the left optical frame.
    EXPECT_GT(pair.left.centre().y(), pair.right.centre().y());
    EXPECT_GT((pair.left.world_from_camera.inverse() * pair.right.centre()).x(), 0.9 * rig.baseline);
  }
}

TEST(StereoPair, ShiftMovesTheCentresAlongWorldX) {
  for (bool rectified : {true, false}) {
    RigParameters rig;
    rig.rectified = rectified;
    const StereoPairModel a = makeStereoPair(rig);
    rig.shift = 0.07;
    const StereoPairModel b = makeStereoPair(rig);
    EXPECT_LT((b.left.centre() - a.left.centre() - Eigen::Vector3d(0.07, 0.0, 0.0)).norm(), 1e-12);
    EXPECT_LT((b.right.centre() - a.right.centre() - Eigen::Vector3d(0.07, 0.0, 0.0)).norm(), 1e-12);
    EXPECT_TRUE(b.left.world_from_camera.linear().isApprox(a.left.world_from_camera.linear(), 1e-12));
    EXPECT_NEAR(a.left.centre().z(), rig.centre.z(), 1e-12);
  }
}

TEST(StereoPair, InvalidParametersThrow) {
  EXPECT_NO_THROW(makeStereoPair(RigParameters()));
  EXPECT_NO_THROW(makeStereoPair(rawRig()));
  const std::vector<std::pair<std::string, std::function<void(RigParameters&)>>> cases = {
      {"width 0", [](RigParameters& r) { r.width = 0; }},
      {"height -1", [](RigParameters& r) { r.height = -1; }},
      {"width too large", [](RigParameters& r) { r.width = 16385; }},
      {"fx 0", [](RigParameters& r) { r.fx = 0.0; }},
      {"fx NaN", [](RigParameters& r) { r.fx = std::nan(""); }},
      {"baseline 0", [](RigParameters& r) { r.baseline = 0.0; }},
      {"baseline negative", [](RigParameters& r) { r.baseline = -0.1; }},
      {"baseline 2 m", [](RigParameters& r) { r.baseline = 2.0; }},
      {"centre NaN", [](RigParameters& r) { r.centre.z() = std::nan(""); }},
      {"shift inf", [](RigParameters& r) { r.shift = INFINITY; }},
  };
  for (bool rectified : {true, false}) {
    for (const auto& [name, mutate] : cases) {
      RigParameters rig;
      rig.rectified = rectified;
      mutate(rig);
      EXPECT_THROW(makeStereoPair(rig), std::invalid_argument) << name << " rectified=" << rectified;
    }
  }
  const std::vector<std::pair<std::string, std::function<void(RigParameters&)>>> raw_cases = {
      {"4 coefficients",
       [](RigParameters& r) {
         r.distortion = {0.1, 0.0, 0.0, 0.0};
       }},
      {"no coefficients", [](RigParameters& r) { r.distortion.clear(); }},
      {"NaN coefficient", [](RigParameters& r) { r.distortion[0] = std::nan(""); }},
      {"left rotation 0.2",
       [](RigParameters& r) {
         r.left_rotation = {0.0, 0.2, 0.0};
       }},
      {"right rotation large",
       [](RigParameters& r) {
         r.right_rotation = {0.15, 0.15, 0.0};
       }},
      {"right rotation NaN", [](RigParameters& r) { r.right_rotation.x() = std::nan(""); }},
  };
  for (const auto& [name, mutate] : raw_cases) {
    RigParameters rig = rawRig();
    mutate(rig);
    EXPECT_THROW(makeStereoPair(rig), std::invalid_argument) << name;
  }
  // The message names the parameter.
  try {
    RigParameters rig;
    rig.baseline = 3.0;
    makeStereoPair(rig);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("baseline"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------
// Multi-view sets and mono calibrations

TEST(MultiView, CamerasLookAtTheTarget) {
  const Eigen::Vector3d target(-0.3, 0.05, 0.12);
  for (int count : {1, 2, 5}) {
    for (double elevation : {0.0, 0.6, kPi / 2.0}) {
      const auto cams = makeMultiView(count, target, 0.8, elevation, 1.2, 640, 480, 550.0);
      ASSERT_EQ(static_cast<int>(cams.size()), count);
      for (const CameraModel& cam : cams) {
        EXPECT_NO_THROW(cam.validate());
        EXPECT_NEAR((cam.centre() - target).norm(), 0.8, 1e-12);
        EXPECT_NEAR(cam.centre().z() - target.z(), 0.8 * std::sin(elevation), 1e-12);
        Eigen::Vector2d px;
        ASSERT_TRUE(cam.project(target, &px));
        EXPECT_NEAR(px.x(), 319.5, 1e-9);
        EXPECT_NEAR(px.y(), 239.5, 1e-9);
        // Image up ~ world up: a point above the target appears higher in the image (smaller row),
        // unless the camera looks straight down.
        if (elevation < 1.0) {
          ASSERT_TRUE(cam.project(target + Eigen::Vector3d(0.0, 0.0, 0.05), &px));
          EXPECT_LT(px.y(), 239.5 - 5.0);
          EXPECT_NEAR(px.x(), 319.5, 1e-9);
        }
        EXPECT_TRUE(massage_cell::camera::checkCalibration(monoCalibration(cam), cv::Size(640, 480), "cam").empty());
      }
    }
  }
}

TEST(MultiView, AzimuthPlacement) {
  const Eigen::Vector3d target(0.0, 0.0, 0.0);
  // One camera: azimuth 0, on the -x side looking toward +x (head).
  const auto one = makeMultiView(1, target, 1.0, 0.5, 1.0, 320, 240, 300.0);
  EXPECT_LT(one[0].centre().x(), -0.8);
  EXPECT_NEAR(one[0].centre().y(), 0.0, 1e-12);
  // Straight down from azimuth 0: head (+x) at the image top, like the stereo rig.
  const auto down = makeMultiView(1, target, 1.0, kPi / 2.0, 0.0, 320, 240, 300.0);
  Eigen::Vector2d a, b;
  ASSERT_TRUE(down[0].project(Eigen::Vector3d(0.0, 0.0, 0.0), &a));
  ASSERT_TRUE(down[0].project(Eigen::Vector3d(0.1, 0.0, 0.0), &b));
  EXPECT_LT(b.y(), a.y() - 5.0);
  ASSERT_TRUE(down[0].project(Eigen::Vector3d(0.0, 0.1, 0.0), &b));
  EXPECT_LT(b.x(), a.x() - 5.0);
  // Three cameras over 1.2 rad: azimuths -0.6, 0, +0.6 (positive toward -y).
  const auto three = makeMultiView(3, target, 1.0, 0.0, 1.2, 320, 240, 300.0);
  EXPECT_NEAR(three[0].centre().y(), std::sin(0.6), 1e-12);
  EXPECT_NEAR(three[1].centre().y(), 0.0, 1e-12);
  EXPECT_NEAR(three[2].centre().y(), -std::sin(0.6), 1e-12);
  EXPECT_NEAR(three[0].centre().x(), -std::cos(0.6), 1e-12);
  EXPECT_NEAR(three[1].centre().x(), -1.0, 1e-12);
  EXPECT_NEAR(three[2].centre().x(), -std::cos(0.6), 1e-12);
  // Full circle: no duplicated camera.
  const auto ring = makeMultiView(4, target, 1.0, 0.3, 2.0 * kPi, 320, 240, 300.0);
  for (std::size_t i = 0; i < ring.size(); ++i)
    for (std::size_t j = i + 1; j < ring.size(); ++j) EXPECT_GT((ring[i].centre() - ring[j].centre()).norm(), 0.5);
}

TEST(MultiView, InvalidParametersThrow) {
  const Eigen::Vector3d t(0.0, 0.0, 0.0);
  EXPECT_THROW(makeMultiView(0, t, 1.0, 0.5, 1.0, 640, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(-2, t, 1.0, 0.5, 1.0, 640, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, t, 0.0, 0.5, 1.0, 640, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, t, -1.0, 0.5, 1.0, 640, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, t, 1.0, 2.0, 1.0, 640, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, t, 1.0, 0.5, 1.0, 0, 480, 500.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, t, 1.0, 0.5, 1.0, 640, 480, 0.0), std::invalid_argument);
  EXPECT_THROW(makeMultiView(2, Eigen::Vector3d(std::nan(""), 0.0, 0.0), 1.0, 0.5, 1.0, 640, 480, 500.0),
               std::invalid_argument);
}

TEST(MonoCalibration, Fields) {
  CameraModel cam = tiltedCamera({});
  CameraCalibration info = monoCalibration(cam);
  EXPECT_EQ(info.width, 640);
  EXPECT_EQ(info.height, 480);
  EXPECT_EQ(info.distortion_model, "plumb_bob");
  EXPECT_EQ(info.D, std::vector<double>(5, 0.0));
  EXPECT_EQ(info.K, (std::array<double, 9>{520.0, 0.0, 322.5, 0.0, 515.0, 238.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(info.R, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(info.P, (std::array<double, 12>{520.0, 0.0, 322.5, 0.0, 0.0, 515.0, 238.0, 0.0, 0, 0, 1, 0}));
  cam.D = defaultDistortion();
  info = monoCalibration(cam);
  EXPECT_EQ(info.D, cam.D);
  EXPECT_TRUE(massage_cell::camera::checkCalibration(info, cv::Size(640, 480), "mono").empty());
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
