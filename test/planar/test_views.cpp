// Tests of the calibrated views (views.h) on exact synthetic cameras:
// projection matrices from poses and their normalisation, fundamental
// matrices, point and line triangulation (exact without noise, bounded with
// it), the validation messages; the VGG loader on Merton College I against
// the set's own 3D points and corners.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "massage_cell/planar/views.h"
#include "merton_data.h"

namespace planar = massage_cell::planar;

namespace {

using massage_cell::planar::test::mertonFolder;
using massage_cell::planar::test::readNumbers;

// ---------------------------------------------------------------------------
// Synthetic cameras

Eigen::Matrix3d intrinsics(double f = 800.0, double cx = 320.0, double cy = 240.0) {
  Eigen::Matrix3d K;
  K << f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0;
  return K;
}

/// Optical-frame pose (z forward, x right, y down) of a camera at `centre`
/// looking at `target`, with the world's `up` pointing up in the image.
Eigen::Isometry3d lookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ()) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d y = -(up - up.dot(z) * z).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << y.cross(z), y, z;
  pose.translation() = centre;
  return pose;
}

/// Camera centres around the origin, about 2 m away, all looking at it.
std::vector<Eigen::Vector3d> ringCentres(int count) {
  std::vector<Eigen::Vector3d> centres;
  for (int k = 0; k < count; ++k) {
    const double a = 2.0 * M_PI * k / count;
    centres.emplace_back(2.0 * std::cos(a), 2.0 * std::sin(a), 0.7 + 0.2 * k);
  }
  return centres;
}

std::vector<planar::Projection> ringCameras(int count) {
  std::vector<planar::Projection> cameras;
  for (const Eigen::Vector3d& c : ringCentres(count))
    cameras.push_back(planar::projectionFromPose(intrinsics(), lookAt(c, Eigen::Vector3d::Zero())));
  return cameras;
}

/// Points in a 0.6 m cube around the origin (in front of every ring camera).
std::vector<Eigen::Vector3d> randomPoints(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::vector<Eigen::Vector3d> points;
  for (int k = 0; k < count; ++k) points.emplace_back(u(rng), u(rng), u(rng));
  return points;
}

Eigen::Vector2d pixelOf(const planar::Projection& P, const Eigen::Vector3d& X) {
  Eigen::Vector2d x;
  EXPECT_TRUE(planar::project(P, X, &x));
  return x;
}

double distanceToLine(const Eigen::Vector3d& X, const Eigen::Vector3d& point, const Eigen::Vector3d& direction) {
  const Eigen::Vector3d v = X - point;
  return (v - v.dot(direction.normalized()) * direction.normalized()).norm();
}

/// Message of the std::invalid_argument `f` throws ("" when it throws nothing).
template <typename F>
std::string invalidArgumentMessage(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

std::vector<planar::View> twoValidViews() {
  std::vector<planar::View> views(2);
  const std::vector<planar::Projection> cameras = ringCameras(2);
  for (std::size_t k = 0; k < 2; ++k) {
    views[k].name = "cam" + std::to_string(k);
    views[k].image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(90, 120, 150));
    views[k].P = cameras[k];
  }
  return views;
}

// ---------------------------------------------------------------------------
// Merton College I

/// nview-corners: per 3D point, the corner index in each view (-1 for '*').
std::vector<std::vector<int>> readMatches(const std::string& path, int views) {
  std::ifstream in(path);
  std::vector<std::vector<int>> rows;
  std::string token;
  std::vector<int> row;
  while (in >> token) {
    row.push_back(token == "*" ? -1 : std::stoi(token));
    if (static_cast<int>(row.size()) == views) {
      rows.push_back(row);
      row.clear();
    }
  }
  return rows;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// A fresh, empty temporary folder.
std::filesystem::path scratchFolder(const std::string& name) {
  const std::filesystem::path folder = std::filesystem::temp_directory_path() / ("planar_views_" + name);
  std::filesystem::remove_all(folder);
  std::filesystem::create_directories(folder);
  return folder;
}

}  // namespace

