#include "hbds_nodelet.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <stereo_msgs/DisparityImage.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>

#include "calibration_msg.h"
#include "massage_cell/stereo/pipeline.h"
#include "start_parameters.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

/// The library's name of a cfg refinement value (cfg values use '_' where the library uses '-').
std::string refinementName(std::string value) {
  std::replace(value.begin(), value.end(), '_', '-');
  return value;
}

/// The library's parameters of a configuration (the disparity range is set per pair). Throws
/// std::invalid_argument for an unknown cost, refine or subpixel name.
stereo::StereoParams paramsOf(const HBDSConfig& config) {
  stereo::StereoParams params;
  params.cost.data_term = stereo::parseDataTerm(config.cost);
  params.cost.eta = static_cast<float>(config.eta);
  params.cost.ncc_window = config.ncc_window;
  params.cost.gradient_saturation = static_cast<float>(config.gradient_saturation);
  params.cost.threads = config.threads;
  params.smooth.tau = static_cast<float>(config.tau);
  params.smooth.u_min = static_cast<float>(config.u_min);
  params.smooth.u_max = static_cast<float>(config.u_max);
  params.threads = config.threads;
  params.polish_window = config.polish_window;
  params.hbds_overlap = config.overlap;
  params.hbds_coarse = config.coarse;
  params.refine = stereo::parseRefinement(refinementName(config.refine));
  params.refine_params.window = config.refine_window;
  params.refine_params.threads = config.threads;
  params.subpixel = config.subpixel != "none";
  if (params.subpixel) params.subpixel_params.fit = stereo::parseSubpixelFit(config.subpixel);
  params.lr_check = config.lr_check;
  params.lr_tolerance = static_cast<float>(config.lr_tolerance);
  return params;
}

namespace enc = sensor_msgs::image_encodings;

constexpr double kErrorLogPeriod = 5.0;  // s between two ERRORs naming the same problem

/// The pair's images as 8-bit BGR or grey cv::Mats (shared with the messages
/// when possible); rgb8 is converted, mono16 and the rest are refused.
cv::Mat toMat(const sensor_msgs::ImageConstPtr& msg, const std::string& which) {
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

std::uint32_t packRgb(const cv::Mat& image, int x, int y) {
  if (image.channels() == 1) {
    const std::uint32_t g = image.at<std::uint8_t>(y, x);
    return (g << 16) | (g << 8) | g;
  }
  const cv::Vec3b& bgr = image.at<cv::Vec3b>(y, x);
  return (static_cast<std::uint32_t>(bgr[2]) << 16) | (static_cast<std::uint32_t>(bgr[1]) << 8) | bgr[0];
}

/// Organised cloud `x y z rgb` of the model's points (CV_32FC3, NaN where unknown) coloured by the rectified left
/// image (REP 103: the left optical frame).
sensor_msgs::PointCloud2Ptr pointCloud(const std_msgs::Header& header, const cv::Mat& points, const cv::Mat& colours) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header = header;
  cloud->height = points.rows;
  cloud->width = points.cols;
  sensor_msgs::PointCloud2Modifier modifier(*cloud);
  modifier.setPointCloud2Fields(4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                                "z", 1, sensor_msgs::PointField::FLOAT32, "rgb", 1, sensor_msgs::PointField::FLOAT32);
  cloud->is_dense = false;
  cloud->is_bigendian = false;
  sensor_msgs::PointCloud2Iterator<float> it(*cloud, "x");
  for (int y = 0; y < points.rows; ++y) {
    const cv::Vec3f* p = points.ptr<cv::Vec3f>(y);
    for (int x = 0; x < points.cols; ++x, ++it) {
      float* out = &it[0];
      out[0] = p[x][0];
      out[1] = p[x][1];
      out[2] = p[x][2];
      const std::uint32_t rgb = packRgb(colours, x, y);
      std::memcpy(&out[3], &rgb, sizeof(rgb));
    }
  }
  return cloud;
}

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
  for (const std::string& problem : startParameterProblems<Config>(pnh)) NODELET_ERROR_STREAM(problem);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(config_mutex_, pnh);
  reconfigure_server_->setCallback([this](Config& config, uint32_t level) { configCb(config, level); });

  // Diagnostics.
  updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, pnh.getNamespace());
  updater_->setHardwareID("none");
  updater_->add("dense stereo (hbds)", this, &HbdsNodelet::diagnose);
  // Once a second of wall time: Updater::update() goes by ROS time, which
  // stalls when a looping bag sends the simulated clock back.
  diagnostics_timer_ =
      nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->force_update(); });

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
  std::vector<std::string> problems;
  if (config.method != "hbds" && config.method != "sgbm" && config.method != "wta") {
    problems.push_back("method '" + config.method + "' (hbds, sgbm or wta)");
  }
  if (config.downsample != 1 && config.downsample != 2 && config.downsample != 4) {
    problems.push_back("downsample = " + std::to_string(config.downsample) + " (1, 2 or 4)");
  }
  try {
    for (const stereo::ParamProblem& p : stereo::checkParams(paramsOf(config))) {
      problems.push_back(p.name + " " + p.problem);
    }
  } catch (const std::invalid_argument& e) {  // an unknown cost, refine or subpixel name
    problems.push_back(e.what());
  }
  if (!problems.empty()) {
    for (const std::string& problem : problems)
      NODELET_ERROR_STREAM("rejected " << problem << ": keeping the previous parameters");
    config = config_;
    return;
  }
  config_ = config;
  NODELET_INFO_STREAM("method " << config.method << ", disparities " << config.min_disparity << ".."
                                << config.min_disparity + config.disparity_range - 1 << ", cost " << config.cost
                                << ", eta " << config.eta << ", ncc_window " << config.ncc_window
                                << ", gradient_saturation " << config.gradient_saturation << ", tau " << config.tau
                                << ", u " << config.u_min << ".." << config.u_max << ", overlap " << config.overlap
                                << ", coarse " << config.coarse << ", polish_window " << config.polish_window
                                << ", refine " << config.refine << ", subpixel " << config.subpixel << ", lr_check "
                                << (config.lr_check ? "on" : "off") << " (tolerance " << config.lr_tolerance
                                << ", fill " << (config.lr_fill ? "on" : "off") << "), threads " << config.threads
                                << ", downsample " << config.downsample);
}

