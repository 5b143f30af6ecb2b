// Tests of the disparity refinement (thesis §2.3): fattening foreground
// detection (FFD) and modified disparity calibration (MDC, Eq. 2.11-2.13).
#include "massage_cell/stereo/refine.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace ms = massage_cell::stereo;

namespace {

constexpr int kW = 160, kH = 120;
constexpr float kBack = 5.0f, kFore = 15.0f;
const cv::Rect kRect(55, 35, 50, 50);  // the foreground object in the left image
constexpr int kFat = 5;                // fattening (pixels) on its left and right sides

/// Textured, low-contrast green-grey background; a saturated red foreground square.
cv::Mat sceneImage() {
  cv::Mat img(kH, kW, CV_8UC3);
  cv::RNG rng(7);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double t = 20.0 * std::sin(x * 0.45) * std::cos(y * 0.3) + rng.uniform(-6, 7);
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(110 + t), cv::saturate_cast<uchar>(140 + t),
                                          cv::saturate_cast<uchar>(100 + t));
    }
  for (int y = kRect.y; y < kRect.br().y; ++y)
    for (int x = kRect.x; x < kRect.br().x; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(30 + rng.uniform(-5, 6)),
                                          cv::saturate_cast<uchar>(40 + rng.uniform(-5, 6)),
                                          cv::saturate_cast<uchar>(210 + rng.uniform(-5, 6)));
  return img;
}

cv::Mat trueDisparity() {
  cv::Mat d(kH, kW, CV_32F, cv::Scalar(kBack));
  d(kRect).setTo(kFore);
  return d;
}

cv::Rect fattenedRect() { return cv::Rect(kRect.x - kFat, kRect.y, kRect.width + 2 * kFat, kRect.height); }

cv::Mat fattenedDisparity() {
  cv::Mat d(kH, kW, CV_32F, cv::Scalar(kBack));
  d(fattenedRect()).setTo(kFore);
  return d;
}

/// The fattened band: inside the fattened rectangle, outside the true one.
cv::Mat bandMask() {
  cv::Mat m = cv::Mat::zeros(kH, kW, CV_8U);
  m(fattenedRect()).setTo(255);
  m(kRect).setTo(0);
  return m;
}

int countDifferent(const cv::Mat& a, const cv::Mat& b, const cv::Mat& where = cv::Mat()) {
  int n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!where.empty() && !where.at<uchar>(y, x)) continue;
      const float u = a.at<float>(y, x), v = b.at<float>(y, x);
      if (!(u == v || (std::isnan(u) && std::isnan(v)))) ++n;
    }
  return n;
}

