// Fuzz target: every YAML loader of the package — CAN axes, arm, acupoint
// model, acupoint regions, camera_info, session routine, hand-eye result,
// planar view sets. The first byte picks the loader, the rest is the file.
// A loader either returns or throws an error of its own that names the
// problem: a crash, a hang, an empty message or a yaml-cpp exception that
// escapes (no file, no field named) is a finding.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include <yaml-cpp/yaml.h>
#include <opencv2/core/utils/logger.hpp>

#include "fuzz_input.h"
#include "massage_cell/arm/config.h"
#include "massage_cell/arm/session.h"
#include "massage_cell/calib/hand_eye.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/can/config.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/planar/camera_views.h"

using namespace massage_cell;

namespace {

const char* const kLoaders[] = {"can_axes",    "arm",     "acupoints", "acupoint_regions",
                                "camera_info", "session", "hand_eye",  "views"};
constexpr int kLoaderCount = sizeof(kLoaders) / sizeof(kLoaders[0]);

// The path-based loaders read the input from this file (tmpfs when there is one).
const std::string& scratchFile() {
  static const std::string path = [] {
    const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    return std::string(dir) + "/massage_cell_fuzz_yaml_" + std::to_string(getpid()) + ".yaml";
  }();
  return path;
}

void load(int loader, const std::string& text) {
  // The arm's file names its CAN file relative to its own folder: the package's.
  static const std::string config_dir = MASSAGE_CELL_CONFIG_DIR;
  if (loader == 0) {
    (void)can::parseCanConfig(text, "fuzz");
    return;
  }
  if (loader == 1) {
    (void)arm::parseArmConfig(text, "fuzz", config_dir);
    return;
  }
  {
    std::ofstream out(scratchFile(), std::ios::binary | std::ios::trunc);
    out << text;
  }
  const std::string& path = scratchFile();
  switch (loader) {
    case 2:
      (void)cect::loadAcupointModel(path);
      break;
    case 3:
      (void)arm::loadAcupointRegions(path);
      break;
    case 4:
      (void)camera::readCameraInfoYaml(path);
      break;
    case 5:
      (void)arm::SessionConfig::load(path);
      break;
    case 6:
      (void)calib::readHandEyeYaml(path);
      break;
    default:
      (void)planar::loadViewSet(path);
      break;
  }
}

[[noreturn]] void broken(int loader, const std::string& what) {
  std::cerr << "fuzz_yaml_loaders: loader '" << kLoaders[loader] << "': " << what << "\n";
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // The view sets name images: a mutated name is an error of ours, not OpenCV's warning.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::FuzzInput in(data, size);
  const int loader = in.byte() % kLoaderCount;
  const std::string text = in.text();
  try {
    load(loader, text);
  } catch (const YAML::Exception& e) {
    broken(loader, std::string("a yaml-cpp exception escaped (names no file or field): ") + e.what());
  } catch (const std::exception& e) {
    if (std::string(e.what()).empty()) broken(loader, "an error without a message");
  }
  return 0;
}
