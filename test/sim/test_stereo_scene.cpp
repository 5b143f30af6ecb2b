// Ground truth of rendered stereo scenes (scene builders + renderer + camera
// models together): the GT 3D points reproject with the GT disparity, raw
// pairs obey their calibration's epipolar geometry, acupoints lie on the
// rendered skin and are seen by both cameras, rendering is deterministic.
#include <gtest/gtest.h>

#include <random>

#include <opencv2/calib3d.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"

namespace sim = massage_cell::sim;

namespace {

sim::RigParameters smallRig(bool rectified) {
  sim::RigParameters rig;
  rig.width = 200;
  rig.height = 150;
  rig.fx = 160.0;
  rig.rectified = rectified;
  return rig;
}

sim::RenderOptions quick(std::uint32_t seed = 1) {
  sim::RenderOptions o;
  o.supersample = 1;
  o.noise_sigma = 1.0f;
  o.noise_seed = seed;
  return o;
}

struct BackFixture : ::testing::Test {
  sim::BackModel back{sim::BodyParameters::mean()};
  sim::Renderer renderer{sim::makeBackScene(back, 3)};
};

TEST_F(BackFixture, GroundTruthPointsReprojectWithGroundTruthDisparity) {
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(true));
  const sim::StereoFrame f = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick());
  ASSERT_FALSE(f.left_disparity.empty());
  const double fx = pair.left_info.P[0], B = pair.baseline();
  std::mt19937 rng(5);
  int checked = 0;
  for (int i = 0; i < 4000 && checked < 500; ++i) {
    const int x = static_cast<int>(rng() % pair.left.width), y = static_cast<int>(rng() % pair.left.height);
    const float d = f.left_disparity.at<float>(y, x);
    const cv::Vec3f p = f.left.points.at<cv::Vec3f>(y, x);
    if (!std::isfinite(d)) {
      EXPECT_FALSE(std::isfinite(p[0]));
      continue;
    }
    Eigen::Vector2d right_pixel;
    ASSERT_TRUE(pair.right.project(Eigen::Vector3d(p[0], p[1], p[2]), &right_pixel));
    EXPECT_NEAR(right_pixel.x(), x - d, 0.05) << "pixel " << x << "," << y;
    EXPECT_NEAR(right_pixel.y(), y, 0.05);
    const float z = f.left.depth.at<float>(y, x);
    EXPECT_NEAR(z, fx * B / d, 1e-5 * z);
    ++checked;
  }
  EXPECT_GE(checked, 500);
}

TEST_F(BackFixture, RawPairObeysItsCalibrationsEpipolarGeometry) {
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(false));
  ASSERT_FALSE(pair.rectified);
  const sim::StereoFrame f = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick());
  EXPECT_TRUE(f.left_disparity.empty());
  auto mat = [](const auto& a, int rows, int cols) {
    return cv::Mat(rows, cols, CV_64F, const_cast<double*>(a.data())).clone();
  };
  const cv::Mat K1 = mat(pair.left_info.K, 3, 3), K2 = mat(pair.right_info.K, 3, 3);
  const cv::Mat R1 = mat(pair.left_info.R, 3, 3), R2 = mat(pair.right_info.R, 3, 3);
  const cv::Mat P1 = mat(pair.left_info.P, 3, 4), P2 = mat(pair.right_info.P, 3, 4);
  std::mt19937 rng(9);
  int checked = 0;
  for (int i = 0; i < 4000 && checked < 300; ++i) {
    const int x = static_cast<int>(rng() % pair.left.width), y = static_cast<int>(rng() % pair.left.height);
    const cv::Vec3f p = f.left.points.at<cv::Vec3f>(y, x);
    if (!std::isfinite(p[0]) || f.left_visible.at<unsigned char>(y, x) == 0) continue;
    Eigen::Vector2d r;
    ASSERT_TRUE(pair.right.project(Eigen::Vector3d(p[0], p[1], p[2]), &r));
    std::vector<cv::Point2d> l_in{{double(x), double(y)}}, r_in{{r.x(), r.y()}}, l_rect, r_rect;
    cv::undistortPoints(l_in, l_rect, K1, pair.left_info.D, R1, P1,
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    cv::undistortPoints(r_in, r_rect, K2, pair.right_info.D, R2, P2,
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    EXPECT_NEAR(l_rect[0].y, r_rect[0].y, 0.05) << "pixel " << x << "," << y;
    ++checked;
  }
  EXPECT_GE(checked, 300);
}

TEST_F(BackFixture, AcupointsLieOnTheRenderedSkinAndAreSeenByBothCameras) {
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(true));
  const auto points = back.acupoints();
  ASSERT_GT(points.size(), 60u);
  for (const auto& [name, p] : points) {
    const Eigen::Vector3d c = pair.left.centre();
    sim::Hit hit;
    ASSERT_TRUE(renderer.intersect(c, p - c, &hit)) << name;
    EXPECT_LT((hit.point - p).norm(), 0.0005) << name << " is off the rendered surface";
    EXPECT_EQ(hit.label, sim::kLabelBack) << name;
    EXPECT_TRUE(sim::isVisible(renderer, pair.left, p)) << name;
    EXPECT_TRUE(sim::isVisible(renderer, pair.right, p)) << name;
  }
}

