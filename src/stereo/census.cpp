// The census and AD-census data terms (cost_volume.h). The census of a pixel
// is one bit per neighbour in its window (neighbour < centre, grey levels,
// the image's edge replicated); the cost of a match is the Hamming distance
// of the two pixels' census strings. AD is the channel-averaged absolute
// colour difference, sampling-insensitive like the thesis's Eq. 2.7
// (Birchfield-Tomasi per channel, both directions). Both are computed per disparity slice in parallel like
// the thesis's term.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/cost_volume.h"

namespace massage_cell::stereo {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("computeCensusCostVolume: " + what); }

void validateCensus(const CostParams& p) {
  const int w = p.census_width, h = p.census_height;
  if (w < 1 || h < 1 || w % 2 == 0 || h % 2 == 0 || w * h - 1 < 8 || w * h - 1 > 64) {
    fail("census window must have odd sides and 8..64 neighbours (got " + std::to_string(w) + "x" + std::to_string(h) +
         ")");
  }
  if (!(p.census_lambda > 0.0f) || !std::isfinite(p.census_lambda)) fail("census_lambda must be positive and finite");
  if (!(p.ad_lambda > 0.0f) || !std::isfinite(p.ad_lambda)) fail("ad_lambda must be positive and finite");
}

cv::Mat grey(const cv::Mat& img) {
  if (img.channels() == 1) return img;
  cv::Mat g;
  cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
  return g;
}

/// Census strings of a grey image, row-major W x H.
std::vector<std::uint64_t> census(const cv::Mat& grey_image, int win_w, int win_h) {
  const int rx = win_w / 2, ry = win_h / 2, W = grey_image.cols, H = grey_image.rows;
  cv::Mat padded;
  cv::copyMakeBorder(grey_image, padded, ry, ry, rx, rx, cv::BORDER_REPLICATE);
  std::vector<std::uint64_t> out(static_cast<std::size_t>(W) * H);
  cv::parallel_for_(cv::Range(0, H), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uchar* centre = padded.ptr<uchar>(y + ry) + rx;
      std::uint64_t* o = out.data() + static_cast<std::size_t>(y) * W;
      for (int x = 0; x < W; ++x) o[x] = 0;
      for (int dy = -ry; dy <= ry; ++dy) {
        const uchar* row = padded.ptr<uchar>(y + ry + dy) + rx;
        for (int dx = -rx; dx <= rx; ++dx) {
          if (dx == 0 && dy == 0) continue;
          for (int x = 0; x < W; ++x) o[x] = (o[x] << 1) | (row[x + dx] < centre[x] ? 1u : 0u);
        }
      }
    }
  });
  return out;
}

/// Twice the per-channel minimum and maximum of a pixel and its two half-pixel
/// interpolants along the row (Birchfield-Tomasi), interleaved like the image.
struct BtBounds {
  std::vector<std::int16_t> lo2, hi2;
};

BtBounds btBounds(const cv::Mat& img) {
  const int W = img.cols, H = img.rows, ch = img.channels();
  BtBounds b;
  b.lo2.resize(static_cast<std::size_t>(W) * H * ch);
  b.hi2.resize(b.lo2.size());
  for (int y = 0; y < H; ++y) {
    const uchar* p = img.ptr<uchar>(y);
    for (int x = 0; x < W; ++x) {
      for (int c = 0; c < ch; ++c) {
        const int v = p[x * ch + c], l = p[std::max(x - 1, 0) * ch + c], r = p[std::min(x + 1, W - 1) * ch + c];
        const std::size_t i = (static_cast<std::size_t>(y) * W + x) * ch + c;
        b.lo2[i] = static_cast<std::int16_t>(std::min({2 * v, v + l, v + r}));
        b.hi2[i] = static_cast<std::int16_t>(std::max({2 * v, v + l, v + r}));
      }
    }
  }
  return b;
}

}  // namespace

