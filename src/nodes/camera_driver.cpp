#include "camera_driver.h"

#include <filesystem>
#include <regex>

#include <camera_calibration_parsers/parse.h>
#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_eigen/tf2_eigen.h>

#include "calibration_msg.h"
#include "camera_info_url.h"
#include "typed_param.h"

namespace massage_cell::nodes {

using camera::ConfigError;

namespace {

// ------------------------------------------------------------ parameters --

std::string encodingOf(const cv::Mat& image) {
  namespace enc = sensor_msgs::image_encodings;
  switch (image.type()) {
    case CV_8UC3:
      return enc::BGR8;
    case CV_8UC1:
      return enc::MONO8;
    case CV_16UC1:
      return enc::MONO16;
    default:
      return "";
  }
}

}  // namespace

// ---------------------------------------------------------------- driver --

CameraDriver::CameraDriver(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, int views)
    : nh_(nh), pnh_(pnh), view_count_(views), it_(nh), updater_(nh, pnh, pnh.getNamespace()) {}

CameraDriver::~CameraDriver() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

void CameraDriver::readParameters() {
  const bool stereo = view_count_ == 2;
  config_.type = camera::parseSourceType(typedParam<std::string>(pnh_, "source", "v4l2"));
  config_.layout =
      stereo ? camera::parseLayout(typedParam<std::string>(pnh_, "layout", "pair")) : camera::Layout::kMono;
  if (config_.layout == camera::Layout::kMono && stereo) {
    throw ConfigError("parameter ~layout: the stereo driver needs 'pair' or 'side_by_side'");
  }
  const bool pair = config_.layout == camera::Layout::kPair;
  switch (config_.type) {
    case camera::SourceType::kV4l2:
      config_.locations = pair ? std::vector<std::string>{typedParam<std::string>(pnh_, "left/device", "/dev/video0"),
                                                          typedParam<std::string>(pnh_, "right/device", "/dev/video1")}
                               : std::vector<std::string>{typedParam<std::string>(pnh_, "device", "/dev/video0")};
      break;
    case camera::SourceType::kVideo:
      config_.locations = pair ? std::vector<std::string>{typedParam<std::string>(pnh_, "left/file", ""),
                                                          typedParam<std::string>(pnh_, "right/file", "")}
                               : std::vector<std::string>{typedParam<std::string>(pnh_, "file", "")};
      for (std::size_t i = 0; i < config_.locations.size(); ++i) {
        if (config_.locations[i].empty()) {
          throw ConfigError(std::string("video source: parameter ~") +
                            (pair ? (i == 0 ? "left/file" : "right/file") : "file") + " is not set");
        }
      }
      break;
    case camera::SourceType::kFolder:
      config_.folder = typedParam<std::string>(pnh_, "folder", "");
      if (config_.folder.empty()) throw ConfigError("folder source: parameter ~folder is not set");
      config_.patterns = pair ? std::vector<std::string>{typedParam<std::string>(pnh_, "left/pattern", "left*"),
                                                         typedParam<std::string>(pnh_, "right/pattern", "right*")}
                              : std::vector<std::string>{typedParam<std::string>(pnh_, "pattern", "*")};
      break;
  }
  config_.width = typedParam<int>(pnh_, "width", 0);
  config_.height = typedParam<int>(pnh_, "height", 0);
  config_.fps = typedParam<double>(pnh_, "fps", 0.0);
  config_.pixel_format = typedParam<std::string>(pnh_, "pixel_format", "");
  config_.buffer_size = typedParam<int>(pnh_, "buffer_queue_size", 1);
  config_.rate = typedParam<double>(pnh_, "rate", 0.0);
  config_.loop = typedParam<bool>(pnh_, "loop", false);
  camera::validate(config_);

  const std::string camera_name = typedParam<std::string>(pnh_, "camera_name", stereo ? "stereo" : "camera");
  static const std::regex valid_name("[A-Za-z0-9_]+");
  if (!std::regex_match(camera_name, valid_name)) {
    throw ConfigError("parameter ~camera_name '" + camera_name + "' may hold only letters, digits and '_'");
  }
  frame_id_ =
      typedParam<std::string>(pnh_, "frame_id", camera_name + (stereo ? "_left_optical_frame" : "_optical_frame"));
  right_frame_id_ = typedParam<std::string>(pnh_, "right_frame_id", camera_name + "_right_optical_frame");
  if (frame_id_.empty()) throw ConfigError("parameter ~frame_id is empty");
  publish_tf_ = typedParam<bool>(pnh_, "publish_tf", true);
  rectified_ = typedParam<bool>(pnh_, "rectified", false);
  capture_delay_ = typedParam<double>(pnh_, "capture_delay", 0.0);
  start_delay_ = typedParam<double>(pnh_, "start_delay", 0.0);
  if (!std::isfinite(start_delay_) || start_delay_ < 0.0 || start_delay_ > 3600.0) {
    throw ConfigError("parameter ~start_delay must be in [0, 3600] seconds");
  }
  if (!std::isfinite(capture_delay_) || capture_delay_ < 0.0 || capture_delay_ > 10.0) {
    throw ConfigError("parameter ~capture_delay must be in [0, 10] seconds");
  }

  views_.clear();
  const std::vector<std::string> labels =
      stereo ? std::vector<std::string>{"left", "right"} : std::vector<std::string>{""};
  for (const auto& label : labels) {
    View v;
    v.label = label;
    const std::string prefix = label.empty() ? "" : label + "/";
    v.camera_name =
        typedParam<std::string>(pnh_, prefix + "camera_name", label.empty() ? camera_name : camera_name + "_" + label);
    if (!std::regex_match(v.camera_name, valid_name)) {
      throw ConfigError("parameter ~" + prefix + "camera_name '" + v.camera_name +
                        "' may hold only letters, digits and '_'");
    }
    v.info_url = typedParam<std::string>(pnh_, prefix + "camera_info_url", "");
    v.nh = label.empty() ? nh_ : ros::NodeHandle(nh_, label);
    views_.push_back(std::move(v));
  }
}

void CameraDriver::setUpView(View& v) {
  const std::string which = v.label.empty() ? "camera" : v.label + " camera";
  const std::string path = calibrationPath(v.info_url, v.camera_name);
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    std::string name_in_file;
    sensor_msgs::CameraInfo info;
    if (!camera_calibration_parsers::readCalibration(path, name_in_file, info)) {
      throw ConfigError(which + " calibration '" + path +
                        "' is malformed (camera_calibration_parsers cannot parse it)");
    }
  } else if (!v.info_url.empty()) {
    ROS_WARN_STREAM("[" << pnh_.getNamespace() << "] " << which << " calibration '" << path
                        << "' does not exist: publishing uncalibrated camera_info until set_camera_info saves one");
  }
  v.info_manager = std::make_shared<camera_info_manager::CameraInfoManager>(v.nh, v.camera_name, v.info_url);
  image_transport::ImageTransport it(v.nh);
  v.publisher = it.advertiseCamera("image_raw", 1);
}

