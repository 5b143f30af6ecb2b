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

#include "calibration_msg.h"
#include "massage_cell/AcupointArray.h"
#include "massage_cell/cect/locate.h"
#include "start_parameters.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

namespace enc = sensor_msgs::image_encodings;

constexpr double kLogPeriod = 5.0;       // s between two logs naming the same problem
constexpr double kTfWait = 0.1;          // s (wall) ~get_acupoint waits for the transform at the estimate's stamp
constexpr double kMarkerLifetime = 1.0;  // s
constexpr int kDebugWidth = 960;         // px: ~debug_image is scaled up to at least this width
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

cect::CectParams cectParams(const CECTConfig& c) {
  cect::CectParams p;
  p.auto_scale = c.auto_scale;
  p.sample_spacing = c.sample_spacing;
  p.min_depth = c.min_depth;
  p.max_depth = c.max_depth;
  p.background.gap = c.background_gap;
  p.background.table_margin = c.table_margin;
  p.min_disparity = c.min_disparity;
  p.max_disparity = c.max_disparity;
  p.min_crossing_angle = c.min_crossing_angle;
  p.edge_window = c.edge_window;
  p.edge_min_bend = c.edge_min_bend;
  p.seed_step = c.seed_step;
  p.seed_column_step = c.seed_column_step;
  p.ncc_radius = c.ncc_radius;
  p.bandpass_low = c.bandpass_low;
  p.bandpass_high = c.bandpass_high;
  p.sheen_sigma = c.sheen_sigma;
  p.sheen_twicing = c.sheen_twicing;
  p.smooth_radius = c.smooth_radius;
  p.quartic_across = c.quartic_across;
  p.rim_profile = c.rim_profile;
  p.slanted_windows = c.slanted_windows;
  p.min_slant = c.min_slant;
  p.max_extrapolation = c.max_extrapolation;
  p.max_triangle_edge = c.max_triangle_edge;
  p.direct_min_sharpness = c.direct_min_sharpness;
  p.seed_search = c.seed_search;
  p.query_search = c.query_search;
  p.min_ncc = c.min_ncc;
  p.max_candidate_spread = c.max_candidate_spread;
  p.continuity_margin = c.continuity_margin;
  p.lr_tolerance = c.lr_tolerance;
  p.pixel_sigma = c.pixel_sigma;
  p.border_sigma = c.border_sigma;
  p.border_sigma_reach = c.border_sigma_reach;
  p.slope_sigma = c.slope_sigma;
  return p;
}

cect::TemporalFilterParams filterParams(const CECTConfig& c) {
  cect::TemporalFilterParams p;
  p.alpha = c.alpha;
  p.gate = c.gate;
  p.reacquire_after = c.reacquire_after;
  p.max_age = c.max_age;
  return p;
}

/// Marker colour of a region (measured in this pair); held estimates are grey.
std_msgs::ColorRGBA regionColour(const std::string& region, bool measured) {
  std_msgs::ColorRGBA c;
  c.a = 1.0f;
  if (!measured) {
    c.r = c.g = c.b = 0.6f;
    c.a = 0.7f;
  } else if (region == "upper_back") {
    c.r = 1.0f, c.g = 0.55f, c.b = 0.0f;
  } else if (region == "lower_back") {
    c.r = 0.1f, c.g = 0.4f, c.b = 1.0f;
  } else if (region == "midline") {
    c.r = 0.1f, c.g = 0.85f, c.b = 0.2f;
  } else if (region == "shoulder") {
    c.r = 0.9f, c.g = 0.1f, c.b = 0.9f;
  } else {
    c.r = c.g = c.b = 1.0f;
  }
  return c;
}

void toArray(const Eigen::Matrix3d& m, double* out) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[3 * r + c] = m(r, c);
}

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
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
    filter_.setParams(filterParams(config_));
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
  NODELET_INFO_STREAM("acupoints (" << model_.points.size() << " from " << model_path_ << ") on "
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
    model_ = cect::loadAcupointModel(model_path_);
    model_.validate();
  } catch (const std::exception& e) {
    NODELET_FATAL_STREAM("acupoint model " << model_path_ << ": " << e.what());
    throw;
  }
  if (model_.points.empty()) {
    NODELET_FATAL_STREAM("acupoint model " << model_path_ << " has no acupoints");
    throw std::runtime_error("empty acupoint model");
  }
  for (const auto& point : model_.points) estimates_[point.name].reason = "no stereo pair analysed yet";
}

