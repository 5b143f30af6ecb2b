#include "cect_nodelet.h"

#include <sstream>
#include <stdexcept>

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/image_encodings.h>
#include <visualization_msgs/MarkerArray.h>
#include <pluginlib/class_list_macros.hpp>

#include "acupoint_messages.h"
#include "calibration_msg.h"
#include "cect_config.h"
#include "massage_cell/AcupointArray.h"
#include "massage_cell/cect/locate.h"
#include "start_parameters.h"

namespace massage_cell::nodes {

namespace {

constexpr double kLogPeriod = 5.0;  // s between two logs naming the same problem
constexpr double kTfWait = 0.1;     // s (wall) ~get_acupoint waits for the transform at the estimate's stamp
constexpr int kDebugWidth = 960;    // px: ~debug_image is scaled up to at least this width

}  // namespace

// ------------------------------------------------------------- set-up --

CectNodelet::CectNodelet() : log_throttle_(kLogPeriod) {}

CectNodelet::~CectNodelet() {
  if (input_) input_->stop();  // before the state its worker uses goes
  landmarks_.reset();          // its callbacks read the tracker's model and the latest pair
}

void CectNodelet::onInit() {
  initOrStop(getName(), [this] { init(); });
}

void CectNodelet::init() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();

  // The acupoint model: a configuration error ends the node (logged FATAL, rethrown).
  loadModel();
  loadSkinMarkers();
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
  reconfigure_server_ = serveConfig<Config>(pnh, config_mutex_, this, &CectNodelet::configCb,
                                            [this](const std::string& problem) { NODELET_ERROR_STREAM(problem); });
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    tracker_->setParams(filterParams(config_));
  }

  // Diagnostics.
  diagnostics_.start(nh, pnh, "acupoints (cect)", this, &CectNodelet::diagnose);

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
  profile_service_ = pnh.advertiseService("save_client_profile", &CectNodelet::saveClientProfile, this);
  landmarks_ = std::make_unique<LandmarkInput>(
      nh, pnh, *tf_buffer_, tracker_->model(),
      [this] {
        std::lock_guard<std::mutex> lock(latest_mutex_);
        return LandmarkInput::View{latest_.frame, latest_.header.frame_id, latest_.decimation, latest_.landmarks};
      },
      kDebugWidth, getName());

  // Inputs, subscribed from the start (tf frames and services have no
  // subscriber count).
  input_->subscribe();
  NODELET_INFO_STREAM("acupoints (" << tracker_->model().points.size() << " from " << model_path_ << ") on "
                                    << nh.resolveName("left/image_raw") << " + " << nh.resolveName("right/image_raw")
                                    << (sync.approximate ? " (approximate sync)" : " (exact sync)") << "; tf frames "
                                    << frame_prefix_ << "<name>");
}

cect::CectParams CectNodelet::pairParams(const Config& config) const {
  cect::CectParams params = cectParams(config);
  params.skin_markers = skin_markers_;
  return params;
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
  NODELET_INFO_STREAM(describe(config));
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
  const std::string line =
      countFailure("skipped a stereo pair", problem, "bad pairs", status_mutex_, stats_, log_throttle_);
  if (!line.empty()) NODELET_ERROR_STREAM(line);
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
  status_.setInput(summary.str());
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
  const cv::Mat left = decimation.apply(colourImage(pair.left_image, "left"));
  const cv::Mat right = decimation.apply(colourImage(pair.right_image, "right"));
  const camera::StereoModel& geometry = *geometry_;

  std_msgs::Header header;
  header.stamp = pair.left_image->header.stamp;
  header.frame_id = li.header.frame_id.empty() ? pair.left_image->header.frame_id : li.header.frame_id;
  if (header.frame_id.empty())
    throw BadInput("left camera_info and image have no frame_id: the acupoints need a frame");

  // 2. CECT on the pair (throws std::invalid_argument for images that do not fit the geometry: a bad pair).
  const auto frame =
      std::make_shared<const cect::CectFrame>(cect::CectFrame::analyse(left, right, geometry, pairParams(config)));
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest_ = Analysed{frame, header, decimation, {}, nullptr};  // the layout comes after the tracking
  }

  // 3. The model's acupoints in the left view, each to 3D, through the temporal filter.
  std::shared_ptr<const cect::LocatedAcupoints> located;
  const cect::TrackerUpdate update = track(*frame, header, decimation, config, &located);
  const cect::BackLandmarks& landmarks = located->landmarks;
  {
    std::lock_guard<std::mutex> lock(latest_mutex_);
    latest_.landmarks = landmarks;
    latest_.located = located;
  }
  if (update.reset) NODELET_INFO("the stamps went back (a replay started over?): acupoint estimates reset");
  if (!update.problem.empty() && log_throttle_.due(update.problem))
    NODELET_WARN_STREAM("no acupoints in this pair: " << update.problem);

  // 4. Outputs, then the status.
  publish(header, *frame, update, landmarks, decimation, config);
  recordStatus(*frame, update, msSince(start), waited_ms);
}

