// The recorded-poses folder of hand_eye_calibrate --data (format in recorded_set.h).
#include "massage_cell/calib/recorded_set.h"

#include <cmath>
#include <fstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "massage_cell/camera/calibration_io.h"
#include "yaml_file.h"

namespace massage_cell::calib {
namespace {

Eigen::Vector3d vector3(const YAML::Node& node, const std::string& what, const std::string& path) {
  if (!node || !node.IsSequence() || node.size() != 3) {
    throw std::runtime_error(path + ": " + what + " must be a list of 3 numbers");
  }
  Eigen::Vector3d v;
  try {
    for (int i = 0; i < 3; ++i) v(i) = node[i].as<double>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(path + ": " + what + " holds a non-number");
  }
  if (!v.allFinite()) throw std::runtime_error(path + ": " + what + " is not finite");
  return v;
}

YAML::Node flowVector(const Eigen::Vector3d& v) {
  YAML::Node n(YAML::NodeType::Sequence);
  for (int i = 0; i < 3; ++i) n.push_back(v(i));
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

RecordedPose readPose(const YAML::Node& node, std::size_t i, const std::string& path) {
  const std::string what = "poses[" + std::to_string(i) + "]";
  if (!node.IsMap()) throw std::runtime_error(path + ": " + what + " must be a map {left, right, tool_tip}");
  RecordedPose p;
  try {
    if (!node["left"] || !node["right"]) throw std::runtime_error("");
    p.left = node["left"].as<std::string>();
    p.right = node["right"].as<std::string>();
  } catch (const std::exception&) {
    throw std::runtime_error(path + ": " + what + " needs image names 'left' and 'right'");
  }
  p.tool_tip = vector3(node["tool_tip"], what + ".tool_tip", path);
  return p;
}

}  // namespace

RecordedSet readRecordedSet(const std::string& dir) {
  RecordedSet set;
  set.left_info = camera::readCameraInfoYaml(dir + "/left.yaml");
  set.right_info = camera::readCameraInfoYaml(dir + "/right.yaml");
  const std::string path = dir + "/poses.yaml";
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap()) throw std::runtime_error(path + ": expected a map with 'poses'");
  if (root["marker_offset"]) set.marker_offset = vector3(root["marker_offset"], "marker_offset", path);
  const YAML::Node poses = root["poses"];
  if (!poses || !poses.IsSequence()) throw std::runtime_error(path + ": missing list 'poses'");
  for (std::size_t i = 0; i < poses.size(); ++i) set.poses.push_back(readPose(poses[i], i, path));
  return set;
}

void writeRecordedSet(const std::string& dir, const RecordedSet& set) {
  camera::writeCameraInfoYaml(dir + "/left.yaml", set.left_info, "left");
  camera::writeCameraInfoYaml(dir + "/right.yaml", set.right_info, "right");
  YAML::Node root;
  if (set.marker_offset) root["marker_offset"] = flowVector(*set.marker_offset);
  YAML::Node poses(YAML::NodeType::Sequence);
  for (const RecordedPose& p : set.poses) {
    YAML::Node n;
    n["left"] = p.left;
    n["right"] = p.right;
    n["tool_tip"] = flowVector(p.tool_tip);
    n.SetStyle(YAML::EmitterStyle::Flow);
    poses.push_back(n);
  }
  root["poses"] = poses;
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment(
             "hand-eye poses: tool_tip = commanded tool tip in arm_base_link, m; "
             "images relative to this folder")
      << root;
  const std::string path = dir + "/poses.yaml";
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  f << out.c_str() << "\n";
  if (!f) throw std::runtime_error(path + ": write failed");
}

}  // namespace massage_cell::calib