void CectNodelet::configCb(Config& config, uint32_t /*level*/) {
  // Runs with config_mutex_ held (dynamic_reconfigure::Server locks it).
  // Combinations the ranges of cfg/CECT.cfg cannot rule out are rejected
  // here: the previous values stay, and the server publishes them back.
  if (config.max_disparity != 0.0 && config.max_disparity <= config.min_disparity) {
    NODELET_ERROR_STREAM("rejected max_disparity = " << config.max_disparity << " <= min_disparity = "
                                                     << config.min_disparity << " (0 means from min_depth): keeping "
                                                     << config_.min_disparity << ".." << config_.max_disparity);
    config.min_disparity = config_.min_disparity;
    config.max_disparity = config_.max_disparity;
  }
  if (config.max_depth <= config.min_depth) {
    NODELET_ERROR_STREAM("rejected max_depth = " << config.max_depth << " m <= min_depth = " << config.min_depth
                                                 << " m: keeping " << config_.min_depth << ".." << config_.max_depth
                                                 << " m");
    config.min_depth = config_.min_depth;
    config.max_depth = config_.max_depth;
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

  // A replay starting over sends the clock back: the estimates belong to another time.
  if (!last_stamp_.isZero() && header.stamp < last_stamp_) {
    NODELET_INFO_STREAM("the stamps went back by " << (last_stamp_ - header.stamp).toSec()
                                                   << " s (a replay started over?): acupoint estimates reset");
    filter_.clear();
  }
  last_stamp_ = header.stamp;
  try {
    filter_.setParams(filterParams(config));
  } catch (const std::invalid_argument& e) {  // the cfg ranges rule this out
    NODELET_ERROR_STREAM_THROTTLE(kLogPeriod, e.what());
  }

  // 2. CECT on the pair (throws std::invalid_argument for images that do not
  // fit the geometry: counted as a bad pair by workLoop).
  const auto frame =
      std::make_shared<const cect::CectFrame>(cect::CectFrame::analyse(left, right, geometry, cectParams(config)));
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest_ = Analysed{frame, header, decimation};
  }

  // 3. The model's acupoints in the left view, each to 3D, into the filter.
  cect::LocateOptions options;
  options.correct_parallax = config.correct_parallax;
  options.levels_in_3d = config.levels_in_3d;
  const cect::LocatedAcupoints located = cect::locateAcupoints(*frame, model_, options);
  std::vector<PointResult> results(model_.points.size());
  const std::string frame_problem = located.reason;  // non-empty: the pair gives no acupoint at all
  const double stamp = header.stamp.toSec();
  int measured = 0;
  const double body_angle = located.valid ? located.landmarks.body_angle_deg : std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < results.size() && i < located.points.size(); ++i) {
    const cect::LocatedAcupoint& p = located.points[i];
    PointResult& r = results[i];
    r.placed = p.placed;
    r.rectified = p.rectified;
    r.raw = decimation.toFull(p.raw);  // the camera's pixels
    r.reason = p.reason;
    if (!p.valid) continue;
    r.measured = true;
    ++measured;
    r.accepted = filter_.update(p.name, p.point.position, p.point.covariance, stamp);
    if (r.accepted) layout_covariance_[p.name] = p.layout_covariance;
    if (!r.accepted) {
      const cect::FilteredPoint* f = filter_.get(p.name, stamp);
      std::ostringstream why;
      why << "measurement rejected as an outlier";
      if (f) why << " (" << (p.point.position - f->position).norm() * 100.0 << " cm from the estimate)";
      r.reason = why.str();
    }
  }
  if (!frame_problem.empty()) {
    for (auto& r : results) r.reason = frame_problem;
    if (log_throttle_.due(frame_problem)) NODELET_WARN_STREAM("no acupoints in this pair: " << frame_problem);
  }

  // 4. Outputs.
  publish(header, *frame, results, frame_problem, config);

  // 5. Status.
  const double elapsed = msSince(start);
  int valid = 0;
  {
    std::lock_guard<std::mutex> lock(estimates_mutex_);
    for (const auto& e : estimates_) valid += e.second.valid ? 1 : 0;
  }
  std::lock_guard<std::mutex> lock(status_mutex_);
  stats_.processedOne(elapsed, waited_ms);
  if (!frame_problem.empty()) ++unusable_;
  last_problem_ = frame_problem;
  last_valid_ = valid;
  last_measured_ = measured;
  rejected_outliers_ = filter_.rejected();
  last_cect_ms_ = frame->timings().total_ms;
  if (frame->valid()) last_scale_ = frame->scale();
  last_disparity_range_ = frame->disparityRange();
  if (std::isfinite(body_angle)) last_body_angle_ = body_angle;
  if (located.valid) last_landmarks_ = cect::describeLandmarks(located.landmarks);
  if (frame->left().valid) last_trunk_ = frame->left().trunk.summary();
  last_background_ = frame->background().summary();
  if (stats_.processed() == 1) {
    NODELET_INFO_STREAM("first pair: " << valid << " of " << model_.points.size() << " acupoints valid, " << elapsed
                                       << " ms");
  }
}

