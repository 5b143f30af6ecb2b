// Tests of the textured-plane stereo renderer: exact geometry, the stereo
// relation between the views, texture properties, determinism, validation.
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/sim/textured_plane.h"

namespace {

using massage_cell::sim::leftCalibration;
using massage_cell::sim::renderStereo;
using massage_cell::sim::rightCalibration;
using massage_cell::sim::StereoRender;
using massage_cell::sim::StereoRig;
using massage_cell::sim::TexturedPlane;

TexturedPlane frontoParallel(double z) {
  TexturedPlane plane;
  plane.point = {0.0, 0.0, z};
  plane.normal = {0.0, 0.0, -1.0};
  return plane;
}

/// Mean absolute difference over all channels of two equally sized patches.
double meanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar m = cv::mean(diff);
  return (m[0] + m[1] + m[2]) / 3.0;
}

/// Mean Sobel gradient magnitude of the grey version of a BGR image.
double meanGradient(const cv::Mat& bgr) {
  cv::Mat grey, gx, gy, magnitude;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::Sobel(grey, gx, CV_32F, 1, 0);
  cv::Sobel(grey, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, magnitude);
  return cv::mean(magnitude)[0];
}

/// Number of non-NaN pixels of a CV_32F image.
int countFinite(const cv::Mat& m) {
  int n = 0;
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) n += std::isfinite(m.at<float>(r, c)) ? 1 : 0;
  return n;
}

TEST(TexturedPlane, OutputsHaveTheRigSizeAndTypes) {
  StereoRig rig;
  rig.width = 64;
  rig.height = 48;
  rig.cx = 31.5;
  rig.cy = 23.5;
  const StereoRender r = renderStereo(rig, frontoParallel(0.8), 1);
  for (const cv::Mat* m : {&r.left, &r.right}) {
    EXPECT_EQ(m->type(), CV_8UC3);
    EXPECT_EQ(m->size(), cv::Size(64, 48));
  }
  for (const cv::Mat* m : {&r.left_depth, &r.left_disparity}) {
    EXPECT_EQ(m->type(), CV_32F);
    EXPECT_EQ(m->size(), cv::Size(64, 48));
  }
}

TEST(TexturedPlane, FrontoParallelDepthAndDisparityAreExactEverywhere) {
  StereoRig rig;
  rig.fx = 310;
  rig.fy = 290;
  rig.cx = 150;
  rig.cy = 125;
  rig.baseline = 0.075;
  for (double z : {0.35, 0.8, 2.5}) {
    const StereoRender r = renderStereo(rig, frontoParallel(z), 1);
    const double expected_disparity = rig.fx * rig.baseline / z;
    for (int y = 0; y < rig.height; ++y) {
      for (int x = 0; x < rig.width; ++x) {
        ASSERT_NEAR(r.left_depth.at<float>(y, x), z, 1e-6) << "z=" << z << " at (" << x << ", " << y << ")";
        ASSERT_NEAR(r.left_disparity.at<float>(y, x), expected_disparity, 1e-4 * expected_disparity)
            << "z=" << z << " at (" << x << ", " << y << ")";
      }
    }
  }
}

