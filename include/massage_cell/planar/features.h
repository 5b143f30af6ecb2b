// Features of calibrated views and their matches across views: keypoints
// (OpenCV AKAZE / ORB / SIFT), line segments (ximgproc FastLineDetector),
// point tracks and line tracks triangulated in 3D. ROS-free.
//
// Matching uses the calibration first (epipolar distance, cheirality, the
// reprojection into every other view) and appearance second (descriptor
// distance with Lowe's ratio for points; the normalised cross-correlation
// of the two strips beside the segment, sampled at epipolar-corresponding
// positions, for lines).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

struct FeatureParams {
  std::string detector = "akaze";     ///< "akaze", "orb" or "sift"
  int max_keypoints = 5000;           ///< per view, strongest kept
  double min_segment_length = 0.025;  ///< line segments shorter than this fraction of the image diagonal are dropped
  double epipolar_tolerance = 1.5;    ///< pixels: distance of a match from its epipolar line / of a reprojection
  double ratio = 0.8;                 ///< Lowe's ratio test on descriptor distances
  double min_line_ncc = 0.6;          ///< two-view line matches: strip correlation at least this
  double max_line_angle_deg = 20.0;  ///< 2-view line matches: orientation difference at most this (after accounting for
                                     ///< the views' rotation it is loose)
  /// Throws std::invalid_argument naming the field for a bad value.
  void validate() const;
};

struct ViewFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;              ///< one row per keypoint
  std::vector<cv::Vec4f> segments;  ///< x0 y0 x1 y1, pixels
};

/// Keypoints, descriptors and line segments of one view.
ViewFeatures detectFeatures(const View& view, const FeatureParams& params);

/// (view index, feature index in that view's keypoints or segments).
using Observation = std::pair<int, int>;

struct PointTrack {
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  std::vector<Observation> observations;  ///< >= 2, at most one per view
  double reprojection_rms = 0.0;          ///< pixels, over the observations
};

struct LineTrack {
  /// End points of the 3D segment: the line triangulated from all its
  /// observations, bounded by the union of the observed segments' extents.
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  std::vector<Observation> observations;  ///< >= 2, at most one per view
  Eigen::Vector3d direction() const { return (b - a).normalized(); }
};

/// Point tracks over all views (each view's keypoints matched to every
/// other's, consistent with the calibration; chained into tracks, each
/// triangulated with all its observations and kept when every reprojection
/// is within epipolar_tolerance and the point is in front of every camera).
std::vector<PointTrack> matchPoints(const std::vector<View>& views, const std::vector<ViewFeatures>& features,
                                    const FeatureParams& params);

/// Line tracks over all views: segments of view i whose epipolar band meets
/// a segment of view j. Where another view can check the triangulated line,
/// it must reproject onto one of that view's segments and the strips beside
/// the two segments must still correlate loosely (0.5); where none can (two
/// views, or the line out of frame or near-epipolar elsewhere), the strips
/// must correlate at min_line_ncc, and supported candidates rank first. Lines
/// within 10 degrees of an epipolar direction cannot be triangulated and are left out.
std::vector<LineTrack> matchLines(const std::vector<View>& views, const std::vector<ViewFeatures>& features,
                                  const FeatureParams& params);

}  // namespace massage_cell::planar
