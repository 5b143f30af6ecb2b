// Left-right consistency and occlusion filling (consistency.h) and the
// pipeline's lr_check: occluded pixels and the border band found and filled
// from the background, visible ones kept, bad input named; the two views
// matched concurrently give the sequential result, and an exception of either
// view leaves match().
#include "massage_cell/stereo/consistency.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/pipeline.h"

namespace ms = massage_cell::stereo;

namespace {

const float kNan = std::numeric_limits<float>::quiet_NaN();

// A fronto-parallel foreground at disparity 6 over left columns [20, 30) in
// front of a background at 2, W = 48: the exact maps of both views.
constexpr int kW = 48, kH = 4, kBack = 2, kFore = 6, kX0 = 20, kX1 = 30;

cv::Mat exactLeft(float occluded_value) {
  cv::Mat d(kH, kW, CV_32F, cv::Scalar(kBack));
  d.colRange(kX0, kX1).setTo(kFore);
  // Left pixels whose background point the foreground hides from the right
  // camera: x - 2 in the foreground's right columns [14, 24) -> x in [16, 20).
  d.colRange(kX0 - (kFore - kBack), kX0).setTo(occluded_value);
  return d;
}

cv::Mat exactRight() {
  cv::Mat d(kH, kW, CV_32F, cv::Scalar(kBack));
  d.colRange(kX0 - kFore, kX1 - kFore).setTo(kFore);
  return d;
}

/// A random texture pair of that scene (nearest-pixel shifts).
void texturePair(cv::Mat& left, cv::Mat& right) {
  cv::Mat background(kH * 8, kW, CV_8UC3), foreground(kH * 8, kW, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(background, cv::RNG::UNIFORM, 0, 256);
  rng.fill(foreground, cv::RNG::UNIFORM, 0, 256);
  left.create(background.size(), CV_8UC3);
  right.create(background.size(), CV_8UC3);
  // Scene coordinates = right-image columns; the left sees x_r + d.
  for (int y = 0; y < left.rows; ++y)
    for (int x = 0; x < kW; ++x) {
      const bool fore_l = x >= kX0 && x < kX1, fore_r = x >= kX0 - kFore && x < kX1 - kFore;
      const int src_l = x - (fore_l ? kFore : kBack);  // the right-image column this left pixel sees
      left.at<cv::Vec3b>(y, x) =
          fore_l ? foreground.at<cv::Vec3b>(y, (src_l + kW) % kW) : background.at<cv::Vec3b>(y, (src_l + kW) % kW);
      right.at<cv::Vec3b>(y, x) = fore_r ? foreground.at<cv::Vec3b>(y, x) : background.at<cv::Vec3b>(y, x);
    }
}

/// Whether two maps are the same bit for bit (NaN included).
bool sameBits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

/// match() with lr_check spelled out as its documented steps, one after the other on this thread.
ms::MatchResult sequentialLrCheck(const cv::Mat& left, const cv::Mat& right, ms::Method method, ms::StereoParams p) {
  p.lr_check = false;
  ms::MatchResult result = ms::match(left, right, method, p);
  const cv::Mat right_disparity = ms::rightViewDisparity(
      left, right, [&](const cv::Mat& a, const cv::Mat& b) { return ms::match(a, b, method, p).disparity; });
  result.consistent = ms::leftRightCheck(result.disparity, right_disparity, p.lr_tolerance);
  result.disparity = ms::fillFromBackground(result.disparity, result.consistent);
  return result;
}

/// While alive, the default cv::Mat allocator: it throws InjectedFailure for every matrix allocated on the
/// threads chosen (this thread, or every other one), and counts the other threads' allocations.
struct InjectedFailure : std::bad_alloc {};
class FailingAllocator : public cv::MatAllocator {
 public:
  enum class Fail { kOnThisThread, kOnOtherThreads };
  explicit FailingAllocator(Fail fail) : fail_(fail), previous_(cv::Mat::getDefaultAllocator()) {
    cv::Mat::setDefaultAllocator(this);
  }
  ~FailingAllocator() override { cv::Mat::setDefaultAllocator(previous_); }
  FailingAllocator(const FailingAllocator&) = delete;
  FailingAllocator& operator=(const FailingAllocator&) = delete;

  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step, cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    const bool here = std::this_thread::get_id() == owner_;
    if (!here) ++other_threads_;
    if (here == (fail_ == Fail::kOnThisThread)) throw InjectedFailure();
    return std_->allocate(dims, sizes, type, data, step, flags, usage);  // std_ frees it (UMatData::currAllocator)
  }
  bool allocate(cv::UMatData* data, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return std_->allocate(data, flags, usage);
  }
  void deallocate(cv::UMatData* data) const override { std_->deallocate(data); }
  int otherThreadsAllocations() const { return other_threads_; }

 private:
  Fail fail_;
  cv::MatAllocator* previous_;
  cv::MatAllocator* std_ = cv::Mat::getStdAllocator();
  std::thread::id owner_ = std::this_thread::get_id();
  mutable std::atomic<int> other_threads_{0};
};

}  // namespace

