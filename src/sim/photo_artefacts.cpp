#include "massage_cell/sim/photo_artefacts.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::sim {

namespace {

std::string num(double v) {
  std::ostringstream s;
  s.precision(3);
  s << v;
  return s.str();
}

cv::Mat motionBlur(const cv::Mat& img, double length, double angle) {
  const int size = 2 * static_cast<int>(std::ceil(0.5 * length)) + 1;
  cv::Mat kernel = cv::Mat::zeros(size, size, CV_32F);
  const cv::Point2d c(0.5 * (size - 1), 0.5 * (size - 1));
  const cv::Point2d d(0.5 * length * std::cos(angle), 0.5 * length * std::sin(angle));
  cv::line(kernel, c - d, c + d, cv::Scalar(1.0), 1, cv::LINE_AA);
  kernel /= cv::sum(kernel)[0];
  cv::Mat out;
  cv::filter2D(img, out, -1, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
  return out;
}

/// Gains per pixel: 1 at the centre, 1 - vignetting at the corners (cos^4 of
/// the field angle for a lens whose corner sees the fall-off asked for).
cv::Mat vignettingGain(cv::Size size, double vignetting) {
  const double corner_cos = std::pow(1.0 - vignetting, 0.25);
  const double corner_tan = std::tan(std::acos(corner_cos));
  const double half_diag = 0.5 * std::hypot(size.width, size.height);
  cv::Mat gain(size, CV_32F);
  for (int y = 0; y < size.height; ++y) {
    float* g = gain.ptr<float>(y);
    for (int x = 0; x < size.width; ++x) {
      const double r = std::hypot(x - 0.5 * (size.width - 1), y - 0.5 * (size.height - 1)) / half_diag;
      const double c = std::cos(std::atan(r * corner_tan));
      g[x] = static_cast<float>(c * c * c * c);
    }
  }
  return gain;
}

}  // namespace

bool PhotoArtefacts::any() const {
  return colour_gains != cv::Vec3d(1.0, 1.0, 1.0) || vignetting > 0.0 || motion_blur_px > 0.0 || jpeg_quality > 0;
}

void PhotoArtefacts::validate() const {
  for (int c = 0; c < 3; ++c) {
    if (!(colour_gains[c] >= 0.5 && colour_gains[c] <= 1.5))
      throw std::invalid_argument("PhotoArtefacts: colour gain " + num(colour_gains[c]) + " is not in 0.5 .. 1.5");
  }
  if (!(vignetting >= 0.0 && vignetting <= 0.8))
    throw std::invalid_argument("PhotoArtefacts: vignetting " + num(vignetting) + " is not in 0 .. 0.8");
  if (!(motion_blur_px >= 0.0 && motion_blur_px <= 30.0))
    throw std::invalid_argument("PhotoArtefacts: motion blur " + num(motion_blur_px) + " px is not in 0 .. 30");
  if (!std::isfinite(motion_blur_angle))
    throw std::invalid_argument("PhotoArtefacts: the motion blur's angle is not finite");
  if (!(jpeg_quality >= 0 && jpeg_quality <= 100))
    throw std::invalid_argument("PhotoArtefacts: JPEG quality " + std::to_string(jpeg_quality) +
                                " is not in 0 (none) .. 100");
}

std::string PhotoArtefacts::describe() const {
  std::ostringstream o;
  const char* sep = "";
  if (colour_gains != cv::Vec3d(1.0, 1.0, 1.0)) {
    o << "cast " << num(colour_gains[0]) << "/" << num(colour_gains[1]) << "/" << num(colour_gains[2]);
    sep = ", ";
  }
  if (vignetting > 0.0) {
    o << sep << "vignetting " << num(vignetting);
    sep = ", ";
  }
  if (motion_blur_px > 0.0) {
    o << sep << "blur " << num(motion_blur_px) << " px";
    sep = ", ";
  }
  if (jpeg_quality > 0) o << sep << "JPEG " << jpeg_quality;
  return o.str().empty() ? "none" : o.str();
}

cv::Mat applyPhotoArtefacts(const cv::Mat& bgr, const PhotoArtefacts& a) {
  if (bgr.empty() || bgr.type() != CV_8UC3)
    throw std::invalid_argument("applyPhotoArtefacts: expected a non-empty CV_8UC3 (BGR) image");
  a.validate();
  cv::Mat out = a.motion_blur_px > 0.0 ? motionBlur(bgr, a.motion_blur_px, a.motion_blur_angle) : bgr.clone();
  if (a.vignetting > 0.0 || a.colour_gains != cv::Vec3d(1.0, 1.0, 1.0)) {
    cv::Mat f;
    out.convertTo(f, CV_32FC3);
    if (a.vignetting > 0.0) {
      cv::Mat gain = vignettingGain(out.size(), a.vignetting), gain3;
      cv::merge(std::vector<cv::Mat>{gain, gain, gain}, gain3);
      f = f.mul(gain3);
    }
    f = f.mul(cv::Scalar(a.colour_gains[0], a.colour_gains[1], a.colour_gains[2]));
    f.convertTo(out, CV_8UC3);  // saturates at 0 and 255
  }
  if (a.jpeg_quality > 0) {
    std::vector<unsigned char> buf;
    if (!cv::imencode(".jpg", out, buf, {cv::IMWRITE_JPEG_QUALITY, a.jpeg_quality}))
      throw std::runtime_error("applyPhotoArtefacts: OpenCV could not encode a JPEG");
    out = cv::imdecode(buf, cv::IMREAD_COLOR);
  }
  return out;
}

}  // namespace massage_cell::sim
