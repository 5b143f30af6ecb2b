// Spinning helpers shared by the rostest nodes (roscpp; test_util.h stays ROS-free).
#pragma once

#include <ros/ros.h>

namespace massage_cell::test {

/// Spins the global callback queue until done() holds or `timeout` wall
/// seconds pass; returns done().
template <typename Done>
bool spinUntil(Done done, double timeout) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && !done() && ros::WallTime::now() < end) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  return done();
}

}  // namespace massage_cell::test
