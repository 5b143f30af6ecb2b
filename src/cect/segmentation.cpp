// CECT step 1: the back in one view (see segmentation.h).
//
// Design (ours; the thesis extract only names the step):
//
// * Chroma: log-chromaticity of the encoded 8-bit values,
//     u = ln(R + k) - ln(G + k),  v = ln(G + k) - ln(B + k)   (k = kLogOffset).
//   Scaling R, G, B together (brighter or dimmer light, shading, a cast
//   shadow: with a gamma-encoded image this is still a common factor) leaves
//   u and v unchanged, so brightness plays no part. Skin of every tone is
//   reddish-orange: R > G > B, u > 0 and v > 0; darker skin is more
//   saturated, not a different hue. The small offset k pulls very dark
//   (noisy) pixels toward neutral. Chroma is blurred by blur_sigma.
//
// * Detection (stage A, on a copy reduced to ~kDetectionRows rows for
//   speed): a skin-likelihood l = u + v (= ln(R/B)), lowered where the hue
//   leaves the skin sector (u < 0: yellow-green, v < 0: magenta). The
//   threshold is chosen per image by Otsu on the histogram of l, then Otsu
//   again inside the upper class for as long as that class is itself clearly
//   bimodal (Otsu separability >= kBimodal): skin is the most chromatic
//   distinct class. (A single Otsu fails on pale skin: a neutral sheet, a
//   warm grey floor and pale skin are three classes and the floor goes with
//   the skin.) The largest region above the threshold is the detection;
//   when the most chromatic class holds no region of min_area_fraction
//   (only red hair or a coloured cushion), the previous threshold's. Pixels
//   the caller marks as background (depth_gate.h: the floor) take no part.
//   Priors reject images without skin: the region must be at least
//   kMinSkinChroma red (median ln(R/B)) and about uniform in chroma (skin
//   is; a multi-coloured texture is not), and cover min_area_fraction.
//
// * Score (stage B, full size): a two-class linear fit of the back against
//   its own surroundings. mu_s = median chroma of the detection's core,
//   mu_b = median chroma of a ring just outside it (sheet, cast shadow);
//     score = (c - (mu_s + mu_b) / 2) . (mu_s - mu_b) / |mu_s - mu_b|^2,
//   +0.5 on the back's skin, -0.5 on its surroundings, 0 half way. The
//   score is linear in the chroma, so it is computed per pixel from three
//   look-up tables and then blurred (= blurring the chroma). A blurred step
//   between the two sides crosses its mid-value exactly at the step: the
//   zero crossing is an unbiased, sub-pixel border (a global threshold would
//   not be: for pale skin the mid-value between skin and sheet is a warm
//   grey, the floor's colour).
//
// * Mask: score > 0, opened and closed (elliptical kernels); pieces of the
//   back that a thin band across it split (a strap, a seam, a row of paper
//   tags: gap_join.h) joined again once the arms are cut off (trunk.h); of
//   the resulting regions (outer contours, drawn filled: holes filled) the one
//   holding most of the detection. The score is then made to agree with the
//   mask in sign (see segmentation.h), so zero crossings are exactly the
//   back's border.
//
// * Contour: that region's outer contour (one sample per boundary pixel),
//   smoothed circularly with a Gaussian, resampled uniformly by arc length,
//   oriented counter-clockwise as seen on the image, each sample moved along
//   its normal onto the score's zero crossing (the pixel contour runs through
//   the centres of the boundary pixels, ~0.5 px inside the border).
#include "massage_cell/cect/segmentation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "gap_join.h"
#include "stats_detail.h"

