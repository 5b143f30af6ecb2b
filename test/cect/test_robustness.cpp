// CECT never crashes: randomised degenerate inputs (no back, a sliver of
// back, a back with very few contour samples, one colour, noise, tiny and
// huge images, non-finite calibrations) give a clear invalid result or a
// std::invalid_argument naming the problem. Run under ASan / UBSan too
// (scripts/run_sanitizers.sh).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/locate.h"

using namespace massage_cell;

namespace {

camera::CameraCalibration rectifiedCamera(int w, int h, double f, double tx) {
  camera::CameraCalibration c;
  c.width = w;
  c.height = h;
  c.D.assign(5, 0.0);
  c.K = {f, 0, (w - 1) / 2.0, 0, f, (h - 1) / 2.0, 0, 0, 1};
  c.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.P = {f, 0, (w - 1) / 2.0, tx, 0, f, (h - 1) / 2.0, 0, 0, 0, 1, 0};
  return c;
}

camera::StereoModel rectifiedGeometry(int w, int h, double f = 500.0, double baseline = 0.1) {
  return camera::StereoModel(rectifiedCamera(w, h, f, 0.0), rectifiedCamera(w, h, f, -f * baseline));
}

const cect::AcupointModel& model() {
  static const cect::AcupointModel m =
      cect::loadAcupointModel(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/acupoints.yaml");
  return m;
}

const cv::Scalar kSkin(120, 150, 205), kSheet(225, 220, 212);  // BGR

/// The right view of a fronto-parallel scene at disparity d.
cv::Mat shifted(const cv::Mat& left, double d) {
  const cv::Matx23d m(1, 0, -d, 0, 1, 0);
  cv::Mat right;
  cv::warpAffine(left, right, m, left.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return right;
}

/// A pair with `shape` drawn in skin colour on a sheet, faint noise on both.
std::pair<cv::Mat, cv::Mat> shapePair(cv::Size size, double d, const std::function<void(cv::Mat&)>& shape) {
  cv::Mat left(size, CV_8UC3, kSheet);
  shape(left);
  cv::Mat noise(size, CV_8UC3);
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(3));
  left += noise;
  return {left, shifted(left, d)};
}

/// What the randomised cases share: a 320x240 rectified rig (f 250 px) and
/// uniform draws in [0, 1) from a fixed seed.
struct RandomCases {
  explicit RandomCases(std::uint32_t seed) : rng(seed) {}
  double u() { return unit(rng); }
  const cv::Size size{320, 240};
  const camera::StereoModel geometry = rectifiedGeometry(320, 240, 250.0);
  std::mt19937 rng;
  std::uniform_real_distribution<double> unit{0.0, 1.0};
};

/// What every degenerate case must give: no crash, an invalid frame with a
/// reason, and acupoints all invalid with that reason.
void expectInvalid(const cv::Mat& left, const cv::Mat& right, const camera::StereoModel& g, const std::string& what) {
  SCOPED_TRACE(what);
  const cect::CectFrame f = cect::CectFrame::analyse(left, right, g, cect::CectParams{});
  EXPECT_FALSE(f.valid());
  EXPECT_FALSE(f.reason().empty());
  const cect::LocatedAcupoints a = cect::locateAcupoints(f, model());
  EXPECT_FALSE(a.valid);
  EXPECT_EQ(a.validCount(), 0);
  ASSERT_EQ(a.points.size(), model().points.size());
  for (const auto& p : a.points) EXPECT_FALSE(p.reason.empty()) << p.name;
  const cect::LocalizedPoint q = f.localize(cv::Point2f(left.cols / 2.0f, left.rows / 2.0f));
  EXPECT_FALSE(q.valid);
  EXPECT_FALSE(q.reason.empty());
}

/// Whatever the frame: every answer is either valid and finite or carries a reason.
void expectConsistent(const cv::Mat& left, const cv::Mat& right, const camera::StereoModel& g,
                      const std::string& what) {
  SCOPED_TRACE(what);
  const cect::CectFrame f = cect::CectFrame::analyse(left, right, g, cect::CectParams{});
  if (!f.valid()) {
    EXPECT_FALSE(f.reason().empty());
  }
  const cect::LocatedAcupoints a = cect::locateAcupoints(f, model());
  if (!a.valid) {
    EXPECT_FALSE(a.reason.empty());
  }
  for (const auto& p : a.points) {
    if (p.valid) {
      EXPECT_TRUE(p.point.position.allFinite()) << p.name;
    } else {
      EXPECT_FALSE(p.reason.empty()) << p.name;
    }
  }
}

}  // namespace

TEST(CectRobustness, NoBackOneColourOrNoiseIsAClearInvalidResult) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  const camera::StereoModel g = rectifiedGeometry(320, 240, 250.0);
  for (int i = 0; i < 6; ++i) {
    const cv::Scalar colour(byte(rng), byte(rng), byte(rng));
    const cv::Mat one(240, 320, CV_8UC3, colour);
    expectInvalid(one, one, g, "one colour " + std::to_string(i));
    cv::Mat noise(240, 320, CV_8UC3);
    cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(256));
    expectInvalid(noise, shifted(noise, 7), g, "noise " + std::to_string(i));
  }
  const cv::Mat skin(240, 320, CV_8UC3, kSkin);
  expectInvalid(skin, skin, g, "skin colour everywhere");
  const cv::Mat sheet(240, 320, CV_8UC3, kSheet);
  expectInvalid(sheet, sheet, g, "only the sheet");
}

