#include "planar_nodelet.h"

#include <algorithm>
#include <sstream>

#include <cv_bridge/cv_bridge.h>
#include <visualization_msgs/Marker.h>
#include <pluginlib/class_list_macros.hpp>

#include "calibration_msg.h"
#include "massage_cell/planar/camera_views.h"
#include "massage_cell/planar/model.h"
#include "start_parameters.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

constexpr double kErrorLogPeriod = 5.0;  // s between two ERRORs naming the same problem

planar::ReconstructParams toParams(const massage_cell::PlanarConfig& c) {
  planar::ReconstructParams p;
  p.method = planar::halfPlaneMethod(c.method);
  p.features.detector = c.detector;
  p.features.max_keypoints = c.max_keypoints;
  p.half_planes.strip_width = c.strip_width;
  p.half_planes.min_ncc = c.min_ncc;
  p.half_planes.sweep_step_deg = c.sweep_step_deg;
  p.half_planes.coplanar_pixels = c.coplanar_pixels;
  p.extension.coplanar_pixels = c.coplanar_pixels;
  p.extension.growth_step = c.growth_step;
  p.extension.merge_angle_deg = c.merge_angle_deg;
  p.extension.min_support = c.min_support;
  p.delineation.enabled = c.delineate;
  p.delineation.min_ncc = c.delineate_min_ncc;
  p.delineation.coplanar_pixels = c.coplanar_pixels;
  p.validate();
  return p;
}

cv::Mat toBgr(const sensor_msgs::ImageConstPtr& msg, const std::string& which) {
  try {
    return cv_bridge::toCvCopy(msg, "bgr8")->image;
  } catch (const cv_bridge::Exception& e) {
    throw BadInput(which + " image (" + msg->encoding + ") cannot be converted to bgr8: " + e.what());
  }
}

std_msgs::ColorRGBA rgba(const cv::Vec3b& bgr, float alpha) {
  std_msgs::ColorRGBA c;
  c.r = bgr[2] / 255.0f;
  c.g = bgr[1] / 255.0f;
  c.b = bgr[0] / 255.0f;
  c.a = alpha;
  return c;
}

massage_cell::PlanarModel toMessage(const planar::PlanarModel& model, const std_msgs::Header& header) {
  massage_cell::PlanarModel msg;
  msg.header = header;
  for (const planar::Facet& f : model.facets) {
    massage_cell::PlanarFacet facet;
    facet.plane.coef = {f.plane.n.x(), f.plane.n.y(), f.plane.n.z(), f.plane.d};
    for (const auto& poly : f.polygons) {
      geometry_msgs::Polygon polygon;
      for (const Eigen::Vector3d& X : poly) {
        geometry_msgs::Point32 p;
        p.x = static_cast<float>(X.x());
        p.y = static_cast<float>(X.y());
        p.z = static_cast<float>(X.z());
        polygon.points.push_back(p);
      }
      facet.polygons.push_back(polygon);
    }
    facet.colour = rgba(f.colour, 1.0f);
    facet.support_points = f.support_points;
    facet.score = f.score;
    msg.facets.push_back(facet);
  }
  return msg;
}

visualization_msgs::Marker toMarker(const planar::PlanarModel& model, const std_msgs::Header& header) {
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = "planar";
  m.id = 0;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color.a = 1.0;
  const planar::TriangleMesh mesh = planar::toMesh(model);
  if (mesh.triangles.empty()) {
    m.action = visualization_msgs::Marker::DELETE;  // a latched empty model clears the old mesh in rviz
    return m;
  }
  m.type = visualization_msgs::Marker::TRIANGLE_LIST;
  m.action = visualization_msgs::Marker::ADD;
  for (const auto& t : mesh.triangles) {
    for (int k : t) {
      geometry_msgs::Point p;
      p.x = mesh.vertices[static_cast<std::size_t>(k)].x();
      p.y = mesh.vertices[static_cast<std::size_t>(k)].y();
      p.z = mesh.vertices[static_cast<std::size_t>(k)].z();
      m.points.push_back(p);
      m.colors.push_back(rgba(mesh.colours[static_cast<std::size_t>(k)], 0.8f));
    }
  }
  return m;
}

}  // namespace

