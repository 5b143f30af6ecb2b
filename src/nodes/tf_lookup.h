// tf2 lookups the nodes share: a point into another frame (cect's ~get_acupoint), a transform that must be fresh
// (the arm's targets), and the positions of a family of frames (the arm's view of the body's acupoints).
#pragma once

#include <string>
#include <vector>

#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <tf2_ros/buffer.h>
#include <Eigen/Core>

namespace massage_cell::nodes {

/// `point` in `target`: the transform at the point's stamp, waited for up to `wall_wait` s of wall time (polled:
/// tf2's own timeout goes by ROS time, which stands still when a replay ends); failing that the latest transform
/// (right for static and slow-moving frames), which `message` notes. False, with `message` saying why, when tf knows
/// no such frame or no path to it.
bool transformPoint(const tf2_ros::Buffer& buffer, const geometry_msgs::PointStamped& point, const std::string& target,
                    double wall_wait, geometry_msgs::PointStamped* out, std::string* message);

/// The transform `target` <- `frame` at `stamp` (0: the latest), waiting up to `timeout` s, and no older than
/// `max_age` s (a chain of static transforms, stamp 0, is never stale). False, with `error` saying why: "'<frame>' is
/// unknown or not connected to <target> (...)" or "'<frame>' is stale: ...".
bool lookupFresh(const tf2_ros::Buffer& buffer, const std::string& target, const std::string& frame,
                 const ros::Time& stamp, double timeout, double max_age, geometry_msgs::TransformStamped* out,
                 std::string* error);

/// The positions in `target` of every frame whose name starts with `prefix`, leaving out those older than `max_age`
/// s and those not connected to `target`.
std::vector<Eigen::Vector3d> framePositions(const tf2_ros::Buffer& buffer, const std::string& target,
                                            const std::string& prefix, double max_age);

}  // namespace massage_cell::nodes