TEST(CectRobustness, ASliverOfBackIsAClearInvalidResult) {
  RandomCases r(12);
  const cv::Size size = r.size;
  const camera::StereoModel& g = r.geometry;
  for (int i = 0; i < 6; ++i) {
    const double angle = 180.0 * r.u();
    const int thickness = 1 + static_cast<int>(4 * r.u());
    const auto pair = shapePair(size, 20 + 20 * r.u(), [&](cv::Mat& img) {
      cv::ellipse(img, cv::Point(160, 120), cv::Size(150, thickness), angle, 0, 360, kSkin, -1);
    });
    expectInvalid(pair.first, pair.second, g, "sliver at " + std::to_string(angle) + " deg");
  }
}

// A flat band along the rows: big enough for the segmentation, but only its
// two short ends cross the epipolar lines, so fewer contour samples exist
// than the correspondence search's continuity window (the out-of-bounds read
// behind a SIGSEGV on real scenes). Not a back: no acupoints.
TEST(CectRobustness, VeryFewContourSamplesDoNotCrash) {
  RandomCases r(13);
  const cv::Size size = r.size;
  const camera::StereoModel& g = r.geometry;
  for (int i = 0; i < 8; ++i) {
    const int height = 8 + static_cast<int>(14 * r.u());
    const int top = 20 + static_cast<int>(180 * r.u());
    const auto pair = shapePair(size, 10 + 30 * r.u(),
                                [&](cv::Mat& img) { cv::rectangle(img, cv::Rect(10, top, 300, height), kSkin, -1); });
    expectConsistent(pair.first, pair.second, g, "band " + std::to_string(height) + " px high");
    EXPECT_FALSE(cect::locateAcupoints(cect::CectFrame::analyse(pair.first, pair.second, g, {}), model()).valid);
  }
}

TEST(CectRobustness, TinyAndHugeImages) {
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(2, 2), cv::Size(16, 12), cv::Size(40, 30)}) {
    const camera::StereoModel g = rectifiedGeometry(size.width, size.height, size.width * 0.8);
    cv::Mat img(size, CV_8UC3, kSheet);
    cv::circle(img, cv::Point(size.width / 2, size.height / 2), std::max(1, size.width / 3), kSkin, -1);
    expectInvalid(img, img, g, std::to_string(size.width) + "x" + std::to_string(size.height));
  }
  const cv::Size huge(4000, 3000);
  const camera::StereoModel g = rectifiedGeometry(huge.width, huge.height, 3000.0);
  cv::Mat img(huge, CV_8UC3, kSheet);
  expectInvalid(img, img, g, "4000x3000 without a back");
}

