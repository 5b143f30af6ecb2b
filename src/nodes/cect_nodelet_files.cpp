// The cect nodelet's files (cect_nodelet.h): at start-up the acupoint model with a client's profile on it, and the
// skin-marker kit (read once; a bad model stops the node, a bad kit is logged and left out, a profile that cannot be
// used is logged and every layout refused with it: TrustRules::configuration_problem); on
// ~save_client_profile, the client's profile measured on the latest pair.
#include <sstream>
#include <stdexcept>

#include <ros/package.h>

#include "cect_nodelet.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

/// A profile's error without its leading "client profile '<file or client>': " (the node names the file itself).
std::string withoutPrefix(const std::string& error) {
  const std::string head = "client profile '";
  const auto end = error.find("': ", head.size());
  if (error.compare(0, head.size(), head) != 0 || end == std::string::npos) return error;
  return error.substr(end + 3);
}

}  // namespace

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
  // The client's profile: one that cannot be used (unreadable, or not the format's) does not stop the node, but no
  // layout is trusted while it runs without it (the therapist meant this client's corrections and length check).
  client_profile_path_ = typedParam<std::string>(pnh, "client_profile_file", "");
  if (!client_profile_path_.empty()) {
    try {
      client_ = cect::loadClientProfile(client_profile_path_);
      model = cect::withCorrections(model, client_);
      NODELET_INFO_STREAM("client profile " << client_profile_path_ << ": " << cect::describeClientProfile(client_));
    } catch (const std::exception& e) {
      client_ = {};
      client_profile_problem_ = "client profile " + client_profile_path_ + " not usable: " + withoutPrefix(e.what()) +
                                "; no layout is trusted until the node is started with a readable profile (or none)";
      NODELET_ERROR_STREAM(e.what() << "; going on without the client's profile, trusting no layout until the node is "
                                       "started with a readable profile (or none)");
    }
  }
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    if (client_profile_path_.empty())
      status_.setClientProfile("none", "");
    else if (client_profile_problem_.empty())
      status_.setClientProfile(client_profile_path_ + " (" + cect::describeClientProfile(client_) + ")", "");
    else
      status_.setClientProfile(client_profile_path_ + " not usable", client_profile_problem_);
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

bool CectNodelet::saveClientProfile(massage_cell::SaveClientProfile::Request& request,
                                    massage_cell::SaveClientProfile::Response& response) {
  std::shared_ptr<const cect::LocatedAcupoints> located;
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    located = latest_.located;
  }
  response.success = false;
  if (request.path.empty()) {
    response.message = "no path: name the file to write";
  } else if (!located) {
    response.message = "no pair analysed yet";
  } else {
    try {
      const cect::ClientProfile profile = cect::measuredProfile(client_, *located, request.client);
      cect::saveClientProfile(profile, request.path);
      std::ostringstream s;
      s << "saved " << request.path << ": client '" << profile.client << "', C7 -> L4 " << profile.c7_to_l4_m << " m, "
        << profile.corrections.size() << " corrections";
      response.success = true;
      response.message = s.str();
    } catch (const std::exception& e) {
      response.message = std::string("not saved: ") + e.what();
    }
  }
  if (response.success)
    NODELET_INFO_STREAM("~save_client_profile: " << response.message);
  else
    NODELET_WARN_STREAM("~save_client_profile: " << response.message);
  return true;
}

}  // namespace massage_cell::nodes
