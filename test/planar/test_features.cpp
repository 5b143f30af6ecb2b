// Tests of the features and their matches (features.h) on views rendered
// here with OpenCV: a textured floor with textured rectangles on it and a
// textured plate above it, seen by three cameras (exact projections, so
// the true 3D points and edges are known); the parameters' validation;
// Merton College I against the set's own 3D points and lines (counts and
// timings printed).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/planar/features.h"
#include "massage_cell/planar/views.h"
#include "merton_data.h"

namespace planar = massage_cell::planar;

namespace {

using massage_cell::planar::test::mertonFolder;
using massage_cell::planar::test::readNumbers;

// ---------------------------------------------------------------------------
// The rendered scene

constexpr int kWidth = 800, kHeight = 600;
constexpr double kFocal = 800.0;
constexpr double kPlateHeight = 0.08;  ///< metres above the floor

/// A textured rectangle in 3D: texel (u, v) (its centre) is at
/// origin + u ex + v ey; the rectangle ends half a texel beyond the outer
/// texels' centres.
struct Rectangle {
  Eigen::Vector3d origin, ex, ey;
  cv::Mat texture;  ///< CV_8UC3

  std::vector<Eigen::Vector3d> corners() const {
    const double w = texture.cols - 0.5, h = texture.rows - 0.5;
    return {origin - 0.5 * ex - 0.5 * ey, origin + w * ex - 0.5 * ey, origin + w * ex + h * ey,
            origin - 0.5 * ex + h * ey};
  }
};

/// Noise blurred at several scales (texels), spread over [lo, hi] per
/// channel (the mean at the middle, 2.5 standard deviations at the ends).
cv::Mat noiseTexture(int cols, int rows, const std::vector<double>& blurs, cv::Scalar lo, cv::Scalar hi, int seed) {
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  cv::Mat sum = cv::Mat::zeros(rows, cols, CV_32FC1);
  for (double blur : blurs) {
    cv::Mat noise(rows, cols, CV_32FC1), smooth;
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
    cv::GaussianBlur(noise, smooth, cv::Size(), blur);
    cv::Scalar mean, stddev;
    cv::meanStdDev(smooth, mean, stddev);
    sum += smooth / stddev[0];
  }
  cv::Scalar mean, stddev;
  cv::meanStdDev(sum, mean, stddev);
  const cv::Mat unit = (sum - mean[0]) / (5.0 * stddev[0]) + 0.5;  // mean +- 2.5 sigma -> [0, 1]
  std::vector<cv::Mat> channels;
  for (int c = 0; c < 3; ++c) channels.push_back(lo[c] + (hi[c] - lo[c]) * unit);
  cv::Mat merged, texture;
  cv::merge(channels, merged);
  merged.convertTo(texture, CV_8UC3);
  return texture;
}

/// A horizontal rectangle (z = height) centred at (x, y), turned by `degrees`
/// about the vertical, with noise blurred at `blurs` (metres).
Rectangle rectangle(double x, double y, double height, double width, double depth, double degrees, double texel,
                    const std::vector<double>& blurs, cv::Scalar lo, cv::Scalar hi, int seed) {
  Rectangle r;
  const double a = degrees * M_PI / 180.0;
  r.ex = texel * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
  r.ey = texel * Eigen::Vector3d(-std::sin(a), std::cos(a), 0.0);
  const int cols = static_cast<int>(std::lround(width / texel)), rows = static_cast<int>(std::lround(depth / texel));
  r.origin = Eigen::Vector3d(x, y, height) - 0.5 * (cols - 1) * r.ex - 0.5 * (rows - 1) * r.ey;
  std::vector<double> blurs_in_texels;
  for (double b : blurs) blurs_in_texels.push_back(b / texel);
  r.texture = noiseTexture(cols, rows, blurs_in_texels, lo, hi, seed);
  return r;
}

struct Scene {
  std::vector<Rectangle> layers;  ///< back to front: the floor, rectangles on it, the plate
  std::vector<planar::View> views;
  /// The edges of the rectangles on the floor and of the plate.
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges;
};

/// Optical-frame pose of a camera at `centre` looking at `target`, world +y up in the image.
Eigen::Isometry3d lookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized(), up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d y = -(up - up.dot(z) * z).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << y.cross(z), y, z;
  pose.translation() = centre;
  return pose;
}