DataTerm parseDataTerm(const std::string& name) {
  if (name == "thesis") return DataTerm::kThesis;
  if (name == "census") return DataTerm::kCensus;
  if (name == "ad-census") return DataTerm::kAdCensus;
  throw std::invalid_argument("unknown data term '" + name + "' (thesis, census or ad-census)");
}

std::string toString(DataTerm term) {
  switch (term) {
    case DataTerm::kCensus:
      return "census";
    case DataTerm::kAdCensus:
      return "ad-census";
    default:
      return "thesis";
  }
}

CostVolume computeCensusCostVolume(const cv::Mat& left, const cv::Mat& right, const CostParams& params, int threads) {
  validateCostInputs(left, right, params);
  validateCensus(params);
  const int W = left.cols, H = left.rows, ch = left.channels();
  const std::vector<std::uint64_t> cl = census(grey(left), params.census_width, params.census_height);
  const std::vector<std::uint64_t> cr = census(grey(right), params.census_width, params.census_height);
  const bool ad = params.data_term == DataTerm::kAdCensus;
  const BtBounds bl = ad ? btBounds(left) : BtBounds{}, br = ad ? btBounds(right) : BtBounds{};
  const float inv_bits = 1.0f / static_cast<float>(params.census_width * params.census_height - 1);
  // rho(c, lambda) = 1 - exp(-c / lambda) by table: census distances 0..64, mean channel differences in thirds.
  std::vector<float> rho_census(65), rho_ad(3 * 255 + 1);
  for (int c = 0; c <= 64; ++c) rho_census[c] = 1.0f - std::exp(-c / params.census_lambda);
  for (int s = 0; s <= 3 * 255; ++s) rho_ad[s] = 1.0f - std::exp(-(s / 3.0f) / params.ad_lambda);

  CostVolume vol(W, H, params.dmin, params.dmax, CostVolume::Uninitialised{});
  const int levels = vol.levels();
  const double stripes = threads > 0 ? std::min(threads, levels) : -1.0;
  cv::parallel_for_(
      cv::Range(0, levels),
      [&](const cv::Range& r) {
        for (int d = params.dmin + r.start; d < params.dmin + r.end; ++d) {
          float* slice = vol.slice(d);
          for (int y = 0; y < H; ++y) {
            float* out = slice + static_cast<std::size_t>(y) * W;
            const std::uint64_t* a = cl.data() + static_cast<std::size_t>(y) * W;
            const std::uint64_t* b = cr.data() + static_cast<std::size_t>(y) * W;
            const int x0 = std::min(d, W);
            for (int x = 0; x < x0; ++x) out[x] = 1.0f;
            if (!ad) {
              for (int x = x0; x < W; ++x) out[x] = __builtin_popcountll(a[x] ^ b[x - d]) * inv_bits;
              continue;
            }
            const uchar* li = left.ptr<uchar>(y);
            const uchar* ri = right.ptr<uchar>(y);
            const std::size_t row = static_cast<std::size_t>(y) * W * ch;
            const std::int16_t* llo = bl.lo2.data() + row;
            const std::int16_t* lhi = bl.hi2.data() + row;
            const std::int16_t* rlo = br.lo2.data() + row;
            const std::int16_t* rhi = br.hi2.data() + row;
            for (int x = x0; x < W; ++x) {
              int sum2 = 0;  // twice the summed sampling-insensitive channel differences
              for (int c = 0; c < ch; ++c) {
                const int i = x * ch + c, j = (x - d) * ch + c, l2 = 2 * li[i], r2 = 2 * ri[j];
                const int forward = std::max({0, l2 - rhi[j], rlo[j] - l2});
                const int backward = std::max({0, r2 - lhi[i], llo[i] - r2});
                sum2 += std::min(forward, backward);
              }
              const int thirds = ch == 3 ? sum2 / 2 : 3 * sum2 / 2;  // mean difference x 3
              out[x] = 0.5f * (rho_census[__builtin_popcountll(a[x] ^ b[x - d])] + rho_ad[thirds]);
            }
          }
        }
      },
      stripes);
  return vol;
}

}  // namespace massage_cell::stereo
