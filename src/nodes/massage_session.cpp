// massage_session: the cell's main job. Waits until the CECT node's acupoints
// of the routine (config/session.yaml) have settled, homes the arm, presses
// each acupoint by its tf frame through the arm's ~massage service, strokes
// the routine's paths (technique stroke), and prints a report: the fix and
// every press against the recording's ground truth (the tool tip while it
// holds at depth against the true acupoint pushed to that depth), every
// stroke against the path through the acupoints' true positions (the tool's
// farthest distance across the skin while it glides), the verdict.
//
// Subscribes (in its namespace, e.g. /stereo): acupoints
//   (massage_cell/AcupointArray), ground_truth/acupoints (the session
//   player's truth, optional), left/image_raw, left/camera_info, disparity
//   (for the report's pictures and latencies); <arm>/state
//   (massage_cell/ArmState); /tf (the acupoint frames' latency).
// Calls: <arm>/home, <arm>/massage.
// Parameters: ~session (YAML path, required), ~arm ("/arm"), ~base_frame
//   ("arm_base_link"), ~tolerance (0.005 m: the report counts the presses
//   within it of the truth), ~max_error (0.02 m: a press further from the
//   truth, about an acupoint's own size, fails the session), ~service_timeout
//   (30 s), ~report (a folder: index.html and pictures are written there,
//   with a force plot per press by force from <arm>/state; empty: none).
// Exit status: 0 every press and stroke done (and, with ground truth, within
//   ~max_error); 1 one failed or missed, no stable fix, or the arm was not
//   there; 2 a bad session file.
#include <algorithm>

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <stereo_msgs/DisparityImage.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <mutex>

#include <opencv2/imgcodecs.hpp>

#include "massage_cell/AcupointArray.h"
#include "massage_cell/ArmState.h"
#include "massage_cell/Massage.h"
#include "massage_cell/arm/plan.h"
#include "massage_cell/arm/session.h"
#include "massage_cell/session/report.h"
#include "typed_param.h"

namespace {

using massage_cell::nodes::readParam;

namespace arm = massage_cell::arm;
namespace report = massage_cell::session;

class Session {
 public:
  Session(ros::NodeHandle& nh, ros::NodeHandle& pnh, const arm::SessionConfig& config)
      : config_(config), fix_(config.fix_window, config.fix_samples, config.fix_tolerance), listener_(tf_) {
    readParam(pnh, "arm", &arm_ns_);
    readParam(pnh, "base_frame", &base_frame_);
    readParam(pnh, "tolerance", &tolerance_);
    readParam(pnh, "max_error", &max_error_);
    readParam(pnh, "service_timeout", &service_timeout_);
    readParam(pnh, "report", &report_dir_);
    report_.latencies = {{"camera stamp -> acupoints (cect)", {}},
                         {"camera stamp -> acupoint tf", {}},
                         {"camera stamp -> disparity (hbds)", {}},
                         {"acupoint tf stamp -> press start", {}}};
    image_sub_ = nh.subscribe("left/image_raw", 5, &Session::onImage, this);
    info_sub_ = nh.subscribe("left/camera_info", 5, &Session::onInfo, this);
    disparity_sub_ = nh.subscribe("disparity", 2, &Session::onDisparity, this);
    tf_sub_ = ros::NodeHandle().subscribe("/tf", 100, &Session::onTf, this);
    acupoints_sub_ = nh.subscribe("acupoints", 5, &Session::onAcupoints, this);
    truth_sub_ = nh.subscribe("ground_truth/acupoints", 5, &Session::onTruth, this);
    state_sub_ = nh.subscribe(arm_ns_ + "/state", 20, &Session::onState, this);
    home_ = nh.serviceClient<std_srvs::Trigger>(arm_ns_ + "/home");
    massage_ = nh.serviceClient<massage_cell::Massage>(arm_ns_ + "/massage");
  }

  /// The whole session; the report's verdict as the exit status.
  int run() {
    const ros::WallTime start = ros::WallTime::now();
    if (!waitForArm() || !waitForFix(start) || !homeArm()) return finish();
    for (const std::string& name : config_.acupoints) press(name);
    for (const std::vector<std::string>& path : config_.strokes) stroke(path);
    return finish();
  }