namespace massage_cell::cect {

namespace {

/// Grey levels added before taking logarithms: keeps ln finite at 0 and
/// pulls the chroma of very dark, noisy pixels toward neutral.
constexpr double kLogOffset = 2.0;
/// Weight of the hue-sector penalty in the detection likelihood.
constexpr double kHuePenalty = 2.0;
/// Histogram of the detection likelihood: range and bins.
constexpr double kHistLow = -0.5, kHistHigh = 1.0;
constexpr int kHistBins = 300;
/// Otsu separability (between-class / total variance) above which a class
/// counts as two (a single Gaussian gives 0.64, a uniform spread 0.75).
constexpr double kBimodal = 0.8;
/// Weakest skin: median ln(R/B) of the detected class (encoded values). The
/// palest rendered subjects are ~0.18, the warm grey floor ~0.08, neutral 0.
constexpr double kMinSkinChroma = 0.12;
/// Weakest accepted chroma difference between the back and its surroundings.
constexpr double kMinContrast = 0.06;
/// Most chroma spread inside the detected region (robust sigma (1.4826 MAD) of its core pixels' score, each pixel's
/// own (u, v), in units of the back/surroundings difference) for it to count as skin. Measured (CECT_SPREAD_LOG, a
/// throwaway print in skinModel, issue 59 item 7): skin at most 0.107 (the back with a strap across it,
/// RealBacks.AStrapAcrossTheBack...; every other back of test/cect's test_segmentation, test_real_backs, test_cect,
/// test_robustness <= 0.080, the darkest synthetic skin) and at most 0.079 over 30 rendered pairs (both views) of
/// `cect_eval --experiments real --conditions dark_skin,towel,photo,skin_marks,mixed,arms_touching
/// --condition-subjects 5`; what it rejects: the warm multi-chroma texture of SegmentBack.NoSubjectIsNotValid, 0.224
/// (the boxes and the empty table fail earlier, on kMinSkinChroma). The whole `cect_eval --experiments real
/// --condition-subjects 28 --given-landmarks 5` then refused two `photo` pairs (subjects 8 and 21: motion blur and
/// JPEG) at 0.16 against a first 0.15: 0.19 lies ~1.2x above that and ~1.2x below the texture, which the margins
/// are thin for on both sides (a photo's blur spreads the skin's chroma); photos of real backs should be measured.
/// It does not see a skin-coloured sheet joined to a pale back (RealBacks.ASheetOfSkins...:
/// 0.080-0.082, the sheet under half the core, which a median deviation ignores: kMaxSkinOtherDistance does); the
/// former 0.2 was tuned on a statistic that paired one pixel's u with another's v (0.31 there).
constexpr double kMaxSkinSpread = 0.19;
/// A second material of skin's colour in the detected region, beside the skin (a beige sheet or towel the region ran
/// on into): the kSkinOtherQuantile quantile of the core pixels' chroma distance from the core's median chroma (both
/// axes, each pixel's own (u, v), in units of the back/surroundings difference) is at most kMaxSkinOtherDistance for
/// skin, i.e. at most a fifth of the core is half the contrast or more from the skin's chroma. Measured (a throwaway
/// print in skinModel, same scenes as kMaxSkinSpread), the 0.8 quantile: skin at most 0.274 (the strap across the
/// back, RealBacks.AStrapAcrossTheBack...; every other view of a back in test/cect's test_segmentation,
/// test_real_backs, test_cect, test_robustness, ~230, <= 0.189) and at most 0.184 over the 30 rendered pairs of
/// `cect_eval --experiments real --conditions dark_skin,towel,photo,skin_marks,mixed,arms_touching
/// --condition-subjects 5`; the beige sheet joined to a pale back (RealBacks.ASheetOfSkins..., colour alone: the
/// sheet is 34-35 % of the core) 1.01-1.06; the warm texture 0.41 (rejected by kMaxSkinSpread first). 0.5 lies 1.8x
/// above the most spread skin and 2.0x below the sheet. (The same check as a share: skin has at most 7.9 % of its
/// core beyond 0.5 (photo), 2.8 % in the tests; the sheet 34-35 %.) The distance must be 2-D: along the score's
/// direction alone the sheet's 0.8 quantile is 0.37-0.41 against skin's 0.27 (the sheet differs from skin mostly
/// across it). What did not separate: a two-cluster k-means (its clusters' separation over their spread is 3.5 on
/// the sheet, 1.4-47 on skin, highest with hair or skin markers in view). The distance is relative: in absolute chroma
/// the sheet's 0.066 lies below the strapped back's 0.085; the sheet's scene has the least contrast (0.062-0.065,
/// skin's scenes >= 0.106). A minority under a fifth of the core passes.
constexpr double kSkinOtherQuantile = 0.8;
constexpr double kMaxSkinOtherDistance = 0.5;
/// Detection runs on a copy with about this many rows (or the full image if smaller).
constexpr int kDetectionRows = 240;
/// Contour samples move onto the score's zero crossing along their normal,
/// searched this far either side (pixels) in steps of kSnapStep.
constexpr double kSnapReach = 2.0;
constexpr double kSnapStep = 0.25;
/// Highest score of skin: the back's own chroma scores +0.5, its spread
/// (robust sigma) is below kMaxSkinSpread.
constexpr float kMaxScore = 2.5f;
/// fillRaisedSkin: height above the surroundings (metres), lowest score, and
/// inset from the raised region's edge (fraction of the image's rows).
constexpr double kRaise = 0.05;
constexpr float kFillMinScore = -0.3f;
constexpr double kFillInset = 1.0 / 60.0;
/// Score given to pixels whose sign had to be forced to agree with the mask.
constexpr float kForcedScore = 0.5f;
// The smallest piece of skin that may be joined to another across a thin band
// (gap_join.h), as a share of the image: the neck and shoulders above a strap
// at T1 in a view down to the buttocks are ~2 %.
constexpr double kMinPieceShare = 0.01;

// The skin model's medians are the upper middle sample of an even count (its thresholds were tuned with that).
using detail::median;  // stats_detail.h
constexpr detail::EvenCount kUpperMiddle = detail::EvenCount::kUpperMiddle;

struct OtsuSplit {
  int bin = -1;             ///< first bin of the upper class; -1 when the range cannot be split
  double separability = 0;  ///< between-class / total variance
  double upper_mass = 0;    ///< pixels in the upper class
};

/// Otsu's split of the histogram bins [begin, end).
OtsuSplit otsu(const std::vector<double>& hist, int begin, int end) {
  double n = 0, sum = 0, sum2 = 0;
  for (int i = begin; i < end; ++i) {
    n += hist[i];
    sum += i * hist[i];
    sum2 += double(i) * i * hist[i];
  }
  OtsuSplit best;
  if (n <= 0) return best;
  const double total_var = sum2 / n - (sum / n) * (sum / n);
  double n0 = 0, s0 = 0, best_between = -1;
  for (int k = begin + 1; k < end; ++k) {
    n0 += hist[k - 1];
    s0 += (k - 1) * hist[k - 1];
    const double n1 = n - n0;
    if (n0 <= 0 || n1 <= 0) continue;
    const double d = s0 / n0 - (sum - s0) / n1;
    const double between = n0 * n1 * d * d / (n * n);
    if (between > best_between) {
      best_between = between;
      best.bin = k;
      best.upper_mass = n1;
    }
  }
  if (best.bin >= 0 && total_var > 0) best.separability = best_between / total_var;
  return best;
}

/// Bilinear sample of a CV_32F image; false outside [0, cols-1] x [0, rows-1].
bool sampleBilinear(const cv::Mat& img, double x, double y, double* value) {
  if (!(x >= 0.0 && y >= 0.0 && x <= img.cols - 1 && y <= img.rows - 1)) return false;
  const int x0 = std::min(static_cast<int>(x), img.cols - 1), y0 = std::min(static_cast<int>(y), img.rows - 1);
  const int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  const double fx = x - x0, fy = y - y0;
  const float* r0 = img.ptr<float>(y0);
  const float* r1 = img.ptr<float>(y1);
  *value = (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x1]);
  return true;
}

/// Gaussian smoothing of a closed polyline along its samples (circular).
std::vector<cv::Point2d> smoothClosed(const std::vector<cv::Point>& pts, double sigma) {
  const int n = static_cast<int>(pts.size());
  std::vector<cv::Point2d> out(pts.begin(), pts.end());
  if (sigma <= 0.0 || n < 3) return out;
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<double> w(static_cast<std::size_t>(2 * radius + 1));
  double wsum = 0;
  for (int k = -radius; k <= radius; ++k)
    wsum += w[static_cast<std::size_t>(k + radius)] = std::exp(-0.5 * k * k / (sigma * sigma));
  for (double& x : w) x /= wsum;
  for (int i = 0; i < n; ++i) {
    cv::Point2d acc(0, 0);
    for (int k = -radius; k <= radius; ++k) {
      const int j = ((i + k) % n + n) % n;
      acc += w[static_cast<std::size_t>(k + radius)] * cv::Point2d(pts[static_cast<std::size_t>(j)]);
    }
    out[static_cast<std::size_t>(i)] = acc;
  }
  return out;
}

/// Uniform resampling of a closed polyline by arc length: round(L / spacing)
/// samples (at least 3), the first at pts[0].
std::vector<cv::Point2f> resampleClosed(const std::vector<cv::Point2d>& pts, double spacing) {
  const std::size_t n = pts.size();
  std::vector<double> cum(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) cum[i + 1] = cum[i] + cv::norm(pts[(i + 1) % n] - pts[i]);
  const double length = cum[n];
  std::vector<cv::Point2f> out;
  if (n == 0 || length <= 0.0) return out;
  const int count = std::max(3, static_cast<int>(std::lround(length / spacing)));
  const double step = length / count;
  out.reserve(static_cast<std::size_t>(count));
  std::size_t seg = 0;
  for (int j = 0; j < count; ++j) {
    const double s = j * step;
    while (seg + 1 < n && cum[seg + 1] <= s) ++seg;
    const double len = cum[seg + 1] - cum[seg];
    const double t = len > 0 ? (s - cum[seg]) / len : 0.0;
    const cv::Point2d p = pts[seg] + t * (pts[(seg + 1) % n] - pts[seg]);
    out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  }
  return out;
}

/// Moves each contour sample along its normal onto the score's zero
/// crossing nearest to it (within kSnapReach pixels); samples with no
/// crossing there (on the image border) stay. Expects the contour
/// counter-clockwise as seen on the image (interior on the left).
void snapToCrossings(const cv::Mat& score, std::vector<cv::Point2f>* contour) {
  const std::size_t n = contour->size();
  if (n < 3) return;
  const std::vector<cv::Point2f> in = *contour;
  constexpr int kSteps = static_cast<int>(2 * kSnapReach / kSnapStep);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point2f t = in[(i + 1) % n] - in[(i + n - 1) % n];
    const double len = std::hypot(t.x, t.y);
    if (len <= 0) continue;
    const double nx = -t.y / len, ny = t.x / len;  // outward: the interior is on (t.y, -t.x)
    double best = std::numeric_limits<double>::infinity(), prev_s = 0, prev_t = 0;
    bool have_prev = false;
    for (int k = 0; k <= kSteps; ++k) {
      const double tt = -kSnapReach + k * kSnapStep;
      double s;
      if (!sampleBilinear(score, in[i].x + tt * nx, in[i].y + tt * ny, &s)) {
        have_prev = false;
        continue;
      }
      if (have_prev && prev_s > 0 && s <= 0) {  // leaving the back walking outward
        const double at = prev_t + (tt - prev_t) * prev_s / (prev_s - s);
        if (std::abs(at) < std::abs(best)) best = at;
      }
      prev_s = s;
      prev_t = tt;
      have_prev = true;
    }
    if (std::isfinite(best)) {
      (*contour)[i] = cv::Point2f(static_cast<float>(in[i].x + best * nx), static_cast<float>(in[i].y + best * ny));
    }
  }
}