void CameraDriver::checkCalibrations() {
  const cv::Size size = source_->viewSize();
  std::vector<camera::CameraCalibration> calibs;
  for (auto& v : views_) {
    calibs.push_back(toCalibration(v.info_manager->getCameraInfo()));
    const auto problems =
        camera::checkCalibration(calibs.back(), size, v.label.empty() ? "camera" : v.label + " camera");
    if (!problems.empty()) throw ConfigError(problems.front());
  }
  if (calibs.size() == 2) {
    for (const auto& p : camera::checkStereoCalibration(calibs[0], calibs[1])) {
      ROS_WARN_STREAM("[" << pnh_.getNamespace() << "] " << p);
    }
    if (calibs[0].isCalibrated() != calibs[1].isCalibrated()) {
      ROS_WARN_STREAM("[" << pnh_.getNamespace() << "] only one camera of the pair is calibrated");
    }
  }
}

void CameraDriver::start() {
  readParameters();
  try {
    source_ = camera::openSource(config_);
  } catch (const cv::Exception& e) {
    throw ConfigError(std::string("cannot open the source: ") + e.what());
  }
  if (source_->views() != view_count_) throw ConfigError("source delivers the wrong number of views");
  for (const auto& w : source_->warnings()) ROS_WARN_STREAM("[" << pnh_.getNamespace() << "] " << w);
  for (auto& v : views_) setUpView(v);
  checkCalibrations();

  expected_rate_ = source_->nominalRate();
  source_description_ = source_->describe();
  updater_.setHardwareID(source_description_);
  rate_diagnostic_ = std::make_unique<diagnostic_updater::HeaderlessTopicDiagnostic>(
      view_count_ == 2 ? "image pairs" : "images", updater_,
      diagnostic_updater::FrequencyStatusParam(&expected_rate_, &expected_rate_, 0.1, 10));
  updater_.add("source", this, &CameraDriver::diagnose);
  diagnostics_timer_ =
      nh_.createWallTimer(ros::WallDuration(0.5), [this](const ros::WallTimerEvent&) { updater_.update(); });

  ROS_INFO_STREAM("[" << pnh_.getNamespace() << "] publishing " << source_->describe() << " in frame " << frame_id_
                      << (rectified_ ? " (declared rectified)" : ""));
  running_ = true;
  thread_ = std::thread([this] { captureLoop(); });
}

