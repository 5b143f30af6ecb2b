// CECT step 1: the back in one view. A skin score from chroma (robust to the
// light's direction and strength: brightness is left out), thresholded per
// image, cleaned morphologically; the largest component with its holes
// filled; its outer contour, smoothed and resampled uniformly. ROS-free.
//
// The score is continuous and crosses 0 at the back's border, so callers can
// find sub-pixel border crossings along any line (CECT's epipolar lines) by
// interpolating the score linearly between two pixels.
//
// Method (details in segmentation.cpp): log-chromaticity (ln R/G, ln G/B),
// blurred; the back detected as the most chromatic distinct class (Otsu,
// repeated inside the upper class while it is bimodal) that is reddish and
// uniform like skin; the score is then a two-class linear fit of the back's
// chroma against its immediate surroundings (+0.5 skin, -0.5 surroundings),
// so its zero crossing is the unbiased mid-point of the blurred border.
// Limits: chroma only, so anything uniformly skin-coloured next to the back
// joins it, and over-exposed skin (channels clipped at 255) loses its chroma.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/cect/trunk.h"

namespace massage_cell::cect {

struct SegmentationParams {
  double blur_sigma = 1.5;          ///< Gaussian smoothing of the chroma before scoring, pixels
  double min_area_fraction = 0.03;  ///< smallest back, as a fraction of the image
  int open_radius = 2;              ///< morphological opening (removes specks), pixels
  int close_radius = 4;             ///< morphological closing (bridges the spine groove's shadow), pixels
  double contour_spacing = 4.0;     ///< distance between contour samples, pixels
  double contour_smoothing = 2.0;   ///< Gaussian smoothing of the contour along its length, samples (0: none)
  /// Pixels closer than this to the image border are "at the border": a back
  /// whose contour runs along the border is partly out of view.
  int border_margin = 2;
  /// The trunk out of the skin-coloured region (arms, skin-coloured cloth): trunk.h.
  TrunkParams trunk;
};

struct Segmentation {
  bool valid = false;
  /// Why not valid; always starts "no back in view: " (no skin-coloured
  /// region, too small, multi-coloured, ...). A back partly out of view is
  /// still valid: see border_fraction.
  std::string reason;
  /// CV_32F, same size as the image: > 0 on skin, < 0 elsewhere, 0 at the
  /// threshold (chosen per image). Smooth (blurred).
  /// Its sign agrees with `mask` everywhere (never exactly 0): where the
  /// cleaning changed the mask (filled holes, closed gaps, removed specks,
  /// skin-coloured regions other than the back) the score is set to +-0.5,
  /// so zero crossings are exactly the back's border. About +0.5 on the
  /// back's skin and -0.5 on its surroundings; far from the back the
  /// magnitude means nothing. Not valid: -0.5 everywhere.
  cv::Mat score;
  /// CV_8U 255 on the back (largest component, holes filled), 0 elsewhere.
  cv::Mat mask;
  /// The outer contour of `mask`, closed (last sample connects to the first),
  /// counter-clockwise in image coordinates (x right, y down, so the interior
  /// is to the left when walking it), resampled every `contour_spacing` px.
  /// Precisely: counter-clockwise as seen on the image, i.e. the shoelace
  /// area sum(x_i y_i+1 - x_i+1 y_i) / 2 is negative, and the interior lies
  /// on (t.y, -t.x) for a walking direction t. Spacing is L / round(L /
  /// contour_spacing) for the perimeter L; each sample is then moved along
  /// its normal onto the score's zero crossing (sub-pixel, < 2 px). Empty
  /// when not valid.
  std::vector<cv::Point2f> contour;
  /// Fraction of the contour's samples within `border_margin` of the image
  /// border (0: the back is entirely in view). Such samples lie on the
  /// image's edge, not on the back's border: callers decide what to accept.
  double border_fraction = 0.0;
  /// What was cut away from the skin-coloured region to leave the trunk.
  TrunkReport trunk;
  /// Pieces of skin joined to another across a thin band that split the back
  /// (a strap, a seam, a row of paper tags), after the trunk was cut out.
  int joined_pieces = 0;
};

/// Segments the back in a BGR (CV_8UC3) image. `background` (optional,
/// CV_8U of the image's size): pixels known not to be the back whatever
/// their colour (depth_gate.h: the floor far behind the table); they take
/// no part in choosing the skin's colour and never join the back. `depth`
/// (optional, CV_32F metres, NaN unknown; depth_gate.h): pixels well above
/// the back's surroundings whose colour is not clearly the surroundings'
/// (skin whose chroma a sheen has paled) join it, inside its border. Never
/// throws for image content; throws std::invalid_argument for an empty or
/// non-CV_8UC3 image or a background mask of another size or type.
/// Thread-safe (no shared state). ~3 ms for 640 x 480 (Release, 2 cores).
/// `marks` (optional, CV_8U): pixels that are skin whatever their colour (skin markers' dots: skinMarkerPixels).
Segmentation segmentBack(const cv::Mat& bgr, const SegmentationParams& params = {},
                         const cv::Mat& background = cv::Mat(), const cv::Mat& depth = cv::Mat(),
                         const cv::Mat& marks = cv::Mat());

/// Sub-pixel x positions where `score` changes sign along row y (y may be
/// fractional: the score is interpolated bilinearly between rows), in
/// increasing x; `rising` (optional) receives true where the score goes from
/// < 0 to > 0 (entering the back walking right).
/// Each crossing is interpolated linearly between the two pixels around it;
/// a run of exact zeros between opposite signs gives one crossing at its
/// middle, zeros with the same sign on both sides or at the row's ends none
/// (NaN counts as 0). Empty for an empty score or y outside [0, rows - 1];
/// throws std::invalid_argument for a score that is not CV_32FC1.
std::vector<double> rowCrossings(const cv::Mat& score, double y, std::vector<bool>* rising = nullptr);

}  // namespace massage_cell::cect