/// Shoelace area in image coordinates (negative: counter-clockwise as seen on the image).
double signedArea(const std::vector<cv::Point2f>& c) {
  double a = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const cv::Point2f& p = c[i];
    const cv::Point2f& q = c[(i + 1) % c.size()];
    a += static_cast<double>(p.x) * q.y - static_cast<double>(q.x) * p.y;
  }
  return 0.5 * a;
}

std::string percent(double fraction) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f%%", 100.0 * fraction);
  return buf;
}

Segmentation invalid(const cv::Size& size, const std::string& reason) {
  Segmentation s;
  s.valid = false;
  s.reason = reason;
  s.score = cv::Mat(size, CV_32F, cv::Scalar(-kForcedScore));
  s.mask = cv::Mat::zeros(size, CV_8U);
  return s;
}

/// Opening or closing of a binary mask with a disk of `radius` (0: none), as
/// if the image continued beyond its edges by replicating them: a region
/// that touches the edge keeps its extent there, and the gap between a
/// region and the edge is not closed (what lies beyond is unknown).
void morphology(cv::Mat* mask, cv::MorphTypes op, int radius) {
  if (radius <= 0) return;
  const cv::Mat disk = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
  cv::Mat padded;
  cv::copyMakeBorder(*mask, padded, radius, radius, radius, radius, cv::BORDER_REPLICATE);
  cv::morphologyEx(padded, padded, op, disk);
  padded(cv::Rect(radius, radius, mask->cols, mask->rows)).copyTo(*mask);
}

