// A rendered stereo frame with its exact ground truth, and writing it in the
// simulator's folder format. ROS-free.
#pragma once

#include <map>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/renderer.h"

namespace massage_cell::sim {

struct StereoFrame {
  ViewRender left, right;
  /// Rectified pairs only (empty otherwise): fx * B / depth of each view, NaN
  /// where the depth is undefined.
  cv::Mat left_disparity, right_disparity;
  /// CV_8U, 255 where the left view's surface point is also seen by the right
  /// camera, 0 where it is occluded in the right view or nothing was hit.
  cv::Mat left_visible;
};

/// Renders both views of `pair` and derives the ground truth. Visibility is
/// decided by casting a ray from the right camera to each left surface point.
StereoFrame renderStereoFrame(const Renderer& renderer, const StereoPairModel& pair, const Lighting& lighting,
                              const RenderOptions& options);

/// Disparity map fx * baseline / depth (NaN where depth is not finite or <= 0).
cv::Mat disparityFromDepth(const cv::Mat& depth, double fx, double baseline);

/// true when world point `p` is seen by `camera`: in front, inside the image,
/// and the first surface along the ray from the camera is within `tolerance` metres of p.
bool isVisible(const Renderer& renderer, const CameraModel& camera, const Eigen::Vector3d& p, double tolerance = 1e-3);

/// Expresses world points in a camera's optical frame.
std::map<std::string, Eigen::Vector3d> toCameraFrame(const std::map<std::string, Eigen::Vector3d>& world_points,
                                                     const CameraModel& camera);

/// Writes a float map as PFM (non-finite values kept). Throws std::runtime_error.
void writePfm(const std::string& path, const cv::Mat& map);
/// Writes an image (PNG / JPEG by extension). Throws std::runtime_error naming the file.
void writeImage(const std::string& path, const cv::Mat& image);

}  // namespace massage_cell::sim