TEST_F(BackFixture, SameSeedSameImagesOtherSeedOtherNoise) {
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(true));
  const sim::StereoFrame a = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick(4));
  const sim::StereoFrame b = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick(4));
  const sim::StereoFrame c = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick(5));
  EXPECT_EQ(cv::norm(a.left.image, b.left.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.right.image, b.right.image, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a.left.image, c.left.image, cv::NORM_L1), 0.0);
}

TEST_F(BackFixture, LabelsShowTheBackInTheMiddleAndTheTableAround) {
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(true));
  const sim::ViewRender v = renderer.render(pair.left, sim::Lighting(), quick());
  EXPECT_EQ(v.labels.at<unsigned char>(v.labels.rows / 2, v.labels.cols / 2), sim::kLabelBack);
  int back = 0, table = 0;
  for (int y = 0; y < v.labels.rows; ++y) {
    for (int x = 0; x < v.labels.cols; ++x) {
      back += v.labels.at<unsigned char>(y, x) == sim::kLabelBack;
      table += v.labels.at<unsigned char>(y, x) == sim::kLabelTable;
    }
  }
  EXPECT_GT(back, v.labels.total() / 4);
  EXPECT_GT(table, 0);
}

TEST(StereoFrame, OcclusionMaskMarksWhatTheRightCameraCannotSee) {
  // A box on the table hides part of the table from the right camera.
  const sim::Renderer renderer(sim::makeBoxesScene(2, 1));
  const sim::StereoPairModel pair = sim::makeStereoPair(smallRig(true));
  const sim::StereoFrame f = sim::renderStereoFrame(renderer, pair, sim::Lighting(), quick());
  int occluded = 0, visible = 0;
  for (int y = 0; y < f.left_visible.rows; ++y) {
    for (int x = 0; x < f.left_visible.cols; ++x) {
      if (!std::isfinite(f.left.depth.at<float>(y, x))) continue;
      (f.left_visible.at<unsigned char>(y, x) ? visible : occluded)++;
      if (f.left_visible.at<unsigned char>(y, x) && std::isfinite(f.left_disparity.at<float>(y, x))) {
        // Visible: the right view sees the same surface where the point lands
        // (one of the two pixels around it, at depth edges).
        const double xr = x - f.left_disparity.at<float>(y, x);
        const int x0 = static_cast<int>(std::floor(xr));
        if (x0 >= 0 && x0 + 1 < f.right.depth.cols) {
          const cv::Vec3f p = f.left.points.at<cv::Vec3f>(y, x);
          double nearest = 1e9;
          for (int xi : {x0, x0 + 1}) {
            const cv::Vec3f q = f.right.points.at<cv::Vec3f>(y, xi);
            if (std::isfinite(q[0])) nearest = std::min(nearest, cv::norm(p - q));
          }
          EXPECT_LT(nearest, 0.01) << "left pixel " << x << "," << y;
        }
      }
    }
  }
  EXPECT_GT(occluded, 20) << "the box must occlude part of the table";
  EXPECT_GT(visible, occluded);
}

TEST(EfficiencySets, RightViewsSpanTheirLevels) {
  for (bool gradient : {false, true}) {
    const sim::EfficiencySet set = sim::makeEfficiencySet(gradient, 160, 120, 140.0, 1);
    ASSERT_EQ(set.rights.size(), 8u);
    const sim::Renderer renderer(set.scene);
    sim::RenderOptions o = quick();
    const sim::ViewRender left = renderer.render(set.left, sim::Lighting(), o);
    for (std::size_t k = 0; k < set.rights.size(); ++k) {
      EXPECT_EQ(set.levels[k], 8 * static_cast<int>(k + 1));
      const cv::Mat d = sim::disparityFromDepth(left.depth, 140.0, set.baselines[k]);
      double lo = 0, hi = 0;
      cv::minMaxLoc(d, &lo, &hi, nullptr, nullptr, d == d);
      EXPECT_LE(hi - lo, set.levels[k] * (1.0 + 1e-5)) << (gradient ? "gradient" : "layers") << " R" << k + 1;
      EXPECT_GE(hi - lo, set.levels[k] * 0.85) << (gradient ? "gradient" : "layers") << " R" << k + 1;
    }
  }
  EXPECT_THROW(sim::makeEfficiencySet(false, 0, 120, 140.0, 1), std::invalid_argument);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
