// Tests of hbds() (thesis Ch. 2, Sec. 2.2) on hand-built cost volumes: no
// matching cost is computed, the volume is filled directly with cost 0 at the
// true disparity and noise elsewhere.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"
#include "massage_cell/stereo/energy.h"
#include "massage_cell/stereo/optimizers.h"

using namespace massage_cell::stereo;

namespace {

struct Rect {
  int x, y, w, h, d;
};

// Fronto-parallel layers: background disparity `bg`, then rectangles painted
// in order (later ones occlude earlier ones).
cv::Mat layers(int width, int height, int bg, const std::vector<Rect>& rects) {
  cv::Mat truth(height, width, CV_32F, cv::Scalar(static_cast<float>(bg)));
  for (const Rect& r : rects) truth(cv::Rect(r.x, r.y, r.w, r.h)).setTo(static_cast<float>(r.d));
  return truth;
}

// Cost 0 at the true disparity, uniform noise in [noise_lo, 1) elsewhere.
CostVolume syntheticVolume(const cv::Mat& truth, int dmin, int dmax, float noise_lo, unsigned seed = 1234) {
  CostVolume vol(truth.cols, truth.rows, dmin, dmax);
  cv::RNG rng(seed);
  for (int d = dmin; d <= dmax; ++d)
    for (int y = 0; y < truth.rows; ++y)
      for (int x = 0; x < truth.cols; ++x)
        vol(x, y, d) = static_cast<int>(truth.at<float>(y, x)) == d ? 0.0f : rng.uniform(noise_lo, 1.0f);
  return vol;
}

// u_{p,q}: u_min across a disparity edge of `truth`, u_max elsewhere (what
// pairwiseWeights gives for an image whose intensity edges are the layer
// edges). Last column of right / last row of down are 0, as in energy.h.
PairwiseWeights edgeWeights(const cv::Mat& truth, float u_max, float u_min) {
  PairwiseWeights w;
  w.right = cv::Mat::zeros(truth.size(), CV_32F);
  w.down = cv::Mat::zeros(truth.size(), CV_32F);
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      if (x + 1 < truth.cols)
        w.right.at<float>(y, x) = truth.at<float>(y, x) == truth.at<float>(y, x + 1) ? u_max : u_min;
      if (y + 1 < truth.rows)
        w.down.at<float>(y, x) = truth.at<float>(y, x) == truth.at<float>(y + 1, x) ? u_max : u_min;
    }
  return w;
}

SmoothParams smoothParams(float u_max = 0.06f, float u_min = 0.01f) {
  SmoothParams s;
  s.u_max = u_max;
  s.u_min = u_min;
  return s;
}

int countDifferent(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  return cv::countNonZero(diff > 0.5);
}

// Per-pixel argmin of the volume (ties to the smaller d).
cv::Mat bruteWta(const CostVolume& vol) {
  cv::Mat out(vol.height(), vol.width(), CV_32F);
  for (int y = 0; y < vol.height(); ++y)
    for (int x = 0; x < vol.width(); ++x) {
      int best = vol.dmin();
      for (int d = vol.dmin() + 1; d <= vol.dmax(); ++d)
        if (vol(x, y, d) < vol(x, y, best)) best = d;
      out.at<float>(y, x) = static_cast<float>(best);
    }
  return out;
}

void expectValidResult(const OptimizerResult& r, const CostVolume& vol) {
  ASSERT_EQ(r.disparity.type(), CV_32F);
  ASSERT_EQ(r.disparity.rows, vol.height());
  ASSERT_EQ(r.disparity.cols, vol.width());
  EXPECT_EQ(r.cycles, 0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(r.disparity, &lo, &hi);
  EXPECT_GE(lo, vol.dmin());
  EXPECT_LE(hi, vol.dmax());
}

struct LayerCase {
  const char* name;
  int width, height, dmin, dmax, bg;
  std::vector<Rect> rects;
};

std::vector<LayerCase> layerCases() {
  return {
      {"2 layers 40x30 16 levels", 40, 30, 0, 15, 2, {{12, 8, 16, 14, 11}}},
      {"2 layers 80x60 64 levels", 80, 60, 0, 63, 40, {{10, 10, 30, 40, 7}}},
      {"3 layers 60x45 16 levels", 60, 45, 0, 15, 1, {{5, 5, 30, 25, 8}, {25, 15, 28, 24, 15}}},
      {"3 layers 60x45 64 levels offset dmin", 60, 45, 4, 67, 9, {{5, 5, 30, 25, 40}, {25, 15, 28, 24, 66}}},
      {"5 layers 80x60 16 levels",
       80,
       60,
       0,
       15,
       0,
       {{4, 4, 30, 24, 4}, {40, 6, 30, 20, 7}, {10, 32, 28, 22, 12}, {45, 30, 30, 26, 15}}},
      {"5 layers 80x60 64 levels",
       80,
       60,
       0,
       63,
       3,
       {{4, 4, 30, 24, 17}, {40, 6, 30, 20, 29}, {10, 32, 28, 22, 45}, {30, 20, 30, 26, 62}}},
  };
}

}  // namespace

