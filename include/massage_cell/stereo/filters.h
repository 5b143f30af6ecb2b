// The conventional disparity refiners the thesis compares its FFD + MDC with
// (its Table 2.5), each optionally blind to FFD's fattening mask:
// * 2D bilateral (2DBF): each disparity the joint-bilateral average (guided by
//   the left image) of its window's disparities;
// * 3D bilateral (3DBF, Yang et al. 2007): a cost volume min(|d - D(q)|, tau)
//   from the map, each slice joint-bilateral filtered, the minimum per pixel
//   with a parabola through its neighbours (sub-pixel output);
// * weighted median (WMF, OpenCV ximgproc's weightedMedianFilter, Zhang et
//   al. 2014): the median of the window's disparities weighted by colour
//   similarity.
// Support pixels are those with a finite disparity outside `exclude`; a pixel
// whose window holds none keeps its value. ROS-free (OpenCV ximgproc).
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

enum class DisparityFilter { kBilateral2d, kBilateral3d, kWeightedMedian };
DisparityFilter parseDisparityFilter(const std::string& name);  ///< "2dbf" | "3dbf" | "wmf"
std::string toString(DisparityFilter filter);

struct FilterParams {
  int radius = 7;              ///< window (2 radius + 1)^2, >= 1
  float sigma_colour = 12.0f;  ///< colour range of the weights (grey levels) > 0
  float sigma_space = 7.0f;    ///< 2DBF / 3DBF spatial sigma (pixels) > 0
  float truncation = 2.0f;     ///< 3DBF: tau of the cost min(|d - D|, tau), levels > 0
};
/// Throws std::invalid_argument naming the first bad parameter.
void validate(const FilterParams& params);

/// `filter` applied to `disparity` (CV_32F, NaN = invalid) guided by `left`
/// (CV_8UC1 / CV_8UC3, same size); `exclude` (CV_8U, non-zero = not a
/// support, e.g. FFD's mask) may be empty. CV_32F of the same size. Throws
/// std::invalid_argument naming the problem. Safe to call from several threads
/// (the weighted median's OpenCV filter, which keeps static state, runs one call
/// at a time), and the result depends on the arguments alone.
cv::Mat filterDisparity(const cv::Mat& left, const cv::Mat& disparity, DisparityFilter filter, const cv::Mat& exclude,
                        const FilterParams& params);

}  // namespace massage_cell::stereo
