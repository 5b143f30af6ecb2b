// The calibration marker carried by the press tool: a ChArUco board (OpenCV
// contrib aruco), its detection in a stereo pair and the triangulation of its
// reference point in the left optical frame. ROS-free (OpenCV + Eigen).
//
// Board frame (OpenCV's): the chessboard corners lie in its z = 0 plane, on
// the printed face. The reference point is the board's centre on that face,
// the same point whichever corner OpenCV takes as origin.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::calib {

/// A ChArUco board: squares_x x squares_y squares, ArUco markers in the white ones.
struct CharucoSpec {
  int squares_x = 5;
  int squares_y = 4;
  double square_length = 0.048;  ///< metres
  double marker_length = 0.036;  ///< metres, < square_length
  /// cv::aruco::PREDEFINED_DICTIONARY_NAME (default DICT_4X4_50 = 0).
  int dictionary = 0;

  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
  /// Board size, metres (x, y).
  double width() const { return squares_x * square_length; }
  double height() const { return squares_y * square_length; }
  /// Number of chessboard (inner) corners.
  int cornerCount() const { return (squares_x - 1) * (squares_y - 1); }
};

/// The board's centre in its own frame (metres).
Eigen::Vector3d referencePointInBoard(const CharucoSpec& spec);

/// The printable board image (CV_8U, black and white), `pixels_per_metre`
/// resolution, no margin: pixel (u, v) covers board x in [u, u+1) / ppm from the
/// image's left edge and y from its top edge, as OpenCV draws it.
cv::Mat drawBoard(const CharucoSpec& spec, double pixels_per_metre);

/// A rectified stereo pair's geometry: the 3x4 projections and the rotation
/// from the rectified left frame to the left optical frame (R_left^T).
struct RectifiedGeometry {
  cv::Matx34d P_left, P_right;
  Eigen::Matrix3d left_from_rectified = Eigen::Matrix3d::Identity();
};

/// Geometry of a calibrated pair (camera_info of both cameras). Throws
/// std::invalid_argument when the calibrations are not a usable stereo pair
/// (camera::checkStereoCalibration's problems).
RectifiedGeometry rectifiedGeometry(const camera::CameraCalibration& left, const camera::CameraCalibration& right);

/// true when a calibration is already rectified (D = 0, R = I).
bool isRectified(const camera::CameraCalibration& calib);

/// The image rectified with its camera_info (cv::initUndistortRectifyMap with
/// K, D, R, P); returned unchanged (not copied) when isRectified(calib).
/// Throws std::invalid_argument when the image size differs from the calibration's.
cv::Mat rectify(const camera::CameraCalibration& calib, const cv::Mat& raw);

struct DetectOptions {
  int min_corners = 6;          ///< fewer corners seen in both views: not found
  double max_row_error = 1.0;   ///< pixels: a corner whose rows differ more between the views is dropped
  double max_fit_rms_mm = 2.0;  ///< board model vs triangulated corners: above this, not found
};

/// The marker in one stereo pair.
struct MarkerDetection {
  bool found = false;
  std::string problem;                              ///< why not found (empty when found)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< reference point, left optical frame, metres
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
  int corners = 0;                             ///< corners triangulated (seen in both views)
  double fit_rms_mm = 0.0;                     ///< board model vs triangulated corners
  std::vector<int> ids;                        ///< corner ids used
  std::vector<cv::Point2f> left_px, right_px;  ///< their rectified pixels
};

/// Detects the board in a RECTIFIED pair (BGR or grey), triangulates the
/// corners seen in both views (cv::triangulatePoints with the P matrices),
/// fits the board model to them (Eigen::umeyama) and returns its reference
/// point in the left optical frame. A pair where the board is not found is
/// `found = false` with the reason, not an exception; empty or mismatched
/// images and an invalid spec throw std::invalid_argument.
MarkerDetection detectMarker(const cv::Mat& left, const cv::Mat& right, const RectifiedGeometry& geometry,
                             const CharucoSpec& spec, const DetectOptions& options = {});

}  // namespace massage_cell::calib
