// Sub-pixel disparity (subpixel.h): each fit exact on its own cost shape,
// fractional shifts and slanted planes recovered from real cost volumes,
// the pixels it must leave alone, and bad input named.
#include "massage_cell/stereo/subpixel.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/cost_volume.h"

namespace ms = massage_cell::stereo;

namespace {

/// A volume whose cost at every pixel is shape(d - minimum), minimum = d0 + t.
template <typename Shape>
ms::CostVolume syntheticVolume(int w, int h, int dmin, int dmax, double minimum, Shape shape) {
  ms::CostVolume volume(w, h, dmin, dmax);
  for (int d = dmin; d <= dmax; ++d)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) volume(x, y, d) = static_cast<float>(shape(d - minimum));
  return volume;
}

/// A smooth random colour texture (blurred noise: linear interpolation of it
/// is accurate to well under a tenth of a pixel).
cv::Mat smoothTexture(int w, int h, uint64 seed) {
  cv::Mat noise(h, w, CV_8UC3);
  cv::RNG(seed).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat blurred;
  cv::GaussianBlur(noise, blurred, cv::Size(0, 0), 1.2);
  cv::normalize(blurred, blurred, 0, 255, cv::NORM_MINMAX);
  return blurred;
}

/// The left view of `right` for a disparity field: L(x, y) = R(x - d(x, y), y).
cv::Mat leftView(const cv::Mat& right, const cv::Mat& disparity) {
  cv::Mat map_x(right.size(), CV_32F), map_y(right.size(), CV_32F);
  for (int y = 0; y < right.rows; ++y)
    for (int x = 0; x < right.cols; ++x) {
      map_x.at<float>(y, x) = static_cast<float>(x) - disparity.at<float>(y, x);
      map_y.at<float>(y, x) = static_cast<float>(y);
    }
  cv::Mat left;
  cv::remap(right, left, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return left;
}

ms::CostParams costParams(int dmin, int dmax) {
  ms::CostParams p;
  p.dmin = dmin;
  p.dmax = dmax;
  return p;
}

/// Mean |disparity - truth| over the pixels x >= margin.
double meanError(const cv::Mat& disparity, const cv::Mat& truth, int margin) {
  double sum = 0.0;
  int n = 0;
  for (int y = 2; y < truth.rows - 2; ++y)
    for (int x = margin; x < truth.cols - 2; ++x) {
      sum += std::abs(disparity.at<float>(y, x) - truth.at<float>(y, x));
      ++n;
    }
  return sum / n;
}

}  // namespace

TEST(SubpixelDisparity, ParabolaIsExactOnAQuadraticCost) {
  for (const double t : {-0.4, -0.1, 0.0, 0.25, 0.45}) {
    const auto volume = syntheticVolume(6, 4, 0, 10, 5.0 + t, [](double u) { return 0.01 * u * u; });
    const cv::Mat labels(4, 6, CV_32F, cv::Scalar(5.0f));
    const cv::Mat out = ms::subpixelDisparity(volume, labels);
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 6; ++x) EXPECT_NEAR(out.at<float>(y, x), 5.0 + t, 1e-5) << "t = " << t;
  }
}

TEST(SubpixelDisparity, EquiangularIsExactOnAVCostAndTheParabolaIsNot) {
  ms::SubpixelParams equiangular;
  equiangular.fit = ms::SubpixelFit::kEquiangular;
  const auto volume = syntheticVolume(5, 5, 0, 10, 5.3, [](double u) { return 0.05 * std::abs(u); });
  const cv::Mat labels(5, 5, CV_32F, cv::Scalar(5.0f));
  EXPECT_NEAR(ms::subpixelDisparity(volume, labels, equiangular).at<float>(2, 2), 5.3, 1e-5);
  // A parabola through a V pulls the minimum towards the integer (pixel locking).
  EXPECT_LT(ms::subpixelDisparity(volume, labels).at<float>(2, 2), 5.25f);
}

TEST(SubpixelDisparity, FractionalShiftOfARealPairIsRecovered) {
  const cv::Mat right = smoothTexture(96, 48, 3);
  const float truth = 6.3f;
  const cv::Mat disparity(right.size(), CV_32F, cv::Scalar(truth));
  const cv::Mat left = leftView(right, disparity);
  const ms::CostVolume volume = ms::computeCostVolume(left, right, costParams(0, 12));
  const cv::Mat labels = ms::winnerTakesAll(volume);
  const int margin = 12;
  const double integer_error = meanError(labels, disparity, margin);
  const double parabola_error = meanError(ms::subpixelDisparity(volume, labels), disparity, margin);
  ms::SubpixelParams equiangular;
  equiangular.fit = ms::SubpixelFit::kEquiangular;
  const double equiangular_error = meanError(ms::subpixelDisparity(volume, labels, equiangular), disparity, margin);
  EXPECT_NEAR(integer_error, 0.3, 0.05);  // WTA: 6 everywhere
  EXPECT_LT(parabola_error, 0.1);
  EXPECT_LT(equiangular_error, 0.1);
  RecordProperty("integer_error", std::to_string(integer_error));
  RecordProperty("parabola_error", std::to_string(parabola_error));
  RecordProperty("equiangular_error", std::to_string(equiangular_error));
}

