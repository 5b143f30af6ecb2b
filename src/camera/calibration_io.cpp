#include "massage_cell/camera/calibration_io.h"

#include <fstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

namespace massage_cell::camera {

namespace {

template <typename Container>
void emitMatrix(YAML::Emitter& out, const char* key, int rows, int cols, const Container& data) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "rows" << YAML::Value << rows;
  out << YAML::Key << "cols" << YAML::Value << cols;
  out << YAML::Key << "data" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (double v : data) out << v;
  out << YAML::EndSeq << YAML::EndMap;
}

std::vector<double> readMatrix(const YAML::Node& root, const char* key, std::size_t expected, const std::string& path) {
  const YAML::Node node = root[key];
  if (!node) throw std::runtime_error(path + ": missing '" + std::string(key) + "'");
  const YAML::Node data = node["data"];
  if (!data || !data.IsSequence()) throw std::runtime_error(path + ": '" + std::string(key) + "' has no data list");
  std::vector<double> values;
  for (const auto& v : data) values.push_back(v.as<double>());
  if (expected > 0 && values.size() != expected) {
    throw std::runtime_error(path + ": '" + std::string(key) + "' needs " + std::to_string(expected) + " values, has " +
                             std::to_string(values.size()));
  }
  return values;
}

}  // namespace

void writeCameraInfoYaml(const std::string& path, const CameraCalibration& c, const std::string& camera_name) {
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "image_width" << YAML::Value << c.width;
  out << YAML::Key << "image_height" << YAML::Value << c.height;
  out << YAML::Key << "camera_name" << YAML::Value << camera_name;
  emitMatrix(out, "camera_matrix", 3, 3, c.K);
  out << YAML::Key << "distortion_model" << YAML::Value << c.distortion_model;
  emitMatrix(out, "distortion_coefficients", 1, static_cast<int>(c.D.size()), c.D);
  emitMatrix(out, "rectification_matrix", 3, 3, c.R);
  emitMatrix(out, "projection_matrix", 3, 4, c.P);
  out << YAML::EndMap;
  std::ofstream file(path);
  if (!file) throw std::runtime_error("cannot write calibration file '" + path + "'");
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("error writing calibration file '" + path + "'");
}

CameraCalibration readCameraInfoYaml(const std::string& path, std::string* camera_name) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error("cannot open calibration file '" + path + "'");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("calibration file '" + path + "' is not valid YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error("calibration file '" + path + "' is not a YAML map");
  CameraCalibration c;
  try {
    if (!root["image_width"] || !root["image_height"]) {
      throw std::runtime_error(path + ": missing image_width / image_height");
    }
    c.width = root["image_width"].as<int>();
    c.height = root["image_height"].as<int>();
    if (camera_name && root["camera_name"]) *camera_name = root["camera_name"].as<std::string>();
    c.distortion_model = root["distortion_model"] ? root["distortion_model"].as<std::string>() : "plumb_bob";
    const auto K = readMatrix(root, "camera_matrix", 9, path);
    const auto R = readMatrix(root, "rectification_matrix", 9, path);
    const auto P = readMatrix(root, "projection_matrix", 12, path);
    c.D = readMatrix(root, "distortion_coefficients", 0, path);
    std::copy(K.begin(), K.end(), c.K.begin());
    std::copy(R.begin(), R.end(), c.R.begin());
    std::copy(P.begin(), P.end(), c.P.begin());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("calibration file '" + path + "': bad value: " + e.what());
  }
  return c;
}

}  // namespace massage_cell::camera
