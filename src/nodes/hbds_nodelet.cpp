#include "hbds_nodelet.h"

#include <cmath>
#include <sstream>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/image_encodings.h>
#include <stereo_msgs/DisparityImage.h>
#include <pluginlib/class_list_macros.hpp>

#include "hbds_config.h"
#include "massage_cell/stereo/pipeline.h"
#include "start_parameters.h"
#include "stereo_messages.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

constexpr double kErrorLogPeriod = 5.0;  // s between two ERRORs naming the same problem

/// A surface nearer than the search range piles up at its near end. A real surface lying exactly at the range's last
/// level is a thin band of the image (one level of 16-256); 5 % of the pixels there is something too near to
/// measure (the back of the bundled recording, 16..47: none; the rendered back searched at 0..15: ~all).
constexpr double kNearEndWarnShare = 0.05;

}  // namespace

// ------------------------------------------------------------- set-up --

HbdsNodelet::HbdsNodelet() : log_throttle_(kErrorLogPeriod) {}

HbdsNodelet::~HbdsNodelet() {
  if (input_) input_->stop();  // before the state its worker uses goes
}

void HbdsNodelet::onInit() {
  initOrStop(getName(), [this] { init(); });
}

void HbdsNodelet::init() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();

  // Synchronised inputs, as stereo_image_proc: exact stamps by default.
  readParam(pnh, "rectify", &rectify_);
  readParam(pnh, "max_pixels", &max_pixels_);
  if (max_pixels_ < 0) {
    NODELET_ERROR_STREAM("parameter ~max_pixels must be >= 0 (0: no limit), got " << max_pixels_ << ": no limit");
    max_pixels_ = 0;
  }
  const SyncOptions sync = SyncOptions::fromParameters(pnh);
  if (!sync.problem.empty()) NODELET_ERROR_STREAM(sync.problem);
  input_ = std::make_unique<StereoPairInput>(nh, pnh, sync, [this](const StereoPair& pair) { onPair(pair); });

  // Parameters: log what dynamic_reconfigure would clamp silently, then serve them.
  config_ = Config::__getDefault__();
  reconfigure_server_ = serveConfig<Config>(pnh, config_mutex_, this, &HbdsNodelet::configCb,
                                            [this](const std::string& problem) { NODELET_ERROR_STREAM(problem); });

  // Diagnostics.
  diagnostics_.start(nh, pnh, "dense stereo (hbds)", this, &HbdsNodelet::diagnose);

  // Outputs; the inputs are subscribed while any of them has a subscriber.
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);  // no connectCb before the publishers exist
    const ros::SubscriberStatusCallback connect = [this](const ros::SingleSubscriberPublisher&) { connectCb(); };
    const image_transport::SubscriberStatusCallback it_connect =
        [this](const image_transport::SingleSubscriberPublisher&) { connectCb(); };
    disparity_pub_ = nh.advertise<stereo_msgs::DisparityImage>("disparity", 1, connect, connect);
    image_transport::ImageTransport it(nh);
    depth_pub_ = it.advertise("depth", 1, it_connect, it_connect);
    depth_info_pub_ = nh.advertise<sensor_msgs::CameraInfo>("depth/camera_info", 1, connect, connect);
    points_pub_ = nh.advertise<sensor_msgs::PointCloud2>("points2", 1, connect, connect);
    surface_pub_ = nh.advertise<sensor_msgs::PointCloud2>("surface", 1, connect, connect);
    confidence_pub_ = it.advertise("confidence", 1, it_connect, it_connect);
  }
  NODELET_INFO_STREAM("dense stereo on " << nh.resolveName("left/image_raw") << " + "
                                         << nh.resolveName("right/image_raw")
                                         << (sync.approximate ? " (approximate sync)" : " (exact sync)")
                                         << (rectify_ ? "" : ", images taken as rectified"));
}

void HbdsNodelet::configCb(Config& config, uint32_t /*level*/) {
  // Runs with config_mutex_ held (dynamic_reconfigure::Server locks it). A configuration the library or the node
  // refuses is rejected whole: the previous one stays, and the server publishes it back.
  const std::vector<std::string> problems = configProblems(config);
  for (const std::string& problem : problems)
    NODELET_ERROR_STREAM("rejected " << problem << ": keeping the previous parameters");
  if (!problems.empty()) {
    config = config_;
    return;
  }
  config_ = config;
  NODELET_INFO_STREAM(describe(config));
}

