// What lies far behind the body: the floor and the room seen past the
// table's ends and sides. Their colour can be anything, a warm grey or a
// wooden floor as close to pale skin as skin is to itself, so the skin
// segmentation is told from depth where they are: a coarse dense disparity
// (OpenCV's StereoSGBM on a copy about 120 rows high) of each rectified view,
// and every pixel whose depth lies more than `gap` metres behind the nearest
// surfaces of the view (the body and the table) is "far". Pixels without a
// disparity (untextured, or seen by one camera only) are not far. ROS-free.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "massage_cell/camera/stereo_model.h"

namespace massage_cell::cect {

struct DepthGateParams {
  /// Metres behind the nearest surfaces beyond which a pixel is background
  /// (a prone body is at most ~0.35 m thick, a massage table 0.6-0.9 m high:
  /// the floor lies well beyond). 0: no gate.
  double gap = 0.45;
  /// Share of the view's pixels with a disparity that are the "nearest
  /// surfaces": their depth is this quantile of the depths (the body and
  /// the table fill most of a cell's view).
  double nearest_quantile = 0.2;
  /// Metres above the support's plane (tablePixels) below which a pixel is
  /// the table: used only to retry a view whose segmentation failed (a sheet
  /// or towel of skin's colour joined to the back). The rim of a prone trunk
  /// seen from above stands at half its thickness, ~10 cm up. 0: no retry.
  double table_margin = 0.03;
};

struct DepthGate {
  /// CV_8U 255 where a rectified view's pixel is far behind the nearest
  /// surfaces; empty when the gate is off or found nothing to measure.
  cv::Mat left_far, right_far;
  /// CV_32F, each rectified view's coarse depth (metres along the optical
  /// axis, nearest-neighbour upsampled; NaN without a disparity); empty with
  /// left_far.
  cv::Mat left_depth, right_depth;
  /// CV_8U 255 where a view's pixel was taken for the table (tablePixels)
  /// to retry its segmentation; empty where no retry was needed or helped.
  cv::Mat left_table, right_table;
  double nearest_depth = 0.0;   ///< metres: the nearest surfaces' depth (0: not measured)
  double far_depth = 0.0;       ///< metres: beyond this a pixel is far
  std::string summary() const;  ///< one line for diagnostics
};

/// The far pixels of a rectified pair (CV_8UC3 or CV_8UC1, same size, as
/// `geometry` rectifies them); disparities are searched over `range`
/// ([min, max] rectified pixels, disparityRange). Never throws for image
/// content; throws std::invalid_argument for images of different sizes or
/// types.
DepthGate farBackground(const cv::Mat& left_rect, const cv::Mat& right_rect, const camera::StereoModel& geometry,
                        const cv::Vec2d& range, const DepthGateParams& params = {});

/// The pixels of one view (its coarse `depth`, CV_32F, NaN unknown; `far`,
/// CV_8U or empty) lying less than `margin` metres above its support's
/// plane: the largest plane (RANSAC, 2 cm) with no more than 5 % of the
/// view's near points behind it (a plane through the back has the table
/// behind it), refined by least squares. The view's own pixel coordinates
/// are triangulated with `geometry`'s left camera (the plane is used only
/// in that view). Empty when no plane holds 10 % of the points.
cv::Mat tablePixels(const cv::Mat& depth, const cv::Mat& far, const camera::StereoModel& geometry, double margin);

}  // namespace massage_cell::cect
