// Ground truth of named points (acupoints, landmarks) in a rendered stereo
// frame: where each lies in the left optical frame and in both raw images,
// and whether a method could see it there (in view) or why not. ROS-free.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <string>

#include <Eigen/Core>

#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/stereo_frame.h"

namespace massage_cell::sim {

struct PointTruth {
  Eigen::Vector3d world{0.0, 0.0, 0.0};         ///< world frame `table`
  Eigen::Vector3d left_optical{0.0, 0.0, 0.0};  ///< left camera's optical frame
  /// Pixels in the raw (as rendered) images; NaN when behind the camera.
  Eigen::Vector2d left_pixel{Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN())};
  Eigen::Vector2d right_pixel{Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN())};
  std::uint8_t left_label = 0;  ///< ground-truth label at the left pixel (0 when outside the image)
  /// Distance from the rendered left surface point at the pixel to the point, metres (NaN: none).
  double surface_distance = std::numeric_limits<double>::quiet_NaN();
  /// Inside both images, on the back's skin at its left pixel (label kLabelBack, the surface
  /// there within the tolerance of the point: not under a towel, arm or hair) and seen by the right camera.
  bool in_view = false;
  std::string
      reason;  ///< why not in view ("below the image's bottom edge", "under the towel", ...); empty when in view
};

/// Truth of every point of `world_points` (e.g. BackModel::acupoints() or
/// landmarks()) in `frame`, rendered from `pair`. `tolerance`: metres between
/// the point and the rendered surface at its pixel (default 5 mm).
std::map<std::string, PointTruth> acupointTruth(const std::map<std::string, Eigen::Vector3d>& world_points,
                                                const StereoPairModel& pair, const StereoFrame& frame,
                                                double tolerance = 0.005);

}  // namespace massage_cell::sim