cect::TrackerUpdate CectNodelet::track(const cect::CectFrame& frame, const std_msgs::Header& header,
                                       const camera::Decimation& decimation, const Config& config,
                                       std::shared_ptr<const cect::LocatedAcupoints>* located_out) {
  cect::LocateOptions options = locateOptions(config);
  options.given = landmarks_->forPair(frame, decimation);
  options.trust.client_length_m = client_.c7_to_l4_m;
  options.trust.length_tolerance_m = client_.length_tolerance_m;
  options.trust.configuration_problem = client_profile_problem_;  // a profile that could not be read: none trusted
  const auto shared =
      std::make_shared<const cect::LocatedAcupoints>(cect::locateAcupoints(frame, tracker_->model(), options));
  *located_out = shared;
  const cect::LocatedAcupoints& located = *shared;
  if (skin_markers_) {
    if (!located.markers.problems.empty() && log_throttle_.due("skin markers"))
      NODELET_WARN_STREAM("skin markers: " << located.markers.describe());
    std::lock_guard<std::mutex> lock(status_mutex_);
    status_.setMarkers(located.markers.describe());
  }
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
  status_.record(frame, update, rejected);
  if (stats_.processed() == 1) {
    NODELET_INFO_STREAM("first pair: " << update.valid << " of " << update.points.size() << " acupoints valid, "
                                       << elapsed_ms << " ms");
  }
}

void CectNodelet::publish(const std_msgs::Header& header, const cect::CectFrame& frame,
                          const cect::TrackerUpdate& update, const cect::BackLandmarks& landmarks,
                          const camera::Decimation& decimation, const Config& config) {
  auto array = boost::make_shared<massage_cell::AcupointArray>();
  array->header = header;
  array->landmarks = landmarkMsgs(landmarks, frame.geometry(), decimation);
  std::vector<geometry_msgs::TransformStamped> transforms;
  visualization_msgs::MarkerArray markers;
  for (std::size_t i = 0; i < update.points.size(); ++i) {
    const cect::TrackedAcupoint& p = update.points[i];
    array->acupoints.push_back(acupointMsg(p));
    if (p.valid) transforms.push_back(acupointTransform(header, frame_prefix_, p));
    if (config.publish_debug) addAcupointMarkers(header, static_cast<int>(i), p, &markers);
  }
  acupoints_pub_.publish(array);
  if (!transforms.empty()) tf_broadcaster_->sendTransform(transforms);
  if (!config.publish_debug) return;
  if (markers_pub_.getNumSubscribers() > 0) markers_pub_.publish(markers);
  if (debug_image_pub_.getNumSubscribers() > 0) {
    const cv::Mat image = cect::drawAcupoints(frame, update.points, kDebugWidth, cect::layoutLandmarks(landmarks));
    if (!image.empty()) {
      debug_image_pub_.publish(cv_bridge::CvImage(header, sensor_msgs::image_encodings::BGR8, image).toImageMsg());
    }
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
  fillResponse(latest.header, cect::localizePixels(latest.frame.get(), latest.decimation, pixels), &response);
  return true;
}

bool CectNodelet::getAcupoint(massage_cell::GetAcupoint::Request& request,
                              massage_cell::GetAcupoint::Response& response) {
  cect::TrackedAcupoint estimate;
  std_msgs::Header header;
  {
    std::lock_guard<std::mutex> lock(tracker_mutex_);
    estimate = tracker_->estimate(request.name, ros::Time::now().toSec());
    header = tracker_header_;  // the pair the estimates were published with
  }
  fillResponse(request.name, estimate, header, request.target_frame, *tf_buffer_, kTfWait, &response);
  return true;
}

// -------------------------------------------------------- diagnostics --

void CectNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  const StereoPairInput::Counts input = input_->counts();
  std::lock_guard<std::mutex> lock(status_mutex_);
  status_.report(status, stats_, input, static_cast<int>(tracker_->model().points.size()), model_path_);
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::CectNodelet, nodelet::Nodelet)
