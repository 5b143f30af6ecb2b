// Tests of MaxFlow (max_flow.h), the energy of Eq. 2.2 (energy.h) and the
// graph-cut baselines alpha-expansion / alpha-beta swap (optimizers.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/energy.h"
#include "massage_cell/stereo/max_flow.h"
#include "massage_cell/stereo/optimizers.h"

namespace ms = massage_cell::stereo;

namespace {

// ---------------------------------------------------------------- max flow

struct Arc {
  int a, b;
  double cap;
};

/// Brute-force minimum s-t cut over all 2^n source sets.
double bruteMinCut(const std::vector<double>& src, const std::vector<double>& snk, const std::vector<Arc>& arcs) {
  const int n = static_cast<int>(src.size());
  double best = std::numeric_limits<double>::infinity();
  for (unsigned mask = 0; mask < (1u << n); ++mask) {
    double c = 0;
    for (int i = 0; i < n; ++i) c += (mask >> i & 1u) ? snk[i] : src[i];  // bit set: source side
    for (const Arc& e : arcs)
      if ((mask >> e.a & 1u) && !(mask >> e.b & 1u)) c += e.cap;
    best = std::min(best, c);
  }
  return best;
}

/// Cost of the cut that MaxFlow reports.
double reportedCut(const ms::MaxFlow& mf, const std::vector<double>& src, const std::vector<double>& snk,
                   const std::vector<Arc>& arcs) {
  double c = 0;
  for (int i = 0; i < static_cast<int>(src.size()); ++i) c += mf.isSource(i) ? snk[i] : src[i];
  for (const Arc& e : arcs)
    if (mf.isSource(e.a) && !mf.isSource(e.b)) c += e.cap;
  return c;
}

TEST(MaxFlow, TwoNodes) {
  // node 0: s 5 / t 1, node 1: s 2 / t 6, arc 0 -> 1 of 3. Cuts: {} 7, {0} 1+2+3 = 6,
  // {1} 5+6 = 11, {0,1} 7 -> min 6 with 0 on the source side, 1 on the sink side.
  ms::MaxFlow mf;
  EXPECT_EQ(mf.addNodes(2), 0);
  mf.addTerminalWeights(0, 5, 1);
  mf.addTerminalWeights(1, 2, 6);
  mf.addEdge(0, 1, 3, 0);
  EXPECT_NEAR(mf.solve(), 6.0, 1e-12);
  EXPECT_TRUE(mf.isSource(0));
  EXPECT_FALSE(mf.isSource(1));
  EXPECT_NEAR(mf.solve(), 6.0, 1e-12);  // repeated solve() returns the same flow
}

TEST(MaxFlow, Chain) {
  // s -10-> 0 -4-> 1 -2-> 2 -7-> 3 -10-> t: bottleneck 1 -> 2.
  ms::MaxFlow mf(4, 3);
  mf.addNodes(4);
  mf.addTerminalWeights(0, 10, 0);
  mf.addTerminalWeights(3, 0, 10);
  mf.addEdge(0, 1, 4, 0);
  mf.addEdge(1, 2, 2, 0);
  mf.addEdge(2, 3, 7, 0);
  EXPECT_NEAR(mf.solve(), 2.0, 1e-12);
  EXPECT_TRUE(mf.isSource(0));
  EXPECT_TRUE(mf.isSource(1));
  EXPECT_FALSE(mf.isSource(2));
  EXPECT_FALSE(mf.isSource(3));
}

TEST(MaxFlow, ClrsNetwork) {
  // Cormen et al., Fig. 26.1 (3rd ed.): max flow 23, unique minimum cut
  // S = {s, v1, v2, v4}, T = {v3, t}. Nodes v1..v4 -> 0..3.
  ms::MaxFlow mf;
  mf.addNodes(4);
  mf.addTerminalWeights(0, 16, 0);
  mf.addTerminalWeights(1, 13, 0);
  mf.addTerminalWeights(2, 0, 20);
  mf.addTerminalWeights(3, 0, 4);
  mf.addEdge(0, 2, 12, 0);
  mf.addEdge(1, 0, 4, 0);
  mf.addEdge(1, 3, 14, 0);
  mf.addEdge(2, 1, 9, 0);
  mf.addEdge(3, 2, 7, 0);
  EXPECT_NEAR(mf.solve(), 23.0, 1e-12);
  EXPECT_TRUE(mf.isSource(0));
  EXPECT_TRUE(mf.isSource(1));
  EXPECT_FALSE(mf.isSource(2));
  EXPECT_TRUE(mf.isSource(3));
}

TEST(MaxFlow, BothTerminalWeightsPositive) {
  {
    ms::MaxFlow mf;
    mf.addNodes(1);
    mf.addTerminalWeights(0, 5, 3);  // cheaper to cut the sink link: source side
    EXPECT_NEAR(mf.solve(), 3.0, 1e-12);
    EXPECT_TRUE(mf.isSource(0));
  }
  {
    ms::MaxFlow mf;
    mf.addNodes(1);
    mf.addTerminalWeights(0, 2, 0);  // calls accumulate: s 2 + 0, t 0 + 4
    mf.addTerminalWeights(0, 0, 4);
    EXPECT_NEAR(mf.solve(), 2.0, 1e-12);
    EXPECT_FALSE(mf.isSource(0));
  }
  {
    // node 0: s 4 / t 1, node 1: s 1 / t 3, arcs 0 -> 1: 1, 1 -> 0: 5.
    // Cuts: {} 5, {0} 1+1+1 = 3, {1} 4+3+5 = 12, {0,1} 4 -> 3.
    ms::MaxFlow mf;
    mf.addNodes(2);
    mf.addTerminalWeights(0, 4, 1);
    mf.addTerminalWeights(1, 1, 3);
    mf.addEdge(0, 1, 1, 5);
    EXPECT_NEAR(mf.solve(), 3.0, 1e-12);
    EXPECT_TRUE(mf.isSource(0));
    EXPECT_FALSE(mf.isSource(1));
  }
}

TEST(MaxFlow, EmptyAndEdgeless) {
  ms::MaxFlow empty;
  EXPECT_EQ(empty.solve(), 0.0);
  ms::MaxFlow mf;
  mf.addNodes(3);
  mf.addTerminalWeights(0, 1, 2);
  mf.addTerminalWeights(1, 3, 0.5);
  mf.addEdge(1, 2, 0, 0);  // zero arcs only
  EXPECT_NEAR(mf.solve(), 1.5, 1e-12);
  EXPECT_FALSE(mf.isSource(0));
  EXPECT_TRUE(mf.isSource(1));
}

TEST(MaxFlow, RandomGraphsMatchBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> cap(0.0, 1.0);
  std::uniform_int_distribution<int> count(2, 10);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = count(rng);
    std::vector<double> src(n), snk(n);
    std::vector<Arc> arcs;
    ms::MaxFlow mf;
    mf.addNodes(n);
    for (int i = 0; i < n; ++i) {
      src[i] = cap(rng) < 0.4 ? 0.0 : cap(rng);
      snk[i] = cap(rng) < 0.4 ? 0.0 : cap(rng);
      mf.addTerminalWeights(i, src[i], snk[i]);
    }
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) {
        if (cap(rng) < 0.5) continue;
        const double ab = cap(rng) < 0.3 ? 0.0 : cap(rng), ba = cap(rng) < 0.3 ? 0.0 : cap(rng);
        arcs.push_back({i, j, ab});
        arcs.push_back({j, i, ba});
        mf.addEdge(i, j, ab, ba);
      }
    const double best = bruteMinCut(src, snk, arcs);
    ASSERT_NEAR(mf.solve(), best, 1e-9) << "trial " << trial;
    ASSERT_NEAR(reportedCut(mf, src, snk, arcs), best, 1e-9) << "trial " << trial;
  }
}