/// The detection's candidate thresholds (histogram bins), most chromatic
/// first: Otsu, then Otsu inside the upper class while it is clearly two
/// classes (skin is the most chromatic distinct class); then, for when that
/// class is only scattered patches (red hair, a coloured cushion, split off
/// first), the chain's earlier splits and up to two Otsu splits inside the
/// lower class (skin and sheet below the hair). Empty for a single colour.
std::vector<int> skinThresholds(const std::vector<double>& hist, double min_pixels) {
  std::vector<OtsuSplit> chain{otsu(hist, 0, kHistBins)};
  if (chain.back().bin < 0) return {};
  for (;;) {
    const OtsuSplit up = otsu(hist, chain.back().bin, kHistBins);
    if (up.bin < 0 || up.separability < kBimodal || up.upper_mass < min_pixels) break;
    chain.push_back(up);
  }
  std::vector<int> bins;
  for (auto k = chain.rbegin(); k != chain.rend(); ++k) bins.push_back(k->bin);
  for (int extra = 0; extra < 2; ++extra) {
    const OtsuSplit lower = otsu(hist, 0, bins.back());
    if (lower.bin <= 0) break;
    bins.push_back(lower.bin);
  }
  return bins;
}

/// The largest 8-connected component of `binary`: its label in `labels`
/// (CV_32S), its area (0, label 0 when there is none).
void largestComponent(const cv::Mat& binary, cv::Mat* labels, int* best, int* area) {
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(binary, *labels, stats, centroids, 8, CV_32S);
  *best = 0;
  *area = 0;
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) > *area) {
      *area = stats.at<int>(i, cv::CC_STAT_AREA);
      *best = i;
    }
  }
}

/// Skin whose chroma the light's sheen has pulled toward the surroundings'
/// (dark skin under a light above it): pixels standing kRaise or more above
/// the surroundings' depth `ring_depth` (the table), or enclosed by such
/// pixels (the highlight itself matches too far), and not clearly of the
/// surroundings' colour (score above kFillMinScore; and not beyond skin,
/// kMaxScore) join the mask, eroded by
/// kFillInset of the image's rows so that the coarse depth never sets the
/// border where the colour can.
void fillRaisedSkin(const cv::Mat& score, const cv::Mat& depth, double ring_depth, cv::Mat* mask) {
  cv::Mat raised = depth < static_cast<float>(ring_depth - kRaise);
  // With the holes of the raised region: a highlight on the skin is a
  // virtual image of the light behind the surface, and stereo puts it (and
  // the sheen around it) too far away, but it lies inside the body.
  cv::Mat outside;
  cv::copyMakeBorder(~raised, outside, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(255));
  cv::floodFill(outside, cv::Point(0, 0), cv::Scalar(0));
  raised |= outside(cv::Rect(1, 1, raised.cols, raised.rows));
  raised &= (score > kFillMinScore) & (score < kMaxScore);
  const int inset = std::max(1, static_cast<int>(std::lround(kFillInset * depth.rows)));
  cv::erode(raised, raised, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * inset + 1, 2 * inset + 1)));
  *mask |= raised;
}

using LogTable = std::array<float, 256>;

/// Stage A: the most chromatic large region on a reduced copy (about kDetectionRows rows).
struct Detection {
  std::string problem;  ///< non-empty: no back in view, and why
  int factor = 1;       ///< full-size pixels per reduced pixel
  cv::Mat uv;           ///< CV_32FC2 (u, v) chroma of the reduced copy, blurred
  cv::Mat region;       ///< CV_8U, the detected region on the reduced copy
  int area = 0;         ///< its pixels
};

