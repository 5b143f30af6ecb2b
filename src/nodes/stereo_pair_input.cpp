#include "stereo_pair_input.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>
#include <opencv2/imgproc.hpp>

#include "calibration_msg.h"
#include "typed_param.h"

namespace massage_cell::nodes {

// ------------------------------------------------------------ input --

SyncOptions SyncOptions::fromParameters(const ros::NodeHandle& pnh) {
  SyncOptions o;
  readParam(pnh, "queue_size", &o.queue_size);
  readParam(pnh, "approximate_sync", &o.approximate);
  if (o.queue_size < 1) {
    o.problem = "parameter ~queue_size must be >= 1 (got " + std::to_string(o.queue_size) + "): using 5";
    o.queue_size = 5;
  }
  return o;
}

StereoPairInput::StereoPairInput(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const SyncOptions& sync,
                                 Handler handler)
    : nh_(nh), pnh_(pnh), handler_(std::move(handler)), it_(nh_), worker_([this](StereoPair& pair) {
        handler_(pair);
      }) {
  if (sync.approximate) {
    approximate_sync_ = std::make_unique<message_filters::Synchronizer<ApproximatePolicy>>(
        ApproximatePolicy(sync.queue_size), left_image_sub_, left_info_sub_, right_image_sub_, right_info_sub_);
    approximate_sync_->registerCallback(&StereoPairInput::pairCb, this);
  } else {
    exact_sync_ = std::make_unique<message_filters::Synchronizer<ExactPolicy>>(
        ExactPolicy(sync.queue_size), left_image_sub_, left_info_sub_, right_image_sub_, right_info_sub_);
    exact_sync_->registerCallback(&StereoPairInput::pairCb, this);
  }
}

StereoPairInput::~StereoPairInput() { stop(); }

void StereoPairInput::subscribe() {
  if (left_image_sub_.getSubscriber()) return;
  const image_transport::TransportHints hints("raw", ros::TransportHints(), pnh_);
  left_image_sub_.subscribe(it_, "left/image_raw", 1, hints);
  left_info_sub_.subscribe(nh_, "left/camera_info", 1);
  right_image_sub_.subscribe(it_, "right/image_raw", 1, hints);
  right_info_sub_.subscribe(nh_, "right/camera_info", 1);
}

void StereoPairInput::unsubscribe() {
  left_image_sub_.unsubscribe();
  left_info_sub_.unsubscribe();
  right_image_sub_.unsubscribe();
  right_info_sub_.unsubscribe();
}

void StereoPairInput::stop() { worker_.stop(); }

StereoPairInput::Counts StereoPairInput::counts() const { return worker_.counts(); }

void StereoPairInput::pairCb(const sensor_msgs::ImageConstPtr& left_image,
                             const sensor_msgs::CameraInfoConstPtr& left_info,
                             const sensor_msgs::ImageConstPtr& right_image,
                             const sensor_msgs::CameraInfoConstPtr& right_info) {
  worker_.put(StereoPair{left_image, right_image, left_info, right_info});
}

// ------------------------------------------------- per-pair checks --

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

std::string sizeText(unsigned width, unsigned height) { return std::to_string(width) + "x" + std::to_string(height); }

void checkImageSize(const sensor_msgs::CameraInfo& info, const sensor_msgs::Image& image, const std::string& which) {
  if (info.width != image.width || info.height != image.height) {
    throw BadInput(which + " image is " + sizeText(image.width, image.height) + " but its camera_info says " +
                   sizeText(info.width, info.height));
  }
  if (info.binning_x > 1 || info.binning_y > 1 || (info.roi.width != 0 && info.roi.width != info.width) ||
      (info.roi.height != 0 && info.roi.height != info.height)) {
    throw BadInput(which + " camera_info uses binning or a region of interest, which this node does not support");
  }
}

void appendCalibrationKey(std::vector<double>& key, const sensor_msgs::CameraInfo& info) {
  key.push_back(info.width);
  key.push_back(info.height);
  key.push_back(static_cast<double>(std::hash<std::string>{}(info.distortion_model)));
  key.push_back(static_cast<double>(info.D.size()));
  key.insert(key.end(), info.D.begin(), info.D.end());
  key.insert(key.end(), info.K.begin(), info.K.end());
  key.insert(key.end(), info.R.begin(), info.R.end());
  key.insert(key.end(), info.P.begin(), info.P.end());
}

std::shared_ptr<const camera::StereoModel> StereoModelCache::get(const sensor_msgs::CameraInfo& left,
                                                                 const sensor_msgs::CameraInfo& right, double variant,
                                                                 const Make& make, bool* rebuilt) {
  std::vector<double> key{variant};
  appendCalibrationKey(key, left);
  appendCalibrationKey(key, right);
  const bool changed = key != key_;
  if (changed) {
    key_ = key;
    model_.reset();
    error_.clear();
    try {
      model_ = std::make_shared<const camera::StereoModel>(make(toCalibration(left), toCalibration(right)));
    } catch (const std::invalid_argument& e) {  // uncalibrated, sizes differ, not a horizontal pair, ...
      error_ = std::string("unusable calibration: ") + e.what();
    }
  }
  if (rebuilt != nullptr) *rebuilt = changed && model_ != nullptr;
  if (!model_) throw BadInput(error_);
  return model_;
}

cv::Mat matchableImage(const sensor_msgs::ImageConstPtr& msg, const std::string& which) {
  namespace enc = sensor_msgs::image_encodings;
  const std::string& e = msg->encoding;
  if (e != enc::MONO8 && e != enc::BGR8 && e != enc::RGB8) {
    throw BadInput(which + " image encoding '" + e + "' is not supported (mono8, bgr8 or rgb8)");
  }
  cv_bridge::CvImageConstPtr cv_image;
  try {
    cv_image = cv_bridge::toCvShare(msg);
  } catch (const cv_bridge::Exception& ex) {
    throw BadInput(which + " image cannot be read: " + ex.what());
  }
  if (cv_image->image.empty()) throw BadInput(which + " image is empty");
  if (e == enc::RGB8) {
    cv::Mat bgr;
    cv::cvtColor(cv_image->image, bgr, cv::COLOR_RGB2BGR);
    return bgr;
  }
  return cv_image->image;
}

cv::Mat colourImage(const sensor_msgs::ImageConstPtr& msg, const std::string& which) {
  namespace enc = sensor_msgs::image_encodings;
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

bool ProblemThrottle::due(const std::string& problem) {
  const ros::WallTime now = ros::WallTime::now();
  if (last_.size() > 100) last_.clear();
  ros::WallTime& last = last_[problem];
  if (!last.isZero() && (now - last).toSec() < period_s_) return false;
  last = now;
  return true;
}

// ------------------------------------------------------ diagnostics --

void PairStats::processedOne(double ms, double waited_ms) {
  ++processed_;
  if (std::isfinite(waited_ms)) {
    ++waited_;
    total_waited_ms_ += waited_ms;
  }
  last_pair_bad_ = false;
  last_ms_ = ms;
  total_ms_ += ms;
  const ros::WallTime now = ros::WallTime::now();
  times_.push_back(now);
  while (times_.size() > 2 && (now - times_.front()).toSec() > kRateWindow) times_.pop_front();
}

std::uint64_t PairStats::badOne(const std::string& problem) {
  last_pair_bad_ = true;
  last_error_ = problem;
  last_error_time_ = ros::WallTime::now();
  return ++bad_;
}

bool PairStats::recentError() const {
  return !last_error_time_.isZero() && (ros::WallTime::now() - last_error_time_).toSec() < kRateWindow;
}

double PairStats::rate() const {
  if (times_.size() < 2 || (ros::WallTime::now() - times_.back()).toSec() >= kRateWindow) return 0.0;
  return (times_.size() - 1) / std::max(1e-6, (times_.back() - times_.front()).toSec());
}

void PairStats::addCounts(diagnostic_updater::DiagnosticStatusWrapper& status,
                          const StereoPairInput::Counts& input) const {
  status.add("pairs received", input.received);
  status.add("pairs processed", processed_);
  status.add("dropped pairs", input.dropped);
  status.add("bad pairs", bad_);
}

void PairStats::addTimes(diagnostic_updater::DiagnosticStatusWrapper& status, const std::string& stage_label,
                         double stage_ms) const {
  status.add("processing rate (Hz)", rate());
  status.add("last processing time (ms)", last_ms_);
  status.add(stage_label, stage_ms);
  status.add("mean processing time (ms)", processed_ > 0 ? total_ms_ / processed_ : 0.0);
  if (waited_ > 0) status.add("mean wait camera stamp -> processing (ms)", total_waited_ms_ / waited_);
}

std::string countFailure(const std::string& what, const std::string& problem, const std::string& counted,
                         std::mutex& mutex, PairStats& stats, ProblemThrottle& throttle) {
  std::uint64_t count = 0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    count = stats.badOne(problem);
  }
  if (!throttle.due(problem)) return "";
  return what + ": " + problem + " (" + std::to_string(count) + " " + counted + " so far)";
}

}  // namespace massage_cell::nodes