 private:
  bool waitForArm() {
    if (home_.waitForExistence(ros::Duration(service_timeout_)) &&
        massage_.waitForExistence(ros::Duration(service_timeout_)))
      return true;
    fault("the arm's services " + arm_ns_ + "/home and /massage did not appear within " +
          std::to_string(static_cast<int>(service_timeout_)) + " s (is the arm node running?)");
    return false;
  }

  bool waitForFix(const ros::WallTime& start) {
    const std::vector<std::string> all = config_.allAcupoints();
    ROS_INFO("massage_session: waiting for a stable fix of %zu acupoints", all.size());
    ros::WallRate poll(10.0);
    std::vector<std::string> unstable = all;
    while (ros::ok() && (ros::WallTime::now() - start).toSec() < config_.fix_timeout) {
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        unstable = fix_.unstable(all, latest_stamp_);
        if (unstable.empty()) {
          report_.seconds_to_fix = (ros::WallTime::now() - start).toSec();
          recordFix();
          return true;
        }
      }
      poll.sleep();
    }
    std::string names;
    for (const std::string& n : unstable) names += (names.empty() ? "" : ", ") + n;
    fault("no stable fix within " + std::to_string(static_cast<int>(config_.fix_timeout)) + " s for: " + names + " (" +
          std::to_string(report_.pairs) + " pairs seen)");
    return false;
  }

  void recordFix() {
    for (const std::string& name : config_.allAcupoints()) {
      const auto t = truth_.find(name);
      if (t == truth_.end()) continue;
      const Eigen::Vector3d estimate = fix_.mean(name, latest_stamp_);
      report_.fix.push_back({name, (estimate - t->second).norm(), estimate - t->second});
    }
    report_.landmarks.clear();
    if (!latest_acupoints_) return;
    for (const auto& l : latest_acupoints_->landmarks) {
      report_.landmarks += (report_.landmarks.empty() ? "" : ", ") + l.name + " " + l.source +
                           (l.detail.empty() ? std::string() : " (" + l.detail + ")");
    }
  }

  bool homeArm() {
    std_srvs::Trigger srv;
    if (home_.call(srv) && srv.response.success) return true;
    fault("homing the arm failed: " + (srv.response.message.empty() ? "no answer" : srv.response.message));
    return false;
  }

  /// Starts recording the arm's work on `name` (an acupoint, or a stroke's "A -> B"; called with the mutex held).
  void beginRecord(const std::string& name) {
    holding_ = {};
    truth_holding_ = {};
    target_holding_ = {};
    force_holding_ = {};
    force_trace_ = {};
    gliding_ = {};
    trace_start_ = ros::Time();
    current_ = name;
    descending_ = false;
  }

  /// Calls ~massage with `srv`: the record of `name` with the arm's answer, its time and force trace.
  report::PressRecord callArm(massage_cell::Massage& srv, const std::string& name) {
    const ros::WallTime t0 = ros::WallTime::now();
    report::PressRecord record;
    record.acupoint = name;
    record.success = massage_.call(srv) && srv.response.success;
    record.message = srv.response.message.empty() ? "the arm did not answer" : srv.response.message;
    record.seconds = (ros::WallTime::now() - t0).toSec();
    const std::lock_guard<std::mutex> lock(mutex_);
    current_.clear();
    record.force_trace = std::move(force_trace_);
    force_trace_.clear();
    return record;
  }