Detection detectSkinRegion(const cv::Mat& bgr, const SegmentationParams& params, const cv::Mat& background,
                           const LogTable& log_table) {
  Detection d;
  // Chroma of the reduced image, blurred by blur_sigma (in full-size pixels).
  d.factor = std::max(1, bgr.rows / kDetectionRows);
  cv::Mat bgr_small = bgr;
  if (d.factor > 1) {
    cv::resize(bgr, bgr_small, cv::Size(bgr.cols / d.factor, bgr.rows / d.factor), 0, 0, cv::INTER_AREA);
  }
  const cv::Size small = bgr_small.size();
  d.uv.create(small, CV_32FC2);  // (u, v) = (ln R - ln G, ln G - ln B)
  for (int y = 0; y < small.height; ++y) {
    const cv::Vec3b* p = bgr_small.ptr<cv::Vec3b>(y);
    cv::Vec2f* c = d.uv.ptr<cv::Vec2f>(y);
    for (int x = 0; x < small.width; ++x) {
      const float lb = log_table[p[x][0]], lg = log_table[p[x][1]], lr = log_table[p[x][2]];
      c[x] = cv::Vec2f(lr - lg, lg - lb);
    }
  }
  const double sigma_small = params.blur_sigma / d.factor;
  if (sigma_small > 0.0) cv::GaussianBlur(d.uv, d.uv, cv::Size(), sigma_small, sigma_small, cv::BORDER_REPLICATE);

  // Detection likelihood and its histogram (known background left out).
  cv::Mat background_small;
  if (!background.empty()) cv::resize(background, background_small, small, 0, 0, cv::INTER_NEAREST);
  cv::Mat like(small, CV_32F);
  std::vector<double> hist(kHistBins, 0.0);
  const double bin_scale = kHistBins / (kHistHigh - kHistLow);
  for (int y = 0; y < small.height; ++y) {
    const cv::Vec2f* c = d.uv.ptr<cv::Vec2f>(y);
    float* l = like.ptr<float>(y);
    const unsigned char* bg = background_small.empty() ? nullptr : background_small.ptr<unsigned char>(y);
    for (int x = 0; x < small.width; ++x) {
      if (bg && bg[x]) {
        l[x] = static_cast<float>(kHistLow) - 1.0f;  // below every threshold, not in the histogram
        continue;
      }
      const float u = c[x][0], v = c[x][1];
      l[x] = u + v + static_cast<float>(kHuePenalty) * (std::min(u, 0.f) + std::min(v, 0.f));
      const int b = std::clamp(static_cast<int>((l[x] - kHistLow) * bin_scale), 0, kHistBins - 1);
      hist[static_cast<std::size_t>(b)] += 1.0;
    }
  }
  const double min_pixels = params.min_area_fraction * small.area();
  const std::vector<int> bins = skinThresholds(hist, min_pixels);
  if (bins.empty()) {
    d.problem = "no back in view: the image has a single colour";
    return d;
  }
  // The largest region above the most chromatic class's threshold; when that
  // class is only scattered patches, the next threshold's.
  cv::Mat cc_labels;
  int best = 0, top_area = -1;
  for (const int bin : bins) {
    largestComponent(like > static_cast<float>(kHistLow + bin / bin_scale), &cc_labels, &best, &d.area);
    if (top_area < 0) top_area = d.area;
    if (d.area >= min_pixels) break;
  }
  if (d.area < min_pixels) {
    d.problem = "no back in view: the largest skin-coloured region covers " + percent(double(top_area) / small.area()) +
                " of the image (at least " + percent(params.min_area_fraction) + " needed)";
    return d;
  }
  d.region = cc_labels == best;
  return d;
}

/// Stage B: the back's skin against its own surroundings, as a linear chroma score
/// w . (u, v) + bias that is +0.5 on the skin and -0.5 around it.
struct SkinModel {
  std::string problem;                                           ///< non-empty: no back in view, and why
  cv::Vec2d w;                                                   ///< score weights of (u, v)
  double bias = 0.0;                                             ///< score offset
  double ring_depth = std::numeric_limits<double>::quiet_NaN();  ///< median depth around the region (with depth)
};

/// Chroma samples of the region, its core, the ring just outside it and all beyond the transition.
struct ChromaSamples {
  std::vector<float> sl, su, sv, bu, bv, ou, ov;
  std::vector<float> ring_depth;  ///< the ring's depths (with a depth map)
};

