#include "cect_nodelet.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/package.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2/exceptions.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>
#include <visualization_msgs/MarkerArray.h>
#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>

#include "acupoint_markers.h"
#include "calibration_msg.h"
#include "cect_config.h"
#include "massage_cell/AcupointArray.h"
#include "massage_cell/cect/locate.h"
#include "start_parameters.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

namespace enc = sensor_msgs::image_encodings;

constexpr double kLogPeriod = 5.0;  // s between two logs naming the same problem
constexpr double kTfWait = 0.1;     // s (wall) ~get_acupoint waits for the transform at the estimate's stamp
constexpr int kDebugWidth = 960;    // px: ~debug_image is scaled up to at least this width
const double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The image as 8-bit BGR (CECT finds the back by its colour).
cv::Mat toBgr(const sensor_msgs::ImageConstPtr& msg, const std::string& which) {
  const std::string& e = msg->encoding;
  if (!enc::isColor(e) && !enc::isBayer(e)) {
    throw BadInput(which + " image encoding '" + e +
                   "' has no colour: CECT finds the back by its skin colour (bgr8, rgb8, bgra8, rgba8 or Bayer)");
  }
  cv_bridge::CvImageConstPtr cv_image;
  try {
    cv_image = cv_bridge::toCvShare(msg, enc::BGR8);
  } catch (const cv_bridge::Exception& ex) {
    throw BadInput(which + " image cannot be read: " + ex.what());
  } catch (const cv::Exception& ex) {
    throw BadInput(which + " image cannot be converted to bgr8: " + ex.what());
  }
  if (cv_image->image.empty()) throw BadInput(which + " image is empty");
  return cv_image->image;
}

void toArray(const Eigen::Matrix3d& m, double* out) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[3 * r + c] = m(r, c);
}

}  // namespace

// ------------------------------------------------------------- set-up --

CectNodelet::CectNodelet() : log_throttle_(kLogPeriod) {}

CectNodelet::~CectNodelet() {
  if (input_) input_->stop();  // before the state its worker uses goes
}

void CectNodelet::onInit() {
  initOrStop(getName(), [this] { init(); });
}

void CectNodelet::init() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();

  // The acupoint model: a configuration error ends the node (logged FATAL, rethrown).
  loadModel();
  readParam(pnh, "frame_prefix", &frame_prefix_);
  readParam(pnh, "max_width", &max_width_);
  if (max_width_ < 0) {
    NODELET_ERROR_STREAM("parameter ~max_width must be >= 0 (0: full resolution), got " << max_width_
                                                                                        << ": using full resolution");
    max_width_ = 0;
  }
  while (!frame_prefix_.empty() && frame_prefix_.front() == '/')
    frame_prefix_.erase(0, 1);  // tf2 ids have no leading '/'

  // Synchronised inputs, as stereo_image_proc: exact stamps by default.
  const SyncOptions sync = SyncOptions::fromParameters(pnh);
  if (!sync.problem.empty()) NODELET_ERROR_STREAM(sync.problem);
  input_ = std::make_unique<StereoPairInput>(nh, pnh, sync, [this](const StereoPair& pair) { onPair(pair); });

  // Parameters: log what dynamic_reconfigure would clamp silently, then serve them.
  config_ = Config::__getDefault__();
  for (const std::string& problem : startParameterProblems<Config>(pnh)) NODELET_ERROR_STREAM(problem);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(config_mutex_, pnh);
  reconfigure_server_->setCallback([this](Config& config, uint32_t level) { configCb(config, level); });
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    tracker_->setParams(filterParams(config_));
  }

  // Diagnostics, once a second of wall time (Updater::update() goes by ROS
  // time, which stalls when a looping bag sends the simulated clock back).
  updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, pnh.getNamespace());
  updater_->setHardwareID("none");
  updater_->add("acupoints (cect)", this, &CectNodelet::diagnose);
  diagnostics_timer_ =
      nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->force_update(); });

  // Outputs, tf, services.
  acupoints_pub_ = nh.advertise<massage_cell::AcupointArray>("acupoints", 5);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 1);
  image_transport::ImageTransport private_it(pnh);
  debug_image_pub_ = private_it.advertise("debug_image", 1);
  tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);  // its own thread and queue
  localize_service_ = pnh.advertiseService("localize_pixels", &CectNodelet::localizePixels, this);
  acupoint_service_ = pnh.advertiseService("get_acupoint", &CectNodelet::getAcupoint, this);

  // Inputs, subscribed from the start (tf frames and services have no
  // subscriber count).
  input_->subscribe();
  NODELET_INFO_STREAM("acupoints (" << tracker_->model().points.size() << " from " << model_path_ << ") on "
                                    << nh.resolveName("left/image_raw") << " + " << nh.resolveName("right/image_raw")
                                    << (sync.approximate ? " (approximate sync)" : " (exact sync)") << "; tf frames "
                                    << frame_prefix_ << "<name>");
}

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
  try {
    tracker_ = std::make_unique<cect::AcupointTracker>(cect::loadAcupointModel(model_path_));
  } catch (const std::exception& e) {
    NODELET_FATAL_STREAM("acupoint model " << model_path_ << ": " << e.what());
    throw;
  }
}

