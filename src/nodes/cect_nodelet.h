// The `massage_cell/cect` nodelet: the acupoints of the subject's back from a
// synchronised stereo pair, with the project's CECT library
// (include/massage_cell/cect/). Per pair: CectFrame::analyse (rectify,
// segment the back in both views, correspondences from the epipolar lines
// and the contours, barycentric transfer inside), the acupoint model's
// landmarks and placement in the left view (config/acupoints.yaml), each
// placed pixel to 3D, a temporal filter per acupoint; then publishes
// `acupoints` (massage_cell/AcupointArray), a tf frame <frame_prefix><name>
// per valid acupoint, `~markers` and `~debug_image`, and serves
// `~localize_pixels` (any raw left pixel of the latest pair to 3D),
// `~get_acupoint` (one filtered acupoint, in any tf frame) and
// `~save_client_profile` (the latest pair's C7 -> L4 of given landmarks, as
// a client's profile file).
//
// A therapist's landmarks (landmark_input.h): `~set_landmark` (C7, T7 or L4, a
// point in any tf frame or a raw left pixel), `~clear_landmarks`, and clicks
// - rviz's Publish Point on `/clicked_point`, rqt_image_view's on
// `~debug_image_mouse_left` - each taken as the landmark of the latest layout
// nearest to it. They replace the found ones in every pair until cleared.
// Skin markers (~skin_markers_file, a kit: cect/skin_markers.h): coloured
// dots at C7 / L4 found in both views of every pair are given landmarks too,
// followed as the subject breathes; a click overrides a marker. A client's
// profile (~client_profile_file: cect/client_profile.h) moves the model's
// points by its corrections and refuses layouts whose C7 -> L4 disagrees
// with the client's; a profile it cannot read leaves the node running but
// trusting no layout, saying why (the log, the diagnostics, each layout's
// reason).
//
// Validity: an acupoint is published valid while the temporal filter holds
// an estimate refreshed within max_age (so a point this pair could not
// measure, or whose measurement the filter rejected as an outlier, keeps its
// recent estimate, with the reason noted); a pair that yields no acupoint at
// all (no usable view of the back, no landmarks) invalidates every point:
// the subject may have moved away.
//
// Threading (StereoPairInput, stereo_pair_input.h): the synchroniser
// callback only drops the pair into a one-pair slot (replacing, and counting
// as dropped, a pair the worker has not taken yet); a worker thread analyses
// the newest pair. The services read what the worker left behind (the latest frame, the published estimates) under
// their own mutexes, so neither blocks the other for long.
//
// Unlike the hbds nodelet the inputs are subscribed from the start: the tf
// frames and the services are outputs nobody "subscribes" to.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <Eigen/Core>
#include <boost/thread/recursive_mutex.hpp>

#include "cect_status.h"
#include "landmark_input.h"
#include "massage_cell/BackLandmark.h"
#include "massage_cell/CECTConfig.h"
#include "massage_cell/GetAcupoint.h"
#include "massage_cell/LocalizePixels.h"
#include "massage_cell/SaveClientProfile.h"
#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/cect/tracker.h"
#include "stereo_pair_input.h"
#include "wall_diagnostics.h"

namespace massage_cell::nodes {

class CectNodelet : public nodelet::Nodelet {
 public:
  CectNodelet();
  ~CectNodelet() override;

 private:
  using Config = massage_cell::CECTConfig;
  using CameraInfo = sensor_msgs::CameraInfo;

  /// The latest analysed pair (valid or not), for ~localize_pixels.
  struct Analysed {
    std::shared_ptr<const cect::CectFrame> frame;
    std_msgs::Header header;        ///< the left image's stamp, the left optical frame
    camera::Decimation decimation;  ///< the frame's pixels against the camera's
    cect::BackLandmarks landmarks;  ///< the pair's layout (a click is taken as its nearest landmark)
    std::shared_ptr<const cect::LocatedAcupoints> located;  ///< its acupoints and check (~save_client_profile)
  };

