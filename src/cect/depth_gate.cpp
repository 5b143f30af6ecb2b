#include "massage_cell/cect/depth_gate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

constexpr int kCoarseRows = 120;  // rows of the coarse copy matched
constexpr int kBlock = 5;         // SGBM block size, coarse pixels

cv::Mat coarseGrey(const cv::Mat& img, int factor) {
  cv::Mat grey = img;
  if (img.channels() == 3) cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  if (factor == 1) return grey;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(img.cols / factor, img.rows / factor), 0, 0, cv::INTER_AREA);
  return small;
}

/// Each view's disparity (CV_16S, SGBM's fixed point) of the coarse pair:
/// the left view's directly, the right one's by matching the mirrored pair.
/// Padded on the left by the search range, so that the first columns (whose
/// farther points the other camera does see) get a disparity too.
void coarseDisparities(const cv::Mat& coarse_left, const cv::Mat& coarse_right, int min_d, int num_d,
                       cv::Mat disparity[2]) {
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& range) {
    for (int v = range.start; v < range.end; ++v) {
      cv::Mat l, r;
      if (v == 0) {
        l = coarse_left;
        r = coarse_right;
      } else {
        cv::flip(coarse_right, l, 1);
        cv::flip(coarse_left, r, 1);
      }
      const int pad = min_d + num_d;
      cv::copyMakeBorder(l, l, 0, 0, pad, 0, cv::BORDER_REPLICATE);
      cv::copyMakeBorder(r, r, 0, 0, pad, 0, cv::BORDER_REPLICATE);
      const cv::Ptr<cv::StereoSGBM> sgbm =
          cv::StereoSGBM::create(min_d, num_d, kBlock, 8 * kBlock * kBlock, 32 * kBlock * kBlock, 1, 0, 10);
      cv::Mat d;
      sgbm->compute(l, r, d);
      d = d.colRange(pad, d.cols).clone();
      if (v == 1) cv::flip(d, d, 1);
      disparity[v] = d;
    }
  });
}

/// `coarse` (nearest-neighbour) at the full image's size; `fill` where the
/// image's last rows and columns have no coarse pixel.
cv::Mat toFullSize(const cv::Mat& coarse, int factor, const cv::Size& size, const cv::Scalar& fill) {
  cv::Mat up;
  cv::resize(coarse, up, cv::Size(coarse.cols * factor, coarse.rows * factor), 0, 0, cv::INTER_NEAREST);
  cv::Mat out(size, coarse.type(), fill);
  up.copyTo(out(cv::Rect(0, 0, up.cols, up.rows)));
  return out;
}

}  // namespace

std::string DepthGate::summary() const {
  std::ostringstream s;
  s.precision(2);
  if (left_far.empty()) return "no depth gate";
  s << "background beyond " << std::fixed << far_depth << " m (nearest surfaces at " << nearest_depth << " m): "
    << cv::countNonZero(left_far) << " px left, " << cv::countNonZero(right_far) << " px right";
  return s.str();
}

DepthGate farBackground(const cv::Mat& left_rect, const cv::Mat& right_rect, const StereoGeometry& geometry,
                        const cv::Vec2d& range, const DepthGateParams& params) {
  if (left_rect.size() != right_rect.size() || left_rect.type() != right_rect.type())
    throw std::invalid_argument("farBackground: the two views differ in size or type");
  if (left_rect.type() != CV_8UC3 && left_rect.type() != CV_8UC1)
    throw std::invalid_argument("farBackground: expected 8-bit grey or BGR images");
  DepthGate gate;
  const double min_disparity = range[0], max_disparity = range[1];
  const double focal_baseline = geometry.fx() * geometry.baseline();
  // Rectified disparity = f B / z + offset (the principal points' difference).
  const double offset = geometry.disparityAtDepth(1.0) - focal_baseline;
  if (!(params.gap > 0.0) || !(focal_baseline > 0.0) || !(max_disparity > min_disparity) || left_rect.empty())
    return gate;
  const int factor = std::max(1, static_cast<int>(std::lround(static_cast<double>(left_rect.rows) / kCoarseRows)));
  const int min_d = std::max(0, static_cast<int>(std::floor(min_disparity / factor)));
  const int span = static_cast<int>(std::ceil(max_disparity / factor)) - min_d + 1;
  const int num_d = 16 * ((span + 15) / 16);
  if (left_rect.cols / factor < 2 * kBlock || left_rect.rows / factor < 2 * kBlock) return gate;  // nothing to match

  cv::Mat disparity[2];
  coarseDisparities(coarseGrey(left_rect, factor), coarseGrey(right_rect, factor), min_d, num_d, disparity);

  // The nearest surfaces' depth (a quantile of the left view's disparities).
  std::vector<short> valid;
  const short invalid = static_cast<short>((min_d - 1) * 16);
  for (int y = 0; y < disparity[0].rows; ++y) {
    const short* d = disparity[0].ptr<short>(y);
    for (int x = 0; x < disparity[0].cols; ++x)
      if (d[x] > invalid && d[x] > 0) valid.push_back(d[x]);
  }
  if (valid.size() < 100) return gate;
  const auto q = valid.begin() + static_cast<std::ptrdiff_t>((1.0 - params.nearest_quantile) * (valid.size() - 1));
  std::nth_element(valid.begin(), q, valid.end());
  const double nearest_d = *q / 16.0 * factor - offset;
  if (!(nearest_d > 0.0)) return gate;
  gate.nearest_depth = focal_baseline / nearest_d;
  gate.far_depth = gate.nearest_depth + params.gap;
  const double far_d = 16.0 * (focal_baseline / gate.far_depth + offset) / factor;  // SGBM's fixed-point units

  for (int v = 0; v < 2; ++v) {
    cv::Mat far = (disparity[v] > invalid) & (disparity[v] < far_d);
    // Block matching fattens the near surfaces by half a block over the far
    // ones next to them: the far region grown back by as much.
    cv::dilate(far, far, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kBlock, kBlock)));
    (v == 0 ? gate.left_far : gate.right_far) = toFullSize(far, factor, left_rect.size(), cv::Scalar(0));
    // Depth: f B / (d - offset) where the disparity is valid.
    cv::Mat z(disparity[v].size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
    for (int y = 0; y < z.rows; ++y) {
      const short* d = disparity[v].ptr<short>(y);
      float* o = z.ptr<float>(y);
      for (int x = 0; x < z.cols; ++x) {
        const double dd = d[x] / 16.0 * factor - offset;
        if (d[x] > invalid && dd > 0.0) o[x] = static_cast<float>(focal_baseline / dd);
      }
    }
    (v == 0 ? gate.left_depth : gate.right_depth) =
        toFullSize(z, factor, left_rect.size(), cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  }
  return gate;
}

}  // namespace massage_cell::cect
