// Tests of the HBDS matching cost (Eq. 2.6-2.8), winner-takes-all, the
// disparity histogram and the break point (Eq. 2.9-2.10).
#include "massage_cell/stereo/cost_volume.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace ms = massage_cell::stereo;

namespace {

// ---------------------------------------------------------------- helpers --

cv::Mat row8u(const std::vector<int>& v) {
  cv::Mat m(1, static_cast<int>(v.size()), CV_8UC1);
  for (std::size_t i = 0; i < v.size(); ++i) m.at<uchar>(0, static_cast<int>(i)) = cv::saturate_cast<uchar>(v[i]);
  return m;
}

cv::Mat row8uc3(const std::vector<int>& b, const std::vector<int>& g, const std::vector<int>& r) {
  cv::Mat m(1, static_cast<int>(b.size()), CV_8UC3);
  for (std::size_t i = 0; i < b.size(); ++i)
    m.at<cv::Vec3b>(0, static_cast<int>(i)) =
        cv::Vec3b(cv::saturate_cast<uchar>(b[i]), cv::saturate_cast<uchar>(g[i]), cv::saturate_cast<uchar>(r[i]));
  return m;
}

cv::Mat randomImage(int w, int h, int type, uint64 seed) {
  cv::Mat m(h, w, type);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

int clampi(int v, int lo, int hi) { return std::min(std::max(v, lo), hi); }

int reflect101(int i, int n) {
  if (n == 1) return 0;
  while (i < 0 || i >= n) i = i < 0 ? -i : 2 * n - 2 - i;
  return i;
}

cv::Mat grey(const cv::Mat& img) {
  if (img.channels() == 1) return img;
  cv::Mat g;
  cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
  return g;
}

// Hand-written 3x3 Sobel magnitude / max (BORDER_REFLECT_101).
cv::Mat refTextureWeight(const cv::Mat& left, double saturation = 0.0) {
  const cv::Mat g = grey(left);
  cv::Mat mag(g.size(), CV_64F);
  double mx = 0.0;
  for (int y = 0; y < g.rows; ++y)
    for (int x = 0; x < g.cols; ++x) {
      auto I = [&](int dx, int dy) {
        return static_cast<double>(g.at<uchar>(reflect101(y + dy, g.rows), reflect101(x + dx, g.cols)));
      };
      const double gx = (I(1, -1) + 2 * I(1, 0) + I(1, 1)) - (I(-1, -1) + 2 * I(-1, 0) + I(-1, 1));
      const double gy = (I(-1, 1) + 2 * I(0, 1) + I(1, 1)) - (I(-1, -1) + 2 * I(0, -1) + I(1, -1));
      mag.at<double>(y, x) = std::sqrt(gx * gx + gy * gy);
      mx = std::max(mx, mag.at<double>(y, x));
    }
  if (saturation > 0) {
    mag = cv::min(mag / saturation, 1.0);
    return mag;
  }
  if (mx > 0) mag /= mx;
  return mag;
}

// min over s in the segment from value a to value b of |v - s| (linear interpolation).
double segMin(double v, double a, double b) {
  const double lo = std::min(a, b), hi = std::max(a, b);
  if (v >= lo && v <= hi) return 0.0;
  return std::min(std::abs(v - a), std::abs(v - b));
}

// Sampling-insensitive difference of value v against the linearly interpolated
// row `row` around column c (c -+ 1/2), channel ch of nch, edge replicated.
double btMin(double v, const cv::Mat& img, int y, int c, int ch) {
  const int nch = img.channels();
  auto at = [&](int x) { return static_cast<double>(img.ptr<uchar>(y)[clampi(x, 0, img.cols - 1) * nch + ch]); };
  const double mid = at(c), minus = 0.5 * (at(c) + at(c - 1)), plus = 0.5 * (at(c) + at(c + 1));
  return std::min(segMin(v, minus, mid), segMin(v, mid, plus));
}

double refColour(const cv::Mat& L, const cv::Mat& R, int x, int y, int d, double eta) {
  const int nch = L.channels();
  double cf = 0, cr = 0;
  for (int c = 0; c < nch; ++c) {
    cf += btMin(L.ptr<uchar>(y)[x * nch + c], R, y, x - d, c);
    cr += btMin(R.ptr<uchar>(y)[(x - d) * nch + c], L, y, x, c);
  }
  cf /= nch;
  cr /= nch;
  return std::min({cf, cr, eta}) / eta;
}

// Brute-force NCC on the grey images with replicated borders; flat -> 0.
double refNcc(const cv::Mat& Lg, const cv::Mat& Rg, int x, int y, int d, int n) {
  const int r = n / 2;
  double sl = 0, sr = 0;
  const int N = n * n;
  std::vector<double> a, b;
  for (int j = -r; j <= r; ++j)
    for (int i = -r; i <= r; ++i) {
      const int yy = clampi(y + j, 0, Lg.rows - 1);
      a.push_back(Lg.at<uchar>(yy, clampi(x + i, 0, Lg.cols - 1)));
      b.push_back(Rg.at<uchar>(yy, clampi(x - d + i, 0, Rg.cols - 1)));
      sl += a.back();
      sr += b.back();
    }
  const double ml = sl / N, mr = sr / N;
  double vl = 0, vr = 0, cov = 0;
  for (int k = 0; k < N; ++k) {
    vl += (a[k] - ml) * (a[k] - ml);
    vr += (b[k] - mr) * (b[k] - mr);
    cov += (a[k] - ml) * (b[k] - mr);
  }
  if (vl <= 1e-9 || vr <= 1e-9) return 0.0;
  return cov / std::sqrt(vl * vr);
}

double refCost(const cv::Mat& L, const cv::Mat& R, const cv::Mat& w, int x, int y, int d, const ms::CostParams& p) {
  if (x - d < 0) return 1.0;
  const double C = refColour(L, R, x, y, d, p.eta);
  const double T = 0.5 * (1.0 - refNcc(grey(L), grey(R), x, y, d, p.ncc_window));
  const double ww = w.at<double>(y, x);
  return ww * T + (1.0 - ww) * C;
}

void expectVolumeMatchesReference(const cv::Mat& L, const cv::Mat& R, const ms::CostParams& p, double tol) {
  const ms::CostVolume v = ms::computeCostVolume(L, R, p);
  ASSERT_EQ(v.width(), L.cols);
  ASSERT_EQ(v.height(), L.rows);
  ASSERT_EQ(v.dmin(), p.dmin);
  ASSERT_EQ(v.dmax(), p.dmax);
  const cv::Mat w = refTextureWeight(L, p.gradient_saturation);
  int bad = 0;
  for (int d = p.dmin; d <= p.dmax; ++d)
    for (int y = 0; y < L.rows; ++y)
      for (int x = 0; x < L.cols; ++x) {
        const double want = refCost(L, R, w, x, y, d, p);
        if (std::abs(v(x, y, d) - want) > tol && ++bad < 5)
          ADD_FAILURE() << "S(" << x << "," << y << "," << d << ") = " << v(x, y, d) << ", reference " << want;
      }
  EXPECT_EQ(bad, 0);
}

// T(x, y, d) recovered from S where C is negligible (eta huge): S ~ w T.
double textureCostFromS(const ms::CostVolume& v, const cv::Mat& w, int x, int y, int d) {
  return v(x, y, d) / w.at<float>(y, x);
}

ms::CostParams params(int dmin, int dmax, float eta, int n) {
  ms::CostParams p;
  p.dmin = dmin;
  p.dmax = dmax;
  p.eta = eta;
  p.ncc_window = n;
  p.gradient_saturation = 0.0f;  // the thesis's literal w (divided by the maximum); see SaturatedWeight
  return p;
}

// ------------------------------------------------------------ colour cost --

// A 1-pixel window is always flat, so T = 0.5 and S = 0.5 w + (1 - w) C.
double expectedS(const cv::Mat& w, int x, double C) { return 0.5 * w.at<float>(0, x) + (1.0 - w.at<float>(0, x)) * C; }

TEST(ColourCost, HalfPixelShiftCostsNothingWithBirchfieldTomasi) {
  // The left row is the right row shifted by half a pixel (ramp of slope 20,
  // offset 10); the strong edge at x = 6 keeps w < 1 on the ramp.
  const cv::Mat L = row8u({10, 30, 50, 70, 90, 110, 255, 255});
  const cv::Mat R = row8u({0, 20, 40, 60, 80, 100, 250, 250});
  const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 1, 40.0f, 1));
  const cv::Mat w = ms::textureWeight(L);
  for (int x = 1; x <= 4; ++x) {
    ASSERT_LT(w.at<float>(0, x), 0.5f);
    // d = 0: |L - R| = 10 everywhere (a plain absolute difference would give
    // C = 10 / 40 = 0.25), but L(x) = R(x + 1/2) so both BT directions give 0.
    EXPECT_NEAR(v(x, 0, 0), expectedS(w, x, 0.0), 1e-6) << "x = " << x;
    EXPECT_GT(std::abs(v(x, 0, 0) - expectedS(w, x, 0.25)), 0.1);
    // d = 1: L(x) = 20x + 10 vs R(x - 1) = 20x - 20, nearest interpolant
    // R(x - 1/2) = 20x - 10 -> C_f = 20; R(x - 1) vs L(x - 1/2) = 20x -> C_r = 20.
    EXPECT_NEAR(v(x, 0, 1), expectedS(w, x, 20.0 / 40.0), 1e-6) << "x = " << x;
  }
  // Hand values at a non-ramp place: x = 6, d = 1: L = 255 vs R(5) = 100 with
  // interpolants 90 and 175 -> C_f = 80; R(5) = 100 vs L(6) = 255, L(5.5) =
  // 182.5 -> C_r = 82.5; C = min(80, 82.5, 40) / 40 = 1.
  EXPECT_NEAR(v(6, 0, 1), expectedS(w, 6, 1.0), 1e-6);
}

