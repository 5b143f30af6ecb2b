#include "hbds_nodelet.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <cv_bridge/cv_bridge.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <stereo_msgs/DisparityImage.h>

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

bool validRefinement(const std::string& value) {
  try {
    massage_cell::stereo::parseRefinement(refinementName(value));
    return true;
  } catch (const std::invalid_argument&) {
    return false;
  }
}

namespace enc = sensor_msgs::image_encodings;

constexpr double kErrorLogPeriod = 5.0;  // s between two ERRORs naming the same problem

// ------------------------------------------------------ camera_info checks --

bool allZero(const double* values, std::size_t n) {
  return std::all_of(values, values + n, [](double v) { return v == 0.0; });
}

/// Already rectified: no distortion, R = I and K = the left 3x3 of P (what
/// the stereo driver's `rectified` declaration and the simulator publish).
bool isRectified(const sensor_msgs::CameraInfo& info) {
  const double eps = 1e-9;
  if (!std::all_of(info.D.begin(), info.D.end(), [&](double d) { return std::abs(d) < eps; })) return false;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (std::abs(info.R[3 * r + c] - (r == c ? 1.0 : 0.0)) > eps) return false;
      if (std::abs(info.K[3 * r + c] - info.P[4 * r + c]) > eps * std::max(1.0, std::abs(info.K[3 * r + c]))) return false;
    }
  }
  return true;
}

/// Throws BadInput naming what makes `info` unusable for `image`.
void checkInfo(const sensor_msgs::CameraInfo& info, const sensor_msgs::Image& image, const std::string& which) {
  if (allZero(info.K.data(), 9)) {
    throw BadInput(which + " camera_info is uncalibrated (K is all zero): calibrate the camera first");
  }
  if (!(info.K[0] > 0.0) || !(info.K[4] > 0.0) || !(info.P[0] > 0.0) || !(info.P[5] > 0.0) || info.P[10] != 1.0) {
    throw BadInput(which + " camera_info has no valid focal length (K[0], K[4], P[0], P[5] > 0 and P[10] = 1 needed)");
  }
  checkImageSize(info, image, which);
  auto finite = [&](const auto& values, const char* name) {
    if (!std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); })) {
      throw BadInput(which + " camera_info " + name + " holds a non-finite value");
    }
  };
  finite(info.K, "K");
  finite(info.D, "D");
  finite(info.R, "R");
  finite(info.P, "P");
  const cv::Matx33d R(info.R.data());
  if (std::abs(cv::determinant(R) - 1.0) > 1e-3) throw BadInput(which + " camera_info R is not a rotation");
}

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

/// Undistort-and-rectify maps of one view into the frame of its P.
void rectificationMaps(const sensor_msgs::CameraInfo& info, const std::string& which, cv::Mat& map1, cv::Mat& map2) {
  const cv::Matx33d K(info.K.data()), R(info.R.data());
  const cv::Matx33d new_K(info.P[0], info.P[1], info.P[2], info.P[4], info.P[5], info.P[6], info.P[8], info.P[9],
                          info.P[10]);
  const cv::Size size(static_cast<int>(info.width), static_cast<int>(info.height));
  const std::string& model = info.distortion_model;
  if (model == "equidistant") {
    if (info.D.size() != 4) throw BadInput(which + " camera_info: equidistant distortion needs 4 coefficients");
    cv::fisheye::initUndistortRectifyMap(K, cv::Mat(info.D), R, new_K, size, CV_16SC2, map1, map2);
    return;
  }
  const std::size_t n = info.D.size();
  if (model != "plumb_bob" && model != "rational_polynomial" && !(model.empty() && n == 0)) {
    throw BadInput(which + " camera_info distortion model '" + model +
                   "' is not supported (plumb_bob, rational_polynomial, equidistant)");
  }
  if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    throw BadInput(which + " camera_info has " + std::to_string(n) + " distortion coefficients (0, 4, 5, 8, 12 or 14)");
  }
  cv::initUndistortRectifyMap(K, n == 0 ? cv::Mat() : cv::Mat(info.D), R, new_K, size, CV_16SC2, map1, map2);
}