// ------------------------------------------------------ subscriptions --

HbdsNodelet::Outputs HbdsNodelet::wantedOutputs() {
  Outputs o;
  o.disparity = disparity_pub_.getNumSubscribers() > 0;
  o.depth = depth_pub_.getNumSubscribers() > 0 || depth_info_pub_.getNumSubscribers() > 0;
  o.points = points_pub_.getNumSubscribers() > 0;
  o.confidence = confidence_pub_.getNumSubscribers() > 0;
  o.surface = surface_pub_.getNumSubscribers() > 0;
  return o;
}

void HbdsNodelet::connectCb() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  if (wantedOutputs().any()) {
    input_->subscribe();
  } else {
    input_->unsubscribe();
  }
}

// ------------------------------------------------------------- worker --

void HbdsNodelet::onPair(const StereoPair& pair) {
  Config config;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    config = config_;
  }
  const Outputs wanted = wantedOutputs();
  if (!wanted.any()) return;  // the last subscriber left meanwhile
  try {
    process(pair, config, wanted);
  } catch (const BadInput& e) {
    badPair(e.what());
  } catch (const std::exception& e) {  // the library's std::invalid_argument, OpenCV, ...
    badPair(std::string("stereo matching failed: ") + e.what());
  }
}

void HbdsNodelet::badPair(const std::string& problem) {
  const std::string line =
      countFailure("skipped a stereo pair", problem, "bad pairs", status_mutex_, stats_, log_throttle_);
  if (!line.empty()) NODELET_ERROR_STREAM(line);
}

const camera::StereoModel& HbdsNodelet::updateModel(const CameraInfo& left, const CameraInfo& right) {
  // ~rectify false: the images are rectified whatever camera_info says (declared so: D = 0, R = I, K = P).
  bool rebuilt = false;
  model_ = model_cache_.get(
      left, right, rectify_ ? 1.0 : 0.0,
      [this](const camera::CameraCalibration& l, const camera::CameraCalibration& r) {
        return hbdsModel(l, r, rectify_);
      },
      &rebuilt);
  if (rebuilt) {
    NODELET_INFO_STREAM("calibration " << sizeText(left.width, left.height) << ": "
                                       << (model_->identity() ? "images used as they are (rectified)"
                                                              : "rectifying both views (maps cached)"));
  }
  return *model_;
}

HbdsNodelet::Views HbdsNodelet::prepareViews(const StereoPair& pair, int downsample) {
  return prepareHbdsViews(pair, downsample, max_pixels_,
                          [this](const CameraInfo& left, const CameraInfo& right) -> const camera::StereoModel& {
                            return updateModel(left, right);
                          });
}

stereo::StereoParams HbdsNodelet::matchParams(const Config& config, const Views& v) {
  stereo::StereoParams params = stereoParams(config);
  setHbdsRange(&params, config.min_disparity, config.disparity_range, config.downsample, v);
  return params;
}

void HbdsNodelet::process(const StereoPair& pair, const Config& config, const Outputs& wanted) {
  const auto start = Clock::now();
  // 1. Inputs: every problem names itself and skips the pair. Rectified (maps cached per calibration), downsampled.
  const Views v = prepareViews(pair, config.downsample);
  // 2. Match.
  const stereo::StereoParams params = matchParams(config, v);
  const stereo::Method method = stereo::parseMethod(config.method);
  const stereo::MatchResult result = stereo::match(v.images[0], v.images[1], method, params);
  // 3. Outputs: the valid and the confirmed disparities, then each output wanted.
  std_msgs::Header header = pair.left_image->header;
  if (header.frame_id.empty()) header.frame_id = pair.left_info->header.frame_id;
  const ValidDisparity valid = validDisparity(result, params, config.lr_fill);
  publish(header, config, v, params, valid, wanted);
  // 4. Status.
  const double elapsed = msSince(start);
  const CameraInfo& li = *pair.left_info;
  std::ostringstream geometry;
  geometry << sizeText(li.width, li.height)
           << (config.downsample > 1 ? " processed at " + sizeText(v.model.size().width, v.model.size().height)
                                     : std::string())
           << (model_->identity() ? ", rectified input" : ", rectified here") << ", f " << v.model.fx()
           << " px, baseline " << v.model.baseline() << " m, disparities " << params.cost.dmin << ".."
           << params.cost.dmax;
  std::lock_guard<std::mutex> lock(status_mutex_);
  stats_.processedOne(elapsed);
  last_matcher_ms_ = result.total_ms();
  last_far_end_ = valid.far_end;
  last_near_end_ = valid.near_end;
  if (geometry_summary_.empty()) NODELET_INFO_STREAM("first pair: " << geometry.str() << ", " << elapsed << " ms");
  geometry_summary_ = geometry.str();
}