void CectNodelet::configCb(Config& config, uint32_t /*level*/) {
  // Runs with config_mutex_ held (dynamic_reconfigure::Server locks it). A configuration the library refuses (what
  // the ranges of cfg/CECT.cfg cannot rule out, e.g. max_depth <= min_depth) is rejected whole: the previous one
  // stays, and the server publishes it back.
  const std::vector<std::string> problems = cect::checkParams(cectParams(config));
  if (!problems.empty()) {
    for (const std::string& problem : problems) {
      NODELET_ERROR_STREAM("rejected the new parameters: " << problem << "; keeping the previous ones");
    }
    config = config_;
    return;
  }
  config_ = config;
  auto bound = [](double px, const char* otherwise) {
    std::ostringstream s;
    if (px > 0)
      s << px;
    else
      s << otherwise;
    return s.str();
  };
  NODELET_INFO_STREAM("seed_step " << config.seed_step << ", ncc_radius " << config.ncc_radius << ", seed_search "
                                   << config.seed_search << ", query_search " << config.query_search << ", min_ncc "
                                   << config.min_ncc << ", depths " << config.min_depth << ".." << config.max_depth
                                   << " m, disparities " << bound(config.min_disparity, "from max_depth") << ".."
                                   << bound(config.max_disparity, "from min_depth") << ", filter alpha " << config.alpha
                                   << " gate " << config.gate << " m reacquire_after " << config.reacquire_after
                                   << " max_age " << config.max_age << " s");
}

// ------------------------------------------------------------- worker --

void CectNodelet::onPair(const StereoPair& pair) {
  Config config;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    config = config_;
  }
  try {
    process(pair, config);
  } catch (const std::exception& e) {  // BadInput, the library's std::invalid_argument, OpenCV, ...
    badPair(e.what());
  }
}

void CectNodelet::badPair(const std::string& problem) {
  std::uint64_t bad = 0;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    bad = stats_.badOne(problem);
  }
  if (log_throttle_.due(problem))
    NODELET_ERROR_STREAM("skipped a stereo pair: " << problem << " (" << bad << " bad pairs so far)");
}

void CectNodelet::updateGeometry(const CameraInfo& left, const CameraInfo& right) {
  const camera::Decimation decimation = camera::Decimation::toWidth(cv::Size(left.width, left.height), max_width_);
  bool rebuilt = false;
  geometry_ = model_cache_.get(
      left, right, max_width_,
      [&](const camera::CameraCalibration& l, const camera::CameraCalibration& r) {
        return camera::StereoModel(decimation.apply(l), decimation.apply(r));
      },
      &rebuilt);
  decimation_ = decimation;
  if (!rebuilt) return;
  std::ostringstream summary;
  summary << sizeText(left.width, left.height) << (geometry_->identity() ? ", rectified input" : ", rectified here")
          << ", f " << geometry_->fx() << " px, baseline " << geometry_->baseline() << " m";
  if (!decimation_.identity())
    summary << "; processed at " << sizeText(decimation_.size().width, decimation_.size().height) << " (~max_width "
            << max_width_ << ")";
  NODELET_INFO_STREAM("calibration: " << summary.str());
  std::lock_guard<std::mutex> lock(status_mutex_);
  geometry_summary_ = summary.str();
}