PlanarNodelet::PlanarNodelet() : log_throttle_(kErrorLogPeriod) {}

PlanarNodelet::~PlanarNodelet() {
  if (input_) input_->stop();  // before the state its worker uses goes
}

void PlanarNodelet::onInit() {
  initOrStop(getName(), [this] { init(); });
}

void PlanarNodelet::init() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  views_frame_ = typedParam<std::string>(pnh, "views_frame", "planar_views");
  output_prefix_ = typedParam<std::string>(pnh, "output_prefix", "");
  config_ = Config::__getDefault__();
  reconfigure_server_ = serveConfig<Config>(pnh, config_mutex_, this, &PlanarNodelet::configCb,
                                            [this](const std::string& problem) { NODELET_ERROR_STREAM(problem); });

  mesh_pub_ = pnh.advertise<visualization_msgs::Marker>("mesh", 1, /*latch=*/true);
  planes_pub_ = pnh.advertise<massage_cell::PlanarModel>("planes", 1, /*latch=*/true);
  reconstruct_srv_ = pnh.advertiseService("reconstruct", &PlanarNodelet::reconstructCb, this);

  diagnostics_.start(nh, pnh, "planar reconstruction", this, &PlanarNodelet::diagnose);

  const SyncOptions sync = SyncOptions::fromParameters(pnh);
  if (!sync.problem.empty()) NODELET_ERROR_STREAM(sync.problem);
  input_ = std::make_unique<StereoPairInput>(nh, pnh, sync, [this](const StereoPair& pair) { onPair(pair); });
  input_->subscribe();  // the outputs are latched: the model is made whether or not anyone listens yet
  NODELET_INFO_STREAM("planes from " << nh.resolveName("left/image_raw") << " + " << nh.resolveName("right/image_raw")
                                     << " every " << config_.stereo_period << " s, and from "
                                     << pnh.resolveName("reconstruct"));
}

void PlanarNodelet::configCb(Config& config, uint32_t /*level*/) {
  // Runs with config_mutex_ held. Values the .cfg's ranges cannot rule out
  // are rejected: the previous configuration stays and is published back.
  try {
    toParams(config);
  } catch (const std::invalid_argument& e) {
    NODELET_ERROR_STREAM("rejected the parameters: " << e.what() << "; keeping the previous ones");
    config = config_;
    return;
  }
  if (config.detector != "akaze" && config.detector != "orb" && config.detector != "sift") {
    NODELET_ERROR_STREAM("rejected detector '" << config.detector << "' (akaze, orb or sift): keeping '"
                                               << config_.detector << "'");
    config.detector = config_.detector;
  }
  config_ = config;
}

void PlanarNodelet::onPair(const StereoPair& pair) {
  Config config;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    config = config_;
  }
  if (config.stereo_period <= 0.0) return;
  const ros::WallTime now = ros::WallTime::now();
  if (!last_stereo_.isZero() && (now - last_stereo_).toSec() < config.stereo_period) return;
  last_stereo_ = now;
  try {
    const sensor_msgs::CameraInfo& li = *pair.left_info;
    const sensor_msgs::CameraInfo& ri = *pair.right_info;
    checkImageSize(li, *pair.left_image, "left");
    checkImageSize(ri, *pair.right_image, "right");
    const camera::CameraCalibration lc = toCalibration(li), rc = toCalibration(ri);
    std::vector<planar::View> views;
    try {
      views.push_back(
          planar::viewFromCameraInfo("left", toBgr(pair.left_image, "left"), lc, Eigen::Isometry3d::Identity()));
      views.push_back(
          planar::viewFromCameraInfo("right", toBgr(pair.right_image, "right"), rc, camera::rightCameraInLeft(lc, rc)));
    } catch (const std::invalid_argument& e) {
      throw BadInput(e.what());
    }
    std_msgs::Header header = pair.left_image->header;
    if (header.frame_id.empty()) header.frame_id = li.header.frame_id;
    run(views, header, output_prefix_, "stereo pair");
  } catch (const std::exception& e) {
    failed("stereo pair", e.what());
  }
}

