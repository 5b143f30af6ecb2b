// The cect node's therapist's landmarks (cect/given_landmarks.h): the services `~set_landmark` (C7, T7 or L4, a point
// in any tf frame or a raw left pixel) and `~clear_landmarks`, and clicks - rviz's Publish Point on
// `/clicked_point`, rqt_image_view's on `~debug_image_mouse_left` - each taken as the landmark named by the parameter
// `~click_landmark` (consumed by the click), else the latest layout's level nearest to it where that is unambiguous,
// else refused. A 3D point must lie on the measured skin. Each is kept as the camera's raw left pixel with the pose
// of the back it was given on, carried with the back from pair to pair (forPair); a back that moved or turned beyond
// cect::FollowLimits, or was lost, makes them stale (the layout not trusted) until `~confirm_landmarks`
// (std_srvs/Trigger: they hold where they are now), a click or `~set_landmark` gives them again.
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
#include <Eigen/Core>

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

  /// The landmarks carried with the back of `frame` (GivenLandmarkSet::follow; stale beyond its limits) in its
  /// rectified pixels (GivenLandmarkSet::forPair).
  std::vector<cect::GivenLandmark> forPair(const cect::CectFrame& frame, const camera::Decimation& decimation);

 private:
  bool setLandmark(massage_cell::SetLandmark::Request& request, massage_cell::SetLandmark::Response& response);
  bool clearLandmarks(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  bool confirmLandmarks(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  void onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& point);
  void onDebugImageClick(const geometry_msgs::PointStamped::ConstPtr& pixel);
  /// Gives `name` (empty: the latest layout's nearest landmark where that is unambiguous, cect::nameClick) at a 3D
  /// point in any frame (`point`, on the measured skin) or at a rectified pixel of the latest pair (`rect`). False with
  /// `message` saying why; else `message` says what was set.
  bool give(const std::string& name, const geometry_msgs::PointStamped* point, const cv::Point2f* rect,
            cect::LandmarkSource source, bool confirm, std::string* message);
  /// The name set for the next click (~click_landmark, then deleted), or empty.
  std::string clickName();
  /// Whether the 3D point `p` (left camera) at rectified `pixel` lies on the skin `view` measured there.
  bool onSkin(const View& view, const cv::Point2f& pixel, const Eigen::Vector3d& p, std::string* message) const;

  ros::NodeHandle pnh_;
  const tf2_ros::Buffer& tf_;
  const cect::AcupointModel& model_;
  std::function<View()> latest_;
  int debug_width_;
  std::string log_name_;
  mutable std::mutex mutex_;
  cect::GivenLandmarkSet given_;  ///< guarded by mutex_
  ros::ServiceServer set_service_, clear_service_, confirm_service_;
  ros::Subscriber clicked_sub_, debug_click_sub_;
};

}  // namespace massage_cell::nodes