ChromaSamples sampleChroma(const Detection& d, const SegmentationParams& params, const cv::Mat& depth, cv::Size size) {
  // Its core (beyond the blurred transition) and a ring just outside it.
  // (Square neighbourhoods: rectangular erosion / dilation are cheap.)
  const int transition = static_cast<int>(std::ceil((3.0 * params.blur_sigma + 1.0) / d.factor)) + 1;
  const int ring_width = std::max(4, 2 * transition);
  auto square = [](int r) { return cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * r + 1, 2 * r + 1)); };
  cv::Mat core, near_region, ring_outer;
  cv::erode(d.region, core, square(transition));
  cv::dilate(d.region, near_region, square(transition));
  cv::dilate(d.region, ring_outer, square(transition + ring_width));
  // Every `stride`-th pixel is enough for the medians (a few thousand samples).
  const int stride = std::max(1, static_cast<int>(std::sqrt(d.area / 4000.0)));
  ChromaSamples s;
  for (int y = 0; y < d.uv.rows; y += stride) {
    const cv::Vec2f* c = d.uv.ptr<cv::Vec2f>(y);
    const unsigned char* in_region = d.region.ptr<unsigned char>(y);
    const unsigned char* in_core = core.ptr<unsigned char>(y);
    const unsigned char* in_near = near_region.ptr<unsigned char>(y);
    const unsigned char* in_ring = ring_outer.ptr<unsigned char>(y);
    for (int x = 0; x < d.uv.cols; x += stride) {
      if (in_region[x]) s.sl.push_back(c[x][0] + c[x][1]);
      if (in_core[x]) {
        s.su.push_back(c[x][0]);
        s.sv.push_back(c[x][1]);
      } else if (!in_near[x]) {
        if (in_ring[x]) {
          s.bu.push_back(c[x][0]);
          s.bv.push_back(c[x][1]);
          if (!depth.empty()) {
            const float z = depth.at<float>(std::min(y * d.factor + d.factor / 2, size.height - 1),
                                            std::min(x * d.factor + d.factor / 2, size.width - 1));
            if (std::isfinite(z)) s.ring_depth.push_back(z);
          }
        }
        s.ou.push_back(c[x][0]);
        s.ov.push_back(c[x][1]);
      }
    }
  }
  return s;
}

SkinModel skinModel(const Detection& d, const SegmentationParams& params, const cv::Mat& depth, cv::Size size) {
  SkinModel m;
  ChromaSamples s = sampleChroma(d, params, depth, size);
  // Nothing sampled: no skin (0 is below the threshold; the median of nothing is NaN, which is below nothing).
  const double skin_chroma = s.sl.empty() ? 0.0 : median(s.sl, kUpperMiddle);
  if (skin_chroma < kMinSkinChroma) {
    char buf[160];
    std::snprintf(buf, sizeof(buf),
                  "no back in view: no skin-coloured region (the most chromatic region has ln(R/B) = %.3f, skin "
                  "needs %.2f)",
                  skin_chroma, kMinSkinChroma);
    m.problem = buf;
    return m;
  }
  if (s.su.size() < 10) {
    m.problem = "no back in view: the skin-coloured region is too thin";
    return m;
  }
  if (s.bu.size() < 10) {  // nothing around the region (it fills the view): use whatever is outside
    s.bu = std::move(s.ou);
    s.bv = std::move(s.ov);
  }
  if (s.bu.size() < 10) {
    m.problem = "no back in view: skin colour everywhere, no surroundings to tell it from";
    return m;
  }
  const cv::Vec2d mu_s(median(s.su, kUpperMiddle), median(s.sv, kUpperMiddle)),
      mu_b(median(s.bu, kUpperMiddle), median(s.bv, kUpperMiddle));
  const cv::Vec2d diff = mu_s - mu_b;
  const double contrast = cv::norm(diff);
  if (contrast < kMinContrast) {
    m.problem = "no back in view: the skin-coloured region hardly differs from its surroundings";
    return m;
  }
  // score = w . (u, v) + bias: +0.5 at mu_s, -0.5 at mu_b.
  m.w = diff / (contrast * contrast);
  m.bias = -0.5 * (mu_s + mu_b).dot(m.w);
  // Skin is uniform in chroma: robust spread (MAD) of the core's score, each pixel's own (u, v) (su[i], sv[i]: one
  // core pixel; median() works on a copy).
  std::vector<float> core_score(s.su.size());
  for (std::size_t i = 0; i < s.su.size(); ++i) core_score[i] = static_cast<float>(m.w[0] * s.su[i] + m.w[1] * s.sv[i]);
  const double med = median(core_score, kUpperMiddle);
  for (float& x : core_score) x = static_cast<float>(std::abs(x - med));
  const double spread = 1.4826 * median(core_score, kUpperMiddle);
  if (spread > kMaxSkinSpread) {
    char buf[160];
    std::snprintf(buf, sizeof(buf),
                  "no back in view: the skin-coloured region is multi-coloured (chroma spread %.2f of its "
                  "contrast to the surroundings, skin has less than %.2f)",
                  spread, kMaxSkinSpread);
    m.problem = buf;
    return m;
  }
  // A second material of skin's colour joined to the skin (a beige sheet) is a minority of the core the median
  // spread above ignores: the core's kSkinOtherQuantile of distances (both chroma axes) from the core's chroma.
  std::vector<float> distance(s.su.size());
  for (std::size_t i = 0; i < s.su.size(); ++i)
    distance[i] = static_cast<float>(std::hypot(s.su[i] - mu_s[0], s.sv[i] - mu_s[1]) / contrast);
  const double other = detail::quantile(std::move(distance), kSkinOtherQuantile, detail::QuantileIndex::kRoundedOfSpan);
  if (other > kMaxSkinOtherDistance) {
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "no back in view: the skin-coloured region is multi-coloured (%.0f %% of its core lies %.2f or more "
                  "of its contrast to the surroundings from its chroma, skin less than %.2f: a second material of "
                  "skin's colour, a sheet or towel?)",
                  100.0 * (1.0 - kSkinOtherQuantile), other, kMaxSkinOtherDistance);
    m.problem = buf;
    return m;
  }
  if (s.ring_depth.size() >= 10) m.ring_depth = median(s.ring_depth, kUpperMiddle);
  return m;
}