bool PlanarNodelet::reconstructCb(massage_cell::Reconstruct::Request& req, massage_cell::Reconstruct::Response& res) {
  const std::string source = "view set " + req.path;
  try {
    if (req.path.empty()) throw std::invalid_argument("path is empty: give a view set (VGG folder, views.yaml)");
    const std::vector<planar::View> views = planar::loadViewSet(req.path);
    std_msgs::Header header;
    header.stamp = ros::Time::now();
    header.frame_id = req.frame_id.empty() ? views_frame_ : req.frame_id;
    res.model = run(views, header, req.output_prefix, source);
    res.success = true;
    std::ostringstream s;
    s << res.model.facets.size() << " planes from " << views.size() << " views";
    if (!req.output_prefix.empty()) s << ", written to " << req.output_prefix << ".obj / .ply";
    res.message = s.str();
  } catch (const std::exception& e) {
    failed(source, e.what());
    res.success = false;
    res.message = e.what();
  }
  return true;
}

massage_cell::PlanarModel PlanarNodelet::run(const std::vector<planar::View>& views, const std_msgs::Header& header,
                                             const std::string& output_prefix, const std::string& source) {
  planar::ReconstructParams params;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    params = toParams(config_);
  }
  const auto start = Clock::now();
  planar::Reconstruction r;
  {
    std::lock_guard<std::mutex> lock(run_mutex_);
    r = planar::reconstruct(views, params);
  }
  if (!output_prefix.empty()) {
    const planar::TriangleMesh mesh = planar::toMesh(r.model);
    planar::writeObj(mesh, output_prefix + ".obj");
    planar::writePly(mesh, output_prefix + ".ply");
  }
  const massage_cell::PlanarModel msg = toMessage(r.model, header);
  planes_pub_.publish(msg);
  mesh_pub_.publish(toMarker(r.model, header));
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    stats_.processedOne(msSince(start));
    last_source_ = source;
    last_planes_ = static_cast<int>(r.model.facets.size());
    last_times_ = r.times;
  }
  NODELET_INFO_STREAM(source << ": " << r.model.facets.size() << " planes (" << r.points.size() << " point tracks, "
                             << r.lines.size() << " line tracks, " << r.half_planes.size() << " half-planes) in "
                             << r.times.total() << " s");
  return msg;
}

void PlanarNodelet::failed(const std::string& source, const std::string& problem) {
  const std::string line =
      countFailure("no planes from the " + source, problem, "failures", status_mutex_, stats_, log_throttle_);
  if (!line.empty()) NODELET_ERROR_STREAM(line);
}

void PlanarNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using diagnostic_msgs::DiagnosticStatus;
  Config config;
  {
    boost::recursive_mutex::scoped_lock lock(config_mutex_);
    config = config_;
  }
  const StereoPairInput::Counts input = input_->counts();
  std::lock_guard<std::mutex> lock(status_mutex_);
  if (stats_.lastPairBad()) {
    status.summary(DiagnosticStatus::ERROR, "last reconstruction failed: " + stats_.lastError());
  } else if (stats_.processed() == 0) {
    status.summary(DiagnosticStatus::OK, "waiting for a stereo pair or a ~reconstruct call");
  } else {
    status.summary(DiagnosticStatus::OK, std::to_string(last_planes_) + " planes from the " + last_source_);
  }
  status.add("method", config.method);
  status.add("stereo period (s)", config.stereo_period);
  stats_.addCounts(status, input);
  stats_.addTimes(status, "last half-plane search (ms)", 1000.0 * last_times_.half_planes);
  status.add("last total library time (s)", last_times_.total());
  status.add("last error", stats_.lastError());
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::PlanarNodelet, nodelet::Nodelet)
