// What a real camera or a phone photo does to an image that the renderer does
// not: a colour cast (white balance), vignetting, motion blur, JPEG
// compression. Applied to a rendered 8-bit BGR image, deterministically.
// ROS-free (OpenCV only; JPEG through OpenCV's codec).
#pragma once

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace massage_cell::sim {

struct PhotoArtefacts {
  /// Per-channel gains (B, G, R) of a wrong white balance, each 0.5 .. 1.5
  /// (1, 1, 1: none). A tungsten cast is about (0.8, 0.95, 1.15).
  cv::Vec3d colour_gains{1.0, 1.0, 1.0};
  /// Brightness lost at the image's corners, 0 .. 0.8 (cos^4-like fall-off
  /// from the centre; 0: none).
  double vignetting = 0.0;
  /// Length of a linear motion blur, pixels, 0 .. 30 (0: none), and its
  /// direction in the image, radians from the x axis.
  double motion_blur_px = 0.0;
  double motion_blur_angle = 0.0;
  /// JPEG quality 1 .. 100 of a compress-decompress round trip (0: none).
  int jpeg_quality = 0;

  bool any() const;
  /// Throws std::invalid_argument naming the first value out of range.
  void validate() const;
  /// One line, e.g. "cast 0.80/0.95/1.15, vignetting 0.3, blur 4 px, JPEG 60".
  std::string describe() const;
};

/// `bgr` (CV_8UC3) with the artefacts in the order a camera makes them:
/// motion blur (the exposure), vignetting (the lens), the colour cast (white
/// balance), JPEG (the file). Throws std::invalid_argument for a bad image or
/// bad artefacts.
cv::Mat applyPhotoArtefacts(const cv::Mat& bgr, const PhotoArtefacts& artefacts);

}  // namespace massage_cell::sim
