// YAML file of a hand-eye calibration (yaml-cpp).
#include <cmath>
#include <fstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "massage_cell/calib/hand_eye.h"
#include "yaml_file.h"

namespace massage_cell::calib {
namespace {

YAML::Node field(const YAML::Node& node, const std::string& key, const std::string& path) {
  const YAML::Node v = node[key];
  if (!v) throw std::runtime_error(path + ": missing field '" + key + "'");
  return v;
}

double number(const YAML::Node& node, const std::string& key, const std::string& path) {
  const YAML::Node v = field(node, key, path);
  double d = 0.0;
  try {
    d = v.as<double>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(path + ": field '" + key + "' is not a number");
  }
  if (!std::isfinite(d)) throw std::runtime_error(path + ": field '" + key + "' is not finite");
  return d;
}

YAML::Node flowMap(std::initializer_list<std::pair<const char*, double>> items) {
  YAML::Node n;
  for (const auto& [k, v] : items) n[k] = v;
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

}  // namespace

void writeHandEyeYaml(const std::string& path, const HandEyeResult& r) {
  const Eigen::Vector3d t = r.camera_from_base.translation();
  const Eigen::Quaterniond q(r.camera_from_base.linear());
  YAML::Node root;
  root["parent_frame"] = r.parent_frame;
  root["child_frame"] = r.child_frame;
  root["translation"] = flowMap({{"x", t.x()}, {"y", t.y()}, {"z", t.z()}});
  root["rotation"] = flowMap({{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}});
  YAML::Node res(YAML::NodeType::Sequence);
  for (double e : r.residuals_mm) res.push_back(e);
  res.SetStyle(YAML::EmitterStyle::Flow);
  root["residuals_mm"] = res;
  root["rms_mm"] = r.rms_mm;
  root["max_mm"] = r.max_mm;
  YAML::Node warnings(YAML::NodeType::Sequence);
  for (const auto& w : r.warnings) warnings.push_back(w);
  root["warnings"] = warnings;
  root["date"] = r.date;

  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment("hand-eye calibration: pose of child_frame in parent_frame (p_parent = T p_child)") << root;
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  f << out.c_str() << "\n";
  if (!f) throw std::runtime_error(path + ": write failed");
}

namespace {

HandEyeResult handEye(const std::string& path) {
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap()) throw std::runtime_error(path + ": expected a map at the top level");
  HandEyeResult r;
  try {
    r.parent_frame = field(root, "parent_frame", path).as<std::string>();
    r.child_frame = field(root, "child_frame", path).as<std::string>();
    r.date = root["date"] ? root["date"].as<std::string>() : "";
  } catch (const YAML::Exception&) {
    throw std::runtime_error(path + ": parent_frame, child_frame and date must be strings");
  }
  if (r.parent_frame.empty() || r.child_frame.empty()) throw std::runtime_error(path + ": empty frame name");
  const YAML::Node t = field(root, "translation", path);
  const YAML::Node q = field(root, "rotation", path);
  const Eigen::Vector3d tv(number(t, "x", path), number(t, "y", path), number(t, "z", path));
  Eigen::Quaterniond qv(number(q, "w", path), number(q, "x", path), number(q, "y", path), number(q, "z", path));
  if (std::abs(qv.norm() - 1.0) > 1e-3) {
    throw std::runtime_error(path + ": rotation quaternion has norm " + std::to_string(qv.norm()) + ", expected 1");
  }
  qv.normalize();
  r.camera_from_base = Eigen::Isometry3d::Identity();
  r.camera_from_base.linear() = qv.toRotationMatrix();
  r.camera_from_base.translation() = tv;
  if (const YAML::Node res = root["residuals_mm"]) {
    if (!res.IsSequence()) throw std::runtime_error(path + ": residuals_mm must be a list");
    try {
      for (const auto& e : res) r.residuals_mm.push_back(e.as<double>());
    } catch (const YAML::Exception&) {
      throw std::runtime_error(path + ": residuals_mm holds a non-number");
    }
  }
  if (root["rms_mm"]) r.rms_mm = number(root, "rms_mm", path);
  if (root["max_mm"]) r.max_mm = number(root, "max_mm", path);
  if (const YAML::Node w = root["warnings"]) {
    if (!w.IsSequence()) throw std::runtime_error(path + ": warnings must be a list");
    for (const auto& s : w) r.warnings.push_back(s.as<std::string>());
  }
  return r;
}

}  // namespace

// A yaml-cpp error the field readers did not name still names the file and its line.
HandEyeResult readHandEyeYaml(const std::string& path) {
  try {
    return handEye(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

}  // namespace massage_cell::calib
