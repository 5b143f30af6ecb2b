// The `massage_cell/hbds` nodelet: dense stereo with the project's HBDS
// library (include/massage_cell/stereo/pipeline.h) behind the interface of
// stereo_image_proc's disparity + point_cloud2 nodelets. Subscribes to a
// synchronised raw (or rectified) stereo pair with its camera_info, rectifies
// it itself, and publishes `disparity`, `depth` + `depth/camera_info` and
// `points2`, all in the left optical frame with the pair's stamp.
//
// Threading (StereoPairInput, stereo_pair_input.h): the synchroniser
// callback only drops the pair into a one-pair slot (replacing, and counting
// as dropped, a pair the worker has not taken yet); a worker thread matches
// the newest pair. Subscriber callbacks are therefore never blocked by the
// matcher (0.1-1.5 s a pair).
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <boost/thread/recursive_mutex.hpp>
#include <opencv2/core.hpp>

#include "hbds_views.h"
#include "massage_cell/HBDSConfig.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/stereo/pipeline.h"
#include "stereo_messages.h"
#include "stereo_pair_input.h"
#include "wall_diagnostics.h"

namespace massage_cell::nodes {

class HbdsNodelet : public nodelet::Nodelet {
 public:
  HbdsNodelet();
  ~HbdsNodelet() override;

 private:
  using Config = massage_cell::HBDSConfig;
  using CameraInfo = sensor_msgs::CameraInfo;

  /// Which outputs have subscribers (decided per pair).
  struct Outputs {
    bool disparity = false, depth = false, points = false, confidence = false, surface = false;
    bool any() const { return disparity || depth || points || confidence || surface; }
  };

  /// A pair rectified and downsampled, with the model of the processed images (hbds_views.h).
  using Views = HbdsViews;

  void onInit() override;  ///< init(); a parameter of the wrong type: FATAL, the node exits 1
  void init();
  void connectCb();
  void configCb(Config& config, uint32_t level);
  Outputs wantedOutputs();
  void onPair(const StereoPair& pair);  // the input's worker thread
  void process(const StereoPair& pair, const Config& config, const Outputs& wanted);
  const camera::StereoModel& updateModel(const CameraInfo& left, const CameraInfo& right);
  Views prepareViews(const StereoPair& pair, int downsample);
  stereo::StereoParams matchParams(const Config& config, const Views& views);
  void publish(const std_msgs::Header& header, const Config& config, const Views& views,
               const stereo::StereoParams& params, const ValidDisparity& valid, const Outputs& wanted);
  /// `surface`: the confirmed points (needs lr_check), ~kSurfaceColumns across.
  void publishSurface(const std_msgs::Header& header, const stereo::StereoParams& params, const ValidDisparity& valid,
                      const cv::Mat& points);
  static constexpr int kSurfaceColumns = 80;
  void badPair(const std::string& problem);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  // Inputs (subscribed only while an output has subscribers) and the worker
  // thread (stopped first in the destructor).
  std::unique_ptr<StereoPairInput> input_;
  int max_pixels_ = 1200000;  ///< ~max_pixels: larger processed pairs are refused (0: no limit)
  bool rectify_ = true;       ///< ~rectify: false when the images are rectified already whatever camera_info says

  // Outputs.
  std::mutex connect_mutex_;  // guards (un)subscribing the inputs
  ros::Publisher disparity_pub_, depth_info_pub_, points_pub_, surface_pub_;
  image_transport::Publisher depth_pub_, confidence_pub_;

  // Parameters (dynamic_reconfigure; the server locks config_mutex_ around configCb).
  boost::recursive_mutex config_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config config_;  // the accepted configuration, guarded by config_mutex_

  // Worker-thread state.
  StereoModelCache model_cache_;
  std::shared_ptr<const camera::StereoModel> model_;  ///< of the current calibration, at full resolution
  ProblemThrottle log_throttle_;                      // per-problem log throttling

  // Status for the diagnostics (guarded by status_mutex_).
  WallDiagnostics diagnostics_;
  std::mutex status_mutex_;
  PairStats stats_;
  double last_matcher_ms_ = 0.0;
  double last_far_end_ = 0.0, last_near_end_ = 0.0;  // shares of the last pair's disparities at the range's ends
  std::string geometry_summary_;                     // size, rectification, f, baseline of the last good pair
};

}  // namespace massage_cell::nodes
