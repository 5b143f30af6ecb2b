// Helpers shared by the refinement's two halves (refine.cpp: FFD, refineDisparity; mdc.cpp: MDC). Internal to
// the stereo library.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::stereo::refine_detail {

/// roundedLevels' mark of a NaN disparity.
constexpr int kInvalidLevel = std::numeric_limits<int>::min();

[[noreturn]] inline void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

inline void checkImage(const char* where, const cv::Mat& left, const cv::Mat& disparity) {
  if (left.empty()) fail(where, "empty image");
  if (disparity.empty()) fail(where, "empty disparity map");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3) fail(where, "unsupported image type (need CV_8UC1 or CV_8UC3)");
  if (disparity.type() != CV_32FC1) fail(where, "disparity map must be CV_32FC1");
  if (left.size() != disparity.size()) fail(where, "image and disparity map sizes differ");
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x)
      if (std::isinf(d[x])) fail(where, "infinite disparity at (" + std::to_string(x) + ", " + std::to_string(y) + ")");
  }
}

/// Integer level of every finite disparity; `lo`, `hi`: their range (lo > hi: none).
inline cv::Mat roundedLevels(const cv::Mat& disparity, int& lo, int& hi) {
  cv::Mat levels(disparity.size(), CV_32S);
  lo = std::numeric_limits<int>::max();
  hi = std::numeric_limits<int>::min();
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    int* l = levels.ptr<int>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (std::isnan(d[x])) {
        l[x] = kInvalidLevel;
        continue;
      }
      const double r = std::round(static_cast<double>(d[x]));
      if (r < -1e8 || r > 1e8) fail("refine", "disparity magnitude too large");
      l[x] = static_cast<int>(r);
      lo = std::min(lo, l[x]);
      hi = std::max(hi, l[x]);
    }
  }
  return levels;
}

/// CIELab (L 0..100) as three planar CV_32F images.
inline void labPlanes(const cv::Mat& left, cv::Mat planes[3]) {
  if (left.channels() == 1) {
    left.convertTo(planes[0], CV_32F, 100.0 / 255.0);
    planes[1] = cv::Mat::zeros(left.size(), CV_32F);
    planes[2] = cv::Mat::zeros(left.size(), CV_32F);
    return;
  }
  cv::Mat f, lab;
  left.convertTo(f, CV_32F, 1.0 / 255.0);
  cv::cvtColor(f, lab, cv::COLOR_BGR2Lab);
  cv::split(lab, planes);
}

/// CIELab (L 0..100) of pixel i of an 8-bit Lab (3 channels) or grey image.
inline cv::Vec3d pixelLab(const cv::Mat& image, int i) {
  if (image.channels() == 3) {
    const cv::Vec3b c = image.ptr<cv::Vec3b>(0)[i];
    return cv::Vec3d(c[0] * 100.0 / 255.0, c[1] - 128.0, c[2] - 128.0);
  }
  return cv::Vec3d(image.ptr<uchar>(0)[i] * 100.0 / 255.0, 0.0, 0.0);
}

inline double stripes(int threads, int rows) { return threads > 0 ? std::min(threads, rows) : -1.0; }

}  // namespace massage_cell::stereo::refine_detail
