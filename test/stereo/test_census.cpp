// The census and AD-census data terms (cost_volume.h): exact matches cost 0,
// a gain and offset between the cameras does not move the census's minimum,
// the band off the right image costs 1, bad parameters are named.
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/cost_volume.h"
#include "massage_cell/stereo/pipeline.h"

namespace ms = massage_cell::stereo;

namespace {

constexpr int kShift = 5;

/// A random texture and its copy shifted by kShift (left x matches right x - kShift); the right
/// copy optionally with a gain and offset (another camera's exposure).
void shiftedPair(cv::Mat& left, cv::Mat& right, double gain = 1.0, double offset = 0.0) {
  cv::Mat texture(40, 80 + kShift, CV_8UC3);
  cv::RNG rng(11);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(3, 3), 0.8);
  left = texture.colRange(0, 80).clone();
  texture.colRange(kShift, 80 + kShift).convertTo(right, CV_8UC3, gain, offset);
}

ms::CostParams params(ms::DataTerm term) {
  ms::CostParams p;
  p.dmin = 0;
  p.dmax = 12;
  p.data_term = term;
  return p;
}

double correctShare(const cv::Mat& disparity) {
  int correct = 0, counted = 0;
  for (int y = 4; y < disparity.rows - 4; ++y) {
    for (int x = 16; x < disparity.cols - 5; ++x, ++counted) correct += disparity.at<float>(y, x) == kShift ? 1 : 0;
  }
  return static_cast<double>(correct) / counted;
}

TEST(Census, ExactShiftCostsZeroAndTheBandOne) {
  cv::Mat left, right;
  shiftedPair(left, right);
  for (const auto term : {ms::DataTerm::kCensus, ms::DataTerm::kAdCensus}) {
    const ms::CostVolume v = ms::computeCensusCostVolume(left, right, params(term));
    ASSERT_EQ(v.levels(), 13);
    for (int y = 4; y < 36; ++y) {
      for (int x = 16; x < 75; ++x) {
        ASSERT_EQ(v(x, y, kShift), 0.0f) << ms::toString(term) << " at " << x << "," << y;
        ASSERT_GT(v(x, y, kShift + 3), 0.0f);
        ASSERT_LE(v(x, y, kShift + 3), 1.0f);
      }
      for (int d = 1; d <= 12; ++d) ASSERT_EQ(v(d - 1, y, d), 1.0f) << "x - d < 0 must cost 1";
    }
    // computeCostVolume dispatches on the data term.
    const ms::CostVolume same = ms::computeCostVolume(left, right, params(term));
    EXPECT_EQ(cv::norm(cv::Mat(1, 13 * 40 * 80, CV_32F, const_cast<float*>(same.slice(0))),
                       cv::Mat(1, 13 * 40 * 80, CV_32F, const_cast<float*>(v.slice(0))), cv::NORM_INF),
              0.0);
  }
}

TEST(Census, GainAndOffsetDoNotMoveTheMinimum) {
  cv::Mat left, right;
  shiftedPair(left, right, 0.6, 40.0);
  const double census =
      correctShare(ms::winnerTakesAll(ms::computeCostVolume(left, right, params(ms::DataTerm::kCensus))));
  EXPECT_GT(census, 0.97) << "census WTA under a gain of 0.6 and an offset of 40";
  // A plain colour difference is fooled by it: AD-census's colour half alone (census_lambda huge).
  ms::CostParams colour = params(ms::DataTerm::kAdCensus);
  colour.census_lambda = 1e9f;
  EXPECT_LT(correctShare(ms::winnerTakesAll(ms::computeCostVolume(left, right, colour))), census - 0.3);
}

TEST(Census, GreyImagesWork) {
  cv::Mat left, right, lg, rg;
  shiftedPair(left, right);
  cv::cvtColor(left, lg, cv::COLOR_BGR2GRAY);
  cv::cvtColor(right, rg, cv::COLOR_BGR2GRAY);
  EXPECT_GT(correctShare(ms::winnerTakesAll(ms::computeCostVolume(lg, rg, params(ms::DataTerm::kAdCensus)))), 0.97);
}

TEST(Census, BadParametersAreNamed) {
  cv::Mat left, right;
  shiftedPair(left, right);
  auto expectError = [&](ms::CostParams p, const std::string& text) {
    try {
      ms::computeCostVolume(left, right, p);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  ms::CostParams p = params(ms::DataTerm::kCensus);
  p.census_width = 8;
  expectError(p, "census window");
  p.census_width = 11;  // 11 x 7 - 1 = 76 bits
  expectError(p, "census window");
  p = params(ms::DataTerm::kAdCensus);
  p.ad_lambda = 0.0f;
  expectError(p, "ad_lambda");
  p = params(ms::DataTerm::kAdCensus);
  p.census_lambda = std::numeric_limits<float>::quiet_NaN();
  expectError(p, "census_lambda");
  p = params(ms::DataTerm::kCensus);
  p.dmax = 200;
  expectError(p, "wider than the image");
  EXPECT_THROW(ms::parseDataTerm("sad"), std::invalid_argument);
  EXPECT_EQ(ms::parseDataTerm("ad-census"), ms::DataTerm::kAdCensus);
  EXPECT_EQ(ms::toString(ms::parseDataTerm("census")), "census");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