TEST(ColourCost, ChannelsAreAveragedAndTruncatedByEta) {
  // B: half-pixel-shifted ramp (BT 0); G: constant offset 30 (BT 30);
  // R: identical (0). C_f = C_r = (0 + 30 + 0) / 3 = 10 on the ramp at d = 0
  // (a plain per-channel |dI| average would give (10 + 30 + 0) / 3 = 13.33).
  const cv::Mat L =
      row8uc3({10, 30, 50, 70, 90, 110, 255, 255}, {100, 100, 100, 100, 100, 100, 100, 100}, {5, 5, 5, 5, 5, 5, 5, 5});
  const cv::Mat R =
      row8uc3({0, 20, 40, 60, 80, 100, 250, 250}, {70, 70, 70, 70, 70, 70, 70, 70}, {5, 5, 5, 5, 5, 5, 5, 5});
  const cv::Mat w = ms::textureWeight(L);
  const ms::CostVolume v20 = ms::computeCostVolume(L, R, params(0, 0, 20.0f, 1));
  const ms::CostVolume v5 = ms::computeCostVolume(L, R, params(0, 0, 5.0f, 1));
  const ms::CostVolume v100 = ms::computeCostVolume(L, R, params(0, 0, 100.0f, 1));
  for (int x = 0; x <= 4; ++x) {
    ASSERT_LT(w.at<float>(0, x), 0.5f);
    EXPECT_NEAR(v20(x, 0, 0), expectedS(w, x, 10.0 / 20.0), 1e-6) << "x = " << x;
    EXPECT_NEAR(v5(x, 0, 0), expectedS(w, x, 1.0), 1e-6) << "x = " << x;  // truncated at eta
    EXPECT_NEAR(v100(x, 0, 0), expectedS(w, x, 0.1), 1e-6) << "x = " << x;
  }
}