// ---------------------------------------------------------------------------
// Projection matrices

TEST(ProjectionFromPose, ProjectsLikeTheOpticalFrame) {
  const Eigen::Matrix3d K = intrinsics(700.0, 310.0, 250.0);
  const Eigen::Vector3d c(0.4, -1.5, 1.1);
  const Eigen::Isometry3d pose = lookAt(c, Eigen::Vector3d(0.1, 0.2, 0.0));
  const planar::Projection P = planar::projectionFromPose(K, pose);
  EXPECT_LT((planar::cameraCentre(P) - c).norm(), 1e-12);
  for (const Eigen::Vector3d& X : randomPoints(50, 1)) {
    const Eigen::Vector3d in_camera = pose.rotation().transpose() * (X - c);
    const Eigen::Vector2d expected = (K * in_camera).hnormalized();
    EXPECT_LT((pixelOf(P, X) - expected).norm(), 1e-9);
    EXPECT_NEAR(planar::depthOf(P, X), in_camera.z(), 1e-12);
  }
}

TEST(Project, PointsBehindTheCameraAreNotProjected) {
  const planar::Projection P = planar::projectionFromPose(intrinsics(), Eigen::Isometry3d::Identity());
  Eigen::Vector2d pixel(-7.0, -7.0);
  EXPECT_FALSE(planar::project(P, Eigen::Vector3d(0.1, 0.2, -1.0), &pixel));
  EXPECT_FALSE(planar::project(P, Eigen::Vector3d(0.1, 0.2, 0.0), &pixel));
  EXPECT_LT(planar::depthOf(P, Eigen::Vector3d(0.1, 0.2, -1.0)), 0.0);
  ASSERT_TRUE(planar::project(P, Eigen::Vector3d(0.1, 0.2, 1.0), &pixel));
  EXPECT_LT((pixel - Eigen::Vector2d(400.0, 400.0)).norm(), 1e-12);
}

TEST(NormalisedProjection, ScaleAndSignChangeNeitherPixelsNorDepth) {
  const planar::Projection P = ringCameras(1).front();
  for (double scale : {-3.7, 0.02, 1e4}) {
    const planar::Projection N = planar::normalisedProjection(scale * P);
    EXPECT_NEAR(N.row(2).head<3>().norm(), 1.0, 1e-12) << scale;
    EXPECT_GT(N.leftCols<3>().determinant(), 0.0) << scale;
    EXPECT_LT((N - P).norm(), 1e-9 * P.norm()) << scale;  // P from a pose is already normalised
    for (const Eigen::Vector3d& X : randomPoints(20, 2)) {
      EXPECT_LT((pixelOf(N, X) - pixelOf(P, X)).norm(), 1e-9) << scale;
      EXPECT_GT(planar::depthOf(N, X), 0.0) << scale;
      // depthOf does not depend on P's scale either.
      EXPECT_NEAR(planar::depthOf(scale * P, X), planar::depthOf(P, X), 1e-9) << scale;
    }
  }
}