TEST(Hbds, RecoversSyntheticFrontoParallelLayers) {
  for (const LayerCase& c : layerCases())
    for (int overlap : {0, 1, 2}) {
      SCOPED_TRACE(c.name + std::string(", overlap ") + std::to_string(overlap));
      const cv::Mat truth = layers(c.width, c.height, c.bg, c.rects);
      const CostVolume vol = syntheticVolume(truth, c.dmin, c.dmax, 0.2f);
      const SmoothParams sp = smoothParams();
      const OptimizerResult r = hbds(vol, edgeWeights(truth, sp.u_max, sp.u_min), sp, 2, overlap);
      expectValidResult(r, vol);
      EXPECT_EQ(countDifferent(r.disparity, truth), 0);
      EXPECT_GE(r.cuts, 1);
      EXPECT_GE(r.layers, 1);
      EXPECT_NEAR(r.energy.data, 0.0, 1e-9);  // every pixel at its zero-cost disparity
    }
}

TEST(Hbds, RecoversLayersWithWeightsFromPairwiseWeights) {
  // The weights come from an image whose grey levels change at the layer
  // edges (the intended pipeline), not from the truth directly.
  const cv::Mat truth = layers(64, 48, 3, {{8, 6, 24, 20, 20}, {30, 20, 26, 22, 31}});
  cv::Mat image;
  truth.convertTo(image, CV_8U, 6.0, 20.0);  // 38, 140, 206: strong edges
  const CostVolume vol = syntheticVolume(truth, 0, 31, 0.2f);
  const SmoothParams sp = smoothParams();
  const OptimizerResult r = hbds(vol, pairwiseWeights(image, sp), sp, 0);
  expectValidResult(r, vol);
  EXPECT_EQ(countDifferent(r.disparity, truth), 0);
}

TEST(Hbds, ConstantDisparityScene) {
  const cv::Mat truth = layers(50, 40, 7, {});
  const CostVolume vol = syntheticVolume(truth, 0, 15, 0.1f);
  const SmoothParams sp = smoothParams();
  const OptimizerResult r = hbds(vol, edgeWeights(truth, sp.u_max, sp.u_min), sp);
  expectValidResult(r, vol);
  EXPECT_EQ(countDifferent(r.disparity, truth), 0);
  // Every cut sends all pixels to one side: one node per depth.
  EXPECT_EQ(r.cuts, r.layers);
  EXPECT_GE(r.layers, 1);
  EXPECT_NEAR(r.energy.total(), 0.0, 1e-9);
}

TEST(Hbds, SingleLevelVolumeNeedsNoCut) {
  const cv::Mat truth = layers(20, 10, 4, {});
  CostVolume vol(20, 10, 4, 4, 0.5f);
  const SmoothParams sp = smoothParams();
  const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
  const OptimizerResult r = hbds(vol, w, sp);
  expectValidResult(r, vol);
  EXPECT_EQ(countDifferent(r.disparity, truth), 0);
  EXPECT_EQ(r.cuts, 0);
  EXPECT_EQ(r.layers, 0);
  EXPECT_NEAR(r.energy.data, 0.5 * 200, 1e-4);
  EXPECT_NEAR(r.energy.smooth, 0.0, 1e-12);
}

TEST(Hbds, EnergyIsLabellingEnergyOfTheResult) {
  // Noisy, ambiguous volume (noise down to 0) so the result is not trivial.
  const cv::Mat truth = layers(48, 36, 2, {{10, 8, 20, 16, 9}, {20, 14, 20, 16, 14}});
  CostVolume vol = syntheticVolume(truth, 0, 15, 0.0f, 99);
  cv::RNG rng(5);
  for (int y = 0; y < truth.rows; ++y)  // the true disparity is not free either
    for (int x = 0; x < truth.cols; ++x) vol(x, y, static_cast<int>(truth.at<float>(y, x))) = rng.uniform(0.0f, 0.4f);
  for (float truncation : {0.0f, 2.0f}) {
    SCOPED_TRACE(truncation);
    SmoothParams sp = smoothParams(0.08f, 0.02f);
    sp.truncation = truncation;
    const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
    const OptimizerResult r = hbds(vol, w, sp, 1);
    expectValidResult(r, vol);
    const Energy e = labellingEnergy(vol, w, r.disparity, truncation);
    EXPECT_NEAR(r.energy.data, e.data, 1e-6 * (1.0 + e.data));
    EXPECT_NEAR(r.energy.smooth, e.smooth, 1e-6 * (1.0 + e.smooth));
    EXPECT_GT(r.energy.data, 0.0);
    EXPECT_GT(r.energy.smooth, 0.0);
  }
}

