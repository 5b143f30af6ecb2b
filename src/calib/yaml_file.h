// A YAML file of the calibration library loaded with errors that name it
// (cannot open / not valid YAML). Internal to src/calib/.
#pragma once

#include <stdexcept>
#include <string>

#include <yaml-cpp/yaml.h>

namespace massage_cell::calib {

inline YAML::Node loadYamlFile(const std::string& path) {
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(path + ": cannot open");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": not valid YAML: " + e.what());
  }
}

}  // namespace massage_cell::calib