TEST(MaxFlow, InvalidInputThrows) {
  ms::MaxFlow mf;
  EXPECT_THROW(ms::MaxFlow(-1, 0), std::invalid_argument);
  EXPECT_THROW(mf.addNodes(-1), std::invalid_argument);
  mf.addNodes(2);
  EXPECT_THROW(mf.addTerminalWeights(2, 1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addTerminalWeights(-1, 1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addTerminalWeights(0, -1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addTerminalWeights(0, 1, -0.5), std::invalid_argument);
  EXPECT_THROW(mf.addTerminalWeights(0, std::nan(""), 1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(0, 2, 1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(-1, 1, 1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(1, 1, 1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(0, 1, -1, 1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(0, 1, 1, -1), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(0, 1, std::numeric_limits<double>::infinity(), 1), std::invalid_argument);
  EXPECT_THROW(mf.isSource(0), std::logic_error);  // before solve()
  mf.addEdge(0, 1, 1, 1);
  mf.solve();
  EXPECT_THROW(mf.isSource(5), std::invalid_argument);
  EXPECT_THROW(mf.addEdge(0, 1, 1, 1), std::logic_error);  // after solve()
}

// ---------------------------------------------------------- pairwise weights

TEST(PairwiseWeights, UniformImageGivesUMax) {
  ms::SmoothParams sp;
  const cv::Mat img(6, 7, CV_8UC1, cv::Scalar(90));
  const ms::PairwiseWeights pw = ms::pairwiseWeights(img, sp);
  ASSERT_EQ(pw.right.type(), CV_32FC1);
  ASSERT_EQ(pw.down.type(), CV_32FC1);
  ASSERT_EQ(pw.right.size(), img.size());
  ASSERT_EQ(pw.down.size(), img.size());
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 7; ++x) {
      EXPECT_FLOAT_EQ(pw.right.at<float>(y, x), x == 6 ? 0.0f : sp.u_max);
      EXPECT_FLOAT_EQ(pw.down.at<float>(y, x), y == 5 ? 0.0f : sp.u_max);
    }
}

TEST(PairwiseWeights, EdgesByHand) {
  ms::SmoothParams sp;
  sp.tau = 20.0f;
  sp.u_min = 0.01f;
  sp.u_max = 0.06f;
  // Columns 0..2 grey 100, column 3 grey 105 (diff 5), columns 4..5 grey 160 (diff 55 >= tau).
  cv::Mat img(4, 6, CV_8UC1, cv::Scalar(100));
  img.col(3).setTo(105);
  img.colRange(4, 6).setTo(160);
  img.at<uchar>(2, 0) = 120;  // vertical difference exactly tau between rows 1-2 and 2-3
  const ms::PairwiseWeights pw = ms::pairwiseWeights(img, sp);
  const float mid = (0.01f - 0.06f) * 5.0f / 20.0f + 0.06f;  // 0.0475
  EXPECT_FLOAT_EQ(pw.right.at<float>(0, 2), mid);
  EXPECT_FLOAT_EQ(pw.right.at<float>(0, 3), 0.01f);
  EXPECT_FLOAT_EQ(pw.right.at<float>(0, 4), 0.06f);
  EXPECT_FLOAT_EQ(pw.right.at<float>(2, 0), 0.01f);  // 120 vs 100
  EXPECT_FLOAT_EQ(pw.down.at<float>(1, 0), 0.01f);
  EXPECT_FLOAT_EQ(pw.down.at<float>(2, 0), 0.01f);
  EXPECT_FLOAT_EQ(pw.down.at<float>(0, 0), 0.06f);
  EXPECT_FLOAT_EQ(pw.down.at<float>(3, 3), 0.0f);
  EXPECT_FLOAT_EQ(pw.right.at<float>(1, 5), 0.0f);
}

TEST(PairwiseWeights, ColourUsesLargestChannelDifference) {
  ms::SmoothParams sp;
  sp.tau = 10.0f;
  sp.u_min = 0.0f;
  sp.u_max = 1.0f;
  cv::Mat img(2, 2, CV_8UC3, cv::Scalar(50, 50, 50));
  img.at<cv::Vec3b>(0, 1) = cv::Vec3b(52, 46, 51);  // channel diffs 2, 4, 1 -> 4
  img.at<cv::Vec3b>(1, 0) = cv::Vec3b(50, 50, 80);  // 30 -> clamped at tau
  const ms::PairwiseWeights pw = ms::pairwiseWeights(img, sp);
  EXPECT_FLOAT_EQ(pw.right.at<float>(0, 0), 0.6f);
  EXPECT_FLOAT_EQ(pw.down.at<float>(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(pw.right.at<float>(1, 0), 0.0f);  // (50,50,80) vs (50,50,50): 30
  EXPECT_FLOAT_EQ(pw.down.at<float>(0, 1), 0.6f);   // (52,46,51) vs (50,50,50): 4
  EXPECT_FLOAT_EQ(pw.down.at<float>(1, 1), 0.0f);   // last row
}

TEST(PairwiseWeights, InvalidInputThrows) {
  const cv::Mat img(3, 3, CV_8UC1, cv::Scalar(0));
  ms::SmoothParams sp;
  EXPECT_THROW(ms::pairwiseWeights(cv::Mat(), sp), std::invalid_argument);
  EXPECT_THROW(ms::pairwiseWeights(cv::Mat(3, 3, CV_32FC1, cv::Scalar(0)), sp), std::invalid_argument);
  EXPECT_THROW(ms::pairwiseWeights(cv::Mat(3, 3, CV_8UC4, cv::Scalar(0)), sp), std::invalid_argument);
  sp.tau = 0;
  EXPECT_THROW(ms::pairwiseWeights(img, sp), std::invalid_argument);
  sp = ms::SmoothParams();
  sp.u_min = -0.1f;
  EXPECT_THROW(ms::pairwiseWeights(img, sp), std::invalid_argument);
  sp = ms::SmoothParams();
  sp.u_max = sp.u_min / 2;
  EXPECT_THROW(ms::pairwiseWeights(img, sp), std::invalid_argument);
  sp = ms::SmoothParams();
  sp.u_max = sp.u_min;  // allowed: constant weights
  EXPECT_NO_THROW(ms::pairwiseWeights(img, sp));
}

// ------------------------------------------------------------------ energy

ms::CostVolume randomVolume(int w, int h, int dmin, int dmax, unsigned seed) {
  ms::CostVolume v(w, h, dmin, dmax);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int d = dmin; d <= dmax; ++d)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) v(x, y, d) = u(rng);
  return v;
}

ms::PairwiseWeights randomWeights(int w, int h, float lo, float hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  ms::PairwiseWeights pw;
  pw.right = cv::Mat::zeros(h, w, CV_32F);
  pw.down = cv::Mat::zeros(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x + 1 < w) pw.right.at<float>(y, x) = u(rng);
      if (y + 1 < h) pw.down.at<float>(y, x) = u(rng);
    }
  return pw;
}

cv::Mat randomLabels(int w, int h, int dmin, int dmax, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(dmin, dmax);
  cv::Mat m(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m.at<float>(y, x) = static_cast<float>(u(rng));
  return m;
}

/// Independent recomputation: sum over all ordered neighbour pairs / 2.
double bruteEnergy(const ms::CostVolume& v, const ms::PairwiseWeights& pw, const cv::Mat& d, float trunc) {
  double e = 0;
  auto V = [&](int a, int b) {
    double t = std::fabs(double(a) - double(b));
    return trunc > 0 ? std::min(t, double(trunc)) : t;
  };
  for (int y = 0; y < v.height(); ++y)
    for (int x = 0; x < v.width(); ++x) {
      const int dp = static_cast<int>(d.at<float>(y, x));
      e += v(x, y, dp);
      const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
      for (int k = 0; k < 4; ++k) {
        const int qx = x + dx[k], qy = y + dy[k];
        if (qx < 0 || qy < 0 || qx >= v.width() || qy >= v.height()) continue;
        const double u = dx[k] == 1    ? pw.right.at<float>(y, x)
                         : dx[k] == -1 ? pw.right.at<float>(y, qx)
                         : dy[k] == 1  ? pw.down.at<float>(y, x)
                                       : pw.down.at<float>(qy, x);
        e += 0.5 * u * V(dp, static_cast<int>(d.at<float>(qy, qx)));
      }
    }
  return e;
}

TEST(LabellingEnergy, MatchesBruteForce) {
  const ms::CostVolume v = randomVolume(9, 7, 2, 11, 3);
  const ms::PairwiseWeights pw = randomWeights(9, 7, 0.0f, 0.3f, 4);
  const cv::Mat d = randomLabels(9, 7, 2, 11, 5);
  for (float trunc : {0.0f, -1.0f, 2.0f, 3.5f}) {
    const ms::Energy e = ms::labellingEnergy(v, pw, d, trunc);
    EXPECT_NEAR(e.total(), bruteEnergy(v, pw, d, trunc), 1e-9) << "truncation " << trunc;
    double data = 0;
    for (int y = 0; y < 7; ++y)
      for (int x = 0; x < 9; ++x) data += v(x, y, static_cast<int>(d.at<float>(y, x)));
    EXPECT_NEAR(e.data, data, 1e-9);
  }
  EXPECT_LT(ms::labellingEnergy(v, pw, d, 2.0f).smooth, ms::labellingEnergy(v, pw, d, 0.0f).smooth);
}

TEST(LabellingEnergy, InvalidInputThrows) {
  const ms::CostVolume v = randomVolume(5, 4, 0, 3, 1);
  const ms::PairwiseWeights pw = randomWeights(5, 4, 0.0f, 0.1f, 2);
  cv::Mat d(4, 5, CV_32F, cv::Scalar(1));
  EXPECT_NO_THROW(ms::labellingEnergy(v, pw, d, 0));
  EXPECT_THROW(ms::labellingEnergy(v, pw, cv::Mat(4, 6, CV_32F, cv::Scalar(1)), 0), std::invalid_argument);
  EXPECT_THROW(ms::labellingEnergy(v, pw, cv::Mat(4, 5, CV_8U, cv::Scalar(1)), 0), std::invalid_argument);
  cv::Mat bad = d.clone();
  bad.at<float>(2, 2) = 1.5f;
  EXPECT_THROW(ms::labellingEnergy(v, pw, bad, 0), std::invalid_argument);
  bad.at<float>(2, 2) = 4.0f;
  EXPECT_THROW(ms::labellingEnergy(v, pw, bad, 0), std::invalid_argument);
  bad.at<float>(2, 2) = -1.0f;
  EXPECT_THROW(ms::labellingEnergy(v, pw, bad, 0), std::invalid_argument);
  bad.at<float>(2, 2) = std::nanf("");
  EXPECT_THROW(ms::labellingEnergy(v, pw, bad, 0), std::invalid_argument);
  ms::PairwiseWeights small = randomWeights(4, 4, 0.0f, 0.1f, 2);
  EXPECT_THROW(ms::labellingEnergy(v, small, d, 0), std::invalid_argument);
}

// ----------------------------------------------------- expansion and swap

using Optimizer = ms::OptimizerResult (*)(const ms::CostVolume&, const ms::PairwiseWeights&, const ms::SmoothParams&,
                                          const cv::Mat&, int);

struct Named {
  const char* name;
  Optimizer run;
};
const Named kOptimizers[] = {{"expansion", &ms::alphaExpansion}, {"swap", &ms::alphaBetaSwap}};

/// Three fronto-parallel layers (background 1, rectangle 4, disc 6) over
/// 8 levels, 40 x 30. The true level costs U(0, 0.1), others U(0.35, 1);
/// 10 % of the pixels are outliers where one wrong level costs 0. The left
/// image has one grey level per layer.
struct LayerScene {
  cv::Mat truth, image;
  ms::CostVolume volume{40, 30, 0, 7};
};

LayerScene layerScene(unsigned seed) {
  LayerScene s;
  const int w = 40, h = 30;
  s.truth = cv::Mat(h, w, CV_32F, cv::Scalar(1));
  s.image = cv::Mat(h, w, CV_8UC1, cv::Scalar(40));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x >= 8 && x < 30 && y >= 5 && y < 24) {
        s.truth.at<float>(y, x) = 4;
        s.image.at<uchar>(y, x) = 120;
      }
      if ((x - 17) * (x - 17) + (y - 14) * (y - 14) <= 25) {
        s.truth.at<float>(y, x) = 6;
        s.image.at<uchar>(y, x) = 210;
      }
    }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> good(0.0f, 0.1f), bad(0.35f, 1.0f), coin(0.0f, 1.0f);
  std::uniform_int_distribution<int> level(0, 7);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int t = static_cast<int>(s.truth.at<float>(y, x));
      for (int d = 0; d <= 7; ++d) s.volume(x, y, d) = d == t ? good(rng) : bad(rng);
      if (coin(rng) < 0.1f) {
        int wrong = level(rng);
        if (wrong == t) wrong = (t + 3) % 8;
        s.volume(x, y, wrong) = 0.0f;
        s.volume(x, y, t) = 0.1f;
      }
    }
  return s;
}

ms::SmoothParams layerSmooth(float truncation) {
  ms::SmoothParams sp;
  sp.tau = 20;
  sp.u_min = 0.02f;
  sp.u_max = 0.2f;
  sp.truncation = truncation;
  return sp;
}

int countDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat ne;
  cv::compare(a, b, ne, cv::CMP_NE);
  return cv::countNonZero(ne);
}

TEST(GraphCuts, RecoverLayeredScene) {
  for (float trunc : {0.0f, 2.0f}) {
    const LayerScene s = layerScene(11);
    const ms::SmoothParams sp = layerSmooth(trunc);
    const ms::PairwiseWeights pw = ms::pairwiseWeights(s.image, sp);
    for (const Named& opt : kOptimizers) {
      // max_cycles = 0 returns the default start (WTA), which the outliers spoil.
      const ms::OptimizerResult wta = opt.run(s.volume, pw, sp, cv::Mat(), 0);
      EXPECT_GT(countDiff(wta.disparity, s.truth), 60);
      EXPECT_EQ(wta.cycles, 0);
      const ms::OptimizerResult r = opt.run(s.volume, pw, sp, cv::Mat(), 20);
      ASSERT_EQ(r.disparity.type(), CV_32FC1);
      ASSERT_EQ(r.disparity.size(), s.truth.size());
      EXPECT_EQ(countDiff(r.disparity, s.truth), 0) << opt.name << " truncation " << trunc;
      EXPECT_GT(r.cuts, 0);
      EXPECT_GE(r.cycles, 1);
      EXPECT_LT(r.cycles, 20);
      const ms::Energy e = ms::labellingEnergy(s.volume, pw, r.disparity, trunc);
      EXPECT_NEAR(r.energy.data, e.data, 1e-9);
      EXPECT_NEAR(r.energy.smooth, e.smooth, 1e-9);
      EXPECT_LT(r.energy.total(), wta.energy.total());
      EXPECT_LT(r.energy.total(), ms::labellingEnergy(s.volume, pw, s.truth, trunc).total() + 1e-9);
    }
  }
}

TEST(GraphCuts, EnergyNeverIncreases) {
  const int w = 24, h = 18;
  const ms::CostVolume v = randomVolume(w, h, -2, 7, 21);
  const ms::PairwiseWeights pw = randomWeights(w, h, 0.05f, 0.4f, 22);
  const cv::Mat init = randomLabels(w, h, -2, 7, 23);
  for (float trunc : {0.0f, 3.0f}) {
    ms::SmoothParams sp;
    sp.truncation = trunc;
    const double e0 = ms::labellingEnergy(v, pw, init, trunc).total();
    for (const Named& opt : kOptimizers) {
      const ms::OptimizerResult r0 = opt.run(v, pw, sp, init, 0);
      EXPECT_EQ(countDiff(r0.disparity, init), 0) << opt.name;
      EXPECT_NEAR(r0.energy.total(), e0, 1e-9);
      EXPECT_EQ(r0.cuts, 0);
      double prev = e0;
      int prev_cuts = 0;
      for (int cycles = 1; cycles <= 6; ++cycles) {
        const ms::OptimizerResult r = opt.run(v, pw, sp, init, cycles);
        EXPECT_LE(r.energy.total(), prev + 1e-9) << opt.name << " cycles " << cycles;
        EXPECT_GE(r.cuts, prev_cuts);
        EXPECT_LE(r.cycles, cycles);
        prev = r.energy.total();
        prev_cuts = r.cuts;
      }
      EXPECT_LT(prev, e0 * 0.8) << opt.name;  // a random start is far from a minimum
    }
  }
}

TEST(GraphCuts, ConvergedResultIsLocalMinimum) {
  const int w = 20, h = 16;
  const ms::CostVolume v = randomVolume(w, h, 0, 9, 31);
  const ms::PairwiseWeights pw = randomWeights(w, h, 0.05f, 0.3f, 32);
  for (float trunc : {0.0f, 2.0f}) {
    ms::SmoothParams sp;
    sp.truncation = trunc;
    for (const Named& opt : kOptimizers) {
      const ms::OptimizerResult r = opt.run(v, pw, sp, cv::Mat(), 100);
      ASSERT_LT(r.cycles, 100) << opt.name;
      // One more full cycle of every move from the result changes nothing.
      const ms::OptimizerResult again = opt.run(v, pw, sp, r.disparity, 1);
      EXPECT_EQ(again.cycles, 1);
      EXPECT_EQ(countDiff(again.disparity, r.disparity), 0) << opt.name << " truncation " << trunc;
      EXPECT_NEAR(again.energy.total(), r.energy.total(), 1e-9);
    }
  }
}

/// All labellings of a tiny problem: the global minimum.
double bruteForceOptimum(const ms::CostVolume& v, const ms::PairwiseWeights& pw, float trunc) {
  const int n = v.width() * v.height(), L = v.levels();
  std::vector<int> digits(n, 0);
  cv::Mat d(v.height(), v.width(), CV_32F);
  double best = std::numeric_limits<double>::infinity();
  for (;;) {
    for (int i = 0; i < n; ++i) d.at<float>(i / v.width(), i % v.width()) = float(v.dmin() + digits[i]);
    best = std::min(best, bruteEnergy(v, pw, d, trunc));
    int i = 0;
    while (i < n && ++digits[i] == L) digits[i++] = 0;
    if (i == n) break;
  }
  return best;
}

TEST(GraphCuts, NearBruteForceOptimumOnTinyProblems) {
  double worst_exp = 0, worst_swap = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const ms::CostVolume v = randomVolume(3, 3, 0, 2, 100 + seed);
    const ms::PairwiseWeights pw = randomWeights(3, 3, 0.1f, 0.6f, 200 + seed);
    for (float trunc : {0.0f, 1.0f}) {
      ms::SmoothParams sp;
      sp.truncation = trunc;
      const double opt = bruteForceOptimum(v, pw, trunc);
      const double ee = ms::alphaExpansion(v, pw, sp).energy.total();
      const double es = ms::alphaBetaSwap(v, pw, sp).energy.total();
      EXPECT_GE(ee, opt - 1e-9);
      EXPECT_GE(es, opt - 1e-9);
      EXPECT_LE(ee, 1.05 * opt) << "seed " << seed << " truncation " << trunc;
      EXPECT_LE(es, 1.05 * opt) << "seed " << seed << " truncation " << trunc;
      worst_exp = std::max(worst_exp, ee / opt);
      worst_swap = std::max(worst_swap, es / opt);
    }
  }
  std::printf("worst energy / optimum: expansion %.4f, swap %.4f\n", worst_exp, worst_swap);
}

TEST(GraphCuts, TwoLabelsGiveGlobalOptimum) {
  // With two labels one expansion (from all-dmax, alpha = dmin) or one swap
  // reaches every labelling, so both must find the exact optimum (2^16 checked).
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const ms::CostVolume v = randomVolume(4, 4, 3, 4, 300 + seed);
    const ms::PairwiseWeights pw = randomWeights(4, 4, 0.0f, 0.8f, 400 + seed);
    ms::SmoothParams sp;
    const double opt = bruteForceOptimum(v, pw, 0);
    const cv::Mat init(4, 4, CV_32F, cv::Scalar(4));
    EXPECT_NEAR(ms::alphaExpansion(v, pw, sp, init, 1).energy.total(), opt, 1e-9) << "seed " << seed;
    EXPECT_NEAR(ms::alphaBetaSwap(v, pw, sp, init, 1).energy.total(), opt, 1e-9) << "seed " << seed;
  }
}

TEST(GraphCuts, ExpansionMoveIsOptimal) {
  // 3 x 3 pixels, labels 0..3: one cycle (max_cycles = 1) from a random
  // labelling must equal the sequence of optimal single expansions
  // alpha = 0, 1, 2, 3, each found by enumerating all 2^9 expansions.
  for (unsigned seed = 1; seed <= 6; ++seed) {
    const ms::CostVolume v = randomVolume(3, 3, 0, 3, 500 + seed);
    const ms::PairwiseWeights pw = randomWeights(3, 3, 0.1f, 0.7f, 600 + seed);
    cv::Mat init = randomLabels(3, 3, 1, 3, 700 + seed);
    ms::SmoothParams sp;
    sp.truncation = seed % 2 ? 0.0f : 2.0f;
    cv::Mat cur = init.clone();
    for (int alpha = 0; alpha <= 3; ++alpha) {
      cv::Mat best = cur.clone();
      double best_e = bruteEnergy(v, pw, cur, sp.truncation);
      for (unsigned mask = 1; mask < 512; ++mask) {
        cv::Mat cand = cur.clone();
        for (int i = 0; i < 9; ++i)
          if (mask >> i & 1u) cand.at<float>(i / 3, i % 3) = float(alpha);
        const double e = bruteEnergy(v, pw, cand, sp.truncation);
        if (e < best_e - 1e-12) {
          best_e = e;
          best = cand;
        }
      }
      cur = best;
    }
    const ms::OptimizerResult r = ms::alphaExpansion(v, pw, sp, init, 1);
    EXPECT_NEAR(r.energy.total(), bruteEnergy(v, pw, cur, sp.truncation), 1e-9) << "seed " << seed;
  }
}

TEST(GraphCuts, DefaultStartIsWinnerTakesAllWithTiesToSmallerD) {
  ms::CostVolume v(3, 2, 2, 5, 0.5f);  // all tied -> dmin everywhere
  v(1, 0, 3) = 0.1f;
  v(1, 0, 4) = 0.1f;  // tie between 3 and 4 -> 3
  v(2, 1, 5) = 0.2f;
  const ms::PairwiseWeights pw = randomWeights(3, 2, 0.0f, 0.1f, 9);
  for (const Named& opt : kOptimizers) {
    const ms::OptimizerResult r = opt.run(v, pw, ms::SmoothParams(), cv::Mat(), 0);
    const cv::Mat expected = (cv::Mat_<float>(2, 3) << 2, 3, 2, 2, 2, 5);
    EXPECT_EQ(countDiff(r.disparity, expected), 0) << opt.name;
  }
}

TEST(GraphCuts, InvalidInputThrows) {
  const ms::CostVolume v = randomVolume(5, 4, 0, 3, 1);
  const ms::PairwiseWeights pw = randomWeights(5, 4, 0.0f, 0.1f, 2);
  ms::SmoothParams sp;
  for (const Named& opt : kOptimizers) {
    EXPECT_THROW(opt.run(v, pw, sp, cv::Mat(4, 6, CV_32F, cv::Scalar(1)), 5), std::invalid_argument);
    EXPECT_THROW(opt.run(v, pw, sp, cv::Mat(4, 5, CV_8U, cv::Scalar(1)), 5), std::invalid_argument);
    EXPECT_THROW(opt.run(v, pw, sp, cv::Mat(4, 5, CV_32F, cv::Scalar(0.5)), 5), std::invalid_argument);
    EXPECT_THROW(opt.run(v, pw, sp, cv::Mat(4, 5, CV_32F, cv::Scalar(4)), 5), std::invalid_argument);
    EXPECT_THROW(opt.run(v, pw, sp, cv::Mat(), -1), std::invalid_argument);
    EXPECT_THROW(opt.run(v, randomWeights(4, 4, 0.0f, 0.1f, 2), sp, cv::Mat(), 5), std::invalid_argument);
    ms::PairwiseWeights neg = randomWeights(5, 4, 0.0f, 0.1f, 2);
    neg.right.at<float>(1, 1) = -0.5f;
    EXPECT_THROW(opt.run(v, neg, sp, cv::Mat(), 5), std::invalid_argument);
    ms::CostVolume single(5, 4, 2, 2, 0.5f);  // one level: nothing to do
    const ms::OptimizerResult r = opt.run(single, pw, sp, cv::Mat(), 5);
    EXPECT_EQ(r.cuts, 0);
    EXPECT_EQ(cv::countNonZero(r.disparity != 2.0f), 0);
  }
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

// reset() keeps the object's memory but must behave exactly like a new graph.
TEST(MaxFlow, ResetReusesObject) {
  auto build = [](ms::MaxFlow& mf, int seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const int n = 50;
    mf.addNodes(n);
    for (int i = 0; i < n; ++i) mf.addTerminalWeights(i, u(rng), u(rng));
    for (int i = 0; i + 1 < n; ++i) mf.addEdge(i, i + 1, 0.3 * u(rng), 0.3 * u(rng));
    return mf.solve();
  };
  ms::MaxFlow reused;
  build(reused, 1);
  for (int seed = 2; seed < 5; ++seed) {
    reused.reset(50, 49);
    ms::MaxFlow fresh;
    EXPECT_EQ(build(reused, seed), build(fresh, seed));
    for (int i = 0; i < 50; ++i) EXPECT_EQ(reused.isSource(i), fresh.isSource(i));
  }
  reused.reset();
  EXPECT_THROW(reused.isSource(0), std::invalid_argument);
  EXPECT_EQ(reused.solve(), 0.0);
  EXPECT_THROW(reused.reset(-1, 0), std::invalid_argument);
}

// ------------------------------------------------------- local expansion

// With a window covering the whole range no pixel is left out of a move but
// the ones already at alpha: the same moves as alpha-expansion, same result.
TEST(LocalExpansion, WideWindowEqualsAlphaExpansion) {
  const int w = 22, h = 17;
  const ms::CostVolume v = randomVolume(w, h, 2, 9, 51);
  const ms::PairwiseWeights pw = randomWeights(w, h, 0.05f, 0.4f, 52);
  const cv::Mat init = randomLabels(w, h, 2, 9, 53);
  for (float trunc : {0.0f, 3.0f}) {
    ms::SmoothParams sp;
    sp.truncation = trunc;
    for (int cycles : {1, 20}) {
      const ms::OptimizerResult e = ms::alphaExpansion(v, pw, sp, init, cycles);
      const ms::OptimizerResult l = ms::localExpansion(v, pw, sp, init, 7, cycles);
      EXPECT_EQ(countDiff(e.disparity, l.disparity), 0) << "truncation " << trunc << " cycles " << cycles;
      EXPECT_NEAR(e.energy.total(), l.energy.total(), 1e-9);
      EXPECT_EQ(e.cuts, l.cuts);
    }
  }
}

// Narrow windows: the energy never rises, a converged result is a local
// minimum of its own moves, and the energy reported is Eq. 2.2's.
TEST(LocalExpansion, DescendsToItsOwnLocalMinimum) {
  const int w = 24, h = 18;
  const ms::CostVolume v = randomVolume(w, h, 0, 11, 61);
  const ms::PairwiseWeights pw = randomWeights(w, h, 0.05f, 0.4f, 62);
  const cv::Mat init = randomLabels(w, h, 0, 11, 63);
  for (float trunc : {0.0f, 2.0f}) {
    ms::SmoothParams sp;
    sp.truncation = trunc;
    const double e0 = ms::labellingEnergy(v, pw, init, trunc).total();
    for (int window : {1, 2, 4}) {
      double prev = e0;
      for (int cycles = 1; cycles <= 4; ++cycles) {
        const ms::OptimizerResult r = ms::localExpansion(v, pw, sp, init, window, cycles);
        EXPECT_LE(r.energy.total(), prev + 1e-9) << "window " << window << " cycles " << cycles;
        prev = r.energy.total();
      }
      EXPECT_LT(prev, 0.9 * e0) << "window " << window;
      const ms::OptimizerResult r = ms::localExpansion(v, pw, sp, init, window, 100);
      ASSERT_LT(r.cycles, 100);
      const ms::Energy recomputed = ms::labellingEnergy(v, pw, r.disparity, trunc);
      EXPECT_NEAR(r.energy.total(), recomputed.total(), 1e-9);
      const ms::OptimizerResult again = ms::localExpansion(v, pw, sp, r.disparity, window, 1);
      EXPECT_EQ(countDiff(again.disparity, r.disparity), 0) << "window " << window;
    }
  }
}

// The window really restricts the moves: a block labelled 0 whose data only
// favours level 7 (every other level costs the same) cannot reach it through
// moves of one level, while alpha-expansion jumps there at once.
TEST(LocalExpansion, WindowBlocksLongJumps) {
  const int w = 12, h = 10;
  ms::CostVolume v(w, h, 0, 7, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) v(x, y, 7) = 0.0f;
  ms::PairwiseWeights pw;
  pw.right = cv::Mat::zeros(h, w, CV_32F);
  pw.down = cv::Mat::zeros(h, w, CV_32F);
  const cv::Mat init(h, w, CV_32F, cv::Scalar(0));
  const ms::SmoothParams sp;
  const ms::OptimizerResult local = ms::localExpansion(v, pw, sp, init, 1, 20);
  EXPECT_EQ(countDiff(local.disparity, init), 0);
  const ms::OptimizerResult full = ms::alphaExpansion(v, pw, sp, init, 20);
  EXPECT_EQ(cv::countNonZero(full.disparity != 7.0f), 0);
  // Within reach (window 7) the block goes to 7 as well.
  const ms::OptimizerResult wide = ms::localExpansion(v, pw, sp, init, 7, 20);
  EXPECT_EQ(cv::countNonZero(wide.disparity != 7.0f), 0);
}

// Polishing an HBDS labelling never raises its energy.
TEST(LocalExpansion, PolishesHbds) {
  const LayerScene s = layerScene(17);
  const ms::SmoothParams sp = layerSmooth(0.0f);
  const ms::PairwiseWeights pw = ms::pairwiseWeights(s.image, sp);
  const ms::OptimizerResult h = ms::hbds(s.volume, pw, sp, 1);
  const ms::OptimizerResult p = ms::localExpansion(s.volume, pw, sp, h.disparity, 2, 3);
  EXPECT_LE(p.energy.total(), h.energy.total() + 1e-9);
  EXPECT_LE(countDiff(p.disparity, s.truth), countDiff(h.disparity, s.truth) + 2);
}

TEST(LocalExpansion, InvalidWindowThrows) {
  const ms::CostVolume v = randomVolume(6, 5, 0, 4, 71);
  const ms::PairwiseWeights pw = randomWeights(6, 5, 0.1f, 0.2f, 72);
  const ms::SmoothParams sp;
  EXPECT_THROW(ms::localExpansion(v, pw, sp, cv::Mat(), 0), std::invalid_argument);
  EXPECT_THROW(ms::localExpansion(v, pw, sp, cv::Mat(), -3), std::invalid_argument);
  EXPECT_THROW(ms::localExpansion(v, pw, sp, cv::Mat(6, 5, CV_32F, cv::Scalar(9)), 2), std::invalid_argument);
}

// After convergence no restricted move improves the energy: checked by brute
// force over every subset of each move's eligible pixels on 3 x 3 problems.
// (A wrong unary for neighbours outside the window would leave improving
// moves that this search finds.)
TEST(LocalExpansion, ConvergedResultHasNoImprovingMoveBruteForce) {
  for (unsigned seed = 1; seed <= 60; ++seed) {
    const ms::CostVolume v = randomVolume(3, 3, 0, 5, 500 + seed);
    const ms::PairwiseWeights pw = randomWeights(3, 3, 0.05f, 0.5f, 600 + seed);
    for (int window : {1, 2}) {
      ms::SmoothParams sp;
      const ms::OptimizerResult r = ms::localExpansion(v, pw, sp, randomLabels(3, 3, 0, 5, 700 + seed), window, 100);
      ASSERT_LT(r.cycles, 100);
      const double e = ms::labellingEnergy(v, pw, r.disparity, 0).total();
      for (int alpha = 0; alpha <= 5; ++alpha) {
        std::vector<int> eligible;
        for (int p = 0; p < 9; ++p) {
          const int d = static_cast<int>(r.disparity.at<float>(p / 3, p % 3));
          if (d != alpha && std::abs(d - alpha) <= window) eligible.push_back(p);
        }
        for (unsigned mask = 1; mask < (1u << eligible.size()); ++mask) {
          cv::Mat moved = r.disparity.clone();
          for (std::size_t k = 0; k < eligible.size(); ++k)
            if (mask & (1u << k)) moved.at<float>(eligible[k] / 3, eligible[k] % 3) = static_cast<float>(alpha);
          EXPECT_GE(ms::labellingEnergy(v, pw, moved, 0).total(), e - 1e-9)
              << "seed " << seed << " window " << window << " alpha " << alpha << " mask " << mask;
        }
      }
    }
  }
}

// ------------------------------------------------------------- coarse polish

// The fusion is accepted only when it lowers the energy: from any start, any
// block side (partial blocks at the borders), any truncation, the result's
// energy is never above the start's and is reported exactly.
TEST(CoarsePolish, EnergyNeverIncreases) {
  const int w = 23, h = 17;
  const ms::CostVolume v = randomVolume(w, h, -2, 7, 81);
  const ms::PairwiseWeights pw = randomWeights(w, h, 0.05f, 0.4f, 82);
  for (unsigned seed : {83u, 84u, 85u}) {
    const cv::Mat init = randomLabels(w, h, -2, 7, seed);
    for (float trunc : {0.0f, 3.0f}) {
      ms::SmoothParams sp;
      sp.truncation = trunc;
      const double e0 = ms::labellingEnergy(v, pw, init, trunc).total();
      for (int block : {2, 3, 4}) {
        for (int window : {2, 10}) {
          const ms::OptimizerResult r = ms::coarsePolish(v, pw, sp, init, block, window, 1);
          EXPECT_LE(r.energy.total(), e0 + 1e-9) << "block " << block << " window " << window;
          const ms::Energy e = ms::labellingEnergy(v, pw, r.disparity, trunc);
          EXPECT_NEAR(r.energy.total(), e.total(), 1e-9);
          EXPECT_GT(r.cuts, 0);
        }
      }
    }
  }
}

// A flat region of the layered scene's rectangle (true level 4) labelled 0,
// far outside a local window: the coarse full-range cycle finds level 4 for
// its blocks and the fusion brings it back at full resolution. Without the
// fusion step (the start returned) the region stays wrong.
TEST(CoarsePolish, RecoversWronglyLabelledFlatRegion) {
  for (float trunc : {0.0f, 3.0f}) {
    const LayerScene s = layerScene(19);
    const ms::SmoothParams sp = layerSmooth(trunc);
    const ms::PairwiseWeights pw = ms::pairwiseWeights(s.image, sp);
    cv::Mat init = s.truth.clone();
    init(cv::Rect(9, 20, 19, 4)).setTo(0.0f);  // 76 pixels of the rectangle, below the disc
    const int wrong = countDiff(init, s.truth);
    ASSERT_EQ(wrong, 76);
    for (int block : {2, 3}) {
      const ms::OptimizerResult r = ms::coarsePolish(s.volume, pw, sp, init, block, 7, 1);
      EXPECT_LT(r.energy.total(), ms::labellingEnergy(s.volume, pw, init, trunc).total());
      EXPECT_LE(countDiff(r.disparity(cv::Rect(9, 20, 19, 4)), s.truth(cv::Rect(9, 20, 19, 4))), 2)
          << "block " << block << " truncation " << trunc;
      // Nothing that was right becomes wrong but a few outlier pixels.
      EXPECT_LE(countDiff(r.disparity, s.truth), 6) << "block " << block << " truncation " << trunc;
    }
  }
}

TEST(CoarsePolish, InvalidInputThrows) {
  const ms::CostVolume v = randomVolume(6, 5, 0, 4, 91);
  const ms::PairwiseWeights pw = randomWeights(6, 5, 0.1f, 0.2f, 92);
  const ms::SmoothParams sp;
  const cv::Mat init = randomLabels(6, 5, 0, 4, 93);
  EXPECT_THROW(ms::coarsePolish(v, pw, sp, init, 1, 4), std::invalid_argument);
  EXPECT_THROW(ms::coarsePolish(v, pw, sp, init, 2, 0), std::invalid_argument);
  EXPECT_THROW(ms::coarsePolish(v, pw, sp, cv::Mat(), 2, 4), std::invalid_argument);
  EXPECT_THROW(ms::coarsePolish(v, pw, sp, cv::Mat(5, 6, CV_32F, cv::Scalar(9)), 2, 4), std::invalid_argument);
}
