// Runs one nodelet of this package as a plain node (the pattern of
// stereo_image_proc's node executables); exits 1 when the nodelet fails to
// load, e.g. on a configuration error it has logged.
#pragma once

#include <nodelet/loader.h>
#include <ros/ros.h>

namespace massage_cell::nodes {

inline int runNodelet(int argc, char** argv, const char* default_name, const char* nodelet_type) {
  ros::init(argc, argv, default_name);
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string nodelet_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), nodelet_type, remappings, nodelet_argv)) {
    ROS_FATAL_STREAM(ros::this_node::getName() << ": " << nodelet_type << " failed to start (see the error above)");
    return 1;
  }
  ros::spin();
  return 0;
}

}  // namespace massage_cell::nodes