TEST(ColourCost, GreyAndColourInputsAgreeWithBruteForceReference) {
  // Full volume against an independent brute-force implementation (segment
  // minima of the interpolated rows, brute-force NCC with replicated borders,
  // hand-written Sobel), for colour and grey inputs and several windows.
  const cv::Mat Lc = randomImage(20, 15, CV_8UC3, 1), Rc = randomImage(20, 15, CV_8UC3, 2);
  expectVolumeMatchesReference(Lc, Rc, params(0, 6, 20.0f, 5), 1e-4);
  expectVolumeMatchesReference(Lc, Rc, params(2, 9, 7.5f, 3), 1e-4);
  expectVolumeMatchesReference(Lc, Rc, params(0, 3, 255.0f, 1), 1e-4);
  expectVolumeMatchesReference(Lc, Rc, params(0, 4, 30.0f, 15), 1e-4);
  expectVolumeMatchesReference(grey(Lc), grey(Rc), params(1, 5, 12.0f, 7), 1e-4);
  // A pair with real correspondences (not just noise): right = left shifted by 3.
  cv::Mat R2 = randomImage(20, 15, CV_8UC3, 3), L2 = R2.clone();
  R2(cv::Rect(0, 0, 17, 15)).copyTo(L2(cv::Rect(3, 0, 17, 15)));
  expectVolumeMatchesReference(L2, R2, params(0, 6, 20.0f, 5), 1e-4);
}

TEST(ColourCost, LargeWindowUsesDoublePathAndStillMatches) {
  // n = 17: window sums of products exceed 2^24, the double accumulator path.
  const cv::Mat L = randomImage(40, 30, CV_8UC3, 4), R = randomImage(40, 30, CV_8UC3, 5);
  expectVolumeMatchesReference(L, R, params(0, 5, 20.0f, 17), 1e-4);
}

