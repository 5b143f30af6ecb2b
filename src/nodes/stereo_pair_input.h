// The input side shared by the stereo nodelets (hbds, cect), the way
// stereo_image_proc does it: left/image_raw + left/camera_info +
// right/image_raw + right/camera_info (image_transport, raw by default)
// synchronised by message_filters with exact stamps, or approximately with
// ~approximate_sync; ~queue_size is the synchroniser's queue.
//
// Threading (camera::LatestWorker): the synchroniser callback only drops the
// pair into a one-pair slot (replacing, and counting as dropped, a pair the
// worker has not taken yet); a worker thread hands the newest pair to the
// nodelet's handler, so subscriber callbacks are never blocked by the
// processing.
//
// Also here: what the nodelets' per-pair checks and diagnostics have in
// common (BadInput, the camera_info / image size check, the calibration key,
// per-problem log throttling, PairStats). Nothing here logs: the nodelets
// log under their own names.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <opencv2/core.hpp>

#include "massage_cell/camera/latest_worker.h"
#include "massage_cell/camera/stereo_model.h"

namespace massage_cell::nodes {

/// One synchronised input pair.
struct StereoPair {
  sensor_msgs::ImageConstPtr left_image, right_image;
  sensor_msgs::CameraInfoConstPtr left_info, right_info;
};

/// How the pair is synchronised: private parameters ~queue_size (5) and
/// ~approximate_sync (false), as stereo_image_proc.
struct SyncOptions {
  int queue_size = 5;
  bool approximate = false;
  std::string problem;  ///< a parameter replaced by its default, for the caller to log (empty: none)

  static SyncOptions fromParameters(const ros::NodeHandle& pnh);
};

/// The synchronised stereo input of a nodelet and the worker thread that
/// processes its newest pair.
class StereoPairInput {
 public:
  using Handler = std::function<void(const StereoPair&)>;
  /// Pairs from the synchroniser; pairs replaced in the slot before the worker took them.
  using Counts = camera::LatestWorker<StereoPair>::Counts;

  /// Starts the worker, which calls `handler` (which must not throw) with
  /// each pair it takes. Topics are resolved in `nh`; the image transport
  /// ("raw" by default) is read from `pnh`'s ~image_transport.
  StereoPairInput(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const SyncOptions& sync, Handler handler);
  ~StereoPairInput();  ///< stop()
  StereoPairInput(const StereoPairInput&) = delete;
  StereoPairInput& operator=(const StereoPairInput&) = delete;

  /// Subscribes to the four inputs (queue size 1 each: the synchroniser's
  /// queue is the one that matters); does nothing while subscribed.
  void subscribe();
  void unsubscribe();
  /// Ends the worker once it has finished the pair it is processing (waits
  /// for it); pairs arriving afterwards are ignored. Idempotent.
  void stop();
  Counts counts() const;

 private:
  using Image = sensor_msgs::Image;
  using CameraInfo = sensor_msgs::CameraInfo;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, CameraInfo, Image, CameraInfo>;
  using ApproximatePolicy = message_filters::sync_policies::ApproximateTime<Image, CameraInfo, Image, CameraInfo>;

  void pairCb(const sensor_msgs::ImageConstPtr& left_image, const sensor_msgs::CameraInfoConstPtr& left_info,
              const sensor_msgs::ImageConstPtr& right_image, const sensor_msgs::CameraInfoConstPtr& right_info);

  ros::NodeHandle nh_, pnh_;
  Handler handler_;
  image_transport::ImageTransport it_;
  image_transport::SubscriberFilter left_image_sub_, right_image_sub_;
  message_filters::Subscriber<CameraInfo> left_info_sub_, right_info_sub_;
  std::unique_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::unique_ptr<message_filters::Synchronizer<ApproximatePolicy>> approximate_sync_;
  camera::LatestWorker<StereoPair> worker_;  ///< the latest-pair slot between the synchroniser and the worker
};

// ------------------------------------------------- per-pair checks --

/// A problem with one input pair: logged (throttled), counted, the pair skipped.
struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point start);

/// "640x480".
std::string sizeText(unsigned width, unsigned height);

/// Throws BadInput when the image does not have the size its camera_info
/// declares or the camera_info uses binning / a region of interest.
void checkImageSize(const sensor_msgs::CameraInfo& info, const sensor_msgs::Image& image, const std::string& which);