TEST(Hbds, DeterministicAcrossThreadCounts) {
  const cv::Mat truth =
      layers(80, 60, 3, {{4, 4, 30, 24, 17}, {40, 6, 30, 20, 29}, {10, 32, 28, 22, 45}, {30, 20, 30, 26, 62}});
  const CostVolume vol = syntheticVolume(truth, 0, 63, 0.0f, 7);  // noisy: many non-trivial cuts
  const SmoothParams sp = smoothParams(0.03f, 0.005f);
  const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
  for (int overlap : {0, 1}) {
    const OptimizerResult r1 = hbds(vol, w, sp, 1, overlap);
    for (int threads : {2, 3, 0}) {
      SCOPED_TRACE("threads " + std::to_string(threads) + ", overlap " + std::to_string(overlap));
      const OptimizerResult rn = hbds(vol, w, sp, threads, overlap);
      EXPECT_EQ(countDifferent(r1.disparity, rn.disparity), 0);
      EXPECT_EQ(r1.cuts, rn.cuts);
      EXPECT_EQ(r1.layers, rn.layers);
      EXPECT_EQ(r1.energy.data, rn.energy.data);
      EXPECT_EQ(r1.energy.smooth, rn.energy.smooth);
    }
    EXPECT_GT(r1.cuts, 10);
  }
}

// A slanted surface (a ramp over 16 levels) whose data term is weak and
// noisy: with disjoint subsets the cut at each break point is a hard
// decision for the pixels whose disparity lies next to it; with overlapping
// subsets they can still reach their disparity from either side.
TEST(Hbds, OverlapHelpsARampCrossingTheBreakPoints) {
  const int w = 96, h = 48;
  cv::Mat truth(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) truth.at<float>(y, x) = static_cast<float>(x / 6);  // 0..15
  CostVolume vol(w, h, 0, 15);
  cv::RNG rng(99);
  for (int d = 0; d <= 15; ++d)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        vol(x, y, d) = 0.04f * std::min(4.0f, std::abs(d - truth.at<float>(y, x))) + rng.uniform(0.0f, 0.6f);
  const SmoothParams sp = smoothParams(0.05f, 0.05f);
  const PairwiseWeights uniform = edgeWeights(cv::Mat(h, w, CV_32F, cv::Scalar(0)), sp.u_max, sp.u_min);
  auto errors = [&](const cv::Mat& d) {
    cv::Mat diff;
    cv::absdiff(d, truth, diff);
    return cv::countNonZero(diff > 1.5);
  };
  const OptimizerResult disjoint = hbds(vol, uniform, sp, 2, 0);
  const OptimizerResult overlap = hbds(vol, uniform, sp, 2, 1);
  expectValidResult(overlap, vol);
  std::printf("ramp: pixels off by > 1 level: disjoint %d, overlap 1 %d (of %d)\n", errors(disjoint.disparity),
              errors(overlap.disparity), w * h);
  // Measured: 714 / 301 pixels; well apart, so a real change shows.
  EXPECT_LT(errors(overlap.disparity), errors(disjoint.disparity) * 2 / 3);
  EXPECT_LE(overlap.energy.total(), disjoint.energy.total());
}

TEST(Hbds, BalancedSceneHasLogarithmicDepth) {
  // One vertical stripe per disparity level: flat histogram, so every break
  // point splits its set in the middle (ties nearest the middle).
  for (int levels : {16, 64}) {
    SCOPED_TRACE(levels);
    const int stripe = 3;
    cv::Mat truth(24, levels * stripe, CV_32F);
    for (int x = 0; x < truth.cols; ++x) truth.col(x).setTo(static_cast<float>(x / stripe));
    const CostVolume vol = syntheticVolume(truth, 0, levels - 1, 0.3f);
    const SmoothParams sp = smoothParams();
    const OptimizerResult r = hbds(vol, edgeWeights(truth, sp.u_max, sp.u_min), sp);
    expectValidResult(r, vol);
    EXPECT_EQ(countDifferent(r.disparity, truth), 0);
    const int expected = static_cast<int>(std::ceil(std::log2(levels)));
    EXPECT_GE(r.layers, expected);
    EXPECT_LE(r.layers, expected + 1);  // an odd set may split one level off-centre
    EXPECT_EQ(r.cuts, levels - 1);      // thesis: |D| - 1 bilateral problems
  }
}