TEST(ColourCost, CostIsNormalisedToUnitRange) {
  const cv::Mat L = randomImage(40, 30, CV_8UC3, 6), R = randomImage(40, 30, CV_8UC3, 7);
  for (float eta : {0.5f, 20.0f, 1000.0f}) {
    const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 10, eta, 5));
    float lo = 10.0f, hi = -10.0f;
    for (int d = 0; d <= 10; ++d)
      for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 40; ++x) {
          lo = std::min(lo, v(x, y, d));
          hi = std::max(hi, v(x, y, d));
        }
    EXPECT_GE(lo, 0.0f) << "eta " << eta;
    EXPECT_LE(hi, 1.0f) << "eta " << eta;
  }
  // eta tiny: every mismatching colour saturates, C = 1 -> S = w T + 1 - w.
  const cv::Mat w = ms::textureWeight(L);
  const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 0, 1e-3f, 1));
  int saturated = 0;
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) saturated += std::abs(v(x, y, 0) - (1.0f - 0.5f * w.at<float>(y, x))) < 1e-6f;
  EXPECT_GT(saturated, 40 * 30 * 9 / 10);
}

TEST(CostVolume, OutOfImageMatchesCostOne) {
  const cv::Mat L = randomImage(30, 10, CV_8UC3, 8), R = randomImage(30, 10, CV_8UC3, 9);
  const ms::CostVolume v = ms::computeCostVolume(L, R, params(3, 12, 20.0f, 5));
  EXPECT_EQ(v.levels(), 10);
  EXPECT_EQ(v.bytes(), std::size_t(30) * 10 * 10 * sizeof(float));
  int inside = 0, below_one = 0;
  for (int d = 3; d <= 12; ++d)
    for (int y = 0; y < 10; ++y)
      for (int x = 0; x < 30; ++x) {
        if (x < d) {
          EXPECT_EQ(v(x, y, d), 1.0f) << x << "," << y << "," << d;
        } else {
          ++inside;
          below_one += v(x, y, d) < 1.0f;
        }
      }
  EXPECT_GT(below_one, inside / 2);  // inside the image the cost is a real cost
}

TEST(CostVolume, ThreadCountDoesNotChangeTheResult) {
  const cv::Mat L = randomImage(64, 48, CV_8UC3, 10), R = randomImage(64, 48, CV_8UC3, 11);
  ms::CostParams p = params(0, 20, 20.0f, 5);
  const ms::CostVolume a = ms::computeCostVolume(L, R, p);
  const ms::CostVolume b = ms::computeCostVolume(L, R, p, 1);
  const ms::CostVolume c = ms::computeCostVolume(L, R, p, 3);
  for (int d = 0; d <= 20; ++d)
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x) {
        ASSERT_EQ(a(x, y, d), b(x, y, d));
        ASSERT_EQ(a(x, y, d), c(x, y, d));
      }
}

// -------------------------------------------------------------- NCC term --

TEST(NccCost, IdenticalPatchesCostZero) {
  const cv::Mat L = randomImage(30, 20, CV_8UC3, 12);
  const ms::CostVolume v = ms::computeCostVolume(L, L, params(0, 2, 20.0f, 5));
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x) EXPECT_NEAR(v(x, y, 0), 0.0f, 1e-6f) << x << "," << y;  // C = 0 and T = 0
}

TEST(NccCost, InvertedPatchesCostOneAndFlatPatchesHalf) {
  const cv::Mat L = randomImage(30, 20, CV_8UC1, 13);
  cv::Mat inv = 255 - L;
  const cv::Mat flat(20, 30, CV_8UC1, cv::Scalar(128));
  const cv::Mat w = ms::textureWeight(L);
  const ms::CostVolume vi = ms::computeCostVolume(L, inv, params(0, 0, 1e9f, 5));  // C ~ 0
  const ms::CostVolume vf = ms::computeCostVolume(L, flat, params(0, 0, 1e9f, 5));
  int checked = 0;
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x) {
      if (w.at<float>(y, x) < 0.2f) continue;
      ++checked;
      EXPECT_NEAR(textureCostFromS(vi, w, x, y, 0), 1.0, 1e-4) << x << "," << y;  // NCC = -1
      EXPECT_NEAR(textureCostFromS(vf, w, x, y, 0), 0.5, 1e-4) << x << "," << y;  // flat: NCC := 0
    }
  EXPECT_GT(checked, 300);
}

TEST(NccCost, AgreesWithBruteForceNcc) {
  const cv::Mat L = randomImage(20, 15, CV_8UC1, 14), R = randomImage(20, 15, CV_8UC1, 15);
  const cv::Mat w = ms::textureWeight(L);
  for (int n : {3, 5, 7}) {
    const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 8, 1e9f, n));
    const int pts[][3] = {{10, 7, 0}, {12, 3, 4}, {19, 14, 8}, {8, 0, 8}, {5, 10, 2}, {15, 8, 6}, {3, 1, 3}};
    for (const auto& q : pts) {
      const int x = q[0], y = q[1], d = q[2];
      if (w.at<float>(y, x) < 0.05f) continue;
      const double want = 0.5 * (1.0 - refNcc(L, R, x, y, d, n));
      EXPECT_NEAR(textureCostFromS(v, w, x, y, d), want, 1e-4) << "n " << n << " at " << x << "," << y << "," << d;
    }
  }
}

