#include "tf_lookup.h"

#include <cstdio>
#include <sstream>

#include <ros/ros.h>
#include <tf2/exceptions.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>

namespace massage_cell::nodes {

namespace {

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", s);
  return buf;
}

}  // namespace

bool transformPoint(const tf2_ros::Buffer& buffer, const geometry_msgs::PointStamped& point, const std::string& target,
                    double wall_wait, geometry_msgs::PointStamped* out, std::string* message) {
  const std::string& source = point.header.frame_id;
  if (!buffer._frameExists(target)) {
    *message = "tf knows no frame '" + target + "'";
    return false;
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(wall_wait);
  while (!buffer.canTransform(target, source, point.header.stamp) && ros::WallTime::now() < deadline) {
    ros::WallDuration(0.005).sleep();
  }
  try {
    geometry_msgs::TransformStamped t;
    std::string note;
    if (buffer.canTransform(target, source, point.header.stamp)) {
      t = buffer.lookupTransform(target, source, point.header.stamp);
    } else {
      t = buffer.lookupTransform(target, source, ros::Time(0));
      std::ostringstream n;
      n << " (latest transform, " << (point.header.stamp - t.header.stamp).toSec() << " s from the estimate)";
      note = n.str();
    }
    tf2::doTransform(point, *out, t);
    out->header.stamp = point.header.stamp;
    out->header.frame_id = target;
    *message = "in " + target + note;
    return true;
  } catch (const tf2::TransformException& ex) {
    *message = "no transform from '" + source + "': " + ex.what();
    return false;
  }
}

bool lookupFresh(const tf2_ros::Buffer& buffer, const std::string& target, const std::string& frame,
                 const ros::Time& stamp, double timeout, double max_age, geometry_msgs::TransformStamped* out,
                 std::string* error) {
  try {
    *out = buffer.lookupTransform(target, frame, stamp, ros::Duration(timeout));
  } catch (const tf2::TransformException& e) {
    *error = "'" + frame + "' is unknown or not connected to " + target + " (" + e.what() + ")";
    return false;
  }
  if (!out->header.stamp.isZero()) {  // a chain of static transforms has stamp 0: never stale
    const double age = (ros::Time::now() - out->header.stamp).toSec();
    if (age > max_age) {
      *error =
          "'" + frame + "' is stale: its transform is " + seconds(age) + " s old (limit " + seconds(max_age) + " s)";
      return false;
    }
  }
  return true;
}

std::vector<Eigen::Vector3d> framePositions(const tf2_ros::Buffer& buffer, const std::string& target,
                                            const std::string& prefix, double max_age) {
  std::vector<Eigen::Vector3d> positions;
  std::vector<std::string> frames;
  buffer._getFrameStrings(frames);
  const ros::Time now = ros::Time::now();
  for (const std::string& frame : frames) {
    if (frame.rfind(prefix, 0) != 0) continue;
    try {
      const auto t = buffer.lookupTransform(target, frame, ros::Time(0));
      if (!t.header.stamp.isZero() && (now - t.header.stamp).toSec() > max_age) continue;  // gone
      positions.emplace_back(t.transform.translation.x, t.transform.translation.y, t.transform.translation.z);
    } catch (const tf2::TransformException&) {
    }
  }
  return positions;
}

}  // namespace massage_cell::nodes
