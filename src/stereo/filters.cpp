// Conventional disparity refiners (filters.h). Masked filtering is a
// normalised joint-bilateral filter: JBF(D m) / JBF(m) with m the support
// mask, so excluded and invalid pixels carry no weight.
#include "massage_cell/stereo/filters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc.hpp>

namespace massage_cell::stereo {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("filterDisparity: " + what); }

void checkInputs(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& exclude) {
  if (left.empty() || disparity.empty()) fail("empty image or disparity");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3) fail("left image must be CV_8UC1 or CV_8UC3");
  if (disparity.type() != CV_32F) fail("disparity must be CV_32F");
  if (left.size() != disparity.size()) fail("image and disparity sizes differ");
  if (!exclude.empty() && (exclude.type() != CV_8U || exclude.size() != disparity.size())) {
    fail("the exclusion mask must be CV_8U of the disparity's size");
  }
}

/// 1 where the disparity is finite and not excluded, else 0 (CV_32F); `values` gets D there, 0 elsewhere.
cv::Mat supportMask(const cv::Mat& disparity, const cv::Mat& exclude, cv::Mat& values) {
  cv::Mat mask(disparity.size(), CV_32F);
  values.create(disparity.size(), CV_32F);
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    const uchar* e = exclude.empty() ? nullptr : exclude.ptr<uchar>(y);
    float* m = mask.ptr<float>(y);
    float* v = values.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (std::isinf(d[x])) fail("infinite disparity");
      const bool support = std::isfinite(d[x]) && (e == nullptr || e[x] == 0);
      m[x] = support ? 1.0f : 0.0f;
      v[x] = support ? d[x] : 0.0f;
    }
  }
  return mask;
}

cv::Mat floatGuide(const cv::Mat& left) {
  cv::Mat guide;
  left.convertTo(guide, left.channels() == 3 ? CV_32FC3 : CV_32F);
  return guide;
}

cv::Mat jointBilateral(const cv::Mat& guide, const cv::Mat& src, const FilterParams& p) {
  cv::Mat out;
  cv::ximgproc::jointBilateralFilter(guide, src, out, 2 * p.radius + 1, p.sigma_colour, p.sigma_space,
                                     cv::BORDER_REPLICATE);
  return out;
}

cv::Mat bilateral2d(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& exclude, const FilterParams& p) {
  cv::Mat values;
  const cv::Mat mask = supportMask(disparity, exclude, values);
  const cv::Mat guide = floatGuide(left);
  const cv::Mat num = jointBilateral(guide, values, p), den = jointBilateral(guide, mask, p);
  cv::Mat out = disparity.clone();
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      if (den.at<float>(y, x) > 1e-6f) out.at<float>(y, x) = num.at<float>(y, x) / den.at<float>(y, x);
    }
  }
  return out;
}

cv::Mat bilateral3d(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& exclude, const FilterParams& p) {
  cv::Mat values;
  const cv::Mat mask = supportMask(disparity, exclude, values);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(values, &lo, &hi, nullptr, nullptr, mask > 0);
  if (cv::countNonZero(mask) == 0) return disparity.clone();
  const int d0 = static_cast<int>(std::floor(lo)), d1 = static_cast<int>(std::ceil(hi));
  const cv::Mat guide = floatGuide(left);
  const cv::Mat den = jointBilateral(guide, mask, p);
  // Per pixel: the best level, its cost and its neighbours' costs for the parabola.
  const int n = d1 - d0 + 1;
  std::vector<cv::Mat> cost(n);
  cv::Mat slice(disparity.size(), CV_32F);
  for (int k = 0; k < n; ++k) {
    const float d = static_cast<float>(d0 + k);
    for (int y = 0; y < slice.rows; ++y) {
      const float* v = values.ptr<float>(y);
      const float* m = mask.ptr<float>(y);
      float* s = slice.ptr<float>(y);
      for (int x = 0; x < slice.cols; ++x) s[x] = m[x] * std::min(std::abs(d - v[x]), p.truncation);
    }
    cost[k] = jointBilateral(guide, slice, p);
  }
  cv::Mat out = disparity.clone();
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      if (!(den.at<float>(y, x) > 1e-6f)) continue;
      int best = 0;
      for (int k = 1; k < n; ++k) {
        if (cost[k].at<float>(y, x) < cost[best].at<float>(y, x)) best = k;
      }
      float offset = 0.0f;
      if (best > 0 && best < n - 1) {
        const float a = cost[best - 1].at<float>(y, x), b = cost[best].at<float>(y, x),
                    c = cost[best + 1].at<float>(y, x);
        const float curvature = a - 2.0f * b + c;
        if (curvature > 1e-9f) offset = std::clamp(0.5f * (a - c) / curvature, -0.5f, 0.5f);
      }
      out.at<float>(y, x) = static_cast<float>(d0 + best) + offset;
    }
  }
  return out;
}