// -------------------------------------------------------- texture weight --

TEST(TextureWeight, NormalisedSobelMagnitude) {
  const cv::Mat L = randomImage(25, 17, CV_8UC3, 16);
  const cv::Mat w = ms::textureWeight(L);
  ASSERT_EQ(w.type(), CV_32F);
  ASSERT_EQ(w.size(), L.size());
  double mn, mx;
  cv::minMaxLoc(w, &mn, &mx);
  EXPECT_FLOAT_EQ(static_cast<float>(mx), 1.0f);
  EXPECT_GE(mn, 0.0);
  const cv::Mat ref = refTextureWeight(L);
  for (int y = 0; y < L.rows; ++y)
    for (int x = 0; x < L.cols; ++x) EXPECT_NEAR(w.at<float>(y, x), ref.at<double>(y, x), 1e-5) << x << "," << y;

  // A vertical step: maximal on the two columns next to the step, 0 elsewhere.
  cv::Mat step(9, 10, CV_8UC1, cv::Scalar(20));
  step.colRange(5, 10).setTo(200);
  const cv::Mat ws = ms::textureWeight(step);
  for (int y = 0; y < 9; ++y)
    for (int x = 0; x < 10; ++x) EXPECT_FLOAT_EQ(ws.at<float>(y, x), (x == 4 || x == 5) ? 1.0f : 0.0f);
}

TEST(TextureWeight, SaturatedWeightReachesOneAtTheSaturationMagnitude) {
  const cv::Mat L = randomImage(25, 17, CV_8UC3, 16);
  const cv::Mat w = ms::textureWeight(L, 20.0f);
  const cv::Mat ref = refTextureWeight(L, 20.0);
  for (int y = 0; y < L.rows; ++y)
    for (int x = 0; x < L.cols; ++x) EXPECT_NEAR(w.at<float>(y, x), ref.at<double>(y, x), 1e-5) << x << "," << y;
  // A weak step (magnitude 4 * 5 = 20 next to it) saturates; without saturation the maximum would be 1 anyway.
  cv::Mat step(9, 10, CV_8UC1, cv::Scalar(100));
  step.colRange(5, 10).setTo(105);
  EXPECT_FLOAT_EQ(ms::textureWeight(step, 40.0f).at<float>(4, 4), 0.5f);
  EXPECT_FLOAT_EQ(ms::textureWeight(step, 10.0f).at<float>(4, 4), 1.0f);
  // The cost volume uses it.
  const cv::Mat R = randomImage(25, 17, CV_8UC3, 17);
  ms::CostParams p = params(0, 6, 20.0f, 5);
  p.gradient_saturation = 20.0f;
  expectVolumeMatchesReference(L, R, p, 1e-4);
}

TEST(TextureWeight, FlatImageGivesZero) {
  const cv::Mat flat(12, 9, CV_8UC3, cv::Scalar(40, 90, 200));
  const cv::Mat w = ms::textureWeight(flat);
  EXPECT_EQ(cv::countNonZero(w), 0);
  EXPECT_THROW(ms::textureWeight(cv::Mat()), std::invalid_argument);
}

// --------------------------------------------------------- winner takes all --

TEST(WinnerTakesAll, RecoversConstantShift) {
  const int W = 60, H = 30, dtrue = 5, n = 5, r = n / 2;
  const cv::Mat R = randomImage(W, H, CV_8UC3, 17);
  cv::Mat L = randomImage(W, H, CV_8UC3, 18);
  R(cv::Rect(0, 0, W - dtrue, H)).copyTo(L(cv::Rect(dtrue, 0, W - dtrue, H)));  // L(x) = R(x - 5)
  const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 12, 20.0f, n));
  const cv::Mat disp = ms::winnerTakesAll(v);
  ASSERT_EQ(disp.type(), CV_32F);
  const cv::Mat w = ms::textureWeight(L);
  int checked = 0;
  for (int y = 0; y < H; ++y)
    for (int x = dtrue + r; x < W - r; ++x) {
      // Where the Sobel magnitude happens to be exactly 0 only the lenient BT
      // colour term decides and may tie at 0 with a wrong d (seen on noise).
      if (w.at<float>(y, x) == 0.0f) continue;
      ++checked;
      EXPECT_EQ(disp.at<float>(y, x), float(dtrue)) << x << "," << y;
    }
  EXPECT_GT(checked, (W - dtrue - 2 * r) * H * 9 / 10);
}