/// Pinhole geometry of the rectified pair at the processing resolution.
struct Geometry {
  double fx = 0, fy = 0, cx_left = 0, cx_right = 0, cy = 0;
  double baseline = 0;  ///< metres, from the right P: Tx = -fx B
  int width = 0, height = 0;
  double offset() const { return cx_left - cx_right; }  ///< d_published = (x_l - x_r) - offset
};

/// Pixel centres are kept in place by cv::resize(INTER_AREA): x_s = (x + 0.5) s - 0.5.
double scaleCentre(double c, double s) { return (c + 0.5) * s - 0.5; }

/// The rectified left camera_info at the processing resolution (depth/camera_info).
sensor_msgs::CameraInfo rectifiedLeftInfo(const sensor_msgs::CameraInfo& left, const std_msgs::Header& header,
                                          int width, int height) {
  const double sx = static_cast<double>(width) / left.width, sy = static_cast<double>(height) / left.height;
  sensor_msgs::CameraInfo out;
  out.header = header;
  out.width = width;
  out.height = height;
  out.distortion_model = "plumb_bob";
  out.D.assign(5, 0.0);
  out.P = left.P;
  for (int c = 0; c < 4; ++c) {
    out.P[c] *= sx;
    out.P[4 + c] *= sy;
  }
  out.P[2] = scaleCentre(left.P[2], sx);
  out.P[6] = scaleCentre(left.P[6], sy);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.K[3 * r + c] = out.P[4 * r + c];
  }
  out.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  return out;
}

std::uint32_t packRgb(const cv::Mat& image, int x, int y) {
  if (image.channels() == 1) {
    const std::uint32_t g = image.at<std::uint8_t>(y, x);
    return (g << 16) | (g << 8) | g;
  }
  const cv::Vec3b& bgr = image.at<cv::Vec3b>(y, x);
  return (static_cast<std::uint32_t>(bgr[2]) << 16) | (static_cast<std::uint32_t>(bgr[1]) << 8) | bgr[0];
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
  stereo::retainFreedMemory();  // every pair allocates and frees its cost volume and graphs
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
  NODELET_INFO_STREAM("dense stereo on " << nh.resolveName("left/image_raw") << " + " << nh.resolveName("right/image_raw")
                                         << (sync.approximate ? " (approximate sync)" : " (exact sync)")
                                         << (rectify_ ? "" : ", images taken as rectified"));
}

