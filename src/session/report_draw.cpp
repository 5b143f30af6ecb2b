// The report's pictures of the camera's view: the acupoints, the tool's path, the disparity (see report.h).
#include <algorithm>

#include <opencv2/imgproc.hpp>

#include "massage_cell/session/report.h"

namespace massage_cell::session {

namespace {

cv::Mat bgr(const cv::Mat& image) {
  cv::Mat out;
  if (image.channels() == 1) {
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  } else {
    out = image.clone();
  }
  return out;
}

}  // namespace

cv::Mat drawAcupoints(const cv::Mat& image, const std::vector<MarkedPixel>& estimates,
                      const std::vector<MarkedPixel>& truth, const std::vector<MarkedPixel>& landmarks) {
  cv::Mat out = bgr(image);
  const int r = std::max(2, out.cols / 160);
  for (const MarkedPixel& t : truth) cv::drawMarker(out, t.pixel, {0, 200, 0}, cv::MARKER_CROSS, 3 * r, 1);
  for (const MarkedPixel& l : landmarks) {
    cv::drawMarker(out, l.pixel, {255, 255, 0}, cv::MARKER_DIAMOND, 4 * r, 1, cv::LINE_AA);
    // Ending left of the diamond: the routine's labels run to the right of their points, on and beside the spine.
    const double scale = 0.3 * r / 2.0 + 0.2;
    int baseline = 0;
    const cv::Size text = cv::getTextSize(l.label, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    cv::putText(out, l.label, l.pixel + cv::Point2d(-2.0 * r - 2 - text.width, 0.5 * text.height),
                cv::FONT_HERSHEY_SIMPLEX, scale, {255, 255, 0}, 1, cv::LINE_AA);
  }
  for (const MarkedPixel& e : estimates) {
    if (!e.labelled) {
      cv::circle(out, e.pixel, std::max(1, r / 2), {0, 0, 160}, cv::FILLED, cv::LINE_AA);
      continue;
    }
    cv::circle(out, e.pixel, r, {0, 0, 255}, cv::FILLED, cv::LINE_AA);
    cv::putText(out, e.label, e.pixel + cv::Point2d(r + 2, -r), cv::FONT_HERSHEY_SIMPLEX, 0.3 * r / 2.0 + 0.2,
                {0, 255, 255}, 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat drawTrajectory(const cv::Mat& image, const std::vector<cv::Point2d>& path) {
  cv::Mat out = bgr(image);
  for (std::size_t i = 1; i < path.size(); ++i) {
    const double a = static_cast<double>(i) / path.size();
    cv::line(out, path[i - 1], path[i], cv::Scalar(255 * a, 80, 255 * (1 - a)), 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat colourDisparity(const cv::Mat& disparity) {
  cv::Mat d;
  disparity.convertTo(d, CV_32F);
  const cv::Mat valid = (d > 0.0f) & (d == d);
  double lo = 0.0, hi = 1.0;
  if (cv::countNonZero(valid) > 0) cv::minMaxLoc(d, &lo, &hi, nullptr, nullptr, valid);
  cv::Mat grey;
  d.convertTo(grey, CV_8U, 255.0 / std::max(hi - lo, 1e-6), -lo * 255.0 / std::max(hi - lo, 1e-6));
  cv::Mat out;
  cv::applyColorMap(grey, out, cv::COLORMAP_TURBO);
  out.setTo(cv::Scalar::all(0), ~valid);
  return out;
}

}  // namespace massage_cell::session