  void onInit() override;  ///< init(); a parameter of the wrong type: FATAL, the node exits 1
  void init();
  void loadModel();
  void loadSkinMarkers();
  /// The pair's CECT parameters: the configuration's, with the skin-marker kit.
  cect::CectParams pairParams(const Config& config) const;
  void configCb(Config& config, uint32_t level);
  void onPair(const StereoPair& pair);  // the input's worker thread
  void process(const StereoPair& pair, const Config& config);
  void updateGeometry(const CameraInfo& left, const CameraInfo& right);
  cect::TrackerUpdate track(const cect::CectFrame& frame, const std_msgs::Header& header,
                            const camera::Decimation& decimation, const Config& config,
                            std::shared_ptr<const cect::LocatedAcupoints>* located);
  void publish(const std_msgs::Header& header, const cect::CectFrame& frame, const cect::TrackerUpdate& update,
               const cect::BackLandmarks& landmarks, const camera::Decimation& decimation, const Config& config);
  void recordStatus(const cect::CectFrame& frame, const cect::TrackerUpdate& update, double elapsed_ms,
                    double waited_ms);
  void badPair(const std::string& problem);
  bool localizePixels(massage_cell::LocalizePixels::Request& request, massage_cell::LocalizePixels::Response& response);
  bool getAcupoint(massage_cell::GetAcupoint::Request& request, massage_cell::GetAcupoint::Response& response);
  /// ~save_client_profile (cect_nodelet_files.cpp): the latest pair's C7 -> L4 with client_'s corrections.
  bool saveClientProfile(massage_cell::SaveClientProfile::Request& request,
                         massage_cell::SaveClientProfile::Response& response);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  // Inputs and the worker thread (stopped first in the destructor).
  std::unique_ptr<StereoPairInput> input_;

  // Outputs and services.
  ros::Publisher acupoints_pub_, markers_pub_;
  image_transport::Publisher debug_image_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::ServiceServer localize_service_, acupoint_service_, profile_service_;
  std::unique_ptr<LandmarkInput> landmarks_;  ///< a therapist's landmarks (its services and clicks)
  std::string frame_prefix_ = "acupoint/";
  std::optional<cect::SkinMarkerOptions> skin_markers_;  ///< the kit of ~skin_markers_file (read once at start-up)
  cect::ClientProfile client_;                           ///< ~client_profile_file (read once at start-up; or none)
  std::string client_profile_path_;                      ///< ~client_profile_file ("" none)
  /// Why ~client_profile_file could not be used ("" when it was, or none was named): every layout is refused with
  /// it (TrustRules::configuration_problem) and the diagnostics say it.
  std::string client_profile_problem_;

  // The acupoint model (read once at start-up) and the acupoints tracked over the pairs: written by the worker,
  // read by ~get_acupoint (guarded by tracker_mutex_).
  std::string model_path_;
  std::mutex tracker_mutex_;
  std::unique_ptr<cect::AcupointTracker> tracker_;
  std_msgs::Header tracker_header_;  ///< of the pair the tracker's estimates were last published with

  // Parameters (dynamic_reconfigure; the server locks config_mutex_ around configCb).
  boost::recursive_mutex config_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config config_;  // the accepted configuration, guarded by config_mutex_

  // Worker-thread state.
  StereoModelCache model_cache_;                         ///< the model of the current calibration and max_width
  std::shared_ptr<const camera::StereoModel> geometry_;  ///< of the decimated images
  int max_width_ = 0;                                    ///< ~max_width: images wider are decimated (0: never)
  camera::Decimation decimation_;                        ///< of the current calibration
  ProblemThrottle log_throttle_;                         // per-problem log throttling

  // What the services read.
  std::mutex latest_mutex_;
  Analysed latest_;

  // Status for the diagnostics (guarded by status_mutex_).
  WallDiagnostics diagnostics_;
  std::mutex status_mutex_;
  PairStats stats_;
  CectStatus status_;
};

}  // namespace massage_cell::nodes