void CectNodelet::publish(const std_msgs::Header& header, const cect::CectFrame& frame,
                          const std::vector<PointResult>& results, const std::string& frame_problem,
                          const Config& config) {
  const double stamp = header.stamp.toSec();
  auto array = boost::make_shared<massage_cell::AcupointArray>();
  array->header = header;
  array->acupoints.resize(model_.points.size());
  std::vector<geometry_msgs::TransformStamped> transforms;
  visualization_msgs::MarkerArray markers;
  std::map<std::string, Estimate> estimates;

  for (std::size_t i = 0; i < model_.points.size(); ++i) {
    const cect::AcupointSpec& spec = model_.points[i];
    const PointResult& r = results[i];
    massage_cell::Acupoint& a = array->acupoints[i];
    a.name = spec.name;
    a.region = spec.region;
    a.u = r.placed ? r.raw.x : std::numeric_limits<float>::quiet_NaN();
    a.v = r.placed ? r.raw.y : std::numeric_limits<float>::quiet_NaN();
    // A pair without a usable back invalidates every point (the subject may
    // have left); otherwise the filter's estimate stands for max_age.
    const cect::FilteredPoint* f = frame_problem.empty() ? filter_.get(spec.name, stamp) : nullptr;
    Estimate& e = estimates[spec.name];
    e.header = header;
    a.valid = e.valid = f != nullptr;
    if (f) {
      // The filtered matching noise plus the layout's (which no averaging removes).
      const auto layout = layout_covariance_.find(spec.name);
      e.position = f->position;
      e.covariance = f->covariance + (layout != layout_covariance_.end() ? layout->second : Eigen::Matrix3d::Zero());
      a.position.x = f->position.x();
      a.position.y = f->position.y();
      a.position.z = f->position.z();
      toArray(e.covariance, a.covariance.data());
      if (!r.accepted) {  // held from earlier pairs: say why this one did not measure it
        std::ostringstream why;
        why << r.reason << "; estimate from " << stamp - f->stamp << " s before";
        a.reason = why.str();
      }
      geometry_msgs::TransformStamped t;
      t.header = header;
      t.child_frame_id = frame_prefix_ + spec.name;
      t.transform.translation.x = f->position.x();
      t.transform.translation.y = f->position.y();
      t.transform.translation.z = f->position.z();
      t.transform.rotation.w = 1.0;
      transforms.push_back(t);
    } else {
      a.reason = r.reason.empty() ? "no current estimate" : r.reason;
      e.reason = a.reason;
    }

    if (!config.publish_debug) continue;
    visualization_msgs::Marker sphere;
    sphere.header = header;
    sphere.ns = "acupoints";
    sphere.id = static_cast<int>(2 * i);
    sphere.lifetime = ros::Duration(kMarkerLifetime);
    visualization_msgs::Marker text = sphere;
    text.id = sphere.id + 1;
    if (!f) {
      sphere.action = text.action = visualization_msgs::Marker::DELETE;
    } else {
      sphere.type = visualization_msgs::Marker::SPHERE;
      sphere.action = visualization_msgs::Marker::ADD;
      sphere.pose.position = a.position;
      sphere.pose.orientation.w = 1.0;
      sphere.scale.x = sphere.scale.y = sphere.scale.z = 0.012;
      sphere.color = regionColour(spec.region, r.accepted);
      text.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
      text.action = visualization_msgs::Marker::ADD;
      text.pose = sphere.pose;
      text.pose.position.z -= 0.015;  // toward the camera (optical z looks at the back)
      text.scale.z = 0.01;
      text.color = sphere.color;
      text.text = spec.name;
    }
    markers.markers.push_back(sphere);
    markers.markers.push_back(text);
  }

  {
    std::lock_guard<std::mutex> lock(estimates_mutex_);
    estimates_ = std::move(estimates);
  }
  acupoints_pub_.publish(array);
  if (!transforms.empty()) tf_broadcaster_->sendTransform(transforms);
  if (config.publish_debug) {
    if (markers_pub_.getNumSubscribers() > 0) markers_pub_.publish(markers);
    if (debug_image_pub_.getNumSubscribers() > 0) publishDebugImage(header, frame, results);
  }
}