/// OpenCV's weighted median filter (ximgproc 4.6) run safely and reproducibly: it keeps its colour histogram and its
/// necklace-table cursors in static variables, so two at once (match()'s concurrent views, or two calls) corrupt each
/// other's tables and read out of bounds: the calls take turns. With a colour guide it clusters the colours by k-means
/// from the calling thread's cv::theRNG(): each call starts from a new generator's state (and leaves the caller's as it
/// was), so the result depends neither on the thread nor on earlier calls.
void ximgprocWeightedMedian(const cv::Mat& guide, const cv::Mat& values, cv::Mat& out, const FilterParams& p,
                            const cv::Mat& mask8) {
  static std::mutex one_at_a_time;
  const std::lock_guard<std::mutex> lock(one_at_a_time);
  struct RestoreOnExit {
    cv::RNG& rng;
    const cv::RNG callers;
    ~RestoreOnExit() { rng = callers; }
  } restore{cv::theRNG(), cv::theRNG()};
  restore.rng = cv::RNG();
  cv::ximgproc::weightedMedianFilter(guide, values, out, p.radius, p.sigma_colour, cv::ximgproc::WMF_EXP, mask8);
}

cv::Mat weightedMedian(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& exclude, const FilterParams& p) {
  cv::Mat values;
  const cv::Mat mask = supportMask(disparity, exclude, values);
  cv::Mat mask8, out;
  mask.convertTo(mask8, CV_8U);
  if (cv::countNonZero(mask8) == 0) return disparity.clone();
  // Pixels that are no support hold the smallest support's value, not 0: ximgproc's filter bins the values
  // between their extremes, and a 0 there would stretch the bins (and, were it ever used, lie outside the range).
  double lowest = 0.0, highest = 0.0;
  cv::minMaxLoc(values, &lowest, &highest, nullptr, nullptr, mask8);
  values.setTo(lowest, mask8 == 0);
  ximgprocWeightedMedian(left, values, out, p, mask8);
  // A pixel whose window holds no support keeps its value (the filter leaves such pixels undefined).
  cv::Mat support;
  cv::boxFilter(mask, support, CV_32F, cv::Size(2 * p.radius + 1, 2 * p.radius + 1), cv::Point(-1, -1), false,
                cv::BORDER_REPLICATE);
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      float& o = out.at<float>(y, x);
      if (!(support.at<float>(y, x) > 0.5f) || !std::isfinite(o)) {
        o = disparity.at<float>(y, x);
      } else {  // a median of supports lies between their extremes
        o = std::clamp(o, static_cast<float>(lowest), static_cast<float>(highest));
      }
    }
  }
  return out;
}

}  // namespace

DisparityFilter parseDisparityFilter(const std::string& name) {
  if (name == "2dbf") return DisparityFilter::kBilateral2d;
  if (name == "3dbf") return DisparityFilter::kBilateral3d;
  if (name == "wmf") return DisparityFilter::kWeightedMedian;
  throw std::invalid_argument("unknown disparity filter '" + name + "' (2dbf, 3dbf or wmf)");
}

std::string toString(DisparityFilter filter) {
  switch (filter) {
    case DisparityFilter::kBilateral3d:
      return "3dbf";
    case DisparityFilter::kWeightedMedian:
      return "wmf";
    default:
      return "2dbf";
  }
}

void validate(const FilterParams& p) {
  if (p.radius < 1 || p.radius > 64) fail("radius must be in 1..64 (got " + std::to_string(p.radius) + ")");
  if (!(p.sigma_colour > 0.0f) || !std::isfinite(p.sigma_colour)) fail("sigma_colour must be positive and finite");
  if (!(p.sigma_space > 0.0f) || !std::isfinite(p.sigma_space)) fail("sigma_space must be positive and finite");
  if (!(p.truncation > 0.0f) || !std::isfinite(p.truncation)) fail("truncation must be positive and finite");
}

cv::Mat filterDisparity(const cv::Mat& left, const cv::Mat& disparity, DisparityFilter filter, const cv::Mat& exclude,
                        const FilterParams& params) {
  validate(params);
  checkInputs(left, disparity, exclude);
  switch (filter) {
    case DisparityFilter::kBilateral3d:
      return bilateral3d(left, disparity, exclude, params);
    case DisparityFilter::kWeightedMedian:
      return weightedMedian(left, disparity, exclude, params);
    default:
      return bilateral2d(left, disparity, exclude, params);
  }
}

}  // namespace massage_cell::stereo
