// The acupoints of a stream of stereo pairs: each pair's located acupoints (locate.h) through the per-point
// temporal filter (temporal_filter.h), with what the cell publishes for each point - its estimate and whole
// uncertainty, or why it has none - and the queries of the cect node's services. ROS-free; the node wraps it.
#pragma once

#include <limits>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/cect/temporal_filter.h"

namespace massage_cell::cect {

/// One acupoint after a pair.
struct TrackedAcupoint {
  std::string name, region;
  bool placed = false;    ///< the model placed it in this pair's left view
  cv::Point2f rectified;  ///< that pixel in the (processed) rectified left view
  cv::Point2f raw;        ///< ... in the camera's raw left image
  bool measured = false;  ///< localised in 3D in this pair
  bool accepted = false;  ///< ... and taken by the temporal filter
  /// The estimate (filtered, or held from earlier pairs for max_age): position in the left optical frame and its
  /// whole uncertainty (the filtered matching noise plus the layout's, which no averaging removes), metres.
  bool valid = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double stamp = 0.0;  ///< seconds: the pair it was published with
  std::string reason;  ///< valid: why this pair did not measure it (empty when it did); else why there is none
};

/// What one pair did to the tracked acupoints.
struct TrackerUpdate {
  std::vector<TrackedAcupoint> points;  ///< in the model's order
  std::string problem;                  ///< non-empty: the pair gave no acupoint at all (and why)
  int measured = 0;                     ///< points localised in this pair
  int valid = 0;                        ///< points with an estimate after it
  bool reset = false;                   ///< the stamps went back (a replay started over): estimates cleared first
  std::string landmarks;                ///< describeLandmarks and the check's notes (when the pair found landmarks)
  double body_angle_deg = std::numeric_limits<double>::quiet_NaN();  ///< the body's turn on the table (landmarks)
};

class AcupointTracker {
 public:
  /// Throws std::invalid_argument for an empty or invalid model (AcupointModel::validate).
  explicit AcupointTracker(AcupointModel model);
  const AcupointModel& model() const { return model_; }
  /// Throws std::invalid_argument for bad parameters (the previous ones stay).
  void setParams(const TemporalFilterParams& params);
  const TemporalFilterParams& params() const { return params_; }

  /// One analysed pair at `stamp` (seconds), its located acupoints and the decimation between the processed images
  /// and the camera's (raw pixels are reported in the camera's). A pair without a usable back invalidates every
  /// point (the subject may have left); otherwise a point not measured keeps its estimate for max_age.
  const TrackerUpdate& update(const LocatedAcupoints& located, double stamp, const camera::Decimation& decimation);
  const TrackerUpdate& last() const { return last_; }
  int rejectedOutliers() const { return filter_.rejected(); }

  /// The last published estimate of `name` if it is at most max_age old at `now`; else an invalid point whose
  /// reason says why (unknown name - naming the known ones -, no estimate, too old).
  TrackedAcupoint estimate(const std::string& name, double now) const;

 private:
  AcupointModel model_;
  TemporalFilterParams params_;
  TemporalFilter filter_;
  std::map<std::string, Eigen::Matrix3d> layout_covariance_;  ///< of each point's last accepted measurement
  double last_stamp_ = 0.0;
  bool any_ = false;
  TrackerUpdate last_;
};

/// One pixel of the left image localised in 3D on the analysed pair (the ~localize_pixels service).
struct PixelPoint {
  bool valid = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  std::string reason;  ///< why not valid
};

struct PixelPoints {
  bool success = false;  ///< the frame could be asked (some pixels may still be invalid)
  std::string message;   ///< "3 of 4 pixels localised", or why none could be
  std::vector<PixelPoint> points;
};

/// Raw left pixels of the camera (mapped into `frame`'s processed images by `decimation`) localised on `frame`;
/// `frame` may be null (no pair analysed yet). Never throws for the pixels' values.
PixelPoints localizePixels(const CectFrame* frame, const camera::Decimation& decimation,
                           const std::vector<cv::Point2d>& raw_pixels);

/// The left view with CECT's analysis (CectFrame::drawDebug) and the tracked acupoints at their rectified pixels
/// (filled: measured and accepted; red ring: measured, rejected by the filter; grey ring: placed, not localised)
/// and the layout's `landmarks` as crosses with their names and sources ("C7 given (clicked)"; magenta: given, cyan:
/// measured, grey: inferred), scaled up by an integer factor to at least `min_width` pixels so the names stay
/// legible. Empty when the frame has no left image.
cv::Mat drawAcupoints(const CectFrame& frame, const std::vector<TrackedAcupoint>& points, int min_width,
                      const std::vector<LayoutLandmark>& landmarks = {});

/// The integer factor drawAcupoints scales a `cols`-wide view by to reach `min_width` (>= 1); a pixel (x, y) of its
/// image is the view's ((x + 0.5) / factor - 0.5, (y + 0.5) / factor - 0.5).
int debugImageScale(int cols, int min_width);

}  // namespace massage_cell::cect