TEST(WinnerTakesAll, RecoversTwoLayerScene) {
  // Background at disparity 3, a foreground rectangle at disparity 9.
  const int W = 70, H = 40, db = 3, df = 9, n = 5, r = n / 2;
  const cv::Rect rect(28, 10, 22, 20);
  const cv::Mat Tb = randomImage(W, H, CV_8UC3, 19), Tf = randomImage(W, H, CV_8UC3, 20);
  cv::Mat L(H, W, CV_8UC3), R(H, W, CV_8UC3);
  cv::Mat truth(H, W, CV_32S);  // -1: occluded / no match
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const bool fg = rect.contains(cv::Point(x, y));
      L.at<cv::Vec3b>(y, x) = fg ? Tf.at<cv::Vec3b>(y, x) : Tb.at<cv::Vec3b>(y, x);
      const bool rfg = rect.contains(cv::Point(x + df, y));  // right pixel x shows the foreground
      R.at<cv::Vec3b>(y, x) = rfg ? Tf.at<cv::Vec3b>(y, x + df) : Tb.at<cv::Vec3b>(y, std::min(x + db, W - 1));
      int t = fg ? df : db;
      if (x - t < 0 || (!fg && rect.contains(cv::Point(x - db + df, y)))) t = -1;
      truth.at<int>(y, x) = t;
    }
  const ms::CostVolume v = ms::computeCostVolume(L, R, params(0, 14, 20.0f, n));
  const cv::Mat disp = ms::winnerTakesAll(v);
  const cv::Mat w = ms::textureWeight(L);
  int checked = 0;
  for (int y = r + 1; y < H - r - 1; ++y)
    for (int x = r + 1; x < W - r - 1 - db; ++x) {
      const int t = truth.at<int>(y, x);
      bool uniform = t >= 0;
      for (int j = -r - 1; j <= r + 1 && uniform; ++j)
        for (int i = -r - 1; i <= r + 1 && uniform; ++i) uniform = truth.at<int>(y + j, x + i) == t;
      if (!uniform) continue;
      ++checked;
      EXPECT_EQ(disp.at<float>(y, x), float(t)) << x << "," << y;
    }
  EXPECT_GT(checked, 800);
}

TEST(WinnerTakesAll, TiesGoToSmallerDisparityAndRangeIsClamped) {
  // Width 11: columns 0..7 go through the 4-wide SIMD loop, 8..10 the tail.
  ms::CostVolume v(11, 2, 2, 6, 0.5f);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 11; ++x) {
      if (x % 3 == 0) {
        v(x, y, 3) = 0.1f;
        v(x, y, 5) = 0.1f;  // tie with d = 3
      } else if (x % 3 == 2) {
        v(x, y, 6) = 0.2f;
      }  // x % 3 == 1: all equal -> the smallest d
    }
  const auto expect = [&](const cv::Mat& d, const float want[3]) {
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 11; ++x) EXPECT_EQ(d.at<float>(y, x), want[x % 3]) << x << "," << y;
  };
  const float all[3] = {3.0f, 2.0f, 6.0f};
  expect(ms::winnerTakesAll(v), all);
  const float upper[3] = {5.0f, 4.0f, 6.0f};
  expect(ms::winnerTakesAll(v, 4, 100), upper);  // clamped to [4, 6]
  const float lower[3] = {3.0f, 2.0f, 2.0f};
  expect(ms::winnerTakesAll(v, -7, 4), lower);  // clamped to [2, 4]
  EXPECT_THROW(ms::winnerTakesAll(v, 7, 9), std::invalid_argument);
  EXPECT_THROW(ms::winnerTakesAll(ms::CostVolume()), std::invalid_argument);
}

// --------------------------------------------------------------- histogram --

TEST(DisparityHistogram, CountsRoundedDisparitiesInRange) {
  cv::Mat d =
      (cv::Mat_<float>(2, 4) << 0.4f, 0.6f, 1.49f, 2.5f, -0.2f, 7.0f, std::numeric_limits<float>::quiet_NaN(), 3.0f);
  std::vector<double> h = ms::disparityHistogram(d, 0, 3);
  EXPECT_EQ(h, (std::vector<double>{2, 2, 0, 2}));
  cv::Mat mask = (cv::Mat_<uchar>(2, 4) << 255, 0, 1, 255, 0, 255, 255, 0);
  h = ms::disparityHistogram(d, 0, 3, mask);
  EXPECT_EQ(h, (std::vector<double>{1, 1, 0, 1}));
  h = ms::disparityHistogram(d, 2, 7);
  EXPECT_EQ(h, (std::vector<double>{0, 2, 0, 0, 0, 1}));
  EXPECT_THROW(ms::disparityHistogram(d, 3, 2), std::invalid_argument);
  EXPECT_THROW(ms::disparityHistogram(d, 0, 3, cv::Mat(3, 3, CV_8UC1)), std::invalid_argument);
}

// ------------------------------------------------------------- break point --