TEST(TexturedPlane, TiltedPlaneDepthVariesLinearlyAlongTheTilt) {
  const StereoRig rig;
  // Normal (0.3, 0, -1) through (0, 0, 0.8): z = 0.8 + 0.3 x, tilted about the y axis.
  TexturedPlane about_y = frontoParallel(0.8);
  about_y.normal = {0.3, 0.0, -1.0};
  const StereoRender r = renderStereo(rig, about_y, 1);
  ASSERT_EQ(countFinite(r.left_depth), rig.width * rig.height);
  for (int y = 0; y < rig.height; ++y) {
    for (int x = 0; x < rig.width; ++x) {
      const double z = r.left_depth.at<float>(y, x);
      const double X = z * (x - rig.cx) / rig.fx;  // back-projection of the pixel centre
      ASSERT_NEAR(z, 0.8 + 0.3 * X, 1e-6) << "at (" << x << ", " << y << ")";
      // Tilt about y: depth is constant down each column...
      ASSERT_NEAR(z, r.left_depth.at<float>(0, x), 1e-6);
      ASSERT_NEAR(r.left_disparity.at<float>(y, x), rig.fx * rig.baseline / z, 1e-4);
    }
  }
  // ...grows to the right, and disparity (proportional to 1/z) is affine in x.
  EXPECT_GT(r.left_depth.at<float>(0, rig.width - 1), r.left_depth.at<float>(0, 0) + 0.05);
  for (int x = 1; x + 1 < rig.width; ++x) {
    const float* d = r.left_disparity.ptr<float>(rig.height / 2);
    ASSERT_NEAR(d[x - 1] - 2.0 * d[x] + d[x + 1], 0.0, 1e-3) << "at x=" << x;
  }

  // Normal (0, 0.2, -1): z = 0.8 + 0.2 y, depth constant along rows, growing downwards.
  TexturedPlane about_x = frontoParallel(0.8);
  about_x.normal = {0.0, 0.2, -1.0};
  const StereoRender s = renderStereo(rig, about_x, 1);
  for (int y = 0; y < rig.height; ++y) {
    for (int x = 0; x < rig.width; ++x) {
      const double z = s.left_depth.at<float>(y, x);
      const double Y = z * (y - rig.cy) / rig.fy;
      ASSERT_NEAR(z, 0.8 + 0.2 * Y, 1e-6) << "at (" << x << ", " << y << ")";
      ASSERT_NEAR(z, s.left_depth.at<float>(y, 0), 1e-6);
    }
  }
  EXPECT_GT(s.left_depth.at<float>(rig.height - 1, 0), s.left_depth.at<float>(0, 0) + 0.03);
}

TEST(TexturedPlane, RightViewIsLeftViewShiftedByTheDisparity) {
  const StereoRig rig;
  const double z = 0.75;  // disparity fx * B / z = 300 * 0.06 / 0.75 = 24 px exactly
  const int d = 24;
  const StereoRender r = renderStereo(rig, frontoParallel(z));
  ASSERT_NEAR(r.left_disparity.at<float>(rig.height / 2, rig.width / 2), d, 1e-4);

  // right(x) sees what left(x + d) sees; compare an interior patch.
  const cv::Rect right_patch(20, 20, rig.width - 2 * 20 - d - 4, rig.height - 40);
  const auto leftPatch = [&](int shift) { return r.left(right_patch + cv::Point(shift, 0)); };
  EXPECT_LT(meanAbsDiff(r.right(right_patch), leftPatch(d)), 0.5);
  for (int wrong : {d - 1, d + 1}) {
    EXPECT_GT(meanAbsDiff(r.right(right_patch), leftPatch(wrong)), 3.0) << "shift " << wrong;
  }
  for (int wrong : {d - 4, d + 4, 0}) {
    EXPECT_GT(meanAbsDiff(r.right(right_patch), leftPatch(wrong)), 10.0) << "shift " << wrong;
  }
}

TEST(TexturedPlane, TextureOffsetSlidesThePatternAlongTheFirstPlaneAxis) {
  const StereoRig rig;
  const double z = 0.8;
  TexturedPlane moved = frontoParallel(z);
  moved.texture_offset = {5.0 * z / rig.fx, 0.0};  // 5 pixels' worth at this depth
  const StereoRender before = renderStereo(rig, frontoParallel(z));
  const StereoRender after = renderStereo(rig, moved);
  // The pattern moves 5 px to the left: after(x) == before(x + 5).
  const cv::Rect patch(10, 10, rig.width - 30, rig.height - 20);
  EXPECT_LT(meanAbsDiff(after.left(patch), before.left(patch + cv::Point(5, 0))), 0.5);
  EXPECT_GT(meanAbsDiff(after.left(patch), before.left(patch)), 5.0);
  // Geometry does not depend on the texture.
  EXPECT_EQ(cv::norm(after.left_depth, before.left_depth, cv::NORM_INF), 0.0);
}

TEST(TexturedPlane, RenderingIsDeterministicAndSeedDependent) {
  const StereoRig rig;
  TexturedPlane plane = frontoParallel(0.8);
  plane.seed = 7;
  const StereoRender a = renderStereo(rig, plane, 2, 1.5, 3);
  const StereoRender b = renderStereo(rig, plane, 2, 1.5, 3);
  EXPECT_EQ(cv::norm(a.left, b.left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.right, b.right, cv::NORM_INF), 0.0);

  plane.seed = 8;
  const StereoRender other_texture = renderStereo(rig, plane, 2, 1.5, 3);
  EXPECT_GT(meanAbsDiff(a.left, other_texture.left), 10.0);
  EXPECT_GT(meanAbsDiff(a.right, other_texture.right), 10.0);

  plane.seed = 7;
  const StereoRender other_noise = renderStereo(rig, plane, 2, 1.5, 4);
  EXPECT_GT(cv::norm(a.left, other_noise.left, cv::NORM_INF), 0.0);
  EXPECT_LT(meanAbsDiff(a.left, other_noise.left), 3.0);  // same scene, only the noise differs
}

