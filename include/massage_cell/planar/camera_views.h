// Views of the planar reconstruction from ROS calibrations
// (sensor_msgs/CameraInfo fields, camera::CameraCalibration) and tf poses.
// ROS-free.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

/// The view of one camera whose raw optical frame has the pose
/// `world_from_camera` (REP 103): the image is undistorted and rectified with
/// the calibration's K, D, R into the left 3x3 block of its P (plumb_bob,
/// rational_polynomial or equidistant), and the view's projection maps world
/// points through the pose, R and that block. P's fourth column (a stereo
/// camera's Tx) is not used: the pose already places the camera. Throws
/// std::invalid_argument naming the problem (size mismatch, uncalibrated,
/// non-finite entries, an unknown distortion model).
View viewFromCameraInfo(const std::string& name, const cv::Mat& image, const camera::CameraCalibration& info,
                        const Eigen::Isometry3d& world_from_camera);

/// A set of views from `path`: a VGG folder (images/ + 2D/*.P, see
/// loadVggViews), a folder holding views.yaml, or a views YAML file:
///
///   views:
///     - image: left.png            # relative to the YAML file's folder
///       camera_info: left.yaml     # camera_calibration_parsers format
///       position: [x, y, z]        # the raw optical frame in the world, metres
///       orientation: [qx, qy, qz, qw]
///
/// Throws std::runtime_error naming the file and the problem.
std::vector<View> loadViewSet(const std::string& path);

}  // namespace massage_cell::planar