void CectNodelet::process(const StereoPair& pair, const Config& config) {
  const auto start = Clock::now();
  const double waited_ms = (ros::Time::now() - pair.left_image->header.stamp).toSec() * 1e3;
  const CameraInfo& li = *pair.left_info;
  const CameraInfo& ri = *pair.right_info;

  // 1. Inputs: every problem names itself and skips the pair.
  checkImageSize(li, *pair.left_image, "left");
  checkImageSize(ri, *pair.right_image, "right");
  updateGeometry(li, ri);
  const camera::Decimation decimation = decimation_;
  const cv::Mat left = decimation.apply(toBgr(pair.left_image, "left"));
  const cv::Mat right = decimation.apply(toBgr(pair.right_image, "right"));
  const camera::StereoModel& geometry = *geometry_;

  std_msgs::Header header;
  header.stamp = pair.left_image->header.stamp;
  header.frame_id = li.header.frame_id.empty() ? pair.left_image->header.frame_id : li.header.frame_id;
  if (header.frame_id.empty())
    throw BadInput("left camera_info and image have no frame_id: the acupoints need a frame");

  // 2. CECT on the pair (throws std::invalid_argument for images that do not fit the geometry: a bad pair).
  const auto frame =
      std::make_shared<const cect::CectFrame>(cect::CectFrame::analyse(left, right, geometry, cectParams(config)));
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest_ = Analysed{frame, header, decimation};
  }

  // 3. The model's acupoints in the left view, each to 3D, through the temporal filter.
  const cect::TrackerUpdate update = track(*frame, header, decimation, config);
  if (update.reset) NODELET_INFO("the stamps went back (a replay started over?): acupoint estimates reset");
  if (!update.problem.empty() && log_throttle_.due(update.problem))
    NODELET_WARN_STREAM("no acupoints in this pair: " << update.problem);

  // 4. Outputs, then the status.
  publish(header, *frame, update, config);
  recordStatus(*frame, update, msSince(start), waited_ms);
}

cect::TrackerUpdate CectNodelet::track(const cect::CectFrame& frame, const std_msgs::Header& header,
                                       const camera::Decimation& decimation, const Config& config) {
  cect::LocateOptions options;
  options.correct_parallax = config.correct_parallax;
  options.levels_in_3d = config.levels_in_3d;
  const cect::LocatedAcupoints located = cect::locateAcupoints(frame, tracker_->model(), options);
  std::lock_guard<std::mutex> lock(tracker_mutex_);
  try {
    tracker_->setParams(filterParams(config));
  } catch (const std::invalid_argument& e) {  // the cfg ranges rule this out
    NODELET_ERROR_STREAM_THROTTLE(kLogPeriod, e.what());
  }
  tracker_header_ = header;
  return tracker_->update(located, header.stamp.toSec(), decimation);
}

void CectNodelet::recordStatus(const cect::CectFrame& frame, const cect::TrackerUpdate& update, double elapsed_ms,
                               double waited_ms) {
  int rejected = 0;
  {
    std::lock_guard<std::mutex> lock(tracker_mutex_);
    rejected = tracker_->rejectedOutliers();
  }
  std::lock_guard<std::mutex> lock(status_mutex_);
  stats_.processedOne(elapsed_ms, waited_ms);
  if (!update.problem.empty()) ++unusable_;
  last_problem_ = update.problem;
  last_valid_ = update.valid;
  last_measured_ = update.measured;
  rejected_outliers_ = rejected;
  last_cect_ms_ = frame.timings().total_ms;
  if (frame.valid()) last_scale_ = frame.scale();
  last_disparity_range_ = frame.disparityRange();
  if (std::isfinite(update.body_angle_deg)) last_body_angle_ = update.body_angle_deg;
  if (!update.landmarks.empty()) last_landmarks_ = update.landmarks;
  if (frame.left().valid) last_trunk_ = frame.left().trunk.summary();
  last_background_ = frame.background().summary();
  if (stats_.processed() == 1) {
    NODELET_INFO_STREAM("first pair: " << update.valid << " of " << update.points.size() << " acupoints valid, "
                                       << elapsed_ms << " ms");
  }
}