TEST(TexturedPlane, NoiseHasTheRequestedSigmaAndDiffersBetweenViews) {
  const StereoRig rig;
  const double sigma = 4.0;
  const StereoRender clean = renderStereo(rig, frontoParallel(0.8), 1);
  const StereoRender noisy = renderStereo(rig, frontoParallel(0.8), 1, sigma, 11);
  for (const auto& [c, n] : {std::pair{&clean.left, &noisy.left}, std::pair{&clean.right, &noisy.right}}) {
    cv::Mat diff;
    cv::subtract(*n, *c, diff, cv::noArray(), CV_32F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(diff.reshape(1), mean, stddev);
    EXPECT_NEAR(mean[0], 0.0, 0.2);
    EXPECT_NEAR(stddev[0], sigma, 0.1 * sigma);
  }
  cv::Mat left_noise, right_noise;
  cv::subtract(noisy.left, clean.left, left_noise, cv::noArray(), CV_32F);
  cv::subtract(noisy.right, clean.right, right_noise, cv::noArray(), CV_32F);
  EXPECT_GT(cv::norm(left_noise, right_noise, cv::NORM_L1) / static_cast<double>(left_noise.total()),
            sigma);  // independent draws
}

TEST(TexturedPlane, TextureHasContrastAtAllScales) {
  const StereoRig rig;
  for (double z : {0.4, 0.8, 1.6}) {
    const StereoRender r = renderStereo(rig, frontoParallel(z));
    cv::Mat grey;
    cv::cvtColor(r.left, grey, cv::COLOR_BGR2GRAY);
    cv::Scalar mean, stddev;
    cv::meanStdDev(grey, mean, stddev);
    EXPECT_GT(stddev[0], 20.0) << "z=" << z;
    EXPECT_GT(mean[0], 60.0) << "z=" << z;
    EXPECT_LT(mean[0], 190.0) << "z=" << z;
    // Block-average down to 1/16: gradients must remain at every scale.
    for (int scale : {1, 2, 4, 8, 16}) {
      cv::Mat small;
      cv::resize(r.left, small, cv::Size(), 1.0 / scale, 1.0 / scale, cv::INTER_AREA);
      EXPECT_GT(meanGradient(small), 20.0) << "z=" << z << " scale " << scale;
    }
    // Pixel-scale detail: fine structure survives a 3x3 box filter's removal.
    cv::Mat blurred, detail;
    cv::blur(grey, blurred, cv::Size(3, 3));
    cv::absdiff(grey, blurred, detail);
    EXPECT_GT(cv::mean(detail)[0], 1.0) << "z=" << z;
  }
}

TEST(TexturedPlane, PlaneBehindTheCamerasIsInvisible) {
  const StereoRig rig;
  TexturedPlane behind;
  behind.point = {0.0, 0.0, -0.8};
  behind.normal = {0.0, 0.0, 1.0};
  const StereoRender r = renderStereo(rig, behind);
  EXPECT_EQ(countFinite(r.left_depth), 0);
  EXPECT_EQ(countFinite(r.left_disparity), 0);
  EXPECT_EQ(cv::countNonZero(r.left.reshape(1)), 0);
  EXPECT_EQ(cv::countNonZero(r.right.reshape(1)), 0);
}

TEST(TexturedPlane, FloorBelowTheCamerasFillsOnlyTheLowerHalf) {
  const StereoRig rig;
  TexturedPlane floor;
  floor.point = {0.0, 0.1, 0.0};  // 10 cm below the optical axis (y down)
  floor.normal = {0.0, -1.0, 0.0};
  const StereoRender r = renderStereo(rig, floor, 1);
  for (int y = 0; y < rig.height; ++y) {
    const bool below_horizon = y > rig.cy;
    for (int x = 0; x < rig.width; ++x) {
      const float z = r.left_depth.at<float>(y, x);
      ASSERT_EQ(std::isfinite(z), below_horizon) << "at (" << x << ", " << y << ")";
      if (below_horizon) {
        ASSERT_NEAR(z, 0.1 * rig.fy / (y - rig.cy), 1e-5 * z);
      }
    }
  }
  EXPECT_EQ(cv::countNonZero(r.left(cv::Rect(0, 0, rig.width, rig.height / 2)).reshape(1)), 0);
  EXPECT_GT(meanGradient(r.left(cv::Rect(0, rig.height - 60, rig.width, 60))), 15.0);
}

TEST(TexturedPlane, InvalidInputsThrow) {
  const TexturedPlane plane;
  const auto expectInvalidRig = [&](void (*edit)(StereoRig&), const char* what) {
    StereoRig rig;
    edit(rig);
    EXPECT_THROW(renderStereo(rig, plane), std::invalid_argument) << what;
    EXPECT_THROW(leftCalibration(rig), std::invalid_argument) << what;
    EXPECT_THROW(rightCalibration(rig), std::invalid_argument) << what;
  };
  expectInvalidRig([](StereoRig& r) { r.width = 0; }, "width 0");
  expectInvalidRig([](StereoRig& r) { r.height = -3; }, "height -3");
  expectInvalidRig([](StereoRig& r) { r.fx = 0; }, "fx 0");
  expectInvalidRig([](StereoRig& r) { r.fy = -300; }, "fy -300");
  expectInvalidRig([](StereoRig& r) { r.fx = std::nan(""); }, "fx NaN");
  expectInvalidRig([](StereoRig& r) { r.baseline = 0; }, "baseline 0");
  expectInvalidRig([](StereoRig& r) { r.baseline = -0.06; }, "baseline -0.06");

  const StereoRig rig;
  const auto expectInvalidPlane = [&](void (*edit)(TexturedPlane&), const char* what) {
    TexturedPlane p;
    edit(p);
    EXPECT_THROW(renderStereo(rig, p), std::invalid_argument) << what;
  };
  expectInvalidPlane([](TexturedPlane& p) { p.normal.setZero(); }, "zero normal");
  expectInvalidPlane([](TexturedPlane& p) { p.feature_size = 0; }, "feature_size 0");
  expectInvalidPlane([](TexturedPlane& p) { p.feature_size = -0.01; }, "feature_size -0.01");
  expectInvalidPlane([](TexturedPlane& p) { p.point.x() = INFINITY; }, "infinite point");

  EXPECT_THROW(renderStereo(rig, plane, 0), std::invalid_argument);
  EXPECT_THROW(renderStereo(rig, plane, -2), std::invalid_argument);
  EXPECT_THROW(renderStereo(rig, plane, 3, -1.0), std::invalid_argument);
  try {
    renderStereo(rig, plane, 3, -1.0);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("noise"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(renderStereo(rig, plane, 1, 0.0));
}

TEST(TexturedPlane, CalibrationsDescribeTheRig) {
  StereoRig rig;
  rig.width = 640;
  rig.height = 480;
  rig.fx = 600;
  rig.fy = 610;
  rig.cx = 319.5;
  rig.cy = 241;
  rig.baseline = 0.08;
  const auto left = leftCalibration(rig);
  const auto right = rightCalibration(rig);
  for (const auto* c : {&left, &right}) {
    EXPECT_EQ(c->width, 640);
    EXPECT_EQ(c->height, 480);
    EXPECT_EQ(c->distortion_model, "plumb_bob");
    EXPECT_EQ(c->D, std::vector<double>(5, 0.0));
    EXPECT_EQ(c->K, (std::array<double, 9>{600, 0, 319.5, 0, 610, 241, 0, 0, 1}));
    EXPECT_EQ(c->R, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
    EXPECT_TRUE(massage_cell::camera::checkCalibration(*c, cv::Size(640, 480), "sim").empty());
  }
  EXPECT_EQ(left.P, (std::array<double, 12>{600, 0, 319.5, 0, 0, 610, 241, 0, 0, 0, 1, 0}));
  EXPECT_EQ(right.P, (std::array<double, 12>{600, 0, 319.5, -600 * 0.08, 0, 610, 241, 0, 0, 0, 1, 0}));
  EXPECT_DOUBLE_EQ(right.P[3], -rig.fx * rig.baseline);
  EXPECT_TRUE(massage_cell::camera::checkStereoCalibration(left, right).empty());
  EXPECT_DOUBLE_EQ(massage_cell::camera::baseline(right), 0.08);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