std::vector<double> gaussians(int lo, int hi, const std::vector<std::array<double, 3>>& comps) {
  std::vector<double> h(hi - lo + 1, 0.0);
  for (int t = lo; t <= hi; ++t)
    for (const auto& c : comps) h[t - lo] += c[0] * std::exp(-0.5 * std::pow((t - c[1]) / c[2], 2)) / c[2];
  return h;
}

// Plain Otsu by exhaustive minimisation of the within-class variance (Eq. 2.9);
// returns the threshold t (B = levels <= t) and the class means.
int otsu(const std::vector<double>& h, int lo, double* muB = nullptr, double* muF = nullptr) {
  double best = std::numeric_limits<double>::infinity();
  int bt = lo;
  for (int t = 0; t + 1 < static_cast<int>(h.size()); ++t) {
    double wb = 0, wf = 0, mb = 0, mf = 0;
    for (int i = 0; i < static_cast<int>(h.size()); ++i) (i <= t ? wb : wf) += h[i], (i <= t ? mb : mf) += h[i] * i;
    if (wb <= 0 || wf <= 0) continue;
    mb /= wb;
    mf /= wf;
    double vb = 0, vf = 0;
    for (int i = 0; i < static_cast<int>(h.size()); ++i)
      (i <= t ? vb : vf) += h[i] * (i - (i <= t ? mb : mf)) * (i - (i <= t ? mb : mf));
    const double within = vb + vf;  // = w_B sigma_B^2 + w_F sigma_F^2 (unnormalised)
    if (within < best) {            // first minimum
      best = within;
      bt = lo + t;
      if (muB) *muB = lo + mb;
      if (muF) *muF = lo + mf;
    }
  }
  return bt;
}

TEST(BreakPoint, BimodalSplitsAtTheValley) {
  const auto h = gaussians(0, 20, {{{1000, 5, 1.5}}, {{1000, 15, 1.5}}});
  EXPECT_EQ(ms::breakPoint(h, 0, 20), 10);
  EXPECT_EQ(ms::breakPoint(h, 30, 50), 40);  // same shape, shifted range
  // Asymmetric valley: the minimum is at 11, not at the Otsu threshold.
  auto h2 = h;
  h2[11] = 0.5 * h2[10];
  EXPECT_EQ(ms::breakPoint(h2, 0, 20), 11);
}

TEST(BreakPoint, BimodalWithDifferentVariancesIsNotBiased) {
  // A narrow, tall group at 10 and a wide group at 38 (Fig. 2.5(a)).
  const int lo = 0, hi = 59;
  const auto h = gaussians(lo, hi, {{{1000, 10, 1.5}}, {{3000, 38, 9.0}}});
  // Valley = least-populated level between the two peaks.
  int valley = 10;
  for (int t = 10; t <= 38; ++t)
    if (h[t] < h[valley]) valley = t;
  const int t_otsu = otsu(h, lo);
  // Plain Otsu is biased towards the wide group (Fig. 2.5(a)).
  ASSERT_GE(t_otsu - valley, 3) << "plain Otsu would already hit the valley; test not meaningful";
  const int psi = ms::breakPoint(h, lo, hi);
  EXPECT_EQ(psi, valley) << "Otsu threshold " << t_otsu;
}

TEST(BreakPoint, UnimodalStaysInRangeAndBetweenTheClassMeans) {
  const int lo = 0, hi = 59;
  const auto h = gaussians(lo, hi, {{{1000, 30, 5.0}}});
  double muB = 0, muF = 0;
  otsu(h, lo, &muB, &muF);
  const int psi = ms::breakPoint(h, lo, hi);
  EXPECT_GE(psi, lo);
  EXPECT_LT(psi, hi);
  EXPECT_GE(psi, std::ceil(muB));
  EXPECT_LE(psi, std::floor(muF));
  for (int t = static_cast<int>(std::ceil(muB)); t <= static_cast<int>(std::floor(muF)); ++t) EXPECT_LE(h[psi], h[t]);
  // A skewed unimodal histogram (a long tail to the right).
  std::vector<double> s(hi - lo + 1, 0.0);
  for (int t = 5; t <= hi; ++t) s[t] = 1000.0 * std::exp(-(t - 5) / 8.0);
  const int ps = ms::breakPoint(s, lo, hi);
  EXPECT_GE(ps, lo);
  EXPECT_LT(ps, hi);
}