TEST(Hbds, SmoothnessRemovesSaltNoise) {
  const cv::Mat truth = layers(60, 45, 3, {{15, 10, 30, 25, 12}});
  CostVolume vol = syntheticVolume(truth, 0, 15, 0.3f);
  // Salt: ~3 % of the pixels get cost 0 at a wrong disparity at least 4
  // levels away; their true disparity costs 0.25.
  cv::RNG rng(42);
  int salted = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      if (rng.uniform(0.0, 1.0) >= 0.03) continue;
      const int t = static_cast<int>(truth.at<float>(y, x));
      const int wrong = t >= 8 ? t - 4 - rng.uniform(0, t - 3) : t + 4 + rng.uniform(0, 12 - t);
      ASSERT_GE(wrong, 0);
      ASSERT_LE(wrong, 15);
      vol(x, y, t) = 0.25f;
      vol(x, y, wrong) = 0.0f;
      ++salted;
    }
  ASSERT_GT(salted, 20);

  // Without smoothness, HBDS is the per-pixel argmin: the salt survives.
  const SmoothParams none = smoothParams(0.0f, 0.0f);
  const OptimizerResult raw = hbds(vol, edgeWeights(truth, 0.0f, 0.0f), none);
  EXPECT_EQ(countDifferent(raw.disparity, bruteWta(vol)), 0);
  EXPECT_EQ(countDifferent(raw.disparity, truth), salted);

  // With smoothness the salt is removed.
  const SmoothParams sp = smoothParams(0.1f, 0.01f);
  const OptimizerResult smooth = hbds(vol, edgeWeights(truth, sp.u_max, sp.u_min), sp);
  EXPECT_EQ(countDifferent(smooth.disparity, truth), 0);
  EXPECT_LT(smooth.energy.total(),
            labellingEnergy(vol, edgeWeights(truth, sp.u_max, sp.u_min), raw.disparity, sp.truncation).total());
}

TEST(Hbds, PairsCrossingTheLayerBoundaryPullTowardsTheNeighboursSet) {
  // Left half Q: cost 0 only at d = 3. Right half P: cost 0 at both d = 1 and
  // d = 2 (no data preference), 1 at 0 and 3. The root sends Q to F = [3] and
  // P to B = [0, 2]; the node [0, 2] splits into [0, 1] and [2], where the P
  // pixels have equal data terms (min 0 on both sides). Their left
  // neighbours (in Q, d = 3) already left the node and Eq. 2.2 charges
  // u |d_p - 3|, so P must resolve to d = 2 (the side nearer Q): the
  // labelling of least energy. (Ignoring such pairs leaves the choice to the
  // max-flow's tie-breaking, which sends free nodes to B, i.e. d = 1.)
  const int W = 24, H = 10;
  const float u = 0.05f;
  cv::Mat expected(H, W, CV_32F, cv::Scalar(2.0f));
  expected(cv::Rect(0, 0, W / 2, H)).setTo(3.0f);
  CostVolume vol(W, H, 0, 3, 1.0f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (x < W / 2) {
        vol(x, y, 3) = 0.0f;
      } else {
        vol(x, y, 1) = 0.0f;
        vol(x, y, 2) = 0.0f;
      }
    }
  const SmoothParams sp = smoothParams(u, u);
  PairwiseWeights w;
  w.right = cv::Mat(H, W, CV_32F, cv::Scalar(u));
  w.down = cv::Mat(H, W, CV_32F, cv::Scalar(u));
  w.right.col(W - 1).setTo(0.0f);
  w.down.row(H - 1).setTo(0.0f);
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    const OptimizerResult r = hbds(vol, w, sp, threads);
    expectValidResult(r, vol);
    EXPECT_EQ(countDifferent(r.disparity, expected), 0);
    const Energy best = labellingEnergy(vol, w, expected, sp.truncation);
    EXPECT_NEAR(best.total(), u * H, 1e-6);  // one level across the Q / P edge per row
    EXPECT_NEAR(r.energy.total(), best.total(), 1e-6);
  }
}

