// Reading and writing ROS camera_info YAML files (the format of
// camera_calibration_parsers / camera_info_manager) without ROS, for the
// simulator and the command-line tools. The nodes load calibrations through
// camera_info_manager.
#pragma once

#include <string>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::camera {

/// Writes `calib` as camera_info YAML. Throws std::runtime_error when the
/// file cannot be written.
void writeCameraInfoYaml(const std::string& path, const CameraCalibration& calib, const std::string& camera_name);

/// Reads a camera_info YAML file. Throws std::runtime_error naming the file
/// and the missing or malformed field.
CameraCalibration readCameraInfoYaml(const std::string& path, std::string* camera_name = nullptr);

}  // namespace massage_cell::camera
