// The cect node's therapist's landmarks (cect/given_landmarks.h): the services `~set_landmark` (C7, T7 or L4, a point
// in any tf frame or a raw left pixel) and `~clear_landmarks`, and clicks - rviz's Publish Point on
// `/clicked_point`, rqt_image_view's on `~debug_image_mouse_left` - each taken as the landmark of the latest layout
// nearest to it. Each is kept as the camera's raw left pixel until cleared; forPair() gives them to a pair.
//
// Threading: the callbacks run on the node's spinner threads and the worker calls forPair(); the set is guarded by
// its own mutex. The latest pair is read through `latest` (the nodelet's own lock).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>

#include "massage_cell/SetLandmark.h"
#include "massage_cell/camera/calibration.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/given_landmarks.h"

namespace massage_cell::nodes {

class LandmarkInput {
 public:
  /// What a landmark needs of the latest analysed pair (frame null: none yet).
  struct View {
    std::shared_ptr<const cect::CectFrame> frame;
    std::string frame_id;           ///< the left optical frame
    camera::Decimation decimation;  ///< the frame's pixels against the camera's
    cect::BackLandmarks landmarks;  ///< its layout
  };

  /// Advertises and subscribes (`nh` for /clicked_point, `pnh` for the rest). `model`, `tf` and the getter must
  /// outlive it; `debug_width` is the width the debug image is scaled up to (cect::debugImageScale); `log_name`
  /// names the node's log lines.
  LandmarkInput(ros::NodeHandle& nh, ros::NodeHandle& pnh, const tf2_ros::Buffer& tf, const cect::AcupointModel& model,
                std::function<View()> latest, int debug_width, std::string log_name);

  /// The landmarks in a pair's rectified pixels (GivenLandmarkSet::forPair).
  std::vector<cect::GivenLandmark> forPair(const camera::StereoModel& geometry,
                                           const camera::Decimation& decimation) const;

 private:
  bool setLandmark(massage_cell::SetLandmark::Request& request, massage_cell::SetLandmark::Response& response);
  bool clearLandmarks(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  void onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& point);
  void onDebugImageClick(const geometry_msgs::PointStamped::ConstPtr& pixel);
  /// Gives `name` (empty: the latest layout's nearest landmark) at a 3D point in any frame (`point`) or at a rectified
  /// pixel of the latest pair (`rect`). False with `message` saying why; else `message` says what was set.
  bool give(const std::string& name, const geometry_msgs::PointStamped* point, const cv::Point2f* rect,
            const std::string& source, std::string* message);

  const tf2_ros::Buffer& tf_;
  const cect::AcupointModel& model_;
  std::function<View()> latest_;
  int debug_width_;
  std::string log_name_;
  mutable std::mutex mutex_;
  cect::GivenLandmarkSet given_;  ///< guarded by mutex_
  ros::ServiceServer set_service_, clear_service_;
  ros::Subscriber clicked_sub_, debug_click_sub_;
};

}  // namespace massage_cell::nodes