void HbdsNodelet::configCb(Config& config, uint32_t /*level*/) {
  // Runs with config_mutex_ held (dynamic_reconfigure::Server locks it).
  // Values the ranges of cfg/HBDS.cfg cannot rule out are rejected here: the
  // previous value stays, and the server publishes it back.
  auto reject = [this](const std::string& what) { NODELET_ERROR_STREAM("rejected " << what); };
  if (config.method != "hbds" && config.method != "sgbm" && config.method != "wta") {
    reject("method '" + config.method + "' (hbds, sgbm or wta): keeping '" + config_.method + "'");
    config.method = config_.method;
  }
  if (config.cost != "thesis" && config.cost != "census" && config.cost != "ad-census") {
    reject("cost '" + config.cost + "' (thesis, census or ad-census): keeping '" + config_.cost + "'");
    config.cost = config_.cost;
  }
  if (!validRefinement(config.refine)) {
    reject("refine '" + config.refine +
           "' (none, mdc, ffd_mdc, 2dbf, ffd_2dbf, 3dbf, ffd_3dbf, wmf or ffd_wmf): keeping '" + config_.refine + "'");
    config.refine = config_.refine;
  }
  if (config.subpixel != "none" && config.subpixel != "parabola" && config.subpixel != "equiangular") {
    reject("subpixel '" + config.subpixel + "' (none, parabola or equiangular): keeping '" + config_.subpixel + "'");
    config.subpixel = config_.subpixel;
  }
  if (config.refine_window % 2 == 0) {
    reject("refine_window = " + std::to_string(config.refine_window) + ": it must be odd; keeping " +
           std::to_string(config_.refine_window));
    config.refine_window = config_.refine_window;
  }
  if (config.ncc_window % 2 == 0) {
    reject("ncc_window = " + std::to_string(config.ncc_window) + ": it must be odd; keeping " +
           std::to_string(config_.ncc_window));
    config.ncc_window = config_.ncc_window;
  }
  if (config.u_min > config.u_max) {
    std::ostringstream s;
    s << "u_min = " << config.u_min << " > u_max = " << config.u_max << ": keeping u_min = " << config_.u_min
      << ", u_max = " << config_.u_max;
    reject(s.str());
    config.u_min = config_.u_min;
    config.u_max = config_.u_max;
  }
  if (config.downsample != 1 && config.downsample != 2 && config.downsample != 4) {
    reject("downsample = " + std::to_string(config.downsample) + " (1, 2 or 4): keeping " +
           std::to_string(config_.downsample));
    config.downsample = config_.downsample;
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

void HbdsNodelet::updateRectification(const CameraInfo& left, const CameraInfo& right) {
  std::vector<double> key{rectify_ ? 1.0 : 0.0};
  appendCalibrationKey(key, left);
  appendCalibrationKey(key, right);
  if (key == rectification_.key) return;
  Rectification r;
  r.key = key;
  r.identity = !rectify_ || (isRectified(left) && isRectified(right));
  if (!r.identity) {
    rectificationMaps(left, "left", r.map1[0], r.map2[0]);
    rectificationMaps(right, "right", r.map1[1], r.map2[1]);
  }
  rectification_ = std::move(r);
  NODELET_INFO_STREAM("calibration " << sizeText(left.width, left.height) << ": "
                                     << (rectification_.identity ? "images used as they are (rectified)"
                                                                 : "rectifying both views (maps cached)"));
}

void HbdsNodelet::process(const StereoPair& pair, const Config& config, const Outputs& wanted) {
  const auto start = Clock::now();
  const CameraInfo& li = *pair.left_info;
  const CameraInfo& ri = *pair.right_info;

  // 1. Input checks: every problem names itself and skips the pair.
  checkInfo(li, *pair.left_image, "left");
  checkInfo(ri, *pair.right_image, "right");
  if (li.width != ri.width || li.height != ri.height) {
    throw BadInput("left images are " + sizeText(li.width, li.height) + ", right ones " + sizeText(ri.width, ri.height) +
                   ": both views must have one size");
  }
  if (!(ri.P[3] < 0.0)) {
    throw BadInput("right camera_info P[3] = Tx = " + std::to_string(ri.P[3]) +
                   " must be -fx * baseline < 0 (a calibrated horizontal pair, right camera on the right)");
  }
  if (li.P[7] != 0.0 || ri.P[7] != 0.0) throw BadInput("vertical stereo (P[7] != 0) is not supported");
  const double eps = 1e-6 * li.P[0];
  if (std::abs(li.P[0] - ri.P[0]) > eps || std::abs(li.P[5] - ri.P[5]) > eps || std::abs(li.P[6] - ri.P[6]) > eps) {
    throw BadInput("left and right P differ in fx, fy or cy: the calibration is not of a rectified stereo pair");
  }
  const long processed_pixels =
      static_cast<long>(li.width / config.downsample) * static_cast<long>(li.height / config.downsample);
  if (max_pixels_ > 0 && processed_pixels > max_pixels_) {  // before minutes of work and gigabytes of cost volume
    throw BadInput("images of " + sizeText(li.width, li.height) + " at downsample " +
                   std::to_string(config.downsample) + " are " + std::to_string(processed_pixels) +
                   " pixels, above ~max_pixels " + std::to_string(max_pixels_) + ": raise downsample or max_pixels");
  }
  cv::Mat views[2] = {toMat(pair.left_image, "left"), toMat(pair.right_image, "right")};
  if (views[0].channels() != views[1].channels()) {  // mixed mono / colour: match in grey
    for (auto& v : views) {
      if (v.channels() == 3) cv::cvtColor(v, v, cv::COLOR_BGR2GRAY);
    }
  }

  // 2. Rectify (maps cached per calibration), then downsample.
  updateRectification(li, ri);
  if (!rectification_.identity) {
    for (int i = 0; i < 2; ++i) {
      cv::Mat rectified;
      cv::remap(views[i], rectified, rectification_.map1[i], rectification_.map2[i], cv::INTER_LINEAR);
      views[i] = rectified;
    }
  }
  const int s = config.downsample;
  Geometry g;
  g.width = static_cast<int>(li.width) / s;
  g.height = static_cast<int>(li.height) / s;
  if (g.width < 8 || g.height < 8) {
    throw BadInput("images of " + sizeText(li.width, li.height) + " are too small for downsample " + std::to_string(s));
  }
  const double sx = static_cast<double>(g.width) / li.width, sy = static_cast<double>(g.height) / li.height;
  if (s > 1) {
    for (auto& v : views) {
      cv::Mat small;
      cv::resize(v, small, cv::Size(g.width, g.height), 0, 0, cv::INTER_AREA);
      v = small;
    }
  }
  g.fx = li.P[0] * sx;
  g.fy = li.P[5] * sy;
  g.cx_left = scaleCentre(li.P[2], sx);
  g.cx_right = scaleCentre(ri.P[2], sx);
  g.cy = scaleCentre(li.P[6], sy);
  g.baseline = -ri.P[3] / ri.P[0];  // image_geometry: Tx = -fx B

  // 3. Match. The range is set in full-resolution pixels; at 1/s resolution
  // the searched range is the smallest one covering it.
  const int full_dmax = config.min_disparity + config.disparity_range - 1;
  stereo::StereoParams params;
  params.cost.dmin = static_cast<int>(std::floor(config.min_disparity * sx));
  params.cost.dmax = static_cast<int>(std::ceil(full_dmax * sx));
  if (params.cost.dmax >= g.width) {
    throw BadInput("disparity range " + std::to_string(config.min_disparity) + ".." + std::to_string(full_dmax) +
                   (s > 1 ? " (" + std::to_string(params.cost.dmin) + ".." + std::to_string(params.cost.dmax) +
                                " at downsample " + std::to_string(s) + ")"
                          : std::string()) +
                   " is wider than the image (width " + std::to_string(g.width) + ")");
  }
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
  const stereo::Method method = stereo::parseMethod(config.method);
  const stereo::MatchResult result = stereo::match(views[0], views[1], method, params);

  // 4. Disparity as stereo_msgs/DisparityImage defines it: d = x_l - x_r -
  // (cx_l - cx_r). Invalid pixels hold min_disparity - 1 (below the searched
  // range, as the message defines and stereo_image_proc does): those the
  // method leaves empty (NaN); without the left-right check the left band
  // x < dmax, whose search ran off the right image's edge; with it and
  // lr_fill off, the pixels the right view does not confirm (with lr_fill on
  // they hold the background's disparity and ~confidence marks them).
  std_msgs::Header header = pair.left_image->header;
  if (header.frame_id.empty()) header.frame_id = li.header.frame_id;
  const float offset = static_cast<float>(g.offset());
  const float min_disparity = static_cast<float>(params.cost.dmin) - offset;
  const float max_disparity = static_cast<float>(params.cost.dmax) - offset;
  const float invalid = min_disparity - 1.0f;
  const int valid_x0 = params.lr_check ? 0 : params.cost.dmax;
  const cv::Mat keep = params.lr_check && !config.lr_fill ? result.consistent : cv::Mat();

  auto disparity_msg = boost::make_shared<stereo_msgs::DisparityImage>();
  disparity_msg->header = header;
  disparity_msg->f = static_cast<float>(g.fx);
  disparity_msg->T = static_cast<float>(g.baseline);
  disparity_msg->min_disparity = min_disparity;
  disparity_msg->max_disparity = max_disparity;
  disparity_msg->delta_d = method == stereo::Method::kSgbm || params.subpixel ? 1.0f / 16.0f : 1.0f;
  disparity_msg->valid_window.x_offset = valid_x0;
  disparity_msg->valid_window.y_offset = 0;
  disparity_msg->valid_window.width = g.width - valid_x0;
  disparity_msg->valid_window.height = g.height;
  sensor_msgs::Image& dimage = disparity_msg->image;
  dimage.header = header;
  dimage.width = g.width;
  dimage.height = g.height;
  dimage.encoding = enc::TYPE_32FC1;
  dimage.step = g.width * sizeof(float);
  dimage.data.resize(static_cast<std::size_t>(dimage.step) * g.height);
  cv::Mat disparity(g.height, g.width, CV_32F, dimage.data.data(), dimage.step);
  for (int y = 0; y < g.height; ++y) {
    const float* in = result.disparity.ptr<float>(y);
    float* out = disparity.ptr<float>(y);
    const unsigned char* k = keep.empty() ? nullptr : keep.ptr<unsigned char>(y);
    for (int x = 0; x < g.width; ++x) {
      const bool valid = x >= valid_x0 && std::isfinite(in[x]) && (k == nullptr || k[x] != 0);
      out[x] = valid ? in[x] - offset : invalid;
    }
  }
  if (wanted.disparity) disparity_pub_.publish(disparity_msg);
  if (wanted.confidence) {
    // mono8: 255 where the right view confirms the disparity, 0 elsewhere;
    // without the left-right check, 255 wherever the disparity is valid.
    cv::Mat confidence = params.lr_check ? result.consistent.clone() : cv::Mat(disparity >= min_disparity);
    confidence_pub_.publish(cv_bridge::CvImage(header, enc::MONO8, confidence).toImageMsg());
  }

  // 5. Depth (REP 118: metres, NaN where unknown) = f T / d; d <= 0 is at or
  // beyond infinity and also NaN.
  const float fT = static_cast<float>(g.fx * g.baseline);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat depth(g.height, g.width, CV_32F);
  for (int y = 0; y < g.height; ++y) {
    const float* d = disparity.ptr<float>(y);
    float* z = depth.ptr<float>(y);
    for (int x = 0; x < g.width; ++x) z[x] = (d[x] >= min_disparity && d[x] > 0.0f) ? fT / d[x] : nan;
  }
  if (wanted.depth) {
    depth_pub_.publish(cv_bridge::CvImage(header, enc::TYPE_32FC1, depth).toImageMsg());
    depth_info_pub_.publish(rectifiedLeftInfo(li, header, g.width, g.height));
  }

  // 6. Organised point cloud in the left optical frame (REP 103: x right,
  // y down, z forward), colour from the rectified left image.
  if (wanted.points) {
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    cloud->header = header;
    cloud->height = g.height;
    cloud->width = g.width;
    sensor_msgs::PointCloud2Modifier modifier(*cloud);
    modifier.setPointCloud2Fields(4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                                  "z", 1, sensor_msgs::PointField::FLOAT32, "rgb", 1, sensor_msgs::PointField::FLOAT32);
    cloud->is_dense = false;
    cloud->is_bigendian = false;
    sensor_msgs::PointCloud2Iterator<float> it(*cloud, "x");
    for (int y = 0; y < g.height; ++y) {
      const float* z = depth.ptr<float>(y);
      for (int x = 0; x < g.width; ++x, ++it) {
        float* p = &it[0];
        if (std::isfinite(z[x])) {
          p[0] = static_cast<float>((x - g.cx_left) / g.fx) * z[x];
          p[1] = static_cast<float>((y - g.cy) / g.fy) * z[x];
          p[2] = z[x];
        } else {
          p[0] = p[1] = p[2] = nan;
        }
        const std::uint32_t rgb = packRgb(views[0], x, y);
        std::memcpy(&p[3], &rgb, sizeof(rgb));
      }
    }
    points_pub_.publish(cloud);
  }

  // 7. Status.
  const double elapsed = msSince(start);
  std::ostringstream geometry;
  geometry << sizeText(li.width, li.height) << (s > 1 ? " processed at " + sizeText(g.width, g.height) : "")
           << (rectification_.identity ? ", rectified input" : ", rectified here") << ", f " << g.fx << " px, baseline "
           << g.baseline << " m, disparities " << params.cost.dmin << ".." << params.cost.dmax;
  std::lock_guard<std::mutex> lock(status_mutex_);
  stats_.processedOne(elapsed);
  last_matcher_ms_ = result.total_ms();
  if (geometry_summary_.empty()) NODELET_INFO_STREAM("first pair: " << geometry.str() << ", " << elapsed << " ms");
  geometry_summary_ = geometry.str();
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