TEST(NormalisedProjection, ThrowsForNonFiniteOrSingular) {
  planar::Projection P = ringCameras(1).front();
  P(1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(invalidArgumentMessage([&] { planar::normalisedProjection(P); }).find("non-finite"), std::string::npos);
  planar::Projection S = ringCameras(1).front();
  S.col(2) = S.col(0);
  EXPECT_NE(invalidArgumentMessage([&] { planar::normalisedProjection(S); }).find("singular"), std::string::npos);
}

// ---------------------------------------------------------------------------
// Two-view geometry

TEST(Fundamental, EpipolarConstraintHoldsForRandomPoints) {
  const std::vector<planar::Projection> cameras = ringCameras(4);
  for (std::size_t a = 0; a < cameras.size(); ++a) {
    for (std::size_t b = 0; b < cameras.size(); ++b) {
      if (a == b) continue;
      const Eigen::Matrix3d F = planar::fundamental(cameras[a], cameras[b]);
      EXPECT_NEAR(F.norm(), 1.0, 1e-12);
      EXPECT_LT(std::abs(F.determinant()), 1e-12);
      // The epipole of b in a is F's right null vector.
      const Eigen::Vector3d e = cameras[a] * planar::cameraCentre(cameras[b]).homogeneous();
      EXPECT_LT((F * e).norm() / e.norm(), 1e-12);
      for (const Eigen::Vector3d& X : randomPoints(30, 3)) {
        const Eigen::Vector3d xa = pixelOf(cameras[a], X).homogeneous(), xb = pixelOf(cameras[b], X).homogeneous();
        const Eigen::Vector3d l = F * xa;
        EXPECT_LT(std::abs(xb.dot(l)) / l.head<2>().norm(), 1e-9) << a << " " << b;  // pixels from the epipolar line
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Point triangulation

TEST(TriangulatePoint, ExactFromTwoAndFourViews) {
  const std::vector<planar::Projection> all = ringCameras(4);
  for (std::size_t n : {2u, 4u}) {
    const std::vector<planar::Projection> cameras(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(n));
    for (const Eigen::Vector3d& X : randomPoints(50, 4)) {
      std::vector<Eigen::Vector2d> pixels;
      for (const planar::Projection& P : cameras) pixels.push_back(pixelOf(P, X));
      EXPECT_LT((planar::triangulatePoint(cameras, pixels) - X).norm(), 1e-9) << n << " views";
    }
  }
}

TEST(TriangulatePoint, HalfPixelNoiseGivesMillimetresAndNearOptimalResiduals) {
  // Four cameras 2 m away, f = 800 px: 0.5 px is 1.25 mm across each ray,
  // about 1.5 mm rms in 3D where the four rays meet. A (near-)optimal
  // estimate leaves reprojection residuals of 0.5 px * sqrt((8 - 3) / 8):
  // 8 measurements, 3 unknowns.
  const std::vector<planar::Projection> cameras = ringCameras(4);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.5);
  double error_sq = 0.0, residual_sq = 0.0, worst = 0.0;
  const std::vector<Eigen::Vector3d> points = randomPoints(500, 6);
  for (const Eigen::Vector3d& X : points) {
    std::vector<Eigen::Vector2d> pixels;
    for (const planar::Projection& P : cameras)
      pixels.push_back(pixelOf(P, X) + Eigen::Vector2d(noise(rng), noise(rng)));
    const Eigen::Vector3d Y = planar::triangulatePoint(cameras, pixels);
    error_sq += (Y - X).squaredNorm();
    worst = std::max(worst, (Y - X).norm());
    for (std::size_t k = 0; k < cameras.size(); ++k) residual_sq += (pixelOf(cameras[k], Y) - pixels[k]).squaredNorm();
  }
  const double rms = std::sqrt(error_sq / static_cast<double>(points.size()));
  const double residual_rms = std::sqrt(residual_sq / static_cast<double>(2 * cameras.size() * points.size()));
  std::cout << "  0.5 px noise, 4 views: rms " << rms * 1e3 << " mm, worst " << worst * 1e3 << " mm, reprojection rms "
            << residual_rms << " px\n";
  EXPECT_LT(rms, 2e-3);
  EXPECT_LT(worst, 5e-3);
  EXPECT_NEAR(residual_rms, 0.5 * std::sqrt(5.0 / 8.0), 0.02);
}

TEST(TriangulatePoint, ThrowsForOneViewOrMismatchedSizes) {
  const std::vector<planar::Projection> cameras = ringCameras(2);
  EXPECT_THROW(planar::triangulatePoint({cameras[0]}, {Eigen::Vector2d(1, 2)}), std::invalid_argument);
  EXPECT_THROW(planar::triangulatePoint(cameras, {Eigen::Vector2d(1, 2)}), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Lines

TEST(ImageLine, GivesSignedPixelDistances) {
  const Eigen::Vector2d a(10.0, 20.0), b(110.0, 95.0);
  const Eigen::Vector3d l = planar::imageLine(a, b);
  EXPECT_NEAR(l.head<2>().norm(), 1.0, 1e-15);
  EXPECT_NEAR(l.dot(a.homogeneous()), 0.0, 1e-12);
  EXPECT_NEAR(l.dot(b.homogeneous()), 0.0, 1e-12);
  const Eigen::Vector2d normal = Eigen::Vector2d(-(b - a).y(), (b - a).x()).normalized();
  EXPECT_NEAR(std::abs(l.dot((a + 3.5 * normal).homogeneous())), 3.5, 1e-12);
  EXPECT_NEAR(l.dot((a + 3.5 * normal).homogeneous()), -l.dot((a - 3.5 * normal).homogeneous()), 1e-12);
  EXPECT_THROW(planar::imageLine(a, a), std::invalid_argument);
}

TEST(TriangulateLine, RecoversTheLineFromTwoAndThreeViews) {
  const std::vector<planar::Projection> all = ringCameras(3);
  const Eigen::Vector3d point(0.1, -0.05, 0.2), direction = Eigen::Vector3d(0.3, 1.0, -0.4).normalized();
  for (std::size_t n : {2u, 3u}) {
    const std::vector<planar::Projection> cameras(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(n));
    std::vector<Eigen::Vector3d> lines;
    for (std::size_t k = 0; k < n; ++k) {
      // Each view sees a different stretch of the line.
      const double t0 = -0.2 + 0.05 * static_cast<double>(k), t1 = 0.1 + 0.1 * static_cast<double>(k);
      lines.push_back(
          planar::imageLine(pixelOf(cameras[k], point + t0 * direction), pixelOf(cameras[k], point + t1 * direction)));
    }
    Eigen::Vector3d p, d;
    ASSERT_TRUE(planar::triangulateLine(cameras, lines, &p, &d)) << n << " views";
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    EXPECT_LT(d.cross(direction).norm(), 1e-9) << n << " views";
    EXPECT_LT(distanceToLine(p, point, direction), 1e-9) << n << " views";
  }
}

TEST(TriangulateLine, RejectsALineInAnEpipolarPlane) {
  // A line parallel to the baseline lies in an epipolar plane: both views
  // back-project it to that plane.
  const std::vector<planar::Projection> cameras = ringCameras(2);
  const Eigen::Vector3d baseline = planar::cameraCentre(cameras[1]) - planar::cameraCentre(cameras[0]);
  const Eigen::Vector3d point(0.05, 0.1, -0.1);
  std::vector<Eigen::Vector3d> lines;
  for (const planar::Projection& P : cameras)
    lines.push_back(planar::imageLine(pixelOf(P, point - 0.1 * baseline), pixelOf(P, point + 0.1 * baseline)));
  Eigen::Vector3d p, d;
  EXPECT_FALSE(planar::triangulateLine(cameras, lines, &p, &d));
  // Tilted out of the epipolar plane by 10 degrees it is found again.
  const Eigen::Vector3d normal = baseline.cross(point - planar::cameraCentre(cameras[0])).normalized();
  const Eigen::Vector3d tilted = Eigen::AngleAxisd(10.0 * M_PI / 180.0, normal.cross(baseline).normalized()) * baseline;
  lines.clear();
  for (const planar::Projection& P : cameras)
    lines.push_back(planar::imageLine(pixelOf(P, point - 0.1 * tilted), pixelOf(P, point + 0.1 * tilted)));
  ASSERT_TRUE(planar::triangulateLine(cameras, lines, &p, &d));
  EXPECT_LT(d.cross(tilted.normalized()).norm(), 1e-9);
}

TEST(ClosestOnLineToRay, FindsThePointOfTheLineThePixelSees) {
  const planar::Projection P = ringCameras(1).front();
  const Eigen::Vector3d point(0.1, 0.2, -0.1), direction = Eigen::Vector3d(1.0, -0.5, 0.7).normalized();
  // A pixel on the line's image: exactly the line's point there.
  const Eigen::Vector3d X = point + 0.23 * direction;
  EXPECT_LT((planar::closestOnLineToRay(P, pixelOf(P, X), point, direction) - X).norm(), 1e-9);
  // A pixel off it: the connecting segment is perpendicular to both line and ray.
  const Eigen::Vector2d off = pixelOf(P, X) + Eigen::Vector2d(12.0, -7.0);
  const Eigen::Vector3d Y = planar::closestOnLineToRay(P, off, point, direction);
  const Eigen::Vector3d centre = planar::cameraCentre(P);
  const Eigen::Vector3d ray = P.leftCols<3>().inverse() * off.homogeneous();
  const Eigen::Vector3d on_ray = centre + ray * ray.dot(Y - centre) / ray.squaredNorm();
  EXPECT_LT(distanceToLine(Y, point, direction), 1e-12);
  EXPECT_LT(std::abs((on_ray - Y).normalized().dot(direction)), 1e-9);
  EXPECT_GT((on_ray - Y).norm(), 1e-3);
}

TEST(PixelsPerUnit, IsFocalOverDepthOnTheAxisAndMatchesFiniteDifferences) {
  const planar::Projection P = planar::projectionFromPose(intrinsics(800.0), Eigen::Isometry3d::Identity());
  EXPECT_NEAR(planar::pixelsPerUnit(P, Eigen::Vector3d(0.0, 0.0, 2.0)), 400.0, 1e-9);
  // Off the axis the image of a small square facing the camera is a
  // parallelogram; pixelsPerUnit is the square root of its area ratio.
  const planar::Projection Q = ringCameras(3)[1];
  const Eigen::Vector3d X(0.2, -0.1, 0.25);
  const Eigen::Vector3d ray = (X - planar::cameraCentre(Q)).normalized();
  const Eigen::Vector3d u = ray.unitOrthogonal(), v = ray.cross(u);
  const double h = 1e-6;
  const Eigen::Vector2d du = pixelOf(Q, X + h * u) - pixelOf(Q, X), dv = pixelOf(Q, X + h * v) - pixelOf(Q, X);
  const double area_ratio = std::abs(du.x() * dv.y() - du.y() * dv.x()) / (h * h);
  EXPECT_NEAR(planar::pixelsPerUnit(Q, X), std::sqrt(area_ratio), 1e-4 * std::sqrt(area_ratio));
}

// ---------------------------------------------------------------------------
// Validation

TEST(ValidateViews, AcceptsAValidPair) { EXPECT_NO_THROW(planar::validateViews(twoValidViews())); }

TEST(ValidateViews, NamesTheProblem) {
  auto views = twoValidViews();
  const auto message = [](const std::vector<planar::View>& v) {
    return invalidArgumentMessage([&] { planar::validateViews(v); });
  };
  const std::string one = message({views[0]});
  EXPECT_NE(one.find("at least 2 views"), std::string::npos) << one;

  auto empty = views;
  empty[1].image = cv::Mat();
  const std::string e = message(empty);
  EXPECT_NE(e.find("view 1 (cam1)"), std::string::npos) << e;
  EXPECT_NE(e.find("empty image"), std::string::npos) << e;

  auto deep = views;
  deep[0].image = cv::Mat(480, 640, CV_16UC1, cv::Scalar(0));
  const std::string d = message(deep);
  EXPECT_NE(d.find("view 0 (cam0)"), std::string::npos) << d;
  EXPECT_NE(d.find("8-bit"), std::string::npos) << d;

  auto nan = views;
  nan[0].P(2, 3) = std::numeric_limits<double>::quiet_NaN();
  const std::string n = message(nan);
  EXPECT_NE(n.find("view 0 (cam0)"), std::string::npos) << n;
  EXPECT_NE(n.find("non-finite"), std::string::npos) << n;

  auto same = views;
  same.push_back(views[0]);
  same[2].name = "again";
  same[2].P *= -2.0;  // the same camera, scaled
  const std::string s = message(same);
  EXPECT_NE(s.find("view 0 (cam0) and view 2 (again)"), std::string::npos) << s;
  EXPECT_NE(s.find("same camera centre"), std::string::npos) << s;
}

// ---------------------------------------------------------------------------
// VGG folders

TEST(LoadVggViews, MertonCollegeReprojectsItsPointsOntoItsCorners) {
  const std::string folder = mertonFolder();
  if (!std::filesystem::exists(folder)) GTEST_SKIP() << "Merton College I not found at " << folder;
  const std::vector<planar::View> views = planar::loadVggViews(folder);
  ASSERT_EQ(views.size(), 3u);
  EXPECT_NO_THROW(planar::validateViews(views));
  for (std::size_t v = 0; v < views.size(); ++v) {
    EXPECT_EQ(views[v].name, "00" + std::to_string(v + 1));
    EXPECT_EQ(views[v].image.size(), cv::Size(1024, 768));
    EXPECT_EQ(views[v].image.type(), CV_8UC3);
    EXPECT_NEAR(views[v].P.row(2).head<3>().norm(), 1.0, 1e-12);
    EXPECT_GT(views[v].P.leftCols<3>().determinant(), 0.0);
  }
  const auto points = readNumbers(folder + "/3D/p3d", 3);
  const auto matches = readMatches(folder + "/2D/nview-corners", 3);
  ASSERT_EQ(points.size(), 717u);
  ASSERT_EQ(matches.size(), points.size());
  for (int v = 0; v < 3; ++v) {
    const auto corners = readNumbers(folder + "/2D/00" + std::to_string(v + 1) + ".corners", 2);
    std::vector<double> errors;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const int c = matches[i][static_cast<std::size_t>(v)];
      if (c < 0) continue;
      const Eigen::Vector2d corner(corners[static_cast<std::size_t>(c)][0], corners[static_cast<std::size_t>(c)][1]);
      errors.push_back(
          (pixelOf(views[static_cast<std::size_t>(v)].P, Eigen::Vector3d(points[i][0], points[i][1], points[i][2])) -
           corner)
              .norm());
    }
    const double worst = *std::max_element(errors.begin(), errors.end());
    std::cout << "  view " << v + 1 << ": " << errors.size() << " corners, reprojection median " << median(errors)
              << " px, worst " << worst << " px\n";
    EXPECT_LT(median(errors), 0.2);  // README: 0.14 / 0.12 / 0.11
    EXPECT_LT(worst, 0.5);           // README: 0.41
  }
}

TEST(LoadVggViews, ThrowsNamingTheMissingOrBadFile) {
  const std::filesystem::path folder = scratchFolder("bad");
  const auto message = [&] {
    try {
      planar::loadVggViews(folder.string());
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string nothing = message();
  EXPECT_NE(nothing.find("missing " + (folder / "images" / "001.jpg").string()), std::string::npos) << nothing;

  std::filesystem::create_directories(folder / "images");
  std::filesystem::create_directories(folder / "2D");
  ASSERT_TRUE(cv::imwrite((folder / "images" / "001.jpg").string(), cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3))));
  const std::string no_p = message();
  EXPECT_NE(no_p.find("missing " + (folder / "2D" / "001.P").string()), std::string::npos) << no_p;

  std::ofstream((folder / "2D" / "001.P").string()) << "1 0 0 0\n0 1 0 0\n0 0 1\n";
  const std::string short_p = message();
  EXPECT_NE(short_p.find("001.P does not hold 3 rows of 4 numbers"), std::string::npos) << short_p;

  std::ofstream((folder / "2D" / "001.P").string()) << "1 0 0 0\n0 1 0 0\n0 0 1 0\n";
  std::ofstream((folder / "2D" / "002.P").string()) << "1 0 0 0\n0 1 0 0\n0 0 1 1\n";
  const std::string no_image = message();
  EXPECT_NE(no_image.find("missing " + (folder / "images" / "002.jpg").string()), std::string::npos) << no_image;

  std::ofstream((folder / "images" / "002.jpg").string()) << "not a JPEG";
  const std::string bad_image = message();
  EXPECT_NE(bad_image.find("cannot decode " + (folder / "images" / "002.jpg").string()), std::string::npos)
      << bad_image;
  std::filesystem::remove_all(folder);
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
