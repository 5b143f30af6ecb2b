#include "massage_cell/stereo/consistency.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace massage_cell::stereo {

cv::Mat leftRightCheck(const cv::Mat& left_disparity, const cv::Mat& right_disparity, float tolerance) {
  if (left_disparity.type() != CV_32F || right_disparity.type() != CV_32F) {
    throw std::invalid_argument("leftRightCheck: both disparity maps must be CV_32F");
  }
  if (left_disparity.size() != right_disparity.size()) {
    throw std::invalid_argument("leftRightCheck: the left map is " + std::to_string(left_disparity.cols) + "x" +
                                std::to_string(left_disparity.rows) + ", the right map " +
                                std::to_string(right_disparity.cols) + "x" + std::to_string(right_disparity.rows));
  }
  if (!(tolerance >= 0.0f) || !std::isfinite(tolerance)) {
    throw std::invalid_argument("leftRightCheck: tolerance must be finite and >= 0, got " + std::to_string(tolerance));
  }
  const int W = left_disparity.cols;
  cv::Mat consistent(left_disparity.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < left_disparity.rows; ++y) {
    const float* dl = left_disparity.ptr<float>(y);
    const float* dr = right_disparity.ptr<float>(y);
    unsigned char* c = consistent.ptr<unsigned char>(y);
    for (int x = 0; x < W; ++x) {
      const float d = dl[x];
      if (!std::isfinite(d)) continue;
      const float xr = static_cast<float>(x) - d;
      if (xr < 0.0f || xr > static_cast<float>(W - 1)) continue;  // off the right image
      const int x0 = static_cast<int>(std::floor(xr));
      const int x1 = std::min(x0 + 1, W - 1);
      const float t = xr - static_cast<float>(x0);
      if (!std::isfinite(dr[x0]) || !std::isfinite(dr[x1])) continue;
      const float seen = (1.0f - t) * dr[x0] + t * dr[x1];
      if (std::abs(seen - d) <= tolerance) c[x] = 255;
    }
  }
  return consistent;
}

cv::Mat fillFromBackground(const cv::Mat& disparity, const cv::Mat& keep) {
  if (disparity.type() != CV_32F) throw std::invalid_argument("fillFromBackground: the disparity map must be CV_32F");
  if (keep.type() != CV_8U || keep.size() != disparity.size()) {
    throw std::invalid_argument("fillFromBackground: the mask must be CV_8U of the disparity map's size");
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int W = disparity.cols;
  cv::Mat filled(disparity.size(), CV_32F, cv::Scalar(nan));
  std::vector<float> from_left(W), from_right(W);
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    const unsigned char* k = keep.ptr<unsigned char>(y);
    float* out = filled.ptr<float>(y);
    auto kept = [&](int x) { return k[x] != 0 && std::isfinite(d[x]); };
    float last = nan;
    for (int x = 0; x < W; ++x) {
      if (kept(x)) last = d[x];
      from_left[x] = last;
    }
    last = nan;
    for (int x = W - 1; x >= 0; --x) {
      if (kept(x)) last = d[x];
      from_right[x] = last;
    }
    for (int x = 0; x < W; ++x) {
      if (kept(x)) {
        out[x] = d[x];
      } else if (std::isfinite(from_left[x]) && std::isfinite(from_right[x])) {
        out[x] = std::min(from_left[x], from_right[x]);
      } else {
        out[x] = std::isfinite(from_left[x]) ? from_left[x] : from_right[x];  // the edge: one side (or NaN)
      }
    }
  }
  return filled;
}

}  // namespace massage_cell::stereo
