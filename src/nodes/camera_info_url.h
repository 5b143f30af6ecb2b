// The file behind a camera_info_manager URL, as the camera drivers resolve it to read and check the calibration
// before they serve it.
#pragma once

#include <string>

namespace massage_cell::nodes {

/// The path of `url` (file://, package://, or empty for the default ${ROS_HOME}/camera_info/${NAME}.yaml), with
/// ${NAME} = `camera_name` and ${ROS_HOME} expanded. Throws camera::ConfigError for another scheme or an unknown
/// package.
std::string calibrationPath(const std::string& url, const std::string& camera_name);

}  // namespace massage_cell::nodes