/// The layers drawn by exact homographies (twice the resolution, then
/// averaged down), each over the ones before it.
cv::Mat render(const std::vector<Rectangle>& layers, const planar::Projection& P) {
  constexpr int kSuper = 2;
  Eigen::Matrix3d S;  // image pixel -> supersampled pixel (pixel centres)
  S << kSuper, 0.0, 0.5 * (kSuper - 1), 0.0, kSuper, 0.5 * (kSuper - 1), 0.0, 0.0, 1.0;
  const cv::Size big(kWidth * kSuper, kHeight * kSuper);
  cv::Mat image(big, CV_8UC3, cv::Scalar(0, 0, 0));
  for (const Rectangle& layer : layers) {
    Eigen::Matrix3d H;
    H << P.leftCols<3>() * layer.ex, P.leftCols<3>() * layer.ey, P * layer.origin.homogeneous();
    H = S * H;
    cv::Mat M(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) M.at<double>(r, c) = H(r, c);
    cv::Mat warped, mask;
    cv::warpPerspective(layer.texture, warped, M, big, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    cv::warpPerspective(cv::Mat(layer.texture.size(), CV_8UC1, cv::Scalar(255)), mask, M, big, cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar(0));
    warped.copyTo(image, mask > 127);
  }
  cv::Mat small;
  cv::resize(image, small, cv::Size(kWidth, kHeight), 0.0, 0.0, cv::INTER_AREA);
  return small;
}

/// Cameras 1 m above the floor: 0 and 1 at the same height (their baseline
/// is parallel to the floor's x axis), 2 off to the side.
std::vector<Eigen::Vector3d> cameraCentres() { return {{-0.3, -0.15, 1.0}, {0.3, -0.15, 1.0}, {0.05, 0.3, 1.05}}; }

Scene makeScene(int view_count) {
  Scene scene;
  const std::vector<double> coarse = {1.5e-3, 4e-3, 10e-3}, fine = {2e-3, 5e-3};
  scene.layers.push_back(
      rectangle(0.0, 0.0, 0.0, 2.0, 2.0, 0.0, 1e-3, coarse, cv::Scalar(60, 65, 70), cv::Scalar(150, 155, 145), 1));
  // On the floor: an axis-aligned white one (its x edges lie in epipolar
  // planes of views 0 and 1), a black one and a light cyan one turned.
  scene.layers.push_back(rectangle(-0.17, 0.07, 0.0, 0.14, 0.10, 0.0, 2.5e-4, fine, cv::Scalar(215, 215, 215),
                                   cv::Scalar(255, 255, 255), 2));
  scene.layers.push_back(
      rectangle(0.14, -0.11, 0.0, 0.12, 0.08, 70.0, 2.5e-4, fine, cv::Scalar(0, 0, 0), cv::Scalar(35, 30, 35), 3));
  scene.layers.push_back(rectangle(-0.15, -0.12, 0.0, 0.12, 0.07, 160.0, 2.5e-4, fine, cv::Scalar(230, 215, 120),
                                   cv::Scalar(255, 245, 160), 4));
  // A yellow plate above the floor.
  scene.layers.push_back(rectangle(0.12, 0.10, kPlateHeight, 0.14, 0.09, 100.0, 2.5e-4, fine, cv::Scalar(20, 190, 230),
                                   cv::Scalar(80, 240, 255), 5));
  for (std::size_t k = 1; k < scene.layers.size(); ++k) {
    const std::vector<Eigen::Vector3d> c = scene.layers[k].corners();
    for (std::size_t e = 0; e < 4; ++e) scene.edges.emplace_back(c[e], c[(e + 1) % 4]);
  }
  Eigen::Matrix3d K;
  K << kFocal, 0.0, 0.5 * (kWidth - 1), 0.0, kFocal, 0.5 * (kHeight - 1), 0.0, 0.0, 1.0;
  const std::vector<Eigen::Vector3d> centres = cameraCentres();
  for (int v = 0; v < view_count; ++v) {
    planar::View view;
    view.name = "cam" + std::to_string(v);
    view.P = planar::projectionFromPose(K, lookAt(centres[static_cast<std::size_t>(v)], Eigen::Vector3d::Zero()));
    view.image = render(scene.layers, view.P);
    scene.views.push_back(view);
  }
  return scene;
}

const Scene& threeViews() {
  static const Scene scene = makeScene(3);
  return scene;
}

/// Features of the scene's views (detected once per detector).
const std::vector<planar::ViewFeatures>& sceneFeatures(const std::string& detector) {
  static std::map<std::string, std::vector<planar::ViewFeatures>> cache;
  auto& features = cache[detector];
  if (features.empty()) {
    planar::FeatureParams params;
    params.detector = detector;
    for (const planar::View& v : threeViews().views) features.push_back(planar::detectFeatures(v, params));
  }
  return features;
}

// ---------------------------------------------------------------------------
// Measures

/// Distance from the nearest true surface: the plate where X is over it, else the floor.
double surfaceDistance(const Scene& scene, const Eigen::Vector3d& X) {
  const std::vector<Eigen::Vector3d> plate = scene.layers.back().corners();
  bool inside = true;
  for (std::size_t e = 0; e < 4; ++e) {
    const Eigen::Vector3d a = plate[e], b = plate[(e + 1) % 4];
    inside &= (b - a).x() * (X - a).y() - (b - a).y() * (X - a).x() >= 0.0;
  }
  return std::min(std::abs(X.z()), inside ? std::abs(X.z() - kPlateHeight) : std::numeric_limits<double>::infinity());
}

double distanceToLine(const Eigen::Vector3d& X, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = (b - a).normalized(), v = X - a;
  return (v - v.dot(d) * d).norm();
}

double angleDeg(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  return std::acos(std::min(1.0, std::abs(u.normalized().dot(v.normalized())))) * 180.0 / M_PI;
}

/// Index of the true edge the track lies on, or -1: direction within 1
/// degree, both end points within 2 mm of its line and within 10 mm of its
/// extent (a segment may run a few pixels past a corner along the texture
/// beside it, and the track's extent is the union of its segments').
int trueEdgeOf(const Scene& scene, const planar::LineTrack& track) {
  constexpr double kMaxAngleDeg = 1.0, kMaxDistance = 2e-3, kMaxOverhang = 10e-3;
  for (std::size_t e = 0; e < scene.edges.size(); ++e) {
    const auto& [a, b] = scene.edges[e];
    const double length = (b - a).norm();
    bool within = angleDeg(track.b - track.a, b - a) < kMaxAngleDeg;
    for (const Eigen::Vector3d& X : {track.a, track.b}) {
      const double t = (X - a).dot((b - a) / length);
      within &= distanceToLine(X, a, b) < kMaxDistance && t > -kMaxOverhang && t < length + kMaxOverhang;
    }
    if (within) return static_cast<int>(e);
  }
  return -1;
}

/// The true edges whose image is a segment in `view`: each with an
/// observed segment within 1 px of the edge's line covering half of it.
bool edgeDetected(const planar::View& view, const planar::ViewFeatures& features, const Eigen::Vector3d& a,
                  const Eigen::Vector3d& b) {
  Eigen::Vector2d pa, pb;
  if (!planar::project(view.P, a, &pa) || !planar::project(view.P, b, &pb)) return false;
  const Eigen::Vector3d l = planar::imageLine(pa, pb);
  const double length = (pb - pa).norm();
  double covered = 0.0;
  for (const cv::Vec4f& s : features.segments) {
    const Eigen::Vector2d sa(s[0], s[1]), sb(s[2], s[3]);
    if (std::abs(l.dot(sa.homogeneous())) > 1.0 || std::abs(l.dot(sb.homogeneous())) > 1.0) continue;
    const double ta = (sa - pa).dot(pb - pa) / length, tb = (sb - pa).dot(pb - pa) / length;
    covered += std::max(0.0, std::min(length, std::max(ta, tb)) - std::max(0.0, std::min(ta, tb)));
  }
  return covered >= 0.5 * length;
}

void expectWellFormed(const std::vector<planar::Observation>& observations, std::size_t views) {
  ASSERT_GE(observations.size(), 2u);
  std::set<int> seen;
  for (const planar::Observation& o : observations) {
    EXPECT_GE(o.first, 0);
    EXPECT_LT(o.first, static_cast<int>(views));
    EXPECT_TRUE(seen.insert(o.first).second) << "two observations in view " << o.first;
  }
}

struct LineResult {
  int tracks = 0, on_edges = 0;
  std::set<int> edges_found;
};

LineResult lineResult(const Scene& scene, const std::vector<planar::LineTrack>& tracks) {
  LineResult r;
  r.tracks = static_cast<int>(tracks.size());
  for (const planar::LineTrack& t : tracks) {
    const int e = trueEdgeOf(scene, t);
    if (e >= 0) {
      ++r.on_edges;
      r.edges_found.insert(e);
    }
  }
  return r;
}

// ---------------------------------------------------------------------------
// Merton College I

double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

/// The reference 3D line (l3d row) whose image lies within `tolerance` px of
/// both end points of the track's segment in every view of the track, and
/// overlaps it there; -1 when there is none.
int referenceLineOf(const std::vector<std::vector<double>>& l3d, const std::vector<planar::View>& views,
                    const std::vector<planar::ViewFeatures>& features, const planar::LineTrack& track,
                    double tolerance) {
  for (std::size_t r = 0; r < l3d.size(); ++r) {
    const Eigen::Vector3d A(l3d[r][0], l3d[r][1], l3d[r][2]), B(l3d[r][3], l3d[r][4], l3d[r][5]);
    bool fits = true;
    for (const planar::Observation& o : track.observations) {
      const planar::Projection& P = views[static_cast<std::size_t>(o.first)].P;
      const cv::Vec4f& s = features[static_cast<std::size_t>(o.first)].segments[static_cast<std::size_t>(o.second)];
      Eigen::Vector2d a, b;
      if (!fits || !planar::project(P, A, &a) || !planar::project(P, B, &b)) {
        fits = false;
        break;
      }
      const Eigen::Vector3d l = planar::imageLine(a, b);
      const Eigen::Vector2d sa(s[0], s[1]), sb(s[2], s[3]), dir = (b - a).normalized();
      const double ta = (sa - a).dot(dir), tb = (sb - a).dot(dir);
      fits = std::abs(l.dot(sa.homogeneous())) <= tolerance && std::abs(l.dot(sb.homogeneous())) <= tolerance &&
             std::min((b - a).norm(), std::max(ta, tb)) > std::max(0.0, std::min(ta, tb));
    }
    if (fits) return static_cast<int>(r);
  }
  return -1;
}

}  // namespace