void CameraDriver::setState(const std::string& state, const std::string& error) {
  std::lock_guard<std::mutex> lock(status_mutex_);
  state_ = state;
  if (!error.empty()) last_error_ = error;
}

void CameraDriver::captureLoop() {
  using Clock = std::chrono::steady_clock;
  const std::string who = "[" + pnh_.getNamespace() + "] ";
  const bool live = source_->isLive();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / expected_rate_));
  std::chrono::system_clock::time_point last_capture{};
  if (!live && start_delay_ > 0.0) {  // give subscribers (e.g. rosbag record) time to connect
    setState("waiting to start");
    const auto start =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(start_delay_));
    while (running_ && ros::ok() && Clock::now() < start) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  auto next = Clock::now();
  setState("running");
  while (running_ && ros::ok()) {
    if (!source_) {  // a device failed: try again once a second
      std::this_thread::sleep_for(std::chrono::seconds(1));
      try {
        source_ = camera::openSource(config_);
        ROS_INFO_STREAM(who << "source reopened: " << source_->describe());
        setState("running");
        std::lock_guard<std::mutex> lock(status_mutex_);
        source_description_ = source_->describe();
      } catch (const std::exception& e) {
        setState("reopening", e.what());
        ROS_ERROR_STREAM_THROTTLE(10.0, who << "cannot reopen the source: " << e.what());
      }
      continue;
    }
    if (!live) {  // files: pace at the playback rate
      next += period;
      const auto now = Clock::now();
      if (next + period < now) next = now;  // fell far behind: do not burst
      std::this_thread::sleep_until(next);
    }
    camera::Frame frame;
    const camera::ReadResult result = source_->read(frame);
    switch (result.status) {
      case camera::ReadStatus::kOk:
        if (live && last_capture.time_since_epoch().count() != 0) {
          const double gap = std::chrono::duration<double>(frame.capture_time - last_capture).count() * expected_rate_;
          if (gap > 1.5) {
            std::lock_guard<std::mutex> lock(status_mutex_);
            dropped_frames_ += static_cast<std::uint64_t>(std::lround(gap) - 1);
          }
        }
        last_capture = frame.capture_time;
        publish(frame);
        break;
      case camera::ReadStatus::kBadFrame: {
        std::lock_guard<std::mutex> lock(status_mutex_);
        ++bad_frames_;
        last_error_ = result.message;
        ROS_WARN_STREAM_THROTTLE(live ? 1.0 : 0.0, who << "skipped a bad frame: " << result.message);
        break;
      }
      case camera::ReadStatus::kEnd:
        setState("ended");
        ROS_INFO_STREAM(who << result.message << ": published " << published_ << " frames, skipped " << bad_frames_
                            << " bad ones; the driver stays up (set ~loop to replay)");
        return;
      case camera::ReadStatus::kFailed:
        setState("reopening", result.message);
        ROS_ERROR_STREAM(who << result.message << "; reopening the source");
        source_.reset();
        {
          std::lock_guard<std::mutex> lock(status_mutex_);
          ++reopens_;
          source_description_ = "(closed, reopening)";
        }
        break;
    }
  }
}

