#include "landmark_input.h"

#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Core>

#include "massage_cell/cect/tracker.h"
#include "tf_lookup.h"

namespace massage_cell::nodes {

namespace {
constexpr double kTfWait = 0.1;  // s (wall) a clicked point waits for its transform into the camera
}  // namespace

LandmarkInput::LandmarkInput(ros::NodeHandle& nh, ros::NodeHandle& pnh, const tf2_ros::Buffer& tf,
                             const cect::AcupointModel& model, std::function<View()> latest, int debug_width,
                             std::string log_name)
    : tf_(tf), model_(model), latest_(std::move(latest)), debug_width_(debug_width), log_name_(std::move(log_name)) {
  set_service_ = pnh.advertiseService("set_landmark", &LandmarkInput::setLandmark, this);
  clear_service_ = pnh.advertiseService("clear_landmarks", &LandmarkInput::clearLandmarks, this);
  clicked_sub_ = nh.subscribe("/clicked_point", 5, &LandmarkInput::onClickedPoint, this);
  debug_click_sub_ = pnh.subscribe("debug_image_mouse_left", 5, &LandmarkInput::onDebugImageClick, this);
}

std::vector<cect::GivenLandmark> LandmarkInput::forPair(const camera::StereoModel& geometry,
                                                        const camera::Decimation& decimation) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return given_.forPair(geometry, decimation);
}

bool LandmarkInput::setLandmark(massage_cell::SetLandmark::Request& request,
                                massage_cell::SetLandmark::Response& response) {
  if (const std::string problem = cect::checkGivenLandmarkName(request.name); !problem.empty()) {
    response.success = false;
    response.message = problem;
    return true;
  }
  if (!request.point.header.frame_id.empty()) {
    response.success = give(request.name, &request.point, nullptr, "service", &response.message);
    return true;
  }
  // A raw left pixel of the camera: into the latest pair's rectified pixels.
  cv::Point2f rect;
  if (const View view = latest_(); view.frame) {
    const cv::Point2f raw(static_cast<float>(request.u), static_cast<float>(request.v));
    rect = view.frame->geometry().toRectified(view.decimation.toDecimated(raw));
  }
  response.success = give(request.name, nullptr, &rect, "service", &response.message);
  return true;
}

bool LandmarkInput::clearLandmarks(std_srvs::Trigger::Request& /*request*/, std_srvs::Trigger::Response& response) {
  std::lock_guard<std::mutex> lock(mutex_);
  response.message = "cleared the given landmarks (" + given_.describe() + ")";
  given_.clear();
  response.success = true;
  ROS_INFO_STREAM_NAMED(log_name_, response.message);
  return true;
}

void LandmarkInput::onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& point) {
  std::string message;
  if (give("", point.get(), nullptr, "clicked", &message))
    ROS_INFO_STREAM_NAMED(log_name_, message);
  else
    ROS_WARN_STREAM_NAMED(log_name_, "ignored the clicked point: " << message);
}

void LandmarkInput::onDebugImageClick(const geometry_msgs::PointStamped::ConstPtr& pixel) {
  cv::Point2f rect(std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN());
  if (const View view = latest_(); view.frame) {  // the debug image is the rectified view scaled up by an integer
    const double k = cect::debugImageScale(view.frame->geometry().size().width, debug_width_);
    rect = cv::Point2f(static_cast<float>((pixel->point.x + 0.5) / k - 0.5),
                       static_cast<float>((pixel->point.y + 0.5) / k - 0.5));
  }
  std::string message;
  if (give("", nullptr, &rect, "clicked", &message))
    ROS_INFO_STREAM_NAMED(log_name_, message);
  else
    ROS_WARN_STREAM_NAMED(log_name_, "ignored the click on the debug image: " << message);
}

bool LandmarkInput::give(const std::string& requested, const geometry_msgs::PointStamped* point,
                         const cv::Point2f* rect, const std::string& source, std::string* message) {
  const View view = latest_();
  if (!view.frame) {
    *message = "no stereo pair analysed yet: a landmark needs the camera's view";
    return false;
  }
  const camera::StereoModel& geometry = view.frame->geometry();
  cv::Point2f pixel = rect ? *rect : cv::Point2f();
  if (point) {  // into the left camera, then its rectified pixel
    geometry_msgs::PointStamped in_camera;
    std::string tf_message;
    if (!transformPoint(tf_, *point, view.frame_id, kTfWait, &in_camera, &tf_message)) {
      *message = "cannot express the point in '" + view.frame_id + "': " + tf_message;
      return false;
    }
    const Eigen::Vector3d p(in_camera.point.x, in_camera.point.y, in_camera.point.z);
    if (!(p.z() > 0.0)) {
      *message = "the point lies behind the camera";
      return false;
    }
    const Eigen::Vector3d q = geometry.project(p);
    pixel = cv::Point2f(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }
  const std::string name = requested.empty() ? cect::nearestGivenLandmark(view.landmarks, model_, pixel) : requested;
  if (name.empty()) {
    *message = "the latest pair has no layout to tell C7 from L4 by: name the landmark with ~set_landmark";
    return false;
  }
  const cv::Point2f raw = cect::cameraPixel(pixel, geometry, view.decimation);
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string problem = given_.set(name, raw, source, view.decimation.fullSize());
  if (!problem.empty()) {
    *message = problem;
    return false;
  }
  *message = "landmark given: " + given_.describe();
  return true;
}

}  // namespace massage_cell::nodes