void CectNodelet::publish(const std_msgs::Header& header, const cect::CectFrame& frame,
                          const cect::TrackerUpdate& update, const Config& config) {
  auto array = boost::make_shared<massage_cell::AcupointArray>();
  array->header = header;
  std::vector<geometry_msgs::TransformStamped> transforms;
  visualization_msgs::MarkerArray markers;
  for (std::size_t i = 0; i < update.points.size(); ++i) {
    const cect::TrackedAcupoint& p = update.points[i];
    massage_cell::Acupoint a;
    a.name = p.name;
    a.region = p.region;
    a.u = p.placed ? p.raw.x : std::numeric_limits<float>::quiet_NaN();
    a.v = p.placed ? p.raw.y : std::numeric_limits<float>::quiet_NaN();
    a.valid = p.valid;
    a.reason = p.reason;
    if (p.valid) {
      a.position.x = p.position.x();
      a.position.y = p.position.y();
      a.position.z = p.position.z();
      toArray(p.covariance, a.covariance.data());
      geometry_msgs::TransformStamped t;
      t.header = header;
      t.child_frame_id = frame_prefix_ + p.name;
      t.transform.translation.x = p.position.x();
      t.transform.translation.y = p.position.y();
      t.transform.translation.z = p.position.z();
      t.transform.rotation.w = 1.0;
      transforms.push_back(t);
    }
    array->acupoints.push_back(a);
    if (config.publish_debug) addAcupointMarkers(header, static_cast<int>(i), p, &markers);
  }
  acupoints_pub_.publish(array);
  if (!transforms.empty()) tf_broadcaster_->sendTransform(transforms);
  if (!config.publish_debug) return;
  if (markers_pub_.getNumSubscribers() > 0) markers_pub_.publish(markers);
  if (debug_image_pub_.getNumSubscribers() > 0) {
    const cv::Mat image = cect::drawAcupoints(frame, update.points, kDebugWidth);
    if (!image.empty()) debug_image_pub_.publish(cv_bridge::CvImage(header, enc::BGR8, image).toImageMsg());
  }
}

// ------------------------------------------------------------ services --

bool CectNodelet::localizePixels(massage_cell::LocalizePixels::Request& request,
                                 massage_cell::LocalizePixels::Response& response) {
  Analysed latest;
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest = latest_;
  }
  std::vector<cv::Point2d> pixels;
  for (const auto& pixel : request.pixels) pixels.emplace_back(pixel.x, pixel.y);
  const cect::PixelPoints located = cect::localizePixels(latest.frame.get(), latest.decimation, pixels);
  const std::size_t n = pixels.size();
  response.header = latest.header;
  response.success = located.success;
  response.message = located.message;
  response.points.assign(n, geometry_msgs::Point());
  response.covariances.assign(9 * n, 0.0);
  response.valid.assign(n, false);
  response.reasons.assign(n, "");
  for (std::size_t i = 0; i < n; ++i) {
    const cect::PixelPoint& p = located.points[i];
    response.valid[i] = p.valid;
    response.reasons[i] = p.reason;
    if (!p.valid) continue;
    response.points[i].x = p.position.x();
    response.points[i].y = p.position.y();
    response.points[i].z = p.position.z();
    toArray(p.covariance, &response.covariances[9 * i]);
  }
  return true;
}

