// The `massage_cell/hbds` nodelet: dense stereo with the project's HBDS
// library (include/massage_cell/stereo/pipeline.h) behind the interface of
// stereo_image_proc's disparity + point_cloud2 nodelets. Subscribes to a
// synchronised raw (or rectified) stereo pair with its camera_info, rectifies
// it itself, and publishes `disparity`, `depth` + `depth/camera_info` and
// `points2`, all in the left optical frame with the pair's stamp.
//
// Threading: the synchroniser callback only drops the pair into a one-pair
// slot (replacing, and counting as dropped, a pair the worker has not taken
// yet); a worker thread matches the newest pair. Subscriber callbacks are
// therefore never blocked by the matcher (0.1-1.5 s a pair).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <boost/thread/recursive_mutex.hpp>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <nodelet/nodelet.h>
#include <opencv2/core.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "massage_cell/HBDSConfig.h"

namespace massage_cell::nodes {

class HbdsNodelet : public nodelet::Nodelet {
 public:
  HbdsNodelet() = default;
  ~HbdsNodelet() override;

 private:
  using Config = massage_cell::HBDSConfig;
  using Image = sensor_msgs::Image;
  using CameraInfo = sensor_msgs::CameraInfo;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, CameraInfo, Image, CameraInfo>;
  using ApproximatePolicy = message_filters::sync_policies::ApproximateTime<Image, CameraInfo, Image, CameraInfo>;

  /// One synchronised input pair.
  struct Pair {
    sensor_msgs::ImageConstPtr left_image, right_image;
    sensor_msgs::CameraInfoConstPtr left_info, right_info;
  };

  /// Which outputs have subscribers (decided per pair).
  struct Outputs {
    bool disparity = false, depth = false, points = false;
    bool any() const { return disparity || depth || points; }
  };

  /// Rectification maps of both views, kept until the calibration changes.
  struct Rectification {
    std::vector<double> key;  ///< the calibration the maps were made from
    bool identity = true;     ///< both views already rectified: no remap
    cv::Mat map1[2], map2[2];
  };

  void onInit() override;
  void checkStartParameters();
  void connectCb();
  void pairCb(const sensor_msgs::ImageConstPtr& left_image, const sensor_msgs::CameraInfoConstPtr& left_info,
              const sensor_msgs::ImageConstPtr& right_image, const sensor_msgs::CameraInfoConstPtr& right_info);
  void configCb(Config& config, uint32_t level);
  Outputs wantedOutputs();
  void workLoop();
  void process(const Pair& pair, const Config& config, const Outputs& wanted);
  void updateRectification(const CameraInfo& left, const CameraInfo& right);
  void badPair(const std::string& problem);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  // Inputs (subscribed only while an output has subscribers).
  std::unique_ptr<image_transport::ImageTransport> it_;
  image_transport::SubscriberFilter left_image_sub_, right_image_sub_;
  message_filters::Subscriber<CameraInfo> left_info_sub_, right_info_sub_;
  std::unique_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::unique_ptr<message_filters::Synchronizer<ApproximatePolicy>> approximate_sync_;
  bool rectify_ = true;  ///< ~rectify: false when the images are rectified already whatever camera_info says

  // Outputs.
  std::mutex connect_mutex_;  // guards (un)subscribing the inputs
  ros::Publisher disparity_pub_, depth_info_pub_, points_pub_;
  image_transport::Publisher depth_pub_;

  // Parameters (dynamic_reconfigure; the server locks config_mutex_ around configCb).
  boost::recursive_mutex config_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config config_;  // the accepted configuration, guarded by config_mutex_

  // The latest-pair slot between the synchroniser and the worker.
  std::mutex slot_mutex_;
  std::condition_variable slot_cv_;
  std::optional<Pair> slot_;
  bool stopping_ = false;
  std::thread worker_;

  // Worker-thread state.
  Rectification rectification_;
  std::map<std::string, ros::WallTime> last_logged_;  // per-problem log throttling

  // Status for the diagnostics (guarded by status_mutex_).
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostics_timer_;
  std::mutex status_mutex_;
  std::uint64_t received_ = 0, processed_ = 0, dropped_ = 0, bad_ = 0;
  bool last_pair_bad_ = false;
  double last_processing_ms_ = 0.0, last_matcher_ms_ = 0.0, total_processing_ms_ = 0.0;
  std::deque<ros::WallTime> processed_times_;  // recent completions, for the rate
  std::string last_error_;
  ros::WallTime last_error_time_;
  std::string geometry_summary_;  // size, rectification, f, baseline of the last good pair
};

}  // namespace massage_cell::nodes
