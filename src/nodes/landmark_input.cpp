#include "landmark_input.h"

#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include <Eigen/Core>

#include "massage_cell/cect/tracker.h"
#include "tf_lookup.h"

namespace massage_cell::nodes {

namespace {
constexpr double kTfWait = 0.1;  // s (wall) a clicked point waits for its transform into the camera
/// A landmark given as a 3D point lies on the skin the latest pair measured at its pixel within this (m): rviz's
/// Publish Point lands on the cloud (the depth's noise, a few mm), a point touched with the tool lies on the skin
/// within the breathing's 2-5 mm; 3 cm keeps both and refuses a point that is not on this back (the table, a point
/// in the wrong frame, an old client's place).
constexpr double kMaxOffSkin = 0.03;
/// The parameter naming the next click's landmark (consumed by that click).
constexpr const char* kClickLandmarkParam = "click_landmark";
}  // namespace

LandmarkInput::LandmarkInput(ros::NodeHandle& nh, ros::NodeHandle& pnh, const tf2_ros::Buffer& tf,
                             const cect::AcupointModel& model, std::function<View()> latest, int debug_width,
                             std::string log_name)
    : pnh_(pnh),
      tf_(tf),
      model_(model),
      latest_(std::move(latest)),
      debug_width_(debug_width),
      log_name_(std::move(log_name)) {
  set_service_ = pnh.advertiseService("set_landmark", &LandmarkInput::setLandmark, this);
  clear_service_ = pnh.advertiseService("clear_landmarks", &LandmarkInput::clearLandmarks, this);
  confirm_service_ = pnh.advertiseService("confirm_landmarks", &LandmarkInput::confirmLandmarks, this);
  clicked_sub_ = nh.subscribe("/clicked_point", 5, &LandmarkInput::onClickedPoint, this);
  debug_click_sub_ = pnh.subscribe("debug_image_mouse_left", 5, &LandmarkInput::onDebugImageClick, this);
}

std::vector<cect::GivenLandmark> LandmarkInput::forPair(const cect::CectFrame& frame,
                                                        const camera::Decimation& decimation) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (given_.empty()) return {};
  given_.follow(cect::backView(frame, decimation));
  return given_.forPair(frame.geometry(), decimation);
}

bool LandmarkInput::setLandmark(massage_cell::SetLandmark::Request& request,
                                massage_cell::SetLandmark::Response& response) {
  if (const std::string problem = cect::checkGivenLandmarkName(request.name); !problem.empty()) {
    response.success = false;
    response.message = problem;
    return true;
  }
  if (!request.point.header.frame_id.empty()) {
    response.success = give(request.name, &request.point, nullptr, cect::LandmarkSource::kGivenService, request.confirm,
                            &response.message);
    return true;
  }
  if (request.u == 0.0 && request.v == 0.0) {
    response.success = false;
    response.message = "no point and no pixel: give point (with its header.frame_id) or u, v (the raw left pixel)";
    return true;
  }
  // A raw left pixel of the camera: into the latest pair's rectified pixels.
  cv::Point2f rect;
  if (const View view = latest_(); view.frame) {
    const cv::Point2f raw(static_cast<float>(request.u), static_cast<float>(request.v));
    rect = view.frame->geometry().toRectified(view.decimation.toDecimated(raw));
  }
  response.success =
      give(request.name, nullptr, &rect, cect::LandmarkSource::kGivenService, request.confirm, &response.message);
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

bool LandmarkInput::confirmLandmarks(std_srvs::Trigger::Request& /*request*/, std_srvs::Trigger::Response& response) {
  const View view = latest_();
  response.success = false;
  if (!view.frame) {
    response.message = "no stereo pair analysed yet: nothing to confirm the landmarks on";
    return true;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  if (given_.empty()) {
    response.message = "no landmarks given to confirm";
    return true;
  }
  const std::string problem = given_.confirm(cect::backView(*view.frame, view.decimation));
  response.success = problem.empty();
  response.message =
      problem.empty() ? "confirmed the given landmarks where they are now (" + given_.describe() + ")" : problem;
  ROS_INFO_STREAM_NAMED(log_name_, response.message);
  return true;
}

void LandmarkInput::onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& point) {
  std::string message;
  if (give(clickName(), point.get(), nullptr, cect::LandmarkSource::kGivenClick, false, &message))
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
  if (give(clickName(), nullptr, &rect, cect::LandmarkSource::kGivenClick, false, &message))
    ROS_INFO_STREAM_NAMED(log_name_, message);
  else
    ROS_WARN_STREAM_NAMED(log_name_, "ignored the click on the debug image: " << message);
}

std::string LandmarkInput::clickName() {
  std::string name;
  if (pnh_.getParam(kClickLandmarkParam, name)) pnh_.deleteParam(kClickLandmarkParam);
  return name;
}

bool LandmarkInput::onSkin(const View& view, const cv::Point2f& pixel, const Eigen::Vector3d& p,
                           std::string* message) const {
  const cect::LocalizedPoint skin = view.frame->localizeRectified(pixel);
  if (!skin.valid) {
    *message = "the point is not on the measured back (no skin measured at its pixel: " + skin.reason + ")";
    return false;
  }
  const double off = (p - skin.position).norm();
  if (off <= kMaxOffSkin) return true;
  std::ostringstream s;
  s.precision(3);
  s << std::fixed << "the point lies " << off << " m from the skin measured at its pixel (at most " << kMaxOffSkin
    << " m): not on this back";
  *message = s.str();
  return false;
}

bool LandmarkInput::give(const std::string& requested, const geometry_msgs::PointStamped* point,
                         const cv::Point2f* rect, cect::LandmarkSource source, bool confirm, std::string* message) {
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
    if (!onSkin(view, pixel, p, message)) return false;
  }
  std::string name = requested;
  if (name.empty()) {
    const cect::ClickName named = cect::nameClick(view.landmarks, model_, pixel);
    if (named.name.empty()) {
      *message = named.problem;
      return false;
    }
    name = named.name;
  }
  const cv::Point2f raw = cect::cameraPixel(pixel, geometry, view.decimation);
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string problem =
      given_.set(name, raw, source, view.decimation.fullSize(), confirm, cect::backView(*view.frame, view.decimation));
  if (!problem.empty()) {
    *message = problem;
    return false;
  }
  *message = "landmark given: " + given_.describe();
  return true;
}

}  // namespace massage_cell::nodes