TEST(CectRobustness, RandomSkinShapesGiveConsistentAnswers) {
  RandomCases r(14);
  const cv::Size size = r.size;
  const camera::StereoModel& g = r.geometry;
  for (int i = 0; i < 12; ++i) {
    // Ellipses and rectangles anywhere (partly out of view), at any
    // disparity, also outside the depth range searched or negative.
    const double d = -20.0 + 200.0 * r.u();
    const auto pair = shapePair(size, d, [&](cv::Mat& img) {
      const cv::Point c(static_cast<int>(-40 + 400 * r.u()), static_cast<int>(-40 + 320 * r.u()));
      const cv::Size axes(static_cast<int>(5 + 200 * r.u()), static_cast<int>(5 + 150 * r.u()));
      if (r.u() < 0.5)
        cv::ellipse(img, c, axes, 360 * r.u(), 0, 360, kSkin, -1);
      else
        cv::rectangle(img, cv::Rect(c, axes), kSkin, -1);
    });
    expectConsistent(pair.first, pair.second, g, "shape " + std::to_string(i) + " at d " + std::to_string(d));
  }
}

TEST(CectRobustness, NonFiniteCalibrationsAndMismatchedImagesAreRefused) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  for (const double bad : {nan, inf, 0.0, -500.0}) {
    camera::CameraCalibration l = rectifiedCamera(320, 240, 250.0, 0.0), r = rectifiedCamera(320, 240, 250.0, -25.0);
    l.K[0] = l.P[0] = bad;
    EXPECT_THROW(camera::StereoModel(l, r), std::invalid_argument) << "fx " << bad;
    l = rectifiedCamera(320, 240, 250.0, 0.0);
    r.P[3] = bad;
    if (bad != -500.0) {
      EXPECT_THROW(camera::StereoModel(l, r), std::invalid_argument) << "Tx " << bad;
    }
    r = rectifiedCamera(320, 240, 250.0, -25.0);
    r.D[0] = bad;
    if (!std::isfinite(bad)) {
      EXPECT_THROW(camera::StereoModel(l, r), std::invalid_argument) << "D " << bad;
    }
    r = rectifiedCamera(320, 240, 250.0, -25.0);
  }
  const camera::StereoModel g = rectifiedGeometry(320, 240, 250.0);
  const cv::Mat img(240, 320, CV_8UC3, kSheet), other(200, 320, CV_8UC3, kSheet), grey(240, 320, CV_8U);
  EXPECT_THROW(cect::CectFrame::analyse(img, other, g, {}), std::invalid_argument);
  EXPECT_THROW(cect::CectFrame::analyse(grey, grey, g, {}), std::invalid_argument);
  EXPECT_THROW(cect::CectFrame::analyse(cv::Mat(), img, g, {}), std::invalid_argument);
  cect::CectParams p;
  p.max_depth = nan;
  EXPECT_THROW(cect::CectFrame::analyse(img, img, g, p), std::invalid_argument);
  p = {};
  p.min_depth = 3.0;  // beyond max_depth
  EXPECT_THROW(cect::CectFrame::analyse(img, img, g, p), std::invalid_argument);
}

TEST(CectRobustness, TheDisparitySearchFollowsTheCalibrationAndTheDepthRange) {
  cect::CectParams p;  // 0.25 .. 2.5 m
  const camera::StereoModel a = rectifiedGeometry(640, 480, 500.0, 0.10),
                            b = rectifiedGeometry(1280, 960, 1000.0, 0.06);
  EXPECT_NEAR(cect::disparityRange(p, a)[0], 500.0 * 0.10 / 2.5, 1e-9);
  EXPECT_NEAR(cect::disparityRange(p, a)[1], 500.0 * 0.10 / 0.25, 1e-9);
  EXPECT_NEAR(cect::disparityRange(p, b)[0], 1000.0 * 0.06 / 2.5, 1e-9);
  EXPECT_NEAR(cect::disparityRange(p, b)[1], 1000.0 * 0.06 / 0.25, 1e-9);
  p.min_depth = 0.01;  // nearer than the image can show: capped at its width
  EXPECT_NEAR(cect::disparityRange(p, a)[1], 639.0, 1e-9);
  p.min_disparity = 12.0;
  p.max_disparity = 40.0;
  EXPECT_EQ(cect::disparityRange(p, a), cv::Vec2d(12.0, 40.0));
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