// Coarse to fine (hbds' `coarse`): layers large enough for the coarse cuts
// (>= 8192 pixels) come out as with the full cuts, whatever the thread count.
TEST(Hbds, CoarseToFineRecoversLargeLayers) {
  const cv::Mat truth = layers(160, 120, 5, {{10, 12, 60, 50, 20}, {80, 20, 60, 40, 33}, {40, 70, 90, 40, 47}});
  const CostVolume vol = syntheticVolume(truth, 0, 49, 0.3f, 11);
  const SmoothParams sp = smoothParams();
  const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
  for (int coarse : {2, 4}) {
    for (int overlap : {0, 1}) {
      SCOPED_TRACE("coarse " + std::to_string(coarse) + ", overlap " + std::to_string(overlap));
      const OptimizerResult r = hbds(vol, w, sp, 1, overlap, coarse);
      expectValidResult(r, vol);
      EXPECT_EQ(countDifferent(r.disparity, truth), 0);
      for (int threads : {2, 0}) {
        const OptimizerResult rn = hbds(vol, w, sp, threads, overlap, coarse);
        EXPECT_EQ(countDifferent(r.disparity, rn.disparity), 0) << "threads " << threads;
        EXPECT_EQ(r.energy.total(), rn.energy.total()) << "threads " << threads;
      }
    }
  }
}

// On a noisy, ambiguous volume (many cuts of odd shapes) the coarse cuts give
// a valid labelling whose energy stays close to the full cuts'.
TEST(Hbds, CoarseToFineOnANoisyVolumeStaysNearTheFullCutsEnergy) {
  const cv::Mat truth = layers(128, 96, 2, {{10, 8, 60, 40, 19}, {50, 40, 60, 40, 33}});
  CostVolume vol = syntheticVolume(truth, 0, 39, 0.0f, 21);
  cv::RNG rng(8);
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) vol(x, y, static_cast<int>(truth.at<float>(y, x))) = rng.uniform(0.0f, 0.5f);
  const SmoothParams sp = smoothParams(0.08f, 0.02f);
  const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
  const OptimizerResult full = hbds(vol, w, sp, 1, 1, 1);
  for (int coarse : {2, 4}) {
    SCOPED_TRACE("coarse " + std::to_string(coarse));
    const OptimizerResult r = hbds(vol, w, sp, 1, 1, coarse);
    expectValidResult(r, vol);
    EXPECT_LT(r.energy.total(), 1.05 * full.energy.total());
    const OptimizerResult r2 = hbds(vol, w, sp, 2, 1, coarse);
    EXPECT_EQ(countDifferent(r.disparity, r2.disparity), 0);
  }
}

// The approximation coarse to fine makes: a detail smaller than a block, far
// from any boundary between the blocks' labels, takes its block's label,
// while the full cut keeps it (its pairs with the background are weak);
// elsewhere both agree.
TEST(Hbds, CoarseToFineDropsAnIsolatedPixelTheFullCutKeeps) {
  cv::Mat truth = layers(128, 96, 4, {});
  truth.at<float>(41, 61) = 30.0f;
  const CostVolume vol = syntheticVolume(truth, 0, 39, 0.9f, 3);
  const SmoothParams sp = smoothParams(0.06f, 0.002f);
  const PairwiseWeights w = edgeWeights(truth, sp.u_max, sp.u_min);
  const OptimizerResult full = hbds(vol, w, sp, 1, 0, 1);
  EXPECT_EQ(countDifferent(full.disparity, truth), 0);
  const OptimizerResult coarse = hbds(vol, w, sp, 1, 0, 2);
  EXPECT_EQ(countDifferent(coarse.disparity, truth), 1);
  EXPECT_LE(coarse.disparity.at<float>(41, 61), 19.0f) << "the pixel went with its block to the background's side";
  EXPECT_GT(coarse.energy.total(), full.energy.total());
}

TEST(Hbds, RejectsBadArguments) {
  const CostVolume vol(20, 10, 0, 7);
  PairwiseWeights w = edgeWeights(cv::Mat(10, 20, CV_32F, cv::Scalar(0)), 0.06f, 0.01f);
  EXPECT_THROW(hbds(vol, w, smoothParams(), -1), std::invalid_argument);
  EXPECT_THROW(hbds(vol, w, smoothParams(), 1, -1), std::invalid_argument);
  EXPECT_THROW(hbds(vol, w, smoothParams(), 1, 0, 0), std::invalid_argument);
  EXPECT_THROW(hbds(vol, w, smoothParams(), 1, 0, 9), std::invalid_argument);
  PairwiseWeights small = edgeWeights(cv::Mat(10, 19, CV_32F, cv::Scalar(0)), 0.06f, 0.01f);
  EXPECT_THROW(hbds(vol, small, smoothParams()), std::invalid_argument);
  PairwiseWeights wrong_type = w;
  w.down.convertTo(wrong_type.down, CV_64F);
  EXPECT_THROW(hbds(vol, wrong_type, smoothParams()), std::invalid_argument);
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
