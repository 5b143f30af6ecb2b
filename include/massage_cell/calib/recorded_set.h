// A folder of recorded calibration poses, so a real cell can calibrate from
// files (hand_eye_calibrate --data DIR). ROS-free (yaml-cpp, OpenCV).
//
// DIR/left.yaml, DIR/right.yaml   camera_info YAML of the two cameras (as
//                                 camera_info_manager writes them); raw
//                                 images are rectified with them, rectified
//                                 ones (D = 0, R = I) are used as they are
// DIR/poses.yaml:
//   marker_offset: [0.0, 0.0, 0.06]   # optional: marker centre - tool tip, m, arm base frame
//   poses:
//     - {left: pose_00_left.png, right: pose_00_right.png, tool_tip: [0.10, 0.20, 0.25]}
//     - ...
// tool_tip is the commanded tool tip in arm_base_link (joints + tool_offset
// of config/arm.yaml), metres; image paths are relative to DIR.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::calib {

struct RecordedPose {
  std::string left, right;  ///< image paths (as written in poses.yaml: relative to the folder)
  Eigen::Vector3d tool_tip = Eigen::Vector3d::Zero();
};

struct RecordedSet {
  camera::CameraCalibration left_info, right_info;
  std::optional<Eigen::Vector3d> marker_offset;
  std::vector<RecordedPose> poses;
};

/// Reads DIR/left.yaml, DIR/right.yaml and DIR/poses.yaml (not the images).
/// Throws std::runtime_error naming the file and the missing or malformed field.
RecordedSet readRecordedSet(const std::string& dir);

/// Writes left.yaml, right.yaml and poses.yaml into DIR (which must exist);
/// the images are the caller's. Throws std::runtime_error naming the file.
void writeRecordedSet(const std::string& dir, const RecordedSet& set);

}  // namespace massage_cell::calib
