// Sub-pixel disparity from the cost volume: the integer labels of the
// optimisers (HBDS, expansion, swap, WTA) quantise depth (z = f B / d: one
// level is 23 mm at 0.9 m on the bundled rig); a curve through the
// window-summed cost at d - 1, d, d + 1 puts each label at its minimum.
// ROS-free (OpenCV only).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"

namespace massage_cell::stereo {

/// The curve through the three costs: a parabola (exact for a cost quadratic
/// around its minimum, as correlation costs are) or two lines of equal and
/// opposite slope (exact for a V, as absolute-difference costs are).
enum class SubpixelFit { kParabola, kEquiangular };
SubpixelFit parseSubpixelFit(const std::string& name);  ///< "parabola" | "equiangular"
std::string toString(SubpixelFit fit);

struct SubpixelParams {
  SubpixelFit fit = SubpixelFit::kParabola;
  /// Odd side of the square window the cost is summed over before the
  /// parabola is fitted (1: the pixel's own cost). Summing averages out the
  /// colour term's noise; the window is clipped at the image border.
  int window = 5;
  /// The largest offset from the integer label (pixels, in (0, 0.5]): a
  /// minimum farther out is clamped to it. A label that is a strict local
  /// minimum of the summed cost has its curve's minimum within 0.5.
  float max_offset = 0.5f;
};

/// Throws std::invalid_argument naming the first bad parameter.
void validate(const SubpixelParams& params);

/// `disparity` (CV_32F, labels in the volume's range, NaN allowed) with each
/// integer label d moved to the minimum of the curve through the
/// window-summed cost at d - 1, d, d + 1 where d is a strict local minimum
/// of that cost. Unchanged: NaN pixels, values that are not integers
/// (already sub-pixel), dmin and dmax, and labels where the summed cost is
/// not a strict minimum (a label the smoothness term moved off the data
/// term's minimum keeps its value). Throws std::invalid_argument naming the
/// problem (sizes differ, not CV_32F, a value outside the volume's range,
/// bad window or max_offset).
cv::Mat subpixelDisparity(const CostVolume& volume, const cv::Mat& disparity, const SubpixelParams& params = {});

}  // namespace massage_cell::stereo