TEST(LeftRightCheck, OccludedAndBorderPixelsFailVisibleOnesPass) {
  for (const float occluded_value : {float(kFore), float(kBack), 4.0f}) {  // fattened, background, anything
    const cv::Mat consistent = ms::leftRightCheck(exactLeft(occluded_value), exactRight());
    for (int x = 0; x < kW; ++x) {
      const bool occluded = x >= kX0 - (kFore - kBack) && x < kX0;
      const bool off_image = x < kBack;  // x - 2 < 0
      EXPECT_EQ(consistent.at<uchar>(1, x), occluded || off_image ? 0 : 255)
          << "x " << x << " value " << occluded_value;
    }
  }
}

TEST(LeftRightCheck, ToleranceAndNaN) {
  cv::Mat left = exactLeft(kFore), right = exactRight();
  left.at<float>(0, 40) = kBack + 0.8f;
  left.at<float>(1, 40) = kBack + 1.2f;
  left.at<float>(2, 40) = kNan;
  right.at<float>(3, 40 - kBack) = kNan;
  const cv::Mat consistent = ms::leftRightCheck(left, right, 1.0f);
  EXPECT_EQ(consistent.at<uchar>(0, 40), 255);
  EXPECT_EQ(consistent.at<uchar>(1, 40), 0);
  EXPECT_EQ(consistent.at<uchar>(2, 40), 0);
  EXPECT_EQ(consistent.at<uchar>(3, 40), 0);
  EXPECT_EQ(ms::leftRightCheck(left, right, 0.0f).at<uchar>(0, 40), 0);
}

TEST(FillFromBackground, TakesTheFartherNeighbourAndOneSideAtTheEdge) {
  const cv::Mat d = (cv::Mat_<float>(3, 7) << 9, 2, 7, 7, 6, 6, 5,  //
                     kNan, 3, 1, 1, 1, 4, 8,                        //
                     1, 2, 3, 4, 5, 6, 7);
  const cv::Mat keep = (cv::Mat_<uchar>(3, 7) << 0, 255, 0, 0, 255, 0, 255,  //
                        255, 255, 0, 0, 0, 255, 0,                           //
                        0, 0, 0, 0, 0, 0, 0);
  const cv::Mat f = ms::fillFromBackground(d, keep);
  const cv::Mat want = (cv::Mat_<float>(3, 7) << 2, 2, 2, 2, 6, 5, 5,  //
                        3, 3, 3, 3, 3, 4, 4,                           //
                        kNan, kNan, kNan, kNan, kNan, kNan, kNan);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 7; ++x) {
      const float got = f.at<float>(y, x), w = want.at<float>(y, x);
      if (std::isnan(w)) {
        EXPECT_TRUE(std::isnan(got)) << y << "," << x;
      } else {
        EXPECT_EQ(got, w) << y << "," << x;
      }
    }
}

TEST(LrCheckInMatch, OcclusionAndBorderBandGetTheBackground) {
  cv::Mat left, right;
  texturePair(left, right);
  ms::StereoParams p;
  p.cost.dmin = 0;
  p.cost.dmax = 8;
  p.threads = 1;
  p.refine = ms::Refinement::kNone;  // the check alone, on winner-takes-all's integer layers
  p.lr_check = false;
  const ms::MatchResult plain = ms::match(left, right, ms::Method::kWta, p);
  p.lr_check = true;
  p.lr_tolerance = 0.5f;  // integer layers: the same label (1 lets a label one off pass at the occlusion's rims)
  const ms::MatchResult checked = ms::match(left, right, ms::Method::kWta, p);
  ASSERT_EQ(checked.consistent.type(), CV_8U);
  ASSERT_EQ(checked.consistent.size(), left.size());
  EXPECT_TRUE(plain.consistent.empty());
  EXPECT_GT(checked.lr_ms, 0.0);
  int occluded_marked = 0, occluded = 0, visible_kept = 0, visible = 0, wrong_plain = 0, wrong_checked = 0;
  for (int y = 2; y < left.rows - 2; ++y)
    for (int x = 0; x < kW - 2; ++x) {
      const bool is_occluded = (x >= kX0 - (kFore - kBack) && x < kX0) || x < kBack;
      const float truth = x >= kX0 && x < kX1 ? kFore : kBack;  // occluded pixels: the background behind
      if (is_occluded) {
        ++occluded;
        occluded_marked += checked.consistent.at<uchar>(y, x) == 0;
        wrong_plain += std::abs(plain.disparity.at<float>(y, x) - truth) > 0.5f;
        wrong_checked += std::abs(checked.disparity.at<float>(y, x) - truth) > 0.5f;
      } else if (x > 2 && std::abs(x - kX0) > 2 && std::abs(x - kX1) > 2) {  // away from the windows' edges
        ++visible;
        visible_kept += checked.consistent.at<uchar>(y, x) == 255;
      }
    }
  EXPECT_GE(occluded_marked, occluded * 9 / 10);
  EXPECT_GE(visible_kept, visible * 9 / 10);
  EXPECT_LT(wrong_checked, wrong_plain / 2 + 1) << wrong_plain;
  EXPECT_GT(wrong_plain, occluded / 3);  // WTA alone gets the occluded pixels wrong
}