/// The full-size score. It is linear in (u, v), so blurring the score is blurring the chroma:
/// score = TR[R] + TG[G] + TB[B], then the Gaussian.
cv::Mat scoreImage(const cv::Mat& bgr, const SkinModel& model, const LogTable& log_table, double blur_sigma) {
  std::array<float, 256> tr, tg, tb;
  for (std::size_t i = 0; i < 256; ++i) {
    tr[i] = static_cast<float>(model.w[0] * log_table[i]);
    tg[i] = static_cast<float>((model.w[1] - model.w[0]) * log_table[i]);
    tb[i] = static_cast<float>(-model.w[1] * log_table[i] + model.bias);
  }
  cv::Mat score(bgr.size(), CV_32F);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
    float* s = score.ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x) s[x] = tb[p[x][0]] + tg[p[x][1]] + tr[p[x][2]];
  }
  if (blur_sigma > 0.0) cv::GaussianBlur(score, score, cv::Size(), blur_sigma, blur_sigma, cv::BORDER_REPLICATE);
  return score;
}

/// Of the cleaned mask's regions (holes filled), the one holding most of the detection: its mask and outer border.
struct Back {
  std::string problem;  ///< non-empty: no back in view, and why
  cv::Mat mask;
  std::vector<cv::Point> border;
};

Back chooseBack(cv::Mat& m, const Detection& d, const SegmentationParams& params) {
  Back back;
  const cv::Size size = m.size();
  // Outer contours of the cleaned regions (holes ignored, i.e. filled), each drawn filled with its own label.
  std::vector<std::vector<cv::Point>> outer;
  cv::findContours(m, outer, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::vector<std::pair<double, int>> candidates;  // (area, index), largest first, at most 255
  double largest = 0.0;
  for (std::size_t i = 0; i < outer.size(); ++i) {
    const double a = cv::contourArea(outer[i]);
    largest = std::max(largest, a);
    if (a >= params.min_area_fraction * size.area()) candidates.emplace_back(a, static_cast<int>(i));
  }
  if (candidates.empty()) {
    back.problem = "no back in view: the largest skin region covers " + percent(largest / size.area()) +
                   " of the image (at least " + percent(params.min_area_fraction) + " needed)";
    return back;
  }
  std::sort(candidates.begin(), candidates.end(), std::greater<>());
  if (candidates.size() > 255) candidates.resize(255);
  // Label image: candidate k (0-based) drawn with value k + 1, or 255 when
  // there is a single candidate (then the label image is the mask itself).
  const bool single = candidates.size() == 1;
  cv::Mat labels = single ? cv::Mat(size, CV_8U, cv::Scalar(0)) : m;
  if (!single) labels.setTo(0);
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    cv::drawContours(labels, outer, candidates[k].second, cv::Scalar(single ? 255.0 : double(k + 1)), cv::FILLED,
                     cv::LINE_8);
  }
  std::array<int, 256> overlap{};
  for (int y = 0; y < d.region.rows; ++y) {
    const unsigned char* r = d.region.ptr<unsigned char>(y);
    const unsigned char* lab = labels.ptr<unsigned char>(std::min(y * d.factor + d.factor / 2, size.height - 1));
    for (int x = 0; x < d.region.cols; ++x) {
      if (r[x]) ++overlap[lab[std::min(x * d.factor + d.factor / 2, size.width - 1)]];
    }
  }
  overlap[0] = 0;
  const auto label = std::max_element(overlap.begin(), overlap.end()) - overlap.begin();
  if (overlap[static_cast<std::size_t>(label)] == 0) {
    back.problem = "no back in view: the skin-coloured region does not survive the cleaning";
    return back;
  }
  const std::size_t chosen = single ? 0 : static_cast<std::size_t>(label - 1);
  back.border = outer[static_cast<std::size_t>(candidates[chosen].second)];
  back.mask = single ? labels : (labels == static_cast<double>(label));
  return back;
}

/// The score agrees with the mask in sign: holes and pixels the closing added become positive; pixels the opening
/// removed and skin elsewhere (other regions) negative. Untouched where the two already agree.
void agreeWithMask(const cv::Mat& mask, cv::Mat* score) {
  for (int y = 0; y < mask.rows; ++y) {
    float* s = score->ptr<float>(y);
    const unsigned char* mk = mask.ptr<unsigned char>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (mk[x]) {
        if (!(s[x] > 0.f)) s[x] = kForcedScore;
      } else if (!(s[x] < 0.f)) {
        s[x] = -kForcedScore;
      }
    }
  }
}

/// The contour: smoothed, resampled, counter-clockwise, on the score's zero crossing; and the fraction of it on
/// the image's border.
void traceContour(const std::vector<cv::Point>& border, const SegmentationParams& params, Segmentation* seg) {
  const cv::Size size = seg->score.size();
  seg->contour = resampleClosed(smoothClosed(border, params.contour_smoothing), std::max(params.contour_spacing, 0.1));
  if (signedArea(seg->contour) > 0) {  // clockwise as seen on the image: reverse, keeping the first sample
    std::reverse(seg->contour.begin() + 1, seg->contour.end());
  }
  snapToCrossings(seg->score, &seg->contour);
  int on_border = 0;
  const float margin = static_cast<float>(params.border_margin);
  for (const cv::Point2f& p : seg->contour) {
    const float to_border = std::min(std::min(p.x, p.y), std::min(size.width - 1 - p.x, size.height - 1 - p.y));
    if (to_border < margin) ++on_border;
  }
  seg->border_fraction = seg->contour.empty() ? 0.0 : double(on_border) / seg->contour.size();
}

}  // namespace