TEST(BreakPoint, EmptyOneLevelAndTwoLevelCases) {
  // Empty: the middle (floor).
  EXPECT_EQ(ms::breakPoint(std::vector<double>(10, 0.0), 0, 9), 4);
  EXPECT_EQ(ms::breakPoint(std::vector<double>(11, 0.0), 10, 20), 15);
  EXPECT_EQ(ms::breakPoint(std::vector<double>(6, 0.0), -5, 0), -3);
  // One occupied level: kept whole, on the side with more remaining range.
  std::vector<double> one(21, 0.0);
  one[15] = 50;
  EXPECT_EQ(ms::breakPoint(one, 0, 20), 15);  // B = [0, 15] holds it, F = [16, 20] empty
  one.assign(21, 0.0);
  one[3] = 50;
  EXPECT_EQ(ms::breakPoint(one, 0, 20), 2);  // F = [3, 20] holds it
  one.assign(21, 0.0);
  one[0] = 50;
  EXPECT_EQ(ms::breakPoint(one, 0, 20), 0);
  one.assign(21, 0.0);
  one[20] = 50;
  EXPECT_EQ(ms::breakPoint(one, 0, 20), 19);
  // Two occupied levels far apart: every level between is empty -> the one
  // nearest the middle (9.5; tie 9 / 10 -> 9).
  std::vector<double> two(21, 0.0);
  two[2] = 10;
  two[17] = 40;
  EXPECT_EQ(ms::breakPoint(two, 0, 20), 9);
  // Two-level set: psi = lo always.
  EXPECT_EQ(ms::breakPoint({5, 3}, 7, 8), 7);
  EXPECT_EQ(ms::breakPoint({0, 0}, 7, 8), 7);
  EXPECT_EQ(ms::breakPoint({0, 9}, 7, 8), 7);
  EXPECT_EQ(ms::breakPoint({9, 0}, 7, 8), 7);
  // Three levels, the outer two occupied: the empty middle level.
  EXPECT_EQ(ms::breakPoint({4, 0, 4}, 0, 2), 1);
}

TEST(BreakPoint, InvalidArguments) {
  EXPECT_THROW(ms::breakPoint({1, 2, 3}, 5, 5), std::invalid_argument);
  EXPECT_THROW(ms::breakPoint({1, 2, 3}, 6, 4), std::invalid_argument);
  EXPECT_THROW(ms::breakPoint({1, 2, 3}, 0, 3), std::invalid_argument);
  EXPECT_THROW(ms::breakPoint({1, 2, 3}, 0, 1), std::invalid_argument);
  EXPECT_THROW(ms::breakPoint({1, -2, 3}, 0, 2), std::invalid_argument);
  EXPECT_THROW(ms::breakPoint({}, 0, 1), std::invalid_argument);
}

// -------------------------------------------------------------- validation --

void expectInvalid(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no exception, expected one mentioning '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  } catch (...) {
    ADD_FAILURE() << "wrong exception type";
  }
}

TEST(CostVolumeValidation, RejectsBadInput) {
  const cv::Mat L = randomImage(20, 10, CV_8UC3, 21), R = randomImage(20, 10, CV_8UC3, 22);
  const ms::CostParams ok = params(0, 5, 20.0f, 5);
  EXPECT_NO_THROW(ms::computeCostVolume(L, R, ok));
  expectInvalid([&] { ms::computeCostVolume(cv::Mat(), R, ok); }, "empty");
  expectInvalid([&] { ms::computeCostVolume(L, cv::Mat(), ok); }, "empty");
  expectInvalid([&] { ms::computeCostVolume(L, randomImage(21, 10, CV_8UC3, 1), ok); }, "sizes differ");
  expectInvalid([&] { ms::computeCostVolume(L, grey(R), ok); }, "types differ");
  expectInvalid([&] { ms::computeCostVolume(cv::Mat(10, 20, CV_32FC1, 1.0f), cv::Mat(10, 20, CV_32FC1, 1.0f), ok); },
                "unsupported image type");
  expectInvalid([&] { ms::computeCostVolume(cv::Mat(10, 20, CV_8UC4), cv::Mat(10, 20, CV_8UC4), ok); },
                "unsupported image type");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(6, 5, 20.0f, 5)); }, "dmax < dmin");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(-1, 5, 20.0f, 5)); }, "dmin < 0");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 20, 20.0f, 5)); }, "disparity range wider than the image");
  EXPECT_NO_THROW(ms::computeCostVolume(L, R, params(0, 19, 20.0f, 5)));
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, 20.0f, 4)); }, "ncc_window");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, 20.0f, 0)); }, "ncc_window");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, 20.0f, -3)); }, "ncc_window");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, 20.0f, 11)); }, "ncc_window");  // > height 10
  EXPECT_NO_THROW(ms::computeCostVolume(L, R, params(0, 5, 20.0f, 9)));
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, 0.0f, 5)); }, "eta");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, -1.0f, 5)); }, "eta");
  expectInvalid([&] { ms::computeCostVolume(L, R, params(0, 5, std::numeric_limits<float>::quiet_NaN(), 5)); }, "eta");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