bool CectNodelet::getAcupoint(massage_cell::GetAcupoint::Request& request,
                              massage_cell::GetAcupoint::Response& response) {
  response.success = false;
  cect::TrackedAcupoint e;
  geometry_msgs::PointStamped point;
  {
    std::lock_guard<std::mutex> lock(tracker_mutex_);
    e = tracker_->estimate(request.name, ros::Time::now().toSec());
    point.header = tracker_header_;  // the pair the estimates were published with
  }
  if (!e.valid) {
    response.message = e.reason;
    return true;
  }
  toArray(e.covariance, response.covariance.data());
  point.point.x = e.position.x();
  point.point.y = e.position.y();
  point.point.z = e.position.z();
  const std::string target = request.target_frame;
  if (target.empty() || target == point.header.frame_id) {
    response.point = point;
    response.success = true;
    response.message = "in " + point.header.frame_id;
    return true;
  }

  // Into target_frame: the transform at the estimate's stamp, waited for up
  // to kTfWait of wall time (polled: tf2's own timeout goes by ROS time,
  // which stands still when a replay ends); failing that the latest
  // transform (right for static frames and slow-moving ones).
  if (!tf_buffer_->_frameExists(target)) {
    response.message = "cannot express " + request.name + " in '" + target + "': tf knows no frame '" + target + "'";
    return true;
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(kTfWait);
  while (!tf_buffer_->canTransform(target, point.header.frame_id, point.header.stamp) &&
         ros::WallTime::now() < deadline) {
    ros::WallDuration(0.005).sleep();
  }
  try {
    geometry_msgs::TransformStamped t;
    std::string note;
    if (tf_buffer_->canTransform(target, point.header.frame_id, point.header.stamp)) {
      t = tf_buffer_->lookupTransform(target, point.header.frame_id, point.header.stamp);
    } else {
      t = tf_buffer_->lookupTransform(target, point.header.frame_id, ros::Time(0));
      std::ostringstream n;
      n << " (latest transform, " << (point.header.stamp - t.header.stamp).toSec() << " s from the estimate)";
      note = n.str();
    }
    tf2::doTransform(point, response.point, t);
    response.point.header.stamp = point.header.stamp;
    response.point.header.frame_id = target;
    response.success = true;
    response.message = "in " + target + note;
  } catch (const tf2::TransformException& ex) {
    response.message =
        "cannot express " + request.name + " in '" + target + "' (from '" + point.header.frame_id + "'): " + ex.what();
  }
  return true;
}

// -------------------------------------------------------- diagnostics --

void CectNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using diagnostic_msgs::DiagnosticStatus;
  const StereoPairInput::Counts input = input_->counts();
  std::lock_guard<std::mutex> lock(status_mutex_);
  const int total = static_cast<int>(tracker_->model().points.size());
  if (stats_.lastPairBad()) {
    status.summary(DiagnosticStatus::ERROR, "last pair skipped: " + stats_.lastError());
  } else if (stats_.processed() > 0 && !last_problem_.empty()) {
    status.summary(DiagnosticStatus::WARN, last_problem_);
  } else if (stats_.recentError()) {
    status.summary(DiagnosticStatus::WARN, "some pairs were bad and skipped");
  } else if (input.received == 0) {
    status.summary(DiagnosticStatus::OK, "waiting for stereo pairs");
  } else if (last_valid_ < total) {
    status.summary(DiagnosticStatus::WARN,
                   std::to_string(last_valid_) + " of " + std::to_string(total) + " acupoints valid");
  } else {
    status.summary(DiagnosticStatus::OK, "all " + std::to_string(total) + " acupoints valid");
  }
  status.add("acupoint model", model_path_);
  status.add("input", geometry_summary_);
  stats_.addCounts(status, input);
  status.add("pairs without acupoints", unusable_);
  status.add("valid acupoints", last_valid_);
  status.add("acupoints", total);
  status.add("acupoints measured in the last pair", last_measured_);
  status.add("outliers rejected", rejected_outliers_);
  stats_.addTimes(status, "last CECT time (ms)", last_cect_ms_);
  status.add("view scale (auto_scale; 1 = the reference view)", last_scale_);
  status.add("disparities searched (px, from min_depth / max_depth and camera_info)",
             std::to_string(last_disparity_range_[0]) + ".." + std::to_string(last_disparity_range_[1]));
  status.add("body turned on the table (degrees, + head toward the image right)", last_body_angle_);
  status.add("landmarks (measured; inferred)", last_landmarks_);
  status.add("trunk (what the segmentation cut away)", last_trunk_);
  status.add("background (far behind the table, by depth)", last_background_);
  status.add("last reason", last_problem_);
  status.add("last error", stats_.lastError());
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::CectNodelet, nodelet::Nodelet)