// ---------------------------------------------------------------------------
// Parameters

TEST(FeatureParams, ValidateNamesTheField) {
  const auto message = [](const planar::FeatureParams& p) {
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(message(planar::FeatureParams()), "");
  const auto check = [&](const std::string& field, auto change) {
    planar::FeatureParams p;
    change(p);
    const std::string m = message(p);
    EXPECT_NE(m.find("FeatureParams." + field), std::string::npos) << field << ": \"" << m << "\"";
  };
  check("detector", [](planar::FeatureParams& p) { p.detector = "surf"; });
  check("max_keypoints", [](planar::FeatureParams& p) { p.max_keypoints = 0; });
  check("min_segment_length", [](planar::FeatureParams& p) { p.min_segment_length = 1.0; });
  check("epipolar_tolerance", [](planar::FeatureParams& p) { p.epipolar_tolerance = 0.0; });
  check("ratio", [](planar::FeatureParams& p) { p.ratio = 1.2; });
  check("min_line_ncc", [](planar::FeatureParams& p) { p.min_line_ncc = std::nan(""); });
  check("max_line_angle_deg", [](planar::FeatureParams& p) { p.max_line_angle_deg = 0.0; });
}

// ---------------------------------------------------------------------------
// Detection

TEST(DetectFeatures, EachDetectorFindsKeypointsWithDescriptors) {
  const planar::View& view = threeViews().views[0];
  for (const std::string detector : {"akaze", "orb", "sift"}) {
    planar::FeatureParams params;
    params.detector = detector;
    params.max_keypoints = 800;
    const planar::ViewFeatures f = planar::detectFeatures(view, params);
    std::cout << "  " << detector << ": " << f.keypoints.size() << " keypoints, " << f.segments.size() << " segments\n";
    EXPECT_GT(f.keypoints.size(), 300u) << detector;
    EXPECT_LE(f.keypoints.size(), 800u) << detector;
    EXPECT_EQ(f.descriptors.rows, static_cast<int>(f.keypoints.size())) << detector;
    EXPECT_EQ(f.descriptors.type(), detector == "sift" ? CV_32F : CV_8U) << detector;
  }
}

TEST(DetectFeatures, KeepsTheStrongestKeypoints) {
  const planar::View& view = threeViews().views[0];
  planar::FeatureParams all, few;
  few.max_keypoints = 100;
  const planar::ViewFeatures f_all = planar::detectFeatures(view, all), f_few = planar::detectFeatures(view, few);
  ASSERT_GT(f_all.keypoints.size(), 100u);
  ASSERT_EQ(f_few.keypoints.size(), 100u);
  std::vector<float> responses;
  for (const cv::KeyPoint& k : f_all.keypoints) responses.push_back(k.response);
  std::sort(responses.rbegin(), responses.rend());
  float weakest_kept = std::numeric_limits<float>::infinity();
  for (const cv::KeyPoint& k : f_few.keypoints) weakest_kept = std::min(weakest_kept, k.response);
  EXPECT_EQ(weakest_kept, responses[99]);
  // Descriptors stay with their keypoints.
  for (int r = 0; r < 100; ++r) {
    const cv::KeyPoint& k = f_few.keypoints[static_cast<std::size_t>(r)];
    const auto same = std::find_if(f_all.keypoints.begin(), f_all.keypoints.end(), [&](const cv::KeyPoint& q) {
      return q.pt == k.pt && q.response == k.response && q.octave == k.octave;
    });
    ASSERT_NE(same, f_all.keypoints.end());
    const int row = static_cast<int>(same - f_all.keypoints.begin());
    EXPECT_EQ(cv::norm(f_few.descriptors.row(r), f_all.descriptors.row(row), cv::NORM_HAMMING), 0.0);
  }
}

TEST(DetectFeatures, FindsEveryRectangleEdgeAsLongSegments) {
  const Scene& scene = threeViews();
  const planar::FeatureParams params;
  const double min_length = params.min_segment_length * std::hypot(kWidth, kHeight);
  for (std::size_t v = 0; v < scene.views.size(); ++v) {
    const planar::ViewFeatures& f = sceneFeatures("akaze")[v];
    EXPECT_GT(f.segments.size(), 15u);
    for (const cv::Vec4f& s : f.segments) EXPECT_GE(std::hypot(s[2] - s[0], s[3] - s[1]), min_length);
    for (std::size_t e = 0; e < scene.edges.size(); ++e)
      EXPECT_TRUE(edgeDetected(scene.views[v], f, scene.edges[e].first, scene.edges[e].second))
          << "view " << v << " edge " << e;
  }
}

// ---------------------------------------------------------------------------
// Point tracks

TEST(MatchPoints, TracksLieOnTheTrueSurfacesForEachDetector) {
  // 1 m away, f = 800 px, baselines of 0.45-0.6 m: 0.5 px of disparity is
  // about 1 mm of depth. Across these 30-degree changes of viewpoint the
  // keypoints of the finest scale repeat to 0.1-0.2 px (SIFT), 0.3 px
  // (AKAZE), 0.45 px (ORB), hence the distances 90% of the tracks are
  // within; matches that are wrong but consistent with the epipolar
  // geometry (two views, nothing to check them against) stay rare.
  const Scene& scene = threeViews();
  const std::map<std::string, double> within_90 = {{"akaze", 3e-3}, {"orb", 4e-3}, {"sift", 1e-3}};
  for (const auto& [detector, distance] : within_90) {
    planar::FeatureParams params;
    params.detector = detector;
    const auto start = std::chrono::steady_clock::now();
    const std::vector<planar::PointTrack> tracks = planar::matchPoints(scene.views, sceneFeatures(detector), params);
    const double ms = millisecondsSince(start);
    int within = 0, gross = 0, three_views = 0;
    for (const planar::PointTrack& t : tracks) {
      expectWellFormed(t.observations, scene.views.size());
      EXPECT_LE(t.reprojection_rms, params.epipolar_tolerance);
      for (const planar::Observation& o : t.observations) {
        Eigen::Vector2d x;
        ASSERT_TRUE(planar::project(scene.views[static_cast<std::size_t>(o.first)].P, t.X, &x));
        const cv::Point2f& k =
            sceneFeatures(detector)[static_cast<std::size_t>(o.first)].keypoints[static_cast<std::size_t>(o.second)].pt;
        EXPECT_LE((x - Eigen::Vector2d(k.x, k.y)).norm(), params.epipolar_tolerance);
      }
      within += surfaceDistance(scene, t.X) < distance;
      gross += surfaceDistance(scene, t.X) > 10e-3;
      three_views += t.observations.size() == 3;
    }
    const double n = static_cast<double>(std::max<std::size_t>(1, tracks.size()));
    std::cout << "  " << detector << ": " << tracks.size() << " tracks (" << three_views << " in 3 views), "
              << std::setprecision(3) << 100.0 * within / n << "% within " << distance * 1e3 << " mm of the surface, "
              << 100.0 * gross / n << "% beyond 10 mm, " << ms << " ms\n";
    EXPECT_GT(tracks.size(), 300u) << detector;
    EXPECT_GE(within, 0.9 * n) << detector;
    EXPECT_LE(gross, 0.03 * n) << detector;
  }
}

TEST(MatchPoints, ThrowsForMismatchedFeatures) {
  const Scene& scene = threeViews();
  std::vector<planar::ViewFeatures> features = sceneFeatures("akaze");
  features.pop_back();
  EXPECT_THROW(planar::matchPoints(scene.views, features, planar::FeatureParams()), std::invalid_argument);
  features = sceneFeatures("akaze");
  features[1].keypoints.pop_back();
  EXPECT_THROW(planar::matchPoints(scene.views, features, planar::FeatureParams()), std::invalid_argument);
  features = sceneFeatures("akaze");
  features[2].descriptors.convertTo(features[2].descriptors, CV_32F);
  EXPECT_THROW(planar::matchPoints(scene.views, features, planar::FeatureParams()), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Line tracks

TEST(MatchLines, ThreeViewsRecoverTheEdges) {
  const Scene& scene = threeViews();
  const planar::FeatureParams params;
  const auto start = std::chrono::steady_clock::now();
  const std::vector<planar::LineTrack> tracks = planar::matchLines(scene.views, sceneFeatures("akaze"), params);
  const double ms = millisecondsSince(start);
  for (const planar::LineTrack& t : tracks) expectWellFormed(t.observations, scene.views.size());
  const LineResult r = lineResult(scene, tracks);
  std::cout << "  " << r.tracks << " line tracks, " << r.on_edges << " on true edges; " << r.edges_found.size()
            << " of " << scene.edges.size() << " edges found, " << ms << " ms\n";
  EXPECT_EQ(r.on_edges, r.tracks);
  // Every edge is away from the epipolar planes of two of the three pairs.
  EXPECT_EQ(r.edges_found.size(), scene.edges.size());
}

TEST(MatchLines, TwoViewsRecoverTheEdgesOutsideEpipolarPlanes) {
  // Views 0 and 1 are at the same height: the x edges of the axis-aligned
  // rectangle on the floor (edges 0 and 2) lie in their epipolar planes.
  const Scene& scene = threeViews();
  const std::vector<planar::View> views(scene.views.begin(), scene.views.begin() + 2);
  const std::vector<planar::ViewFeatures> features(sceneFeatures("akaze").begin(), sceneFeatures("akaze").begin() + 2);
  const std::vector<planar::LineTrack> tracks = planar::matchLines(views, features, planar::FeatureParams());
  for (const planar::LineTrack& t : tracks) expectWellFormed(t.observations, 2);
  const LineResult r = lineResult(scene, tracks);
  std::cout << "  " << r.tracks << " line tracks, " << r.on_edges << " on true edges; " << r.edges_found.size()
            << " of " << scene.edges.size() << " edges found\n";
  EXPECT_EQ(r.on_edges, r.tracks);
  EXPECT_EQ(r.edges_found.count(0), 0u);
  EXPECT_EQ(r.edges_found.count(2), 0u);
  EXPECT_GE(r.edges_found.size(), scene.edges.size() - 4);
}

TEST(MatchLines, ThirdViewSupportAloneIsNotEnough) {
  // The true segments, but each view's image replaced by independent noise:
  // every pair still finds its 3D line on the third view's segments, yet
  // the strips beside the segments no longer agree, so no track is made.
  Scene scene = threeViews();
  cv::RNG rng(7);
  for (planar::View& v : scene.views) {
    cv::Mat noise(v.image.size(), CV_8UC3);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(noise, v.image, cv::Size(), 2.0);
  }
  const std::vector<planar::LineTrack> tracks =
      planar::matchLines(scene.views, sceneFeatures("akaze"), planar::FeatureParams());
  EXPECT_LE(tracks.size(), 2u);
}

// ---------------------------------------------------------------------------
// Merton College I

TEST(MertonCollege, PointAndLineTracksAgreeWithTheReference) {
  const std::string folder = mertonFolder();
  if (!std::filesystem::exists(folder)) GTEST_SKIP() << "Merton College I not found at " << folder;
  const std::vector<planar::View> views = planar::loadVggViews(folder);
  const planar::FeatureParams params;
  auto start = std::chrono::steady_clock::now();
  std::vector<planar::ViewFeatures> features;
  for (const planar::View& v : views) features.push_back(planar::detectFeatures(v, params));
  const double detect_ms = millisecondsSince(start);
  start = std::chrono::steady_clock::now();
  const std::vector<planar::PointTrack> points = planar::matchPoints(views, features, params);
  const double points_ms = millisecondsSince(start);
  start = std::chrono::steady_clock::now();
  const std::vector<planar::LineTrack> lines = planar::matchLines(views, features, params);
  const double lines_ms = millisecondsSince(start);

  // Points: the depth (in view 1) of the nearest reference point within
  // 10 px; the facades are smooth at that scale.
  const auto p3d = readNumbers(folder + "/3D/p3d", 3);
  std::vector<Eigen::Vector2d> reference_pixels;
  for (const auto& r : p3d) {
    Eigen::Vector2d x(-1e9, -1e9);
    planar::project(views[0].P, Eigen::Vector3d(r[0], r[1], r[2]), &x);
    reference_pixels.push_back(x);
  }
  int compared = 0, agreeing = 0;
  for (const planar::PointTrack& t : points) {
    Eigen::Vector2d x;
    if (!planar::project(views[0].P, t.X, &x)) continue;
    std::size_t nearest = 0;
    for (std::size_t r = 1; r < p3d.size(); ++r)
      if ((reference_pixels[r] - x).norm() < (reference_pixels[nearest] - x).norm()) nearest = r;
    if ((reference_pixels[nearest] - x).norm() > 10.0) continue;
    const Eigen::Vector3d R(p3d[nearest][0], p3d[nearest][1], p3d[nearest][2]);
    ++compared;
    agreeing += std::abs(planar::depthOf(views[0].P, t.X) / planar::depthOf(views[0].P, R) - 1.0) < 0.02;
  }
  // Lines: on a reference line in every view of the track.
  const auto l3d = readNumbers(folder + "/3D/l3d", 6);
  int on_reference = 0;
  for (const planar::LineTrack& t : lines) on_reference += referenceLineOf(l3d, views, features, t, 3.0) >= 0;

  std::cout << "  segments per view:";
  for (const auto& f : features) std::cout << " " << f.segments.size();
  std::cout << "\n  detect " << detect_ms << " ms; matchPoints " << points_ms << " ms: " << points.size() << " tracks, "
            << agreeing << " of the " << compared << " near a reference point within 2% of its depth; matchLines "
            << lines_ms << " ms: " << lines.size() << " tracks, " << on_reference
            << " on a reference line in all their views\n";
  EXPECT_GT(points.size(), 1000u);
  EXPECT_GT(compared, 500);
  EXPECT_GE(agreeing, 0.9 * compared);
  EXPECT_GT(lines.size(), 100u);
  EXPECT_GE(on_reference, 0.5 * static_cast<double>(lines.size()));
  // Well under a second in a release build (about 0.1 s); the bound leaves
  // room for slow machines and sanitizer builds.
  EXPECT_LT(lines_ms, 3000.0);
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