void CectNodelet::publishDebugImage(const std_msgs::Header& header, const cect::CectFrame& frame,
                                    const std::vector<PointResult>& results) {
  cv::Mat image;
  try {
    image = frame.drawDebug();
  } catch (const std::exception& e) {
    NODELET_WARN_STREAM_THROTTLE(kLogPeriod, "debug picture failed: " << e.what());
  }
  if (image.empty()) image = frame.leftRectified().clone();
  if (image.empty()) return;
  if (image.type() == CV_8UC1) cv::cvtColor(image, image, cv::COLOR_GRAY2BGR);
  if (image.type() != CV_8UC3) return;
  // Scaled up (nearest neighbour, an integer factor) to >= kDebugWidth
  // pixels so that ~100 names stay legible on a small image.
  const int scale = std::max(1, (kDebugWidth + image.cols - 1) / image.cols);
  if (scale > 1) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_NEAREST);
  // The acupoints at their rectified pixels: filled = measured and accepted,
  // red ring = measured but rejected by the filter, grey ring = placed, not localised.
  for (std::size_t i = 0; i < results.size(); ++i) {
    const PointResult& r = results[i];
    if (!r.placed) continue;
    const cv::Point centre(cvRound((r.rectified.x + 0.5) * scale - 0.5), cvRound((r.rectified.y + 0.5) * scale - 0.5));
    const cv::Scalar colour = r.accepted   ? cv::Scalar(0, 255, 255)
                              : r.measured ? cv::Scalar(0, 0, 255)
                                           : cv::Scalar(160, 160, 160);
    cv::circle(image, centre, 3, colour, r.accepted ? cv::FILLED : 1, cv::LINE_AA);
    cv::putText(image, model_.points[i].name, centre + cv::Point(4, -2), cv::FONT_HERSHEY_PLAIN, 0.7, colour, 1,
                cv::LINE_AA);
  }
  debug_image_pub_.publish(cv_bridge::CvImage(header, enc::BGR8, image).toImageMsg());
}

// ------------------------------------------------------------ services --

bool CectNodelet::localizePixels(massage_cell::LocalizePixels::Request& request,
                                 massage_cell::LocalizePixels::Response& response) {
  Analysed latest;
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest = latest_;
  }
  const std::size_t n = request.pixels.size();
  response.points.assign(n, geometry_msgs::Point());
  response.covariances.assign(9 * n, 0.0);
  response.valid.assign(n, false);
  response.reasons.assign(n, "");
  response.header = latest.header;
  if (!latest.frame) {
    response.success = false;
    response.message = "no stereo pair analysed yet";
    std::fill(response.reasons.begin(), response.reasons.end(), response.message);
    return true;
  }
  const cect::CectFrame& frame = *latest.frame;
  if (!frame.valid()) {
    response.success = false;
    response.message = "the latest pair has no usable view of the back: " + frame.reason();
    std::fill(response.reasons.begin(), response.reasons.end(), response.message);
    return true;
  }
  int valid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& pixel = request.pixels[i];
    if (!std::isfinite(pixel.x) || !std::isfinite(pixel.y)) {
      response.reasons[i] = "the pixel is not finite";
      continue;
    }
    cect::LocalizedPoint p;
    try {
      p = frame.localize(
          latest.decimation.toDecimated(cv::Point2f(static_cast<float>(pixel.x), static_cast<float>(pixel.y))));
    } catch (const std::exception& e) {
      response.reasons[i] = std::string("localisation failed: ") + e.what();
      continue;
    }
    response.valid[i] = p.valid;
    if (!p.valid) {
      response.reasons[i] = p.reason.empty() ? "not localised" : p.reason;
      continue;
    }
    ++valid;
    response.points[i].x = p.position.x();
    response.points[i].y = p.position.y();
    response.points[i].z = p.position.z();
    toArray(p.covariance, &response.covariances[9 * i]);
  }
  response.success = true;
  response.message = std::to_string(valid) + " of " + std::to_string(n) + " pixels localised";
  return true;
}

bool CectNodelet::getAcupoint(massage_cell::GetAcupoint::Request& request,
                              massage_cell::GetAcupoint::Response& response) {
  response.success = false;
  if (!model_.find(request.name)) {
    response.message = "unknown acupoint '" + request.name + "' (known: " + joined(model_.names()) + ")";
    return true;
  }
  Estimate e;
  {
    std::lock_guard<std::mutex> lock(estimates_mutex_);
    e = estimates_[request.name];
  }
  if (!e.valid) {
    response.message = "no valid estimate of " + request.name + ": " + e.reason;
    return true;
  }
  double max_age = 0.0;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    max_age = config_.max_age;
  }
  const double age = (ros::Time::now() - e.header.stamp).toSec();
  if (age > max_age) {
    std::ostringstream m;
    m << "the estimate of " << request.name << " is " << age << " s old (max_age " << max_age
      << " s): no usable stereo pair since";
    response.message = m.str();
    return true;
  }
  toArray(e.covariance, response.covariance.data());
  geometry_msgs::PointStamped point;
  point.header = e.header;
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
  const int total = static_cast<int>(model_.points.size());
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
