// The camera driver behind the `massage_cell/stereo_camera` and
// `massage_cell/mono_camera` nodelets: reads a camera::FrameSource on its own
// thread, stamps each capture once, and publishes image_raw + camera_info per
// view through image_transport (camera_info_manager holds the calibrations).
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <camera_info_manager/camera_info_manager.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/publisher.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/frame_source.h"

namespace massage_cell::nodes {

class CameraDriver {
 public:
  /// `views` is 2 for the stereo driver, 1 for the mono driver. Topics live
  /// in `nh`'s namespace, parameters in `pnh`.
  CameraDriver(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, int views);
  ~CameraDriver();
  CameraDriver(const CameraDriver&) = delete;
  CameraDriver& operator=(const CameraDriver&) = delete;

  /// Reads the parameters, opens the source, loads the calibrations and
  /// starts capturing. Throws camera::ConfigError naming the problem.
  void start();

 private:
  struct View {
    std::string label;  // "left", "right" or "" (mono)
    std::string camera_name;
    std::string info_url;
    ros::NodeHandle nh;
    std::shared_ptr<camera_info_manager::CameraInfoManager> info_manager;
    image_transport::CameraPublisher publisher;
  };

  void readParameters();
  void setUpView(View& view);
  void checkCalibrations();
  void captureLoop();
  void publish(const camera::Frame& frame);
  void publishRightTransform(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  void setState(const std::string& state, const std::string& error = "");

  ros::NodeHandle nh_, pnh_;
  int view_count_;
  camera::SourceConfig config_;
  std::unique_ptr<camera::FrameSource> source_;
  std::vector<View> views_;
  std::string frame_id_, right_frame_id_;
  bool publish_tf_ = true;
  bool rectified_ = false;
  double capture_delay_ = 0.0;
  double start_delay_ = 0.0;

  image_transport::ImageTransport it_;
  tf2_ros::StaticTransformBroadcaster tf_broadcaster_;
  std::vector<double> last_right_p_;  // right P last published as a transform

  diagnostic_updater::Updater updater_;
  double expected_rate_ = 0.0;
  std::unique_ptr<diagnostic_updater::HeaderlessTopicDiagnostic> rate_diagnostic_;
  ros::WallTimer diagnostics_timer_;

  std::mutex status_mutex_;  // guards the status below (capture thread vs diagnostics)
  std::string source_description_;
  std::string state_ = "starting";
  std::string last_error_;
  std::uint64_t published_ = 0;
  std::uint64_t bad_frames_ = 0;
  std::uint64_t dropped_frames_ = 0;
  std::uint64_t reopens_ = 0;
  double last_skew_s_ = 0.0;
  ros::Time last_stamp_;

  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace massage_cell::nodes