void CameraDriver::publish(const camera::Frame& frame) {
  const double age = std::chrono::duration<double>(std::chrono::system_clock::now() - frame.capture_time).count();
  std_msgs::Header header;
  header.stamp = ros::Time::now() - ros::Duration(std::max(0.0, age) + capture_delay_);
  header.frame_id = frame_id_;  // both views: the left optical frame (see README)

  std::vector<sensor_msgs::CameraInfoPtr> infos;
  for (std::size_t i = 0; i < views_.size(); ++i) {
    auto info = boost::make_shared<sensor_msgs::CameraInfo>(views_[i].info_manager->getCameraInfo());
    if (info->K[0] == 0.0) {  // uncalibrated: still tell the size
      info->width = frame.views[i].cols;
      info->height = frame.views[i].rows;
    } else if (rectified_) {
      fromCalibration(camera::declareRectified(toCalibration(*info)), *info);
    }
    info->header = header;
    infos.push_back(info);
  }
  if (views_.size() == 2 && publish_tf_) publishRightTransform(*infos[0], *infos[1]);

  const std::string encoding = encodingOf(frame.views[0]);
  for (std::size_t i = 0; i < views_.size(); ++i) {
    sensor_msgs::ImagePtr image = cv_bridge::CvImage(header, encoding, frame.views[i]).toImageMsg();
    views_[i].publisher.publish(image, infos[i]);
  }
  rate_diagnostic_->tick();
  std::lock_guard<std::mutex> lock(status_mutex_);
  ++published_;
  last_skew_s_ = frame.view_skew_s;
  last_stamp_ = header.stamp;
}

void CameraDriver::publishRightTransform(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right) {
  if (right.K[0] == 0.0 || left.K[0] == 0.0) return;
  std::vector<double> key(right.P.begin(), right.P.end());
  key.insert(key.end(), left.R.begin(), left.R.end());
  key.insert(key.end(), right.R.begin(), right.R.end());
  if (key == last_right_p_) return;
  last_right_p_ = key;
  const Eigen::Isometry3d pose = camera::rightCameraInLeft(toCalibration(left), toCalibration(right));
  geometry_msgs::TransformStamped t = tf2::eigenToTransform(pose);
  t.header.stamp = left.header.stamp;
  t.header.frame_id = frame_id_;
  t.child_frame_id = right_frame_id_;
  tf_broadcaster_.sendTransform(t);
}

void CameraDriver::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(status_mutex_);
  using diagnostic_msgs::DiagnosticStatus;
  if (state_ == "running") {
    status.summary(bad_frames_ > 0 || dropped_frames_ > 0 ? DiagnosticStatus::WARN : DiagnosticStatus::OK,
                   bad_frames_ > 0 ? "running; some frames were bad and skipped" : "running");
  } else if (state_ == "ended") {
    status.summary(DiagnosticStatus::OK, "end of recording reached");
  } else if (state_ == "reopening") {
    status.summary(DiagnosticStatus::ERROR, "source failed: " + last_error_);
  } else {
    status.summary(DiagnosticStatus::OK, state_);
  }
  status.add("state", state_);
  status.add("source", source_description_);
  status.add("frames published", published_);
  status.add("bad frames", bad_frames_);
  status.add("dropped frames", dropped_frames_);
  status.add("reopens", reopens_);
  status.add("view skew (s)", last_skew_s_);
  status.add("last stamp", last_stamp_.toSec());
  status.add("last error", last_error_);
}

}  // namespace massage_cell::nodes