// ------------------------------------------------------ subscriptions --

HbdsNodelet::Outputs HbdsNodelet::wantedOutputs() {
  Outputs o;
  o.disparity = disparity_pub_.getNumSubscribers() > 0;
  o.depth = depth_pub_.getNumSubscribers() > 0 || depth_info_pub_.getNumSubscribers() > 0;
  o.points = points_pub_.getNumSubscribers() > 0;
  o.confidence = confidence_pub_.getNumSubscribers() > 0;
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
  std::uint64_t bad = 0;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    bad = stats_.badOne(problem);
  }
  if (log_throttle_.due(problem))
    NODELET_ERROR_STREAM("skipped a stereo pair: " << problem << " (" << bad << " bad pairs so far)");
}

const camera::StereoModel& HbdsNodelet::updateModel(const CameraInfo& left, const CameraInfo& right) {
  // ~rectify false: the images are rectified whatever camera_info says (declared so: D = 0, R = I, K = P).
  bool rebuilt = false;
  model_ = model_cache_.get(
      left, right, rectify_ ? 1.0 : 0.0,
      [this](const camera::CameraCalibration& l, const camera::CameraCalibration& r) {
        return rectify_ ? camera::StereoModel(l, r)
                        : camera::StereoModel(camera::declareRectified(l), camera::declareRectified(r));
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
  const CameraInfo& li = *pair.left_info;
  const CameraInfo& ri = *pair.right_info;
  checkImageSize(li, *pair.left_image, "left");
  checkImageSize(ri, *pair.right_image, "right");
  const camera::StereoModel& full = updateModel(li, ri);
  const long processed_pixels = static_cast<long>(li.width / downsample) * static_cast<long>(li.height / downsample);
  if (max_pixels_ > 0 && processed_pixels > max_pixels_) {  // before minutes of work and gigabytes of cost volume
    throw BadInput("images of " + sizeText(li.width, li.height) + " at downsample " + std::to_string(downsample) +
                   " are " + std::to_string(processed_pixels) + " pixels, above ~max_pixels " +
                   std::to_string(max_pixels_) + ": raise downsample or max_pixels");
  }
  if (static_cast<int>(li.width) / downsample < 8 || static_cast<int>(li.height) / downsample < 8) {
    throw BadInput("images of " + sizeText(li.width, li.height) + " are too small for downsample " +
                   std::to_string(downsample));
  }
  Views v;
  v.images[0] = toMat(pair.left_image, "left");
  v.images[1] = toMat(pair.right_image, "right");
  if (v.images[0].channels() != v.images[1].channels()) {  // mixed mono / colour: match in grey
    for (auto& image : v.images) {
      if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
    }
  }
  full.rectify(v.images[0], v.images[1], &v.images[0], &v.images[1]);
  v.model = downsample > 1 ? full.downsampled(downsample) : full;
  const camera::Decimation decimation(full.size(), downsample);
  for (auto& image : v.images) image = decimation.apply(image);
  v.scale = static_cast<double>(v.model.size().width) / full.size().width;
  return v;
}

stereo::StereoParams HbdsNodelet::matchParams(const Config& config, const Views& v) {
  // The range is set in full-resolution pixels; at 1/s resolution the searched range is the smallest one covering it.
  const int full_dmax = config.min_disparity + config.disparity_range - 1;
  stereo::StereoParams params = paramsOf(config);
  params.cost.dmin = static_cast<int>(std::floor(config.min_disparity * v.scale));
  params.cost.dmax = static_cast<int>(std::ceil(full_dmax * v.scale));
  if (params.cost.dmax >= v.model.size().width) {
    throw BadInput("disparity range " + std::to_string(config.min_disparity) + ".." + std::to_string(full_dmax) +
                   (config.downsample > 1
                        ? " (" + std::to_string(params.cost.dmin) + ".." + std::to_string(params.cost.dmax) +
                              " at downsample " + std::to_string(config.downsample) + ")"
                        : std::string()) +
                   " is wider than the image (width " + std::to_string(v.model.size().width) + ")");
  }
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
  // 3. Outputs.
  std_msgs::Header header = pair.left_image->header;
  if (header.frame_id.empty()) header.frame_id = pair.left_info->header.frame_id;
  publish(header, config, v, params, result, wanted);
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
  if (geometry_summary_.empty()) NODELET_INFO_STREAM("first pair: " << geometry.str() << ", " << elapsed << " ms");
  geometry_summary_ = geometry.str();
}

void HbdsNodelet::publish(const std_msgs::Header& header, const Config& config, const Views& v,
                          const stereo::StereoParams& params, const stereo::MatchResult& result,
                          const Outputs& wanted) {
  // Disparity as stereo_msgs/DisparityImage defines it: d = x_l - x_r - (cx_l - cx_r). Invalid pixels hold
  // min_disparity - 1 (below the searched range, as the message defines and stereo_image_proc does): those the
  // method leaves empty (NaN); without the left-right check the left band x < dmax, whose search ran off the right
  // image's edge; with it and lr_fill off, the pixels the right view does not confirm (with lr_fill on they hold the
  // background's disparity and ~confidence marks them).
  const camera::StereoModel& model = v.model;
  const int width = model.size().width, height = model.size().height;
  const float offset = static_cast<float>(model.offset());
  const float min_disparity = static_cast<float>(params.cost.dmin) - offset;
  const float invalid = min_disparity - 1.0f;
  const int valid_x0 = params.lr_check ? 0 : params.cost.dmax;
  const cv::Mat keep = params.lr_check && !config.lr_fill ? result.consistent : cv::Mat();
  cv::Mat valid(height, width, CV_32F);      // x_l - x_r where valid, NaN elsewhere
  cv::Mat valid_mask(height, width, CV_8U);  // 255 where valid
  for (int y = 0; y < height; ++y) {
    const float* in = result.disparity.ptr<float>(y);
    float* out = valid.ptr<float>(y);
    unsigned char* mask = valid_mask.ptr<unsigned char>(y);
    const unsigned char* k = keep.empty() ? nullptr : keep.ptr<unsigned char>(y);
    for (int x = 0; x < width; ++x) {
      const bool ok = x >= valid_x0 && std::isfinite(in[x]) && (k == nullptr || k[x] != 0);
      out[x] = ok ? in[x] : std::numeric_limits<float>::quiet_NaN();
      mask[x] = ok ? 255 : 0;
    }
  }
  if (wanted.disparity) {
    auto msg = boost::make_shared<stereo_msgs::DisparityImage>();
    msg->header = header;
    msg->f = static_cast<float>(model.fx());
    msg->T = static_cast<float>(model.baseline());
    msg->min_disparity = min_disparity;
    msg->max_disparity = static_cast<float>(params.cost.dmax) - offset;
    msg->delta_d = config.method == "sgbm" || params.subpixel ? 1.0f / 16.0f : 1.0f;
    msg->valid_window.x_offset = valid_x0;
    msg->valid_window.width = width - valid_x0;
    msg->valid_window.height = height;
    cv::Mat published = valid - offset;
    cv::patchNaNs(published, invalid);
    msg->image = *cv_bridge::CvImage(header, enc::TYPE_32FC1, published).toImageMsg();
    disparity_pub_.publish(msg);
  }
  if (wanted.confidence) {
    // mono8: 255 where the right view confirms the disparity, 0 elsewhere; without the left-right check, 255
    // wherever the disparity is valid.
    const cv::Mat confidence = params.lr_check ? result.consistent.clone() : valid_mask;
    confidence_pub_.publish(cv_bridge::CvImage(header, enc::MONO8, confidence).toImageMsg());
  }
  if (!wanted.depth && !wanted.points) return;
  // Depth (REP 118: metres along the rectified optical axis, NaN where unknown or at / beyond infinity).
  const cv::Mat depth = model.depth(valid);
  if (wanted.depth) {
    depth_pub_.publish(cv_bridge::CvImage(header, enc::TYPE_32FC1, depth).toImageMsg());
    sensor_msgs::CameraInfo info;
    info.header = header;
    info.width = width;
    info.height = height;
    fromCalibration(model.rectifiedLeft(), info);
    depth_info_pub_.publish(info);
  }
  if (wanted.points) points_pub_.publish(pointCloud(header, model.points(depth), v.images[0]));
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
  status.add("last error", stats_.lastError());
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::HbdsNodelet, nodelet::Nodelet)
