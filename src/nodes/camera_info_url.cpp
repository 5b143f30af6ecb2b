#include "camera_info_url.h"

#include <cstdlib>

#include <ros/package.h>

#include "massage_cell/camera/frame_source.h"

namespace massage_cell::nodes {

namespace {

void replaceAll(std::string& text, const std::string& from, const std::string& to) {
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

std::string rosHome() {
  if (const char* home = std::getenv("ROS_HOME")) return home;
  if (const char* home = std::getenv("HOME")) return std::string(home) + "/.ros";
  return ".ros";
}

}  // namespace

std::string calibrationPath(const std::string& url_in, const std::string& camera_name) {
  std::string url = url_in.empty() ? "file://${ROS_HOME}/camera_info/${NAME}.yaml" : url_in;
  replaceAll(url, "${NAME}", camera_name);
  replaceAll(url, "${ROS_HOME}", rosHome());
  const std::string file = "file://", package = "package://";
  if (url.rfind(file, 0) == 0) return url.substr(file.size());
  if (url.rfind(package, 0) == 0) {
    const std::string rest = url.substr(package.size());
    const auto slash = rest.find('/');
    const std::string name = rest.substr(0, slash);
    const std::string root = ros::package::getPath(name);
    if (root.empty()) throw camera::ConfigError("camera_info_url '" + url_in + "': package '" + name + "' not found");
    return root + (slash == std::string::npos ? "" : rest.substr(slash));
  }
  throw camera::ConfigError("camera_info_url '" + url_in + "' is not a file:// or package:// URL");
}

}  // namespace massage_cell::nodes