  void press(const std::string& name) {
    massage_cell::Massage srv;
    srv.request.frames = {config_.frame_prefix + name};
    srv.request.technique = config_.technique;
    srv.request.mode = config_.mode;
    srv.request.force = config_.mode == "force" ? config_.force : 0.0;
    srv.request.depth = config_.mode == "force" ? 0.0 : config_.depth;
    srv.request.hold = config_.hold;
    srv.request.repeats = config_.repeats;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      beginRecord(name);
    }
    ROS_INFO("massage_session: pressing %s", name.c_str());
    report::PressRecord record = callArm(srv, name);
    const std::lock_guard<std::mutex> lock(mutex_);
    // To a depth: the truth pushed that depth down; by force the depth is the body's answer (compared across).
    const double depth = config_.mode == "force" ? 0.0 : config_.depth;
    if (!holding_.empty() && !truth_holding_.empty()) {
      record.measured = true;
      record.by_force = config_.mode == "force";
      record.tool_at_depth = average(holding_);
      record.truth_at_depth = average(truth_holding_) - depth * Eigen::Vector3d::UnitZ();
      for (double f : force_holding_) record.force_held += f / static_cast<double>(force_holding_.size());
    }
    if (!holding_.empty() && !target_holding_.empty()) {
      record.targeted = true;
      record.target_at_depth = average(target_holding_) - depth * Eigen::Vector3d::UnitZ();
    }
    ROS_INFO("massage_session: %s %s (%.1f s)", name.c_str(), record.success ? "done" : "FAILED", record.seconds);
    report_.presses.push_back(record);
  }

  /// A stroke along `path` (acupoint names) at the routine's stroke force: its record, with how far the tool glided
  /// from the path through the acupoints' true positions and from the path it was given (their frames).
  void stroke(const std::vector<std::string>& path) {
    massage_cell::Massage srv;
    for (const std::string& name : path) srv.request.frames.push_back(config_.frame_prefix + name);
    srv.request.technique = "stroke";
    srv.request.mode = "force";
    srv.request.force = config_.stroke_force;
    srv.request.repeats = 1;
    const std::string label = path.front() + " -> " + path.back();
    std::vector<Eigen::Vector3d> given, truth;  // arm base frame
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      beginRecord(label);
      for (const std::string& name : path) {
        Eigen::Vector3d p;
        if (frameInBase(config_.frame_prefix + name, &p)) given.push_back(p);
        if (truthInBase(name, &p)) truth.push_back(p);
      }
    }
    ROS_INFO("massage_session: stroking %s", label.c_str());
    report::PressRecord record = callArm(srv, label);
    record.stroke = true;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!gliding_.empty() && truth.size() == path.size() && given.size() == path.size()) {
      record.path_error = record.tracking_error = 0.0;
      for (const Eigen::Vector2d& at : gliding_) {
        record.path_error = std::max(record.path_error, arm::distanceFromPath(at, truth));
        record.tracking_error = std::max(record.tracking_error, arm::distanceFromPath(at, given));
      }
    }
    ROS_INFO("massage_session: %s %s (%.1f s)", label.c_str(), record.success ? "done" : "FAILED", record.seconds);
    report_.presses.push_back(record);
  }

  /// Where tf puts `frame` in the base frame now (called with the mutex held).
  bool frameInBase(const std::string& frame, Eigen::Vector3d* out) const {
    try {
      const auto t = tf_.lookupTransform(base_frame_, frame, ros::Time(0)).transform.translation;
      *out = Eigen::Vector3d(t.x, t.y, t.z);
      return true;
    } catch (const tf2::TransformException&) {
      return false;
    }
  }

  /// The recording's true position of acupoint `name` in the base frame (called with the mutex held).
  bool truthInBase(const std::string& name, Eigen::Vector3d* out) {
    const auto t = truth_.find(name);
    if (t == truth_.end()) return false;
    geometry_msgs::PointStamped in, moved;
    in.header = truth_header_;
    in.header.stamp = ros::Time(0);  // the camera's mount is static: the latest transform
    in.point.x = t->second.x();
    in.point.y = t->second.y();
    in.point.z = t->second.z();
    try {
      tf_.transform(in, moved, base_frame_, ros::Duration(0.05));
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(5.0, "massage_session: the truth cannot be put in %s: %s", base_frame_.c_str(), e.what());
      return false;
    }
    *out = Eigen::Vector3d(moved.point.x, moved.point.y, moved.point.z);
    return true;
  }

  int finish() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!report_dir_.empty()) writeReport();
    std::printf("%s", report_.summary(tolerance_).c_str());
    std::fflush(stdout);
    bool ok = report_.faults.empty() && report_.presses.size() == config_.acupoints.size() + config_.strokes.size();
    for (const report::PressRecord& p : report_.presses) {
      const double error = p.stroke ? p.path_error : p.measured ? p.error() : 0.0;
      ok = ok && p.success && !(error > max_error_);
      if (error > max_error_)
        std::printf("FAILED: %s was %s %.1f mm from its true %s (limit %.1f mm)\n", p.acupoint.c_str(),
                    p.stroke ? "stroked" : "pressed", 1e3 * error, p.stroke ? "path" : "position", 1e3 * max_error_);
    }
    std::printf("%s\n", ok ? "the session went well" : "the session FAILED (see above)");
    return ok ? 0 : 1;
  }

  enum Stage { kCect = 0, kTf = 1, kDisparity = 2, kPressStart = 3 };
  std::vector<double>& latency(Stage s) { return report_.latencies[static_cast<std::size_t>(s)].samples; }

  /// index.html and its pictures in ~report (called with the mutex held).
  void writeReport() {
    std::vector<std::pair<std::string, std::string>> pictures;
    try {
      std::filesystem::create_directories(report_dir_);
      const auto write = [&](const std::string& file, const cv::Mat& image, const std::string& caption) {
        if (image.empty() || !cv::imwrite(report_dir_ + "/" + file, image)) return;
        pictures.emplace_back(file, caption);
      };
      const cv::Mat left = leftImageOf(latest_acupoints_ ? latest_acupoints_->header.stamp : ros::Time());
      if (!left.empty() && latest_acupoints_) {
        std::vector<report::MarkedPixel> estimates, truth;
        const auto inRoutine = [this](const std::string& name) {
          return std::find(config_.acupoints.begin(), config_.acupoints.end(), name) != config_.acupoints.end();
        };
        for (const auto& a : latest_acupoints_->acupoints) {
          if (a.valid && std::isfinite(a.u) && std::isfinite(a.v))
            estimates.push_back({a.name, {a.u, a.v}, inRoutine(a.name)});
        }
        for (const auto& [name, X] : truth_) {
          cv::Point2d p;
          if (inRoutine(name) && projectCamera(X, &p)) truth.push_back({name, p});
        }
        std::vector<report::MarkedPixel> landmarks;
        for (const auto& l : latest_acupoints_->landmarks) {
          if (std::isfinite(l.u) && std::isfinite(l.v))
            landmarks.push_back({l.name + " " + (l.source == "given" ? l.detail : l.source), {l.u, l.v}});
        }
        write("acupoints.png", report::drawAcupoints(left, estimates, truth, landmarks),
              "the left image with the routine's acupoints as CECT placed them (red, named) and their ground truth "
              "(green crosses); the model's other acupoints as small dots; the layout's landmarks (cyan diamonds: "
              "measured, "
              "inferred or how they were given)");
        std::vector<cv::Point2d> path;
        for (const Eigen::Vector3d& X : trajectory_) {
          cv::Point2d p;
          if (projectBase(X, &p)) path.push_back(p);
        }
        write("trajectory.png", report::drawTrajectory(left, path),
              "the tool tip's path over the back during the session (blue: early, red: late), seen by the left camera");
      }
      if (!disparity_.empty())
        write("disparity.png", report::colourDisparity(disparity_), "the HBDS node's disparity of the last pair");
      report_.writeHtml(report_dir_, tolerance_, pictures);
      std::printf("report: %s/index.html\n", report_dir_.c_str());
    } catch (const std::exception& e) {
      report_.faults.push_back(std::string("the report could not be written: ") + e.what());
    }
  }

  cv::Mat leftImageOf(const ros::Time& stamp) const {
    for (const auto& [t, image] : images_) {
      if (t == stamp) return image;
    }
    return images_.empty() ? cv::Mat() : images_.back().second;
  }

  /// A point of the left optical frame in the left image (rectified: its P).
  bool projectCamera(const Eigen::Vector3d& X, cv::Point2d* p) const {
    if (!info_ || !(X.z() > 0.0)) return false;
    const auto& P = info_->P;
    *p = {(P[0] * X.x() + P[2] * X.z()) / X.z(), (P[5] * X.y() + P[6] * X.z()) / X.z()};
    return true;
  }

  bool projectBase(const Eigen::Vector3d& X, cv::Point2d* p) const {
    if (!info_) return false;
    geometry_msgs::PointStamped in, out;
    in.header.frame_id = base_frame_;
    in.point.x = X.x();
    in.point.y = X.y();
    in.point.z = X.z();
    try {
      tf_.transform(in, out, info_->header.frame_id, ros::Duration(0.0));
    } catch (const tf2::TransformException&) {
      return false;
    }
    return projectCamera({out.point.x, out.point.y, out.point.z}, p);
  }

  void onImage(const sensor_msgs::ImageConstPtr& msg) {
    cv::Mat image;
    try {
      image = cv_bridge::toCvCopy(msg, "bgr8")->image;
    } catch (const cv_bridge::Exception&) {
      return;  // the report's picture only: another encoding is not worth a fault
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    images_.emplace_back(msg->header.stamp, image);
    if (images_.size() > 20) images_.pop_front();
  }

  void onInfo(const sensor_msgs::CameraInfoConstPtr& msg) {
    const std::lock_guard<std::mutex> lock(mutex_);
    info_ = msg;
  }

  void onDisparity(const stereo_msgs::DisparityImageConstPtr& msg) {
    const std::lock_guard<std::mutex> lock(mutex_);
    latency(kDisparity).push_back((ros::Time::now() - msg->header.stamp).toSec());
    try {
      disparity_ = cv_bridge::toCvCopy(msg->image)->image;
    } catch (const cv_bridge::Exception&) {
    }
  }

  /// The acupoint frames' latency: once per stamp, the first of them to arrive.
  void onTf(const tf2_msgs::TFMessageConstPtr& msg) {
    const ros::Time now = ros::Time::now();
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& t : msg->transforms) {
      if (t.child_frame_id.rfind(config_.frame_prefix, 0) != 0) continue;
      tf_stamps_[t.child_frame_id] = t.header.stamp;
      if (t.header.stamp != last_tf_stamp_) {
        last_tf_stamp_ = t.header.stamp;
        latency(kTf).push_back((now - t.header.stamp).toSec());
      }
    }
  }

  void fault(const std::string& what) {
    ROS_ERROR("massage_session: %s", what.c_str());
    const std::lock_guard<std::mutex> lock(mutex_);
    report_.faults.push_back(what);
  }

  static Eigen::Vector3d average(const std::vector<Eigen::Vector3d>& v) {
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : v) m += p;
    return m / static_cast<double>(v.size());
  }

  void onAcupoints(const massage_cell::AcupointArrayConstPtr& msg) {
    const std::lock_guard<std::mutex> lock(mutex_);
    ++report_.pairs;
    latest_stamp_ = msg->header.stamp.toSec();
    latency(kCect).push_back((ros::Time::now() - msg->header.stamp).toSec());
    latest_acupoints_ = msg;
    for (const auto& a : msg->acupoints)
      fix_.add(a.name, latest_stamp_, Eigen::Vector3d(a.position.x, a.position.y, a.position.z), a.valid);
  }

  void onTruth(const massage_cell::AcupointArrayConstPtr& msg) {
    const std::lock_guard<std::mutex> lock(mutex_);
    truth_header_ = msg->header;
    for (const auto& a : msg->acupoints) truth_[a.name] = Eigen::Vector3d(a.position.x, a.position.y, a.position.z);
  }

  /// A press by force's sample for its force plot (called with the mutex held): t from the press's first sample.
  void recordForce(const massage_cell::ArmState& msg) {
    const ros::Time stamp = msg.header.stamp.isZero() ? ros::Time::now() : msg.header.stamp;
    if (trace_start_.isZero()) trace_start_ = stamp;
    report::ForceSample s;
    s.t = (stamp - trace_start_).toSec();
    s.force = msg.force_valid ? msg.force : std::numeric_limits<double>::quiet_NaN();
    s.target = msg.force_target;
    s.limit = msg.force_limit;
    s.phase = msg.press_phase;
    force_trace_.push_back(std::move(s));
  }

  /// While the current acupoint is held at depth: the tool tip, and the truth in the arm base frame.
  void onState(const massage_cell::ArmStateConstPtr& msg) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (msg->homed) trajectory_.emplace_back(msg->tool.x, msg->tool.y, msg->tool.z);
    const bool in_press = !current_.empty() && msg->activity.find(current_ + ": ") != std::string::npos;
    const bool going_down = in_press && (msg->activity.find(": descend") != std::string::npos ||
                                         msg->activity.find("seeking the skin") != std::string::npos);
    if (going_down && !descending_) {
      descending_ = true;
      const auto tf = tf_stamps_.find(config_.frame_prefix + current_);
      if (tf != tf_stamps_.end()) latency(kPressStart).push_back((ros::Time::now() - tf->second).toSec());
    }
    if (in_press && !msg->press_phase.empty()) recordForce(*msg);
    if (in_press && msg->press_phase == "glide") gliding_.emplace_back(msg->tool.x, msg->tool.y);
    const bool holding = in_press && (msg->activity.find(current_ + ": hold") != std::string::npos ||
                                      msg->activity.find(": holding") != std::string::npos);
    if (!holding) return;
    holding_.emplace_back(msg->tool.x, msg->tool.y, msg->tool.z);
    if (msg->force_valid) force_holding_.push_back(msg->force);
    Eigen::Vector3d target;  // where the arm was sent: the acupoint's frame now
    if (frameInBase(config_.frame_prefix + current_, &target)) target_holding_.push_back(target);
    Eigen::Vector3d truth;
    if (truthInBase(current_, &truth)) truth_holding_.push_back(truth);
  }

  arm::SessionConfig config_;
  arm::StableFix fix_;
  report::SessionReport report_;
  tf2_ros::Buffer tf_;
  tf2_ros::TransformListener listener_;
  std::string arm_ns_ = "/arm", base_frame_ = "arm_base_link";
  double tolerance_ = 0.005, max_error_ = 0.02, service_timeout_ = 30.0;
  ros::Subscriber acupoints_sub_, truth_sub_, state_sub_, image_sub_, info_sub_, disparity_sub_, tf_sub_;
  std::string report_dir_;
  std::deque<std::pair<ros::Time, cv::Mat>> images_;
  sensor_msgs::CameraInfoConstPtr info_;
  massage_cell::AcupointArrayConstPtr latest_acupoints_;
  cv::Mat disparity_;
  std::map<std::string, ros::Time> tf_stamps_;
  ros::Time last_tf_stamp_;
  std::vector<Eigen::Vector3d> trajectory_;
  bool descending_ = false;
  ros::ServiceClient home_, massage_;
  std::mutex mutex_;
  double latest_stamp_ = 0.0;
  std::map<std::string, Eigen::Vector3d> truth_;
  std_msgs::Header truth_header_;
  std::string current_;
  std::vector<Eigen::Vector3d> holding_, truth_holding_, target_holding_;
  std::vector<double> force_holding_;             ///< the arm's force while holding (mode force)
  std::vector<report::ForceSample> force_trace_;  ///< the current press by force, sample by sample
  std::vector<Eigen::Vector2d> gliding_;          ///< the tool across the skin while the current stroke glides
  ros::Time trace_start_;                         ///< the stamp of its first sample
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "massage_session");
  ros::NodeHandle nh, pnh("~");
  std::string path;
  arm::SessionConfig config;
  try {
    readParam(pnh, "session", &path);
    if (path.empty()) throw std::runtime_error("~session (the routine's YAML file) is not set");
    config = arm::SessionConfig::load(path);
  } catch (const std::exception& e) {
    ROS_FATAL("massage_session: %s", e.what());
    return 2;
  }
  std::unique_ptr<Session> session;
  try {
    session = std::make_unique<Session>(nh, pnh, config);
  } catch (const massage_cell::nodes::ParamError& e) {
    ROS_FATAL("massage_session: %s", e.what());
    return 2;
  }
  ros::AsyncSpinner spinner(3);
  spinner.start();
  const int status = session->run();
  spinner.stop();
  return status;
}