// With two or more threads the views run concurrently, each with part of the threads: every method and
// refinement (the weighted median's OpenCV filter keeps static state) must still give the sequential result.
TEST(LrCheckInMatch, ConcurrentViewsGiveTheSequentialResult) {
  cv::Mat left, right;
  texturePair(left, right);
  cv::Mat left_grey, right_grey;
  cv::extractChannel(left, left_grey, 1);
  cv::extractChannel(right, right_grey, 1);
  struct Case {
    ms::Method method;
    ms::Refinement refine;
    bool subpixel;
  };
  const std::vector<Case> cases{
      {ms::Method::kHbds, ms::Refinement::kFfdMdc, false}, {ms::Method::kHbds, ms::Refinement::kFfdWmf, true},
      {ms::Method::kHbds, ms::Refinement::kWmf, false},    {ms::Method::kExpansion, ms::Refinement::kFfdBf3d, false},
      {ms::Method::kWta, ms::Refinement::kNone, true},     {ms::Method::kSgbm, ms::Refinement::kBf2d, false}};
  for (const bool grey : {false, true}) {
    const cv::Mat& l = grey ? left_grey : left;
    const cv::Mat& r = grey ? right_grey : right;
    for (const Case& c : cases) {
      for (const int threads : {2, 3, 0}) {
        ms::StereoParams p;
        p.cost.dmax = 8;
        p.refine = c.refine;
        p.subpixel = c.subpixel;
        p.threads = threads;
        const ms::MatchResult expected = sequentialLrCheck(l, r, c.method, p);
        for (int repeat = 0; repeat < 5; ++repeat) {
          SCOPED_TRACE(std::string(grey ? "grey" : "colour") + " " + ms::toString(c.method) + " " +
                       ms::toString(c.refine) + " threads " + std::to_string(threads) + " run " +
                       std::to_string(repeat));
          const ms::MatchResult got = ms::match(l, r, c.method, p);
          EXPECT_TRUE(sameBits(got.disparity, expected.disparity));
          EXPECT_TRUE(sameBits(got.consistent, expected.consistent));
          EXPECT_TRUE(sameBits(got.fattening, expected.fattening));
          EXPECT_EQ(got.energy.data, expected.energy.data);
          EXPECT_EQ(got.energy.smooth, expected.energy.smooth);
          EXPECT_EQ(got.cuts, expected.cuts);
          EXPECT_GT(got.lr_ms, 0.0);
        }
      }
    }
  }
}

// The right view runs on a thread of its own (threads >= 2): its exception reaches the caller.
TEST(LrCheckInMatch, AnExceptionOfTheRightViewPropagates) {
  cv::Mat left, right;
  texturePair(left, right);
  ms::StereoParams p;
  p.cost.dmax = 8;
  p.threads = 2;
  {
    const FailingAllocator fail(FailingAllocator::Fail::kOnOtherThreads);
    EXPECT_THROW(ms::match(left, right, ms::Method::kHbds, p), InjectedFailure);
    EXPECT_GT(fail.otherThreadsAllocations(), 0);  // the right view did run elsewhere
  }
  EXPECT_EQ(ms::match(left, right, ms::Method::kHbds, p).disparity.size(), left.size());  // and match() still works
}

// An exception of the left view (this thread) leaves match() only once the right view has finished: nothing of
// the call runs on after it.
TEST(LrCheckInMatch, AnExceptionOfTheLeftViewWaitsForTheRightView) {
  cv::Mat left, right;
  texturePair(left, right);
  ms::StereoParams p;
  p.cost.dmax = 8;
  p.threads = 2;
  const FailingAllocator fail(FailingAllocator::Fail::kOnThisThread);
  EXPECT_THROW(ms::match(left, right, ms::Method::kHbds, p), InjectedFailure);
  const int after_return = fail.otherThreadsAllocations();
  EXPECT_GT(after_return, 0);  // the right view ran...
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(fail.otherThreadsAllocations(), after_return);  // ...and had finished
}

TEST(LeftRightCheck, BadInputIsNamed) {
  const cv::Mat a(3, 4, CV_32F, cv::Scalar(1)), b(3, 5, CV_32F, cv::Scalar(1));
  auto message = [](auto call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([&] { ms::leftRightCheck(a, b); }).find("4x3"), std::string::npos);
  EXPECT_NE(message([&] { ms::leftRightCheck(a, cv::Mat(3, 4, CV_8U)); }).find("CV_32F"), std::string::npos);
  EXPECT_NE(message([&] { ms::leftRightCheck(a, a, -1.0f); }).find("tolerance"), std::string::npos);
  EXPECT_NE(message([&] { ms::fillFromBackground(a, cv::Mat(3, 5, CV_8U)); }).find("mask"), std::string::npos);
  ms::StereoParams p;
  p.lr_check = true;
  p.lr_tolerance = kNan;
  cv::Mat left, right;
  texturePair(left, right);
  EXPECT_NE(message([&] { ms::match(left, right, ms::Method::kWta, p); }).find("lr_tolerance"), std::string::npos);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
