// The cect nodelet's start-up files (cect_nodelet.h): the acupoint model with a client's profile on it, and the
// skin-marker kit. Read once; a bad model stops the node, a bad profile or kit is logged and left out.
#include <stdexcept>

#include <ros/package.h>

#include "cect_nodelet.h"
#include "typed_param.h"

namespace massage_cell::nodes {

void CectNodelet::loadModel() {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  model_path_ = typedParam<std::string>(pnh, "acupoints_file", "");
  if (model_path_.empty()) {
    const std::string root = ros::package::getPath("massage_cell");
    if (root.empty()) {
      NODELET_FATAL("parameter ~acupoints_file is not set and package massage_cell is not found to take its default");
      throw std::runtime_error("no acupoint model");
    }
    model_path_ = root + "/config/acupoints.yaml";
  }
  cect::AcupointModel model;
  try {
    model = cect::loadAcupointModel(model_path_);
  } catch (const std::exception& e) {
    NODELET_FATAL_STREAM("acupoint model " << model_path_ << ": " << e.what());
    throw;
  }
  const std::string profile = typedParam<std::string>(pnh, "client_profile_file", "");
  if (!profile.empty()) {
    try {
      client_ = cect::loadClientProfile(profile);
      model = cect::withCorrections(model, client_);
      NODELET_INFO_STREAM("client profile " << profile << ": '" << client_.client << "', " << client_.corrections.size()
                                            << " corrections");
    } catch (const std::exception& e) {
      client_ = {};
      NODELET_ERROR_STREAM(e.what() << "; going on without the client's profile");
    }
  }
  tracker_ = std::make_unique<cect::AcupointTracker>(model);
}

void CectNodelet::loadSkinMarkers() {
  const std::string path = typedParam<std::string>(getPrivateNodeHandle(), "skin_markers_file", "");
  if (path.empty()) return;
  try {
    skin_markers_ = cect::loadSkinMarkerOptions(path);
    NODELET_INFO_STREAM("skin markers: " << skin_markers_->markers.size() << " from " << path);
  } catch (const std::exception& e) {
    NODELET_ERROR_STREAM(
        "skin markers " << path << ": " << e.what()
                        << "; going on without them (landmarks from the image, clicks, ~set_landmark)");
  }
}

}  // namespace massage_cell::nodes