void expectThrowsWith(const std::function<void()>& f, const std::string& text) {
  try {
    f();
    ADD_FAILURE() << "no exception, expected one mentioning '" << text << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------- FFD --

TEST(DetectFattening, CoversTheFattenedBandAndLittleElse) {
  const cv::Mat img = sceneImage(), band = bandMask();
  const cv::Mat mask = ms::detectFattening(img, fattenedDisparity(), ms::RefineParams());
  ASSERT_EQ(mask.type(), CV_8UC1);
  ASSERT_EQ(mask.size(), img.size());
  const int band_px = cv::countNonZero(band);
  const int hit = cv::countNonZero(mask & band);
  const int rest_px = kW * kH - band_px;
  const int false_px = cv::countNonZero(mask & ~band);
  EXPECT_GE(hit, 0.8 * band_px) << hit << " of " << band_px << " band pixels";
  EXPECT_LE(false_px, 0.05 * rest_px) << false_px << " of " << rest_px << " other pixels";
  // The mask is binary.
  EXPECT_EQ(cv::countNonZero(mask == 255) + cv::countNonZero(mask == 0), kW * kH);
}

TEST(DetectFattening, NoneWhenDisparityEdgesFollowTheImageEdges) {
  const cv::Mat mask = ms::detectFattening(sceneImage(), trueDisparity(), ms::RefineParams());
  EXPECT_EQ(cv::countNonZero(mask), 0);
}

TEST(DetectFattening, GreyImageAndSeedsWork) {
  cv::Mat grey;
  cv::cvtColor(sceneImage(), grey, cv::COLOR_BGR2GRAY);
  const cv::Mat band = bandMask();
  ms::RefineParams p;
  const cv::Mat mask = ms::detectFattening(grey, fattenedDisparity(), p);
  EXPECT_GE(cv::countNonZero(mask & band), 0.8 * cv::countNonZero(band));
  p.superpixels = ms::Superpixels::kSeeds;
  const cv::Mat seeds = ms::detectFattening(sceneImage(), fattenedDisparity(), p);
  EXPECT_GE(cv::countNonZero(seeds & band), 0.5 * cv::countNonZero(band));
}

// OpenCV's SLIC / SLICO read out of bounds and SEEDS crashes or loops forever
// when a superpixel is too large for the image (found by fuzz_stereo_match).
TEST(DetectFattening, ImagesSmallerThanASuperpixelGetAMask) {
  for (const cv::Size size :
       {cv::Size(1, 1), cv::Size(4, 4), cv::Size(5, 5), cv::Size(6, 24), cv::Size(2, 7), cv::Size(40, 3)}) {
    for (const auto kind : {ms::Superpixels::kSlic, ms::Superpixels::kSlico, ms::Superpixels::kSeeds}) {
      cv::Mat left(size, CV_8UC3), disparity(size, CV_32F);
      cv::randu(left, 0, 256);
      cv::randu(disparity, 0.0f, 4.0f);
      ms::RefineParams p;
      p.superpixels = kind;
      p.region_size = 16;
      p.slic_iterations = 3;
      const cv::Mat mask = ms::detectFattening(left, disparity, p);
      EXPECT_EQ(mask.size(), size);
      EXPECT_EQ(mask.type(), CV_8U);
    }
  }
}

TEST(DetectFattening, NanPixelsAreNeverFattening) {
  cv::Mat d = fattenedDisparity();
  d(cv::Rect(0, 0, 20, kH)).setTo(std::numeric_limits<float>::quiet_NaN());
  d.at<float>(kRect.y + 10, kRect.x - 2) = std::numeric_limits<float>::quiet_NaN();  // inside the band
  const cv::Mat mask = ms::detectFattening(sceneImage(), d, ms::RefineParams());
  EXPECT_EQ(cv::countNonZero(mask(cv::Rect(0, 0, 20, kH))), 0);
  EXPECT_EQ(mask.at<uchar>(kRect.y + 10, kRect.x - 2), 0);
  const cv::Mat band = bandMask();
  EXPECT_GE(cv::countNonZero(mask & band), 0.8 * (cv::countNonZero(band) - 1));
  // All NaN: nothing to detect.
  const cv::Mat all_nan(kH, kW, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_EQ(cv::countNonZero(ms::detectFattening(sceneImage(), all_nan, ms::RefineParams())), 0);
}

// ---------------------------------------------------------------------- MDC --

TEST(RecoverDisparity, RecoversTheFattenedBandWithTheMask) {
  const cv::Mat img = sceneImage(), truth = trueDisparity(), band = bandMask();
  ms::RefineParams p;
  const cv::Mat mask = ms::detectFattening(img, fattenedDisparity(), p);
  const cv::Mat out = ms::recoverDisparity(img, fattenedDisparity(), mask, p);
  ASSERT_EQ(out.type(), CV_32FC1);
  EXPECT_EQ(countDifferent(out, truth, band), 0) << "band pixels not recovered";
  EXPECT_EQ(countDifferent(out, truth), 0);
  // refineDisparity chains the two and reports the mask it used.
  cv::Mat used;
  const cv::Mat chained = ms::refineDisparity(img, fattenedDisparity(), p, &used);
  EXPECT_EQ(countDifferent(chained, out), 0);
  EXPECT_EQ(cv::countNonZero(used != mask), 0);
}

TEST(RecoverDisparity, BandGivenExactlyIsRecoveredAndPlainCalibrationIsNot) {
  const cv::Mat img = sceneImage(), truth = trueDisparity(), band = bandMask();
  ms::RefineParams p;
  EXPECT_EQ(countDifferent(ms::recoverDisparity(img, fattenedDisparity(), band, p), truth), 0);
  // With a window not much wider than the band, the fattened band outvotes
  // the background without the mask (Gu's calibration keeps most of it).
  p.window = 11;
  EXPECT_EQ(countDifferent(ms::recoverDisparity(img, fattenedDisparity(), band, p), truth), 0);
  const cv::Mat gu = ms::recoverDisparity(img, fattenedDisparity(), cv::Mat(), p);
  EXPECT_GT(countDifferent(gu, truth, band), cv::countNonZero(band) / 2);
}

TEST(RecoverDisparity, KeepsACorrectMapUnchanged) {
  const cv::Mat img = sceneImage(), truth = trueDisparity();
  const cv::Mat out = ms::recoverDisparity(img, truth, cv::Mat(), ms::RefineParams());
  EXPECT_EQ(countDifferent(out, truth), 0);
  ms::RefineParams p;
  p.detect_fattening = true;
  EXPECT_EQ(countDifferent(ms::refineDisparity(img, truth, p), truth), 0);
}

TEST(RecoverDisparity, RemovesIsolatedNoiseAndKeepsSubPixelValues) {
  const cv::Mat img = sceneImage();
  cv::Mat d = trueDisparity() + 0.25f;  // sub-pixel: kept where the rounded level wins
  d.at<float>(10, 10) = 40.0f;          // outlier in the background
  const cv::Mat out = ms::recoverDisparity(img, d, cv::Mat(), ms::RefineParams());
  EXPECT_FLOAT_EQ(out.at<float>(10, 10), kBack);
  cv::Mat expected = trueDisparity() + 0.25f;
  expected.at<float>(10, 10) = kBack;
  EXPECT_EQ(countDifferent(out, expected), 0);
}

TEST(RecoverDisparity, AllPixelsExcludedKeepsTheInput) {
  const cv::Mat img = sceneImage(), d = fattenedDisparity();
  const cv::Mat everything(kH, kW, CV_8U, cv::Scalar(255));
  EXPECT_EQ(countDifferent(ms::recoverDisparity(img, d, everything, ms::RefineParams()), d), 0);
}

TEST(RecoverDisparity, NanPixelsGetAValueOnlyFromVoters) {
  const cv::Mat img = sceneImage();
  cv::Mat d = trueDisparity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  d(cv::Rect(10, 10, 5, 5)).setTo(nan);        // a hole in the background: filled
  d(cv::Rect(kW - 30, 0, 30, kH)).setTo(nan);  // a wide invalid strip: only its part near voters is filled
  ms::RefineParams p;
  p.window = 11;
  const cv::Mat out = ms::recoverDisparity(img, d, cv::Mat(), p);
  EXPECT_EQ(countDifferent(out(cv::Rect(10, 10, 5, 5)), cv::Mat(5, 5, CV_32F, cv::Scalar(kBack))), 0);
  EXPECT_FLOAT_EQ(out.at<float>(50, kW - 30), kBack);  // 1..5 px from voters
  EXPECT_FLOAT_EQ(out.at<float>(50, kW - 26), kBack);
  EXPECT_TRUE(std::isnan(out.at<float>(50, kW - 25)));  // 6 px: no voter in an 11 x 11 window
  EXPECT_TRUE(std::isnan(out.at<float>(50, kW - 1)));
  // Grey input works too.
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  const cv::Mat out_grey = ms::recoverDisparity(grey, d, cv::Mat(), p);
  EXPECT_EQ(countDifferent(out_grey(cv::Rect(10, 10, 5, 5)), cv::Mat(5, 5, CV_32F, cv::Scalar(kBack))), 0);
  EXPECT_TRUE(std::isnan(out_grey.at<float>(50, kW - 1)));
}

TEST(RecoverDisparity, TiesKeepTheOwnLevelElseTheSmaller) {
  // Flat image, a 1 x 3 row: 2 | 7 | 9 with window 3: every level has one
  // voter; the spatial weights of the two neighbours are equal.
  cv::Mat img(1, 3, CV_8UC1, cv::Scalar(100));
  cv::Mat d = (cv::Mat_<float>(1, 3) << 2.0f, 7.0f, 9.0f);
  ms::RefineParams p;
  p.window = 3;
  cv::Mat out = ms::recoverDisparity(img, d, cv::Mat(), p);
  EXPECT_FLOAT_EQ(out.at<float>(0, 1), 7.0f);  // own level: weight 1 beats exp(-1/γg)
  // Centre excluded: 2 and 9 tie, the smaller wins.
  cv::Mat m = (cv::Mat_<uchar>(1, 3) << 0, 255, 0);
  out = ms::recoverDisparity(img, d, m, p);
  EXPECT_FLOAT_EQ(out.at<float>(0, 1), 2.0f);
  // Centre NaN: same.
  d.at<float>(0, 1) = std::numeric_limits<float>::quiet_NaN();
  out = ms::recoverDisparity(img, d, cv::Mat(), p);
  EXPECT_FLOAT_EQ(out.at<float>(0, 1), 2.0f);
}

// The straightforward MDC the fast one (four pixels per SIMD step, shared tables, min/max shortcut) must match bit
// for bit: per pixel, every voter of the clipped window adds table(Δc) x exp(-Δg/γg) to its level in raster order,
// the maximum wins (ties: own level, else the smallest). The colour index Δc x 64 / γc, clamped to the table, rounds
// half to even.
cv::Mat referenceMdc(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& mask, const ms::RefineParams& p) {
  cv::Mat lab[3];
  if (left.channels() == 1) {
    left.convertTo(lab[0], CV_32F, 100.0 / 255.0);
    lab[1] = cv::Mat::zeros(left.size(), CV_32F);
    lab[2] = cv::Mat::zeros(left.size(), CV_32F);
  } else {
    cv::Mat f, l;
    left.convertTo(f, CV_32F, 1.0 / 255.0);
    cv::cvtColor(f, l, cv::COLOR_BGR2Lab);
    cv::split(l, lab);
  }
  const int table_size = static_cast<int>(88.0f * 64.0f) + 1, last = table_size - 1;
  std::vector<float> table(table_size);
  for (int i = 0; i < table_size; ++i) table[i] = static_cast<float>(std::exp(-i / 64.0));
  table.back() = 0.0f;
  const float to_index = 64.0f / p.gamma_c;
  const int r = p.window / 2, W = disparity.cols, H = disparity.rows;
  auto level = [&](int x, int y, bool voter) {  // INT_MIN: none
    const float d = disparity.at<float>(y, x);
    if (std::isnan(d) || (voter && !mask.empty() && mask.at<uchar>(y, x))) return std::numeric_limits<int>::min();
    return static_cast<int>(std::round(static_cast<double>(d)));
  };
  cv::Mat out = disparity.clone();
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      std::map<int, float> score;
      const int x0 = std::max(0, x - r), x1 = std::min(W - 1, x + r), n = x1 - x0 + 1;
      for (int yy = std::max(0, y - r); yy <= std::min(H - 1, y + r); ++yy)
        for (int i = 0; i < n; ++i) {
          const int xx = x0 + i, l = level(xx, yy, true);
          if (l == std::numeric_limits<int>::min()) continue;
          const float dL = lab[0].at<float>(yy, xx) - lab[0].at<float>(y, x);
          const float da = lab[1].at<float>(yy, xx) - lab[1].at<float>(y, x);
          const float db = lab[2].at<float>(yy, xx) - lab[2].at<float>(y, x);
          const float dc = std::min(std::sqrt(dL * dL + da * da + db * db) * to_index, static_cast<float>(last));
          const int index = static_cast<int>(std::nearbyint(dc));  // default rounding mode: half to even
          const int gx = xx - x, gy = yy - y;
          const float spatial = static_cast<float>(std::exp(-std::sqrt(double(gx * gx + gy * gy)) / p.gamma_g));
          score[l] += table[index] * spatial;  // std::map starts at +0.0f
        }
      if (score.empty()) continue;
      const int own = level(x, y, false);
      int winner = 0;
      float best = -1.0f;
      for (const auto& [l, s] : score)  // ascending: the first maximum is the smallest
        if (s > best) {
          best = s;
          winner = l;
        }
      if (score.count(own) && score[own] == best) winner = own;
      if (winner != own) out.at<float>(y, x) = static_cast<float>(winner);
    }
  return out;
}

/// Bitwise equality (NaN payloads included).
int countBitwiseDifferent(const cv::Mat& a, const cv::Mat& b) {
  int n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) n += std::memcmp(&a.at<float>(y, x), &b.at<float>(y, x), sizeof(float)) != 0;
  return n;
}

TEST(RecoverDisparity, FastVoteEqualsTheStraightforwardOneBitForBit) {
  cv::RNG rng(12345);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  int cases = 0, changed = 0;
  for (const cv::Size size : {cv::Size(90, 70), cv::Size(37, 29), cv::Size(24, 40), cv::Size(6, 5), cv::Size(1, 9)})
    for (const int window : {1, 3, 5, 11, 21, 35})
      for (int variant = 0; variant < 7; ++variant) {
        // Images: random colour, random grey, smooth colour with a few flat (tie-prone) blocks; variant 6: grey
        // levels 0, 51, .. 255 (L = 0, 20, .. 100 exactly) with γc = 512: colour indices k + 0.5 exactly, where the
        // rounding rule (half to even) decides.
        cv::Mat img(size, variant % 3 == 1 || variant == 6 ? CV_8UC1 : CV_8UC3);
        if (variant == 6) {
          rng.fill(img, cv::RNG::UNIFORM, 0, 6);
          img *= 51;
        } else if (variant % 3 == 2) {
          img.setTo(cv::Scalar(90, 120, 60));
          cv::rectangle(img, cv::Rect(size.width / 3, 0, size.width / 3 + 1, size.height), cv::Scalar(30, 40, 200),
                        cv::FILLED);
        } else {
          rng.fill(img, cv::RNG::UNIFORM, 0, 256);
          if (variant >= 3) cv::GaussianBlur(img, img, cv::Size(7, 7), 2.0);
        }
        // Disparities: a few levels in blocks plus noise and outliers, sub-pixel values, NaN holes; variant 4 and
        // 5: many distinct levels (beyond the SIMD path's level limits, and beyond 64 levels).
        cv::Mat d(size, CV_32F);
        const int spread = variant == 4 ? 40 : variant == 5 ? 120 : 3;
        for (int y = 0; y < size.height; ++y)
          for (int x = 0; x < size.width; ++x) {
            float v = 10.0f + static_cast<float>((x / 7 + y / 9) % 3) * 2.0f;
            if (rng.uniform(0.0, 1.0) < 0.15) v = 10.0f + static_cast<float>(rng.uniform(0, spread));
            if (rng.uniform(0.0, 1.0) < 0.3) v += rng.uniform(-0.4f, 0.4f);
            if (rng.uniform(0.0, 1.0) < 0.08) v = nan;
            d.at<float>(y, x) = v;
          }
        if (variant == 2) d(cv::Rect(0, 0, std::max(1, size.width / 4), size.height)).setTo(nan);  // a wide hole
        for (int m = 0; m < 2; ++m) {
          cv::Mat mask;
          if (m == 1) {
            mask.create(size, CV_8U);
            rng.fill(mask, cv::RNG::UNIFORM, 0, 2);
            mask *= 255;
            mask(cv::Rect(0, 0, size.width, std::max(1, size.height / 3))).setTo(0);
          }
          ms::RefineParams p;
          p.window = window;
          if (variant == 3) p.gamma_c = 0.05f;  // weights underflow to 0: all-zero scores
          if (variant == 5) p.gamma_g = 0.02f;
          if (variant == 6) p.gamma_c = 512.0f;
          const cv::Mat expected = referenceMdc(img, d, mask, p);
          for (const int threads : {1, 0}) {
            const cv::Mat got = ms::recoverDisparity(img, d, mask, p, threads);
            ASSERT_EQ(countBitwiseDifferent(got, expected), 0)
                << size << " window " << window << " variant " << variant << " mask " << m << " threads " << threads;
          }
          ++cases;
          changed += countBitwiseDifferent(expected, d) > 0;
        }
      }
  EXPECT_GT(changed, cases / 2);  // the comparisons are not all trivial
  // The structured scene, with FFD's mask and without, and Gu's calibration at the default window.
  const cv::Mat img = sceneImage(), d = fattenedDisparity();
  ms::RefineParams p;
  const cv::Mat mask = ms::detectFattening(img, d, p);
  EXPECT_EQ(countBitwiseDifferent(ms::recoverDisparity(img, d, mask, p), referenceMdc(img, d, mask, p)), 0);
  EXPECT_EQ(countBitwiseDifferent(ms::recoverDisparity(img, d, cv::Mat(), p), referenceMdc(img, d, cv::Mat(), p)), 0);
}

// ------------------------------------------------------------- validation --

TEST(Refine, BadInputThrowsNamingTheProblem) {
  const cv::Mat img = sceneImage(), d = trueDisparity();
  const ms::RefineParams p;
  expectThrowsWith([&] { ms::detectFattening(cv::Mat(), d, p); }, "empty image");
  expectThrowsWith([&] { ms::recoverDisparity(img, cv::Mat(), cv::Mat(), p); }, "empty disparity");
  expectThrowsWith([&] { ms::detectFattening(img(cv::Rect(0, 0, 50, 50)), d, p); }, "sizes differ");
  cv::Mat d64;
  d.convertTo(d64, CV_64F);
  expectThrowsWith([&] { ms::recoverDisparity(img, d64, cv::Mat(), p); }, "CV_32FC1");
  cv::Mat img16;
  img.convertTo(img16, CV_16UC3);
  expectThrowsWith([&] { ms::detectFattening(img16, d, p); }, "unsupported image type");
  cv::Mat inf = d.clone();
  inf.at<float>(3, 4) = std::numeric_limits<float>::infinity();
  expectThrowsWith([&] { ms::refineDisparity(img, inf, p); }, "infinite disparity at (4, 3)");
  expectThrowsWith([&] { ms::recoverDisparity(img, d, cv::Mat(10, 10, CV_8U), p); },
                   "mask and disparity map sizes differ");
  expectThrowsWith([&] { ms::recoverDisparity(img, d, cv::Mat(kH, kW, CV_32F), p); }, "mask must be CV_8UC1");
  ms::RefineParams bad;
  bad.window = 4;
  expectThrowsWith([&] { ms::recoverDisparity(img, d, cv::Mat(), bad); }, "window");
  bad = ms::RefineParams();
  bad.gamma_c = 0.0f;
  expectThrowsWith([&] { ms::refineDisparity(img, d, bad); }, "gamma_c");
  bad = ms::RefineParams();
  bad.gamma_g = std::numeric_limits<float>::quiet_NaN();
  expectThrowsWith([&] { ms::refineDisparity(img, d, bad); }, "gamma_g");
  bad = ms::RefineParams();
  bad.region_size = 2;
  expectThrowsWith([&] { ms::detectFattening(img, d, bad); }, "region_size");
  bad = ms::RefineParams();
  bad.canny_high = 1.0f;
  expectThrowsWith([&] { ms::detectFattening(img, d, bad); }, "canny_high");
  bad = ms::RefineParams();
  bad.edge_tolerance = -1.0f;
  expectThrowsWith([&] { ms::detectFattening(img, d, bad); }, "edge_tolerance");
  bad = ms::RefineParams();
  bad.min_class_fraction = 0.5f;
  expectThrowsWith([&] { ms::detectFattening(img, d, bad); }, "min_class_fraction");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