void HbdsNodelet::publish(const std_msgs::Header& header, const Config& config, const Views& v,
                          const stereo::StereoParams& params, const ValidDisparity& valid, const Outputs& wanted) {
  if (wanted.disparity) {
    const float delta_d = config.method == "sgbm" || params.subpixel ? 1.0f / 16.0f : 1.0f;
    disparity_pub_.publish(disparityImage(header, v.model, params, valid, delta_d));
  }
  if (wanted.confidence) {
    // mono8: 255 where the disparity is a measurement (validDisparity's `confirmed`), 0 elsewhere.
    confidence_pub_.publish(
        cv_bridge::CvImage(header, sensor_msgs::image_encodings::MONO8, valid.confirmed).toImageMsg());
  }
  if (!wanted.depth && !wanted.points && !wanted.surface) return;
  // Depth (REP 118: metres along the rectified optical axis, NaN where unknown or at / beyond infinity).
  const cv::Mat depth = v.model.depth(valid.disparity);
  if (wanted.depth) {
    depth_pub_.publish(cv_bridge::CvImage(header, sensor_msgs::image_encodings::TYPE_32FC1, depth).toImageMsg());
    depth_info_pub_.publish(depthInfo(header, v.model));
  }
  if (!wanted.points && !wanted.surface) return;
  const cv::Mat points = v.model.points(depth);
  if (wanted.points) points_pub_.publish(pointCloud(header, points, v.images[0]));
  if (wanted.surface) publishSurface(header, params, valid, points);
}

void HbdsNodelet::publishSurface(const std_msgs::Header& header, const stereo::StereoParams& params,
                                 const ValidDisparity& valid, const cv::Mat& points) {
  if (!params.lr_check) {  // nothing confirms a disparity: no confident surface
    NODELET_WARN_ONCE("hbds: 'surface' needs lr_check (the confirmed pixels): nothing is published on it");
    return;
  }
  // ~80 points across whatever the resolution: 1-2 cm apart on the back at the cell's distance, the arm's cells.
  const int step = std::max(1, points.cols / kSurfaceColumns);
  surface_pub_.publish(surfaceCloud(header, points, valid.confirmed, step));
}

// -------------------------------------------------------- diagnostics --

void HbdsNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using diagnostic_msgs::DiagnosticStatus;
  Config config;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    config = config_;
  }
  const StereoPairInput::Counts input = input_->counts();
  std::lock_guard<std::mutex> lock(status_mutex_);
  if (stats_.lastPairBad()) {
    status.summary(DiagnosticStatus::ERROR, "last pair skipped: " + stats_.lastError());
  } else if (stats_.recentError()) {
    status.summary(DiagnosticStatus::WARN, "some pairs were bad and skipped");
  } else if (input.received == 0) {
    status.summary(DiagnosticStatus::OK, wantedOutputs().any() ? "waiting for stereo pairs" : "idle (no subscribers)");
  } else if (last_near_end_ > kNearEndWarnShare) {
    status.summary(DiagnosticStatus::WARN, std::to_string(static_cast<int>(std::lround(100.0 * last_near_end_))) +
                                               " % of the last pair at the range's near end: something is closer "
                                               "than the range (raise disparity_range); not confirmed there");
  } else {
    status.summary(DiagnosticStatus::OK, "processing");
  }
  status.add("method", config.method);
  status.add("disparities (full resolution)", std::to_string(config.min_disparity) + ".." +
                                                  std::to_string(config.min_disparity + config.disparity_range - 1));
  status.add("downsample", config.downsample);
  status.add("input", geometry_summary_);
  stats_.addCounts(status, input);
  stats_.addTimes(status, "last matcher time (ms)", last_matcher_ms_);
  status.addf("last pair at the range's far end (%)", "%.1f", 100.0 * last_far_end_);
  status.addf("last pair at the range's near end (%)", "%.1f", 100.0 * last_near_end_);
  status.add("last error", stats_.lastError());
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::HbdsNodelet, nodelet::Nodelet)
