#include "massage_cell/stereo/colourise.h"

#include <algorithm>

#include <opencv2/imgproc.hpp>

namespace massage_cell::stereo {

cv::Mat colourise(const cv::Mat& disparity, double dmin, double dmax) {
  cv::Mat valid = disparity == disparity, scaled, out;
  const double range = std::max(1e-6, dmax - dmin);
  disparity.convertTo(scaled, CV_8U, 255.0 / range, -dmin * 255.0 / range);
  cv::applyColorMap(scaled, out, cv::COLORMAP_TURBO);
  out.setTo(cv::Scalar(0, 0, 0), ~valid);
  return out;
}

}  // namespace massage_cell::stereo
