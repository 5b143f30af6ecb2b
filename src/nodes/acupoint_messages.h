// The cect node's outputs as ROS messages: massage_cell/Acupoint, the acupoint's tf frame, the ~localize_pixels
// response, and rviz markers (~markers: a sphere coloured by body region and the name per acupoint with an estimate).
#pragma once

#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <tf2_ros/buffer.h>

#include "massage_cell/Acupoint.h"
#include "massage_cell/BackLandmark.h"
#include "massage_cell/GetAcupoint.h"
#include "massage_cell/LocalizePixels.h"
#include "massage_cell/cect/given_landmarks.h"
#include "massage_cell/cect/tracker.h"

namespace massage_cell::nodes {

/// A 3x3 matrix into a message's row-major float64[9].
void toRowMajor(const Eigen::Matrix3d& m, double* out);

/// The acupoint's message: its pixel (NaN when not placed), position and covariance when valid, else the reason.
massage_cell::Acupoint acupointMsg(const cect::TrackedAcupoint& point);

/// The layout's landmarks (cect::layoutLandmarks) with their raw left pixels of the camera (full resolution).
std::vector<massage_cell::BackLandmark> landmarkMsgs(const cect::BackLandmarks& landmarks,
                                                     const camera::StereoModel& geometry,
                                                     const camera::Decimation& decimation);

/// The frame `prefix`<name> at the (valid) acupoint's position, axes parallel to `header`'s frame.
geometry_msgs::TransformStamped acupointTransform(const std_msgs::Header& header, const std::string& prefix,
                                                  const cect::TrackedAcupoint& point);

/// ~localize_pixels' response of the library's answer, in `header`'s frame.
void fillResponse(const std_msgs::Header& header, const cect::PixelPoints& located,
                  massage_cell::LocalizePixels::Response* response);

/// ~get_acupoint's response of the tracker's estimate `estimate` of `name` (stamped with `header`: the pair it was
/// published with) as a point in `target` (empty: `header`'s frame) through `tf`, waiting up to `wall_wait` s.
void fillResponse(const std::string& name, const cect::TrackedAcupoint& estimate, const std_msgs::Header& header,
                  const std::string& target, const tf2_ros::Buffer& tf, double wall_wait,
                  massage_cell::GetAcupoint::Response* response);

/// A sphere and the name of acupoint number `index` at `position` (DELETE both when it has no estimate); measured
/// points in their region's colour, held ones grey.
void addAcupointMarkers(const std_msgs::Header& header, int index, const cect::TrackedAcupoint& point,
                        visualization_msgs::MarkerArray* markers);

}  // namespace massage_cell::nodes
