// The energy of Eq. 2.2: pairwise weights u_{p,q} from the left image and
// the energy of an integer labelling.
#include "massage_cell/stereo/energy.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace massage_cell::stereo {

namespace {

/// Largest absolute channel difference between two pixels of a CV_8UC(cn) row.
inline int channelDiff(const uchar* a, const uchar* b, int cn) {
  int m = 0;
  for (int c = 0; c < cn; ++c) m = std::max(m, std::abs(int(a[c]) - int(b[c])));
  return m;
}

}  // namespace

PairwiseWeights pairwiseWeights(const cv::Mat& left, const SmoothParams& params) {
  if (left.empty()) throw std::invalid_argument("pairwiseWeights: empty image");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3)
    throw std::invalid_argument("pairwiseWeights: image must be CV_8UC1 or CV_8UC3");
  if (!(params.tau > 0.0f) || !std::isfinite(params.tau))
    throw std::invalid_argument("pairwiseWeights: tau must be > 0");
  if (!(params.u_min >= 0.0f) || !std::isfinite(params.u_min))
    throw std::invalid_argument("pairwiseWeights: u_min must be >= 0");
  if (!(params.u_max >= params.u_min) || !std::isfinite(params.u_max))
    throw std::invalid_argument("pairwiseWeights: u_max must be >= u_min");

  const int w = left.cols, h = left.rows, cn = left.channels();
  // u as a function of the (integer) intensity difference 0..255.
  float table[256];
  for (int diff = 0; diff < 256; ++diff) {
    const float t = std::min(static_cast<float>(diff), params.tau);
    table[diff] = (params.u_min - params.u_max) * t / params.tau + params.u_max;
  }

  PairwiseWeights out;
  out.right = cv::Mat::zeros(h, w, CV_32F);
  out.down = cv::Mat::zeros(h, w, CV_32F);
  for (int y = 0; y < h; ++y) {
    const uchar* row = left.ptr<uchar>(y);
    const uchar* next = y + 1 < h ? left.ptr<uchar>(y + 1) : nullptr;
    float* r = out.right.ptr<float>(y);
    float* d = out.down.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const uchar* p = row + x * cn;
      if (x + 1 < w) r[x] = table[channelDiff(p, p + cn, cn)];
      if (next) d[x] = table[channelDiff(p, next + x * cn, cn)];
    }
  }
  return out;
}

Energy labellingEnergy(const CostVolume& volume, const PairwiseWeights& weights, const cv::Mat& disparity,
                       float truncation) {
  const int w = volume.width(), h = volume.height();
  if (w <= 0 || h <= 0) throw std::invalid_argument("labellingEnergy: empty cost volume");
  const cv::Size size(w, h);
  if (disparity.type() != CV_32FC1 || disparity.size() != size)
    throw std::invalid_argument("labellingEnergy: disparity must be CV_32FC1 of the volume's size");
  if (weights.right.type() != CV_32FC1 || weights.right.size() != size || weights.down.type() != CV_32FC1 ||
      weights.down.size() != size)
    throw std::invalid_argument("labellingEnergy: weights must be CV_32FC1 of the volume's size");
  if (std::isnan(truncation)) throw std::invalid_argument("labellingEnergy: truncation is NaN");

  const int dmin = volume.dmin(), dmax = volume.dmax();
  auto label = [&](float v, int x, int y) {
    if (!std::isfinite(v) || v != std::floor(v) || v < dmin || v > dmax)
      throw std::invalid_argument("labellingEnergy: disparity at (" + std::to_string(x) + ", " + std::to_string(y) +
                                  ") = " + std::to_string(v) + " is not an integer in [" + std::to_string(dmin) + ", " +
                                  std::to_string(dmax) + "]");
    return static_cast<int>(v);
  };
  auto dist = [&](int a, int b) {
    const double d = std::abs(a - b);
    return truncation > 0.0f ? std::min(d, static_cast<double>(truncation)) : d;
  };

  Energy e;
  for (int y = 0; y < h; ++y) {
    const float* drow = disparity.ptr<float>(y);
    const float* dnext = y + 1 < h ? disparity.ptr<float>(y + 1) : nullptr;
    const float* ur = weights.right.ptr<float>(y);
    const float* ud = weights.down.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const int d = label(drow[x], x, y);
      e.data += volume(x, y, d);
      if (x + 1 < w) e.smooth += static_cast<double>(ur[x]) * dist(d, label(drow[x + 1], x + 1, y));
      if (dnext) e.smooth += static_cast<double>(ud[x]) * dist(d, label(dnext[x], x, y + 1));
    }
  }
  return e;
}

}  // namespace massage_cell::stereo