/// The image for matching: 8-bit grey or BGR, shared with the message when possible (rgb8 is converted). Throws
/// BadInput naming `which` for other encodings (mono16, floats, Bayer, ...) and unreadable or empty images.
cv::Mat matchableImage(const sensor_msgs::ImageConstPtr& msg, const std::string& which);

/// The image as 8-bit BGR (for methods that need colour): any colour or Bayer encoding cv_bridge converts. Throws
/// BadInput naming `which` for images without colour and unreadable or empty ones.
cv::Mat colourImage(const sensor_msgs::ImageConstPtr& msg, const std::string& which);

/// Appends everything of `info` a calibration change affects, to detect
/// changes cheaply by comparing keys.
void appendCalibrationKey(std::vector<double>& key, const sensor_msgs::CameraInfo& info);

/// The camera::StereoModel of a pair's camera_info, made only when the calibrations (or `variant`: whatever else
/// `make` depends on, e.g. a processing width) change. An unusable calibration throws BadInput naming the problem
/// for every pair until the calibration changes. Not thread-safe: the nodelet's worker thread owns it.
class StereoModelCache {
 public:
  using Make = std::function<camera::StereoModel(const camera::CameraCalibration&, const camera::CameraCalibration&)>;
  /// The model; `rebuilt` (optional) tells whether it was made for this pair.
  std::shared_ptr<const camera::StereoModel> get(const sensor_msgs::CameraInfo& left,
                                                 const sensor_msgs::CameraInfo& right, double variant, const Make& make,
                                                 bool* rebuilt = nullptr);

 private:
  std::vector<double> key_;
  std::shared_ptr<const camera::StereoModel> model_;
  std::string error_;
};

/// Per-problem log throttling (wall time), so that a second kind of problem
/// is not hidden by the first. Not thread-safe.
class ProblemThrottle {
 public:
  explicit ProblemThrottle(double period_s) : period_s_(period_s) {}
  /// True when `problem` was not let through within the period (and notes it).
  bool due(const std::string& problem);

 private:
  double period_s_;
  std::map<std::string, ros::WallTime> last_;
};

// ------------------------------------------------------ diagnostics --

/// What the diagnostics of a stereo nodelet say about the pairs it processed
/// and skipped. Not thread-safe: the nodelet guards it with its status mutex.
class PairStats {
 public:
  static constexpr double kRateWindow = 10.0;  ///< s of completions the rate is taken over; also "recent"

  /// A pair processed in `ms` (clears lastPairBad), taken up `waited_ms` after its
  /// camera stamp (NaN: not known; the input's transport and queue).
  void processedOne(double ms, double waited_ms = std::numeric_limits<double>::quiet_NaN());
  std::uint64_t badOne(const std::string& problem);  ///< a pair skipped; returns the bad pairs so far
  std::uint64_t processed() const { return processed_; }
  std::uint64_t bad() const { return bad_; }
  bool lastPairBad() const { return last_pair_bad_; }  ///< the newest pair was skipped
  const std::string& lastError() const { return last_error_; }
  bool recentError() const;  ///< a pair was skipped within kRateWindow
  double rate() const;       ///< processed pairs a second (0 when stalled)

  /// "pairs received", "pairs processed", "dropped pairs", "bad pairs".
  void addCounts(diagnostic_updater::DiagnosticStatusWrapper& status, const StereoPairInput::Counts& input) const;
  /// "processing rate (Hz)", "last processing time (ms)", then
  /// `stage_label` = `stage_ms` (the library's own time), "mean processing time (ms)",
  /// and "mean wait camera stamp -> processing (ms)" when known.
  void addTimes(diagnostic_updater::DiagnosticStatusWrapper& status, const std::string& stage_label,
                double stage_ms) const;

 private:
  std::uint64_t processed_ = 0, bad_ = 0;
  bool last_pair_bad_ = false;
  std::string last_error_;
  ros::WallTime last_error_time_;
  double last_ms_ = 0.0, total_ms_ = 0.0, total_waited_ms_ = 0.0;
  std::uint64_t waited_ = 0;
  std::deque<ros::WallTime> times_;  // recent completions, for the rate
};

/// A failure (a skipped pair): counted in `stats` (under `mutex`, the nodelet's status mutex). Returns the line to
/// log, "<what>: <problem> (<count> <counted> so far)", or "" while `throttle` holds this problem back.
std::string countFailure(const std::string& what, const std::string& problem, const std::string& counted,
                         std::mutex& mutex, PairStats& stats, ProblemThrottle& throttle);

}  // namespace massage_cell::nodes