Segmentation segmentBack(const cv::Mat& bgr, const SegmentationParams& params, const cv::Mat& background,
                         const cv::Mat& depth, const cv::Mat& marks) {
  if (bgr.empty()) throw std::invalid_argument("segmentBack: empty image");
  if (bgr.type() != CV_8UC3) throw std::invalid_argument("segmentBack: expected a CV_8UC3 (BGR) image");
  if (!background.empty() && (background.type() != CV_8UC1 || background.size() != bgr.size()))
    throw std::invalid_argument("segmentBack: the background mask must be CV_8U of the image's size");
  if (!depth.empty() && (depth.type() != CV_32FC1 || depth.size() != bgr.size()))
    throw std::invalid_argument("segmentBack: the depth map must be CV_32F of the image's size");
  if (!marks.empty() && (marks.type() != CV_8UC1 || marks.size() != bgr.size()))
    throw std::invalid_argument("segmentBack: the marks must be CV_8U of the image's size");
  const cv::Size size = bgr.size();
  LogTable log_table;
  for (int i = 0; i < 256; ++i) log_table[static_cast<std::size_t>(i)] = static_cast<float>(std::log(i + kLogOffset));

  // Stage A: detection on a reduced copy; stage B: the skin's chroma model against its surroundings.
  const Detection detection = detectSkinRegion(bgr, params, background, log_table);
  if (!detection.problem.empty()) return invalid(size, detection.problem);
  const SkinModel model = skinModel(detection, params, depth, size);
  if (!model.problem.empty()) return invalid(size, model.problem);
  Segmentation seg;
  seg.score = scoreImage(bgr, model, log_table, params.blur_sigma);

  // Mask: threshold, clean, the region of the detection, holes filled. Skin lies about +0.5; far more chromatic
  // than skin, beyond kMaxScore, is something else of a skin-like hue (red hair, a red towel).
  cv::Mat m = (seg.score > 0) & (seg.score < kMaxScore);
  if (std::isfinite(model.ring_depth)) fillRaisedSkin(seg.score, depth, model.ring_depth, &m);
  if (!background.empty()) m.setTo(0, background);
  if (!marks.empty()) m.setTo(255, marks);
  morphology(&m, cv::MORPH_OPEN, params.open_radius);
  morphology(&m, cv::MORPH_CLOSE, params.close_radius);
  seg.trunk = cutToTrunk(bgr, &m, params.trunk);
  seg.joined_pieces = detail::joinAcrossThinBands(&m, kMinPieceShare * size.area()).joined;
  const Back back = chooseBack(m, detection, params);
  if (!back.problem.empty()) return invalid(size, back.problem);
  seg.mask = back.mask;
  agreeWithMask(seg.mask, &seg.score);
  traceContour(back.border, params, &seg);
  seg.valid = true;
  return seg;
}

std::vector<double> rowCrossings(const cv::Mat& score, double y, std::vector<bool>* rising) {
  if (rising) rising->clear();
  std::vector<double> xs;
  if (score.empty()) return xs;
  if (score.type() != CV_32FC1) throw std::invalid_argument("rowCrossings: expected a CV_32F score");
  if (!(y >= 0.0 && y <= score.rows - 1)) return xs;  // also rejects NaN
  const int y0 = std::min(static_cast<int>(y), score.rows - 1);
  const int y1 = std::min(y0 + 1, score.rows - 1);
  const float f = static_cast<float>(y - y0);
  const float* r0 = score.ptr<float>(y0);
  const float* r1 = score.ptr<float>(y1);
  auto value = [&](int x) { return f > 0.f ? (1.f - f) * r0[x] + f * r1[x] : r0[x]; };
  auto sign = [](float s) { return s > 0.f ? 1 : (s < 0.f ? -1 : 0); };  // NaN: 0
  // Walk right, remembering the last sample with a sign. A sign change
  // between it and the next signed sample is one crossing: interpolated
  // linearly between adjacent samples, at the middle of a run of exact zeros
  // otherwise. Zeros that only touch (same sign both sides) or lie at the
  // row's ends are no crossing.
  int last = -1, last_sign = 0;
  float last_value = 0.f;
  for (int x = 0; x < score.cols; ++x) {
    const float s = value(x);
    const int sg = sign(s);
    if (sg == 0) continue;
    if (last_sign != 0 && sg != last_sign) {
      const double at = (x == last + 1) ? last + static_cast<double>(last_value) / (static_cast<double>(last_value) - s)
                                        : 0.5 * (last + x);
      xs.push_back(at);
      if (rising) rising->push_back(sg > 0);
    }
    last = x;
    last_sign = sg;
    last_value = s;
  }
  return xs;
}

}  // namespace massage_cell::cect
