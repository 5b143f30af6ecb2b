// The acupoint chain on one analysed pair, in one place for the node and the
// tools: landmarks of the back in the left view, the model's corrections with
// the back's 3D, each acupoint placed in the left image and localised in 3D
// by CECT. ROS-free.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/given_landmarks.h"
#include "massage_cell/cect/layout_check.h"
#include "massage_cell/cect/skin_markers.h"

namespace massage_cell::cect {

struct LocateOptions {
  /// Move the midline off the silhouette's parallax (correctMidlineParallax).
  bool correct_parallax = true;
  /// The waist at the spine's height and the levels spaced along the body
  /// in 3D (correctWaistParallax, measureLevelsIn3D).
  bool levels_in_3d = true;
  /// Landmarks given from outside (a therapist's clicks, skin markers): they replace the found ones of the same name
  /// (applyGivenLandmarks). A given landmark that cannot be applied makes the pair invalid with the reason.
  std::vector<GivenLandmark> given;
  /// Refuse a layout that fails the plausibility checks (checkLayout): the pair is then not valid, its reason
  /// "layout not trusted: ...", and its points placed but not valid. Off only to measure what the checks do.
  bool check_layout = true;
  /// ... among them: which landmarks must have been measured or given (checkLayout).
  TrustRules trust;
};

/// One acupoint of the model in one pair.
struct LocatedAcupoint {
  std::string name;
  std::string region;
  bool placed = false;    ///< the model put it on a left-image pixel
  cv::Point2f rectified;  ///< that pixel, rectified left image
  cv::Point2f raw;        ///< ... and raw left image
  LocalizedPoint point;   ///< CECT's 3D point there (point.valid); its covariance is the matching's
  /// The layout's uncertainty there (layoutCovariance) and the point's whole
  /// uncertainty, matching plus layout (metres^2, left optical frame).
  Eigen::Matrix3d layout_covariance = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  bool valid = false;  ///< placed and localised
  std::string reason;  ///< why not valid
};

struct LocatedAcupoints {
  /// The pair gave acupoints (a back was seen and its landmarks found);
  /// otherwise `reason` says why and every point carries it.
  bool valid = false;
  std::string reason;
  BackLandmarks landmarks;
  LayoutCheck check;  ///< the layout's plausibility (when landmarks were found)
  /// What the frame's skin markers gave (with CectParams::skin_markers): each found in both views is a given
  /// landmark (source "marker") unless LocateOptions::given has one of its name (a click overrides a sticker).
  SkinMarkers markers;
  std::vector<LocatedAcupoint> points;  ///< in the model's order
  int validCount() const;
};

/// Runs the chain on `frame` (valid or not: an invalid frame gives every
/// point its reason). Never throws for image content.
LocatedAcupoints locateAcupoints(const CectFrame& frame, const AcupointModel& model, const LocateOptions& options = {});

/// The layout alone on one view's segmentation (a photo, no 3D): landmarks, the given ones, every acupoint placed in
/// pixels (lateral offsets from the shoulder width in pixels: one scale for the whole image) and the plausibility
/// checks that need no scale. Points are valid when placed (no `point`, no covariance). Never throws for image content.
LocatedAcupoints locateLayout(const Segmentation& view, const AcupointModel& model, const LocateOptions& options = {});

}  // namespace massage_cell::cect
