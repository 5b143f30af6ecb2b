// Pictures of disparity maps. ROS-free.
#pragma once

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

/// A colour picture of a disparity map (dmin..dmax -> turbo; NaN black).
cv::Mat colourise(const cv::Mat& disparity, double dmin, double dmax);

}  // namespace massage_cell::stereo
