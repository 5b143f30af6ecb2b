// The trunk out of the skin-coloured region: skin colour alone takes in the
// arms lying along the trunk, raised beside the head or held a little away,
// and sheets or towels of a skin-like colour. Used by segmentBack on its
// cleaned mask, before the back's component is chosen. ROS-free.
//
// - Cloth: woven (fine, terry, waffle) cloth has a fine texture that skin seen
//   from a metre does not: pixels whose relative fine-scale contrast (a
//   band-pass of the grey, rms over a small window) exceeds cloth_contrast,
//   in patches wider than a crease and larger than a mole, away from the
//   silhouette's edge (then grown back to it), leave the mask.
// - Arms held away from the trunk: per row, only the run of skin that holds
//   the body's centre line stays (an arm joins the trunk at the shoulder only).
// - Arms touching the trunk: between arm and trunk lies a crease, a valley of
//   the brightness (log grey, so dark skin counts as much as light) running
//   along the body. Per side, a Viterbi path through the rows picks the
//   crease within a band of the run's width from its outer end, or "no crease"
//   where there is none (above the axilla, below the hands, armless); a side
//   whose crease runs unbroken over at least min_arm_fraction of the rows is
//   an arm, cut off at the crease.
// Rows are image rows: the body lies along the columns (head up or down,
// turned by up to ~20 degrees). The pixel sizes below are for a body whose
// rows of skin are 290 px wide (median; the reference view) and scale with
// the body in view.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace massage_cell::cect {

struct TrunkParams {
  bool reject_cloth = false;  ///< off by default: the shading at skin edges and aliased images read as texture too
  /// Relative fine-scale contrast (rms of the grey's band-pass between
  /// cloth_sigma and 2 cloth_sigma, over the local brightness + 20 grey
  /// levels) above which a pixel is cloth, not skin.
  double cloth_contrast = 0.006;
  double cloth_sigma = 0.6;       ///< band-pass scale, pixels
  double cloth_window = 4.0;      ///< rms window (Gaussian sigma), pixels
  int cloth_open_radius = 9;      ///< cloth patches narrower than twice this (moles, creases, edges) stay skin, pixels
  double cloth_min_area = 0.005;  ///< ... and those covering less than this fraction of the image
  bool separate_arms = true;      ///< the central run and the creases (false: the skin region stays whole)
  /// The crease is searched between these fractions of the row's skin width from each end.
  double crease_min = 0.1;
  double crease_max = 0.33;
  double crease_sigma = 2.0;  ///< smoothing of the log grey before the valley test, pixels
  double crease_reach =
      24.0;  ///< a valley is measured against the crests within this many pixels either side (~ an arm's half-width)
  /// Weakest valley, log-brightness units (0.02: the crease 2 % darker than the crests either side).
  double crease_strength = 0.02;
  double crease_jump = 2.0;  ///< pixels a crease may move between rows
  /// An arm's crease runs without a break over at least this fraction of the
  /// trunk's rows (from the axilla down past the waist; a scapula's edge is shorter).
  double min_arm_fraction = 0.4;
};

/// What cutToTrunk found.
struct TrunkReport {
  int cloth_pixels = 0;      ///< skin-coloured cloth removed
  int side_run_pixels = 0;   ///< skin beside the central run removed (arms held away, hands)
  bool arm_left = false;     ///< arm cut at a crease on the image's left
  bool arm_right = false;    ///< ... on the image's right
  int crease_rows_left = 0;  ///< rows of the crease on the image's left
  int crease_rows_right = 0;
  std::string summary() const;  ///< one line, e.g. "arms cut at creases: left, right; cloth 1200 px"
};

/// Cuts `mask` (CV_8U, 255 skin) of the BGR image `bgr` to the trunk (see
/// above). Never throws for image content; throws std::invalid_argument for
/// a mask that is not CV_8U of the image's size.
TrunkReport cutToTrunk(const cv::Mat& bgr, cv::Mat* mask, const TrunkParams& params);

}  // namespace massage_cell::cect
