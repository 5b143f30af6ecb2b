// The conventional refiners (filters.h): 2DBF, 3DBF and WMF keep a step
// where the image has an edge, remove isolated errors, follow FFD's mask
// (a fattened band wearing the background's colour returns to the
// background only when it is excluded), and name bad input.
#include "massage_cell/stereo/filters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/pipeline.h"

namespace ms = massage_cell::stereo;

namespace {

constexpr int kW = 60, kH = 40, kEdge = 30;
constexpr float kBack = 4.0f, kFore = 12.0f;

/// Left half dark background at disparity 4, right half bright foreground at 12; a textured image.
void stepScene(cv::Mat& image, cv::Mat& disparity) {
  image.create(kH, kW, CV_8UC3);
  cv::RNG rng(5);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const int base = x < kEdge ? 60 : 190;
      image.at<cv::Vec3b>(y, x) = cv::Vec3b::all(static_cast<uchar>(base + rng.uniform(-4, 5)));
    }
  }
  disparity.create(kH, kW, CV_32F);
  disparity.colRange(0, kEdge).setTo(kBack);
  disparity.colRange(kEdge, kW).setTo(kFore);
}

double meanAbsError(const cv::Mat& a, const cv::Mat& truth) {
  cv::Mat diff;
  cv::absdiff(a, truth, diff);
  return cv::mean(diff)[0];
}

const ms::DisparityFilter kAll[3] = {ms::DisparityFilter::kBilateral2d, ms::DisparityFilter::kBilateral3d,
                                     ms::DisparityFilter::kWeightedMedian};

TEST(Filters, KeepTheStepAndRemoveIsolatedErrors) {
  cv::Mat image, truth;
  stepScene(image, truth);
  cv::Mat noisy = truth.clone();
  cv::RNG rng(9);
  for (int i = 0; i < 40; ++i) noisy.at<float>(rng.uniform(0, kH), rng.uniform(0, kW)) = 30.0f;  // 40 outliers
  const double noise = meanAbsError(noisy, truth);
  noisy.at<float>(10, 10) = std::numeric_limits<float>::quiet_NaN();
  for (const auto f : kAll) {
    const cv::Mat out = ms::filterDisparity(image, noisy, f, cv::Mat(), ms::FilterParams());
    ASSERT_EQ(out.type(), CV_32F);
    ASSERT_EQ(out.size(), noisy.size());
    EXPECT_TRUE(std::isfinite(out.at<float>(10, 10))) << ms::toString(f) << ": NaN pixels get their window's value";
    // The outliers move (nearly) back and the step stays where the image's edge is.
    if (f == ms::DisparityFilter::kBilateral2d) {  // an average: the outliers spread thin
      EXPECT_LT(cv::norm(out, truth, cv::NORM_INF), 0.25 * (30.0 - kFore)) << ms::toString(f);
    } else {  // robust: they vanish
      EXPECT_LT(meanAbsError(out, truth), 0.25 * noise) << ms::toString(f);
    }
    EXPECT_NEAR(out.at<float>(20, kEdge - 2), kBack, 0.6) << ms::toString(f);
    EXPECT_NEAR(out.at<float>(20, kEdge + 1), kFore, 0.6) << ms::toString(f);
  }
}

TEST(Filters, FattenedBandReturnsOnlyWhenExcluded) {
  cv::Mat image, truth;
  stepScene(image, truth);
  // The foreground's disparity spills 6 px into the background (fattening, under the filters' radius), as
  // FFD would mark.
  cv::Mat fattened = truth.clone(), mask(kH, kW, CV_8U, cv::Scalar(0));
  fattened.colRange(kEdge - 6, kEdge).setTo(kFore);
  mask.colRange(kEdge - 6, kEdge).setTo(255);
  for (const auto f : kAll) {
    const cv::Mat plain = ms::filterDisparity(image, fattened, f, cv::Mat(), ms::FilterParams());
    const cv::Mat masked = ms::filterDisparity(image, fattened, f, mask, ms::FilterParams());
    const cv::Rect band(kEdge - 6, 0, 6, kH);
    EXPECT_LT(meanAbsError(masked(band), truth(band)), 0.5) << ms::toString(f) << " with the mask";
    EXPECT_GT(meanAbsError(plain(band), truth(band)), 2.0) << ms::toString(f) << " without it";
  }
}

TEST(Filters, ThreeDimensionalBilateralIsSubPixel) {
  // A ramp d = 4 + 0.1 x rounded to integers: 3DBF's parabola gives back values between the levels.
  cv::Mat image(kH, kW, CV_8UC1, cv::Scalar(128)), ramp(kH, kW, CV_32F), rounded;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) ramp.at<float>(y, x) = 4.0f + 0.1f * x;
  ramp.copyTo(rounded);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) rounded.at<float>(y, x) = std::round(ramp.at<float>(y, x));
  const cv::Mat out =
      ms::filterDisparity(image, rounded, ms::DisparityFilter::kBilateral3d, cv::Mat(), ms::FilterParams());
  const cv::Rect inner(10, 10, kW - 20, kH - 20);
  EXPECT_LT(meanAbsError(out(inner), ramp(inner)), 0.6 * meanAbsError(rounded(inner), ramp(inner)));
}

TEST(Filters, NoSupportKeepsTheValueAndBadInputIsNamed) {
  cv::Mat image, truth;
  stepScene(image, truth);
  const cv::Mat everything(kH, kW, CV_8U, cv::Scalar(255));
  for (const auto f : kAll) {
    const cv::Mat out = ms::filterDisparity(image, truth, f, everything, ms::FilterParams());
    EXPECT_EQ(cv::norm(out, truth, cv::NORM_INF), 0.0) << ms::toString(f);
  }
  auto expectError = [&](const cv::Mat& left, const cv::Mat& d, const cv::Mat& mask, ms::FilterParams p,
                         const std::string& text) {
    try {
      ms::filterDisparity(left, d, ms::DisparityFilter::kBilateral2d, mask, p);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  ms::FilterParams p;
  expectError(image, truth(cv::Rect(0, 0, 10, 10)), cv::Mat(), p, "sizes differ");
  expectError(image, cv::Mat(kH, kW, CV_8U), cv::Mat(), p, "CV_32F");
  expectError(image, truth, cv::Mat(kH, kW, CV_32F), p, "exclusion mask");
  cv::Mat inf = truth.clone();
  inf.at<float>(0, 0) = std::numeric_limits<float>::infinity();
  expectError(image, inf, cv::Mat(), p, "infinite");
  p.radius = 0;
  expectError(image, truth, cv::Mat(), p, "radius");
  p = ms::FilterParams();
  p.sigma_colour = std::numeric_limits<float>::quiet_NaN();
  expectError(image, truth, cv::Mat(), p, "sigma_colour");
  EXPECT_THROW(ms::parseDisparityFilter("gauss"), std::invalid_argument);
  EXPECT_EQ(ms::parseRefinement("ffd-wmf"), ms::Refinement::kFfdWmf);
  EXPECT_TRUE(ms::usesFattening(ms::Refinement::kFfdBf3d));
  EXPECT_FALSE(ms::usesFattening(ms::Refinement::kBf3d));
  EXPECT_EQ(ms::toString(ms::parseRefinement("3dbf")), "3dbf");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
