// camera::CameraCalibration (ROS-free) <-> sensor_msgs/CameraInfo.
#pragma once

#include <algorithm>

#include <sensor_msgs/CameraInfo.h>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::nodes {

inline camera::CameraCalibration toCalibration(const sensor_msgs::CameraInfo& info) {
  camera::CameraCalibration c;
  c.width = static_cast<int>(info.width);
  c.height = static_cast<int>(info.height);
  c.distortion_model = info.distortion_model;
  c.D = info.D;
  std::copy(info.K.begin(), info.K.end(), c.K.begin());
  std::copy(info.R.begin(), info.R.end(), c.R.begin());
  std::copy(info.P.begin(), info.P.end(), c.P.begin());
  return c;
}

/// The calibration's model and matrices into `info` (size, header, binning
/// and ROI stay).
inline void fromCalibration(const camera::CameraCalibration& c, sensor_msgs::CameraInfo& info) {
  info.distortion_model = c.distortion_model;
  info.D = c.D;
  std::copy(c.K.begin(), c.K.end(), info.K.begin());
  std::copy(c.R.begin(), c.R.end(), info.R.begin());
  std::copy(c.P.begin(), c.P.end(), info.P.begin());
}

}  // namespace massage_cell::nodes