TEST(SubpixelDisparity, SlantedPlaneErrorDropsUnderAThird) {
  const cv::Mat right = smoothTexture(160, 48, 5);
  cv::Mat disparity(right.size(), CV_32F);
  for (int y = 0; y < disparity.rows; ++y)
    for (int x = 0; x < disparity.cols; ++x) disparity.at<float>(y, x) = 3.0f + 0.04f * x;  // 3 .. 9.4
  const cv::Mat left = leftView(right, disparity);
  const ms::CostVolume volume = ms::computeCostVolume(left, right, costParams(0, 14));
  const cv::Mat labels = ms::winnerTakesAll(volume);
  const int margin = 14;
  const double integer_error = meanError(labels, disparity, margin);
  const double subpixel_error = meanError(ms::subpixelDisparity(volume, labels), disparity, margin);
  EXPECT_GT(integer_error, 0.2);  // a ramp's rounding error averages 0.25
  EXPECT_LT(subpixel_error, integer_error / 3.0) << integer_error;
}

TEST(SubpixelDisparity, LeavesAlonePixelsWithoutACurveToFit) {
  const auto volume = syntheticVolume(4, 1, 0, 8, 4.2, [](double u) { return u * u; });
  cv::Mat labels(1, 4, CV_32F);
  labels.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  labels.at<float>(0, 1) = 0.0f;   // dmin: no d - 1
  labels.at<float>(0, 2) = 7.0f;   // not the cost's minimum (a smoothness label)
  labels.at<float>(0, 3) = 3.75f;  // already sub-pixel
  ms::SubpixelParams one;
  one.window = 1;
  const cv::Mat out = ms::subpixelDisparity(volume, labels, one);
  EXPECT_TRUE(std::isnan(out.at<float>(0, 0)));
  EXPECT_EQ(out.at<float>(0, 1), 0.0f);
  EXPECT_EQ(out.at<float>(0, 2), 7.0f);
  EXPECT_EQ(out.at<float>(0, 3), 3.75f);
  // dmax too, and a flat cost.
  const auto flat = syntheticVolume(2, 1, 0, 8, 0.0, [](double) { return 0.5; });
  cv::Mat ends(1, 2, CV_32F);
  ends.at<float>(0, 0) = 8.0f;
  ends.at<float>(0, 1) = 4.0f;
  const cv::Mat flat_out = ms::subpixelDisparity(flat, ends, one);
  EXPECT_EQ(flat_out.at<float>(0, 0), 8.0f);
  EXPECT_EQ(flat_out.at<float>(0, 1), 4.0f);
}

TEST(SubpixelDisparity, MaxOffsetClamps) {
  const auto volume = syntheticVolume(3, 3, 0, 10, 5.45, [](double u) { return u * u; });
  const cv::Mat labels(3, 3, CV_32F, cv::Scalar(5.0f));
  ms::SubpixelParams p;
  p.max_offset = 0.25f;
  EXPECT_FLOAT_EQ(ms::subpixelDisparity(volume, labels, p).at<float>(1, 1), 5.25f);
}

TEST(SubpixelDisparity, BadInputIsNamed) {
  const auto volume = syntheticVolume(4, 3, 2, 9, 5.0, [](double u) { return u * u; });
  const cv::Mat good(3, 4, CV_32F, cv::Scalar(5.0f));
  auto message = [&](const cv::Mat& labels, const ms::SubpixelParams& p) {
    try {
      ms::subpixelDisparity(volume, labels, p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message(cv::Mat(3, 5, CV_32F, cv::Scalar(5.0f)), {}).find("5x3"), std::string::npos);
  EXPECT_NE(message(cv::Mat(3, 4, CV_8U, cv::Scalar(5)), {}).find("CV_32F"), std::string::npos);
  cv::Mat outside = good.clone();
  outside.at<float>(1, 2) = 10.0f;
  EXPECT_NE(message(outside, {}).find("outside"), std::string::npos);
  ms::SubpixelParams even;
  even.window = 4;
  EXPECT_NE(message(good, even).find("window"), std::string::npos);
  ms::SubpixelParams zero;
  zero.max_offset = 0.0f;
  EXPECT_NE(message(good, zero).find("max_offset"), std::string::npos);
  EXPECT_THROW(ms::parseSubpixelFit("cubic"), std::invalid_argument);
  EXPECT_EQ(ms::parseSubpixelFit(ms::toString(ms::SubpixelFit::kEquiangular)), ms::SubpixelFit::kEquiangular);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
