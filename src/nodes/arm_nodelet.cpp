#include "arm_nodelet.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include <geometry_msgs/TransformStamped.h>
#include <ros/package.h>
#include <sensor_msgs/JointState.h>
#include <tf2/exceptions.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>
#include <yaml-cpp/yaml.h>
#include <pluginlib/class_list_macros.hpp>

#include "massage_cell/ArmState.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }
Eigen::Vector3d toEigen(const geometry_msgs::Vector3& v) { return {v.x, v.y, v.z}; }

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

ArmNodelet::~ArmNodelet() {
  timer_.stop();
  if (spinner_) spinner_->stop();
  if (sim_) sim_->stop();
  if (real_controller_) real_controller_->master().stop();
}

void ArmNodelet::readParameters() {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  config_path_ = ros::package::getPath("massage_cell") + "/config/arm.yaml";
  readParam(pnh, "config", &config_path_);
  // Defaults from the file's node: section, then the private parameters.
  try {
    const YAML::Node node = YAML::LoadFile(config_path_)["node"];
    if (node) {
      if (node["can_interface"]) can_interface_ = node["can_interface"].as<std::string>();
      if (node["base_frame"]) base_frame_ = node["base_frame"].as<std::string>();
      if (node["publish_rate"]) publish_rate_ = node["publish_rate"].as<double>();
      if (node["max_target_age"]) max_target_age_ = node["max_target_age"].as<double>();
      if (node["tf_timeout"]) tf_timeout_ = node["tf_timeout"].as<double>();
      if (node["acupoint_prefix"]) acupoint_prefix_ = node["acupoint_prefix"].as<std::string>();
      if (node["command_timeout"]) command_timeout_ = node["command_timeout"].as<double>();
      if (node["realtime_priority"]) realtime_options_.priority = node["realtime_priority"].as<int>();
      if (node["lock_memory"]) realtime_options_.lock_memory = node["lock_memory"].as<bool>();
    }
  } catch (const YAML::Exception& e) {
    throw arm::ArmConfigError(config_path_ + ": node: " + e.what());
  }
  readParam(pnh, "can_interface", &can_interface_);
  readParam(pnh, "base_frame", &base_frame_);
  readParam(pnh, "publish_rate", &publish_rate_);
  readParam(pnh, "max_target_age", &max_target_age_);
  readParam(pnh, "tf_timeout", &tf_timeout_);
  readParam(pnh, "acupoint_prefix", &acupoint_prefix_);
  readParam(pnh, "command_timeout", &command_timeout_);
  readParam(pnh, "realtime_priority", &realtime_options_.priority);
  readParam(pnh, "lock_memory", &realtime_options_.lock_memory);
  if (!(publish_rate_ > 0.0)) throw arm::ArmConfigError("publish_rate must be > 0, got " + fmt("%g", publish_rate_));
  if (!(max_target_age_ > 0.0))
    throw arm::ArmConfigError("max_target_age must be > 0, got " + fmt("%g", max_target_age_));
  if (!(tf_timeout_ >= 0.0)) throw arm::ArmConfigError("tf_timeout must be >= 0");
  if (!(command_timeout_ > 0.0)) throw arm::ArmConfigError("command_timeout must be > 0");
  if (can_interface_.empty()) throw arm::ArmConfigError("can_interface must be 'sim' or an interface name (can0)");
  if (realtime_options_.priority < 0 || realtime_options_.priority > 99) {
    throw arm::ArmConfigError("realtime_priority must be 0 (normal scheduling) .. 99, got " +
                              std::to_string(realtime_options_.priority));
  }
}

void ArmNodelet::onInit() {
  try {
    readParameters();
    config_ = arm::loadArmConfig(config_path_);
    if (can_interface_ == "sim") sim_ = std::make_unique<arm::SimCell>(config_);
  } catch (const std::exception& e) {
    NODELET_FATAL_STREAM("arm: " << e.what());
    throw;
  }

  ros::NodeHandle nh(getNodeHandle());
  ros::NodeHandle pnh(getPrivateNodeHandle());
  nh.setCallbackQueue(&queue_);
  pnh.setCallbackQueue(&queue_);
  tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, getNodeHandle());
  joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 10);
  state_pub_ = pnh.advertise<massage_cell::ArmState>("state", 10);
  estop_sub_ = pnh.subscribe("estop", 10, &ArmNodelet::estopCb, this);
  if (sim_) fault_sub_ = pnh.subscribe("sim/inject_fault", 10, &ArmNodelet::injectFaultCb, this);
  home_srv_ = pnh.advertiseService("home", &ArmNodelet::home, this);
  stop_srv_ = pnh.advertiseService("stop", &ArmNodelet::stop, this);
  reset_srv_ = pnh.advertiseService("reset_fault", &ArmNodelet::resetFault, this);
  move_srv_ = pnh.advertiseService("move_to", &ArmNodelet::moveTo, this);
  massage_srv_ = pnh.advertiseService("massage", &ArmNodelet::massage, this);
  updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
  updater_->setHardwareID(can_interface_ == "sim" ? "simulated drives (virtual CAN bus)" : "CAN " + can_interface_);
  updater_->add("arm", this, &ArmNodelet::diagnose);

  if (sim_) {
    startController(sim_->controller());
  } else {
    openInterface();  // on failure: logged; the timer retries
  }
  timer_ = pnh.createWallTimer(ros::WallDuration(1.0 / publish_rate_), &ArmNodelet::onTimer, this);
  spinner_ = std::make_unique<ros::AsyncSpinner>(4, &queue_);
  spinner_->start();
  NODELET_INFO_STREAM("arm: " << (sim_ ? "simulated drives on the virtual bus" : "CAN interface " + can_interface_)
                              << ", config " << config_path_ << ", base frame " << base_frame_);
}

void ArmNodelet::startController(arm::Controller& c) {
  c.setLog([this](const std::string& text) {
    if (text.rfind("FAULT", 0) == 0 || text.rfind("E-STOP", 0) == 0) {
      NODELET_ERROR_STREAM("arm: " << text);
    } else if (text.rfind("refused", 0) == 0 || text.find("failed") != std::string::npos) {
      NODELET_WARN_STREAM("arm: " << text);
    } else {
      NODELET_INFO_STREAM("arm: " << text);
    }
  });
  if (estop_input_) c.setEstop(true);  // pressed before the controller existed
  can::RealtimeStatus rt;
  if (sim_) {
    rt = sim_->start(realtime_options_);  // the master's and the drives' threads
  } else {
    rt = c.startThread(realtime_options_);
    c.start();
  }
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    realtime_ = rt;
  }
  controller_ = &c;
  if (!rt.error.empty()) {
    NODELET_WARN_STREAM("arm: real-time scheduling not as configured, running with " << rt.describe());
  } else if (rt.requested > 0 || rt.lock_requested) {
    NODELET_INFO_STREAM("arm: control threads: " << rt.describe());
  }
}

bool ArmNodelet::openInterface() {
  std::string error;
  try {
    can::SocketCanOptions options;
    options.interface = can_interface_;
    auto bus = std::make_unique<can::SocketCanBus>(options);
    auto controller = std::make_unique<arm::Controller>(*bus, can::SteadyClock::instance(), config_);
    socket_bus_ = std::move(bus);
    real_controller_ = std::move(controller);
  } catch (const std::exception& e) {
    error = e.what();
  }
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    next_open_ = ros::WallTime::now() + ros::WallDuration(2.0);
    if (!error.empty()) {
      const bool again = error == open_error_;
      open_error_ = error;
      if (!again) {
        NODELET_ERROR_STREAM("arm: cannot open the CAN interface '"
                             << can_interface_ << "': " << error << ". Check can_interface (node.can_interface in "
                             << config_path_
                             << " or ~can_interface; 'sim' runs simulated drives). The node keeps running, refuses "
                                "every command and retries every 2 s.");
      }
      return false;
    }
    if (!open_error_.empty()) NODELET_INFO_STREAM("arm: CAN interface '" << can_interface_ << "' is open now");
    open_error_.clear();
  }
  startController(*real_controller_);
  return true;
}

std::string ArmNodelet::unavailable() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return "the CAN interface '" + can_interface_ + "' is not available (" + open_error_ +
         "); check can_interface; retrying every 2 s";
}

arm::Controller* ArmNodelet::available(const std::string& what, std::string* message) const {
  arm::Controller* c = controller();
  if (!c) {
    *message = what + " refused: " + unavailable();
    NODELET_WARN_STREAM("arm: " << *message);
  }
  return c;
}

// --------------------------------------------------------------- periodic --

void ArmNodelet::onTimer(const ros::WallTimerEvent&) {
  arm::Controller* c = controller();
  if (!c) {
    bool due;
    {
      std::lock_guard<std::mutex> lock(status_mutex_);
      due = ros::WallTime::now() >= next_open_;
    }
    if (due) openInterface();
  } else {
    c->keepAlive();  // the command watchdog: this node is alive
    checkPressTarget();
  }
  publishState();
  updater_->update();
}

void ArmNodelet::publishState() {
  arm::ArmStatus s;
  if (arm::Controller* c = controller()) {
    s = c->status();
  } else {  // no CAN interface: a fault nothing but the interface clears
    s.mode = arm::Mode::kFault;
    s.faults = {unavailable()};
    s.last_error = s.faults.front();
    s.bus = can::BusState::kDown;
    for (int i = 0; i < 3; ++i) s.axes[i].name = config_.axis_names[i];
  }
  const ros::Time now = ros::Time::now();
  sensor_msgs::JointState js;
  js.header.stamp = now;
  massage_cell::ArmState st;
  st.header.stamp = now;
  st.header.frame_id = base_frame_;
  st.mode = arm::toString(s.mode);
  st.homed = s.homed;
  st.estop_active = s.estop_input;
  st.estop_latched = s.estop_latched;
  for (int i = 0; i < 3; ++i) {
    js.name.push_back(config_.joint_names[i]);
    js.position.push_back(s.axes[i].position);
    st.axis_names.push_back(s.axes[i].name);
    st.position.push_back(s.axes[i].position);
    st.axis_state.push_back(can::toString(s.axes[i].state));
    st.node_state.push_back(can::toString(s.axes[i].node));
    st.axis_homed.push_back(s.axes[i].homed);
  }
  st.tool.x = s.tool.x();
  st.tool.y = s.tool.y();
  st.tool.z = s.tool.z();
  st.faults = s.faults;
  st.activity = s.activity;
  st.last_error = s.last_error;
  st.bus_state = can::toString(s.bus);
  joint_pub_.publish(js);
  state_pub_.publish(st);
}

void ArmNodelet::checkPressTarget() {
  std::string frame;
  {
    std::lock_guard<std::mutex> lock(targets_mutex_);
    if (massage_command_ == 0 || controller()->result(massage_command_).done) return;
    const int index = controller()->status().target;
    for (const FrameTarget& t : frame_targets_) {
      if (t.index == index) frame = t.frame;
    }
  }
  if (frame.empty()) return;
  geometry_msgs::TransformStamped t;
  std::string error;
  if (!lookup(frame, ros::Time(0), &t, &error)) controller()->abortMassage("acupoint frame " + error);
}

bool ArmNodelet::lookup(const std::string& frame, const ros::Time& stamp, geometry_msgs::TransformStamped* out,
                        std::string* error) {
  try {
    *out = tf_buffer_->lookupTransform(base_frame_, frame, stamp, ros::Duration(tf_timeout_));
  } catch (const tf2::TransformException& e) {
    *error = "'" + frame + "' is unknown or not connected to " + base_frame_ + " (" + e.what() + ")";
    return false;
  }
  // A chain of static transforms has stamp 0: never stale.
  if (!out->header.stamp.isZero()) {
    const double age = (ros::Time::now() - out->header.stamp).toSec();
    if (age > max_target_age_) {
      *error = "'" + frame + "' is stale: its transform is " + fmt("%.2f", age) + " s old (limit " +
               fmt("%.2f", max_target_age_) + " s)";
      return false;
    }
  }
  return true;
}

arm::BodySurface ArmNodelet::bodySurface() const {
  arm::BodySurface body;
  std::vector<std::string> frames;
  tf_buffer_->_getFrameStrings(frames);
  const ros::Time now = ros::Time::now();
  for (const std::string& frame : frames) {
    if (frame.rfind(acupoint_prefix_, 0) != 0) continue;
    try {
      const auto t = tf_buffer_->lookupTransform(base_frame_, frame, ros::Time(0));
      if (!t.header.stamp.isZero() && (now - t.header.stamp).toSec() > max_target_age_) continue;  // gone
      body.points.emplace_back(t.transform.translation.x, t.transform.translation.y, t.transform.translation.z);
    } catch (const tf2::TransformException&) {
    }
  }
  return body;
}

// --------------------------------------------------------------- inputs --

void ArmNodelet::estopCb(const std_msgs::BoolConstPtr& msg) {
  estop_input_ = msg->data;
  if (arm::Controller* c = controller()) c->setEstop(msg->data);
}

void ArmNodelet::injectFaultCb(const std_msgs::StringConstPtr& msg) {
  std::istringstream in(msg->data);
  std::string axis, code_text;
  in >> axis >> code_text;
  int joint = -1;
  for (int i = 0; i < 3; ++i) {
    if (config_.axis_names[i] == axis) joint = i;
  }
  unsigned long code = 0;
  try {
    code = std::stoul(code_text, nullptr, 0);
  } catch (const std::exception&) {
    joint = -1;
  }
  if (joint < 0 || code == 0 || code > 0xFFFF) {
    NODELET_ERROR_STREAM("arm: ~sim/inject_fault wants '<axis> <EMCY code>', e.g. 'Y 0x2310'; got '" << msg->data
                                                                                                     << "'");
    return;
  }
  NODELET_WARN_STREAM("arm: simulator: injecting fault " << code_text << " into axis " << axis);
  sim_->drive(joint).injectFault(static_cast<std::uint16_t>(code));
}

// --------------------------------------------------------------- services --

bool ArmNodelet::wait(const arm::Accepted& accepted, std::string* message) {
  if (!accepted) {
    *message = accepted.error;
    return false;
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(command_timeout_);
  arm::Controller* c = controller();  // set: a command was accepted
  arm::CommandResult r = c->result(accepted.id);
  while (!r.done && ros::WallTime::now() < deadline && ros::ok()) {
    ros::WallDuration(0.01).sleep();
    r = c->result(accepted.id);
  }
  if (!r.done) {
    *message = "no result within " + fmt("%.0f", command_timeout_) + " s (the command goes on; see ~state)";
    return false;
  }
  *message = r.message;
  return r.success;
}

bool ArmNodelet::home(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  arm::Controller* c = available("home", &res.message);
  res.success = c && wait(c->home(), &res.message);
  return true;
}

bool ArmNodelet::stop(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  arm::Controller* c = available("stop", &res.message);
  if (!c) {
    res.success = false;
    return true;
  }
  const arm::Accepted a = c->stop("stopped by ~stop");
  std::string message;
  const bool ended_ok = wait(a, &message);
  // The stop succeeded once the command it ended is over, whatever that command's outcome.
  res.success = c->result(a.id).done;
  res.message = ended_ok ? message : "stopped: " + message;
  return true;
}

bool ArmNodelet::resetFault(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  arm::Controller* c = available("reset_fault", &res.message);
  res.success = c && wait(c->resetFault(), &res.message);
  return true;
}

bool ArmNodelet::moveTo(massage_cell::MoveTo::Request& req, massage_cell::MoveTo::Response& res) {
  arm::Controller* c = available("move_to", &res.message);
  if (!c) {
    res.success = false;
    return true;
  }
  geometry_msgs::TransformStamped t;
  std::string error;
  const std::string frame = req.target.header.frame_id;
  if (frame.empty()) {
    res.success = false;
    res.message = "move_to refused: the target has no frame_id";
    return true;
  }
  if (!lookup(frame, req.target.header.stamp, &t, &error)) {
    res.success = false;
    res.message = "move_to refused: the target frame " + error;
    NODELET_WARN_STREAM("arm: " << res.message);
    return true;
  }
  geometry_msgs::Point p;
  tf2::doTransform(req.target.point, p, t);
  const Eigen::Vector3d goal = toEigen(p);
  if (arm::checkTool(config_, goal).empty()) {  // (outside the envelope: the controller says so)
    const std::string why = arm::checkBodyClearance(config_, bodySurface(), c->status().tool, goal,
                                                    config_.limitsOf(config_.default_region).max_depth);
    if (!why.empty()) {
      res.success = false;
      res.message = "move refused: " + why;
      NODELET_WARN_STREAM("arm: " << res.message);
      return true;
    }
  }
  res.success = wait(c->moveTo(goal, req.speed), &res.message);
  return true;
}

bool ArmNodelet::massage(massage_cell::Massage::Request& req, massage_cell::Massage::Response& res) {
  res.success = false;
  arm::Controller* c = available("massage", &res.message);
  if (!c) return true;
  auto refuse = [&](const std::string& why) {
    res.message = "massage refused: " + why;
    NODELET_WARN_STREAM("arm: " << res.message);
    return true;
  };
  const std::size_t n = req.frames.size() + req.points.size();
  if (n == 0) return refuse("no target (frames or points) given");
  if (n > static_cast<std::size_t>(config_.press.max_targets)) {  // before looking up thousands of frames
    return refuse(std::to_string(n) + " targets: at most " + std::to_string(config_.press.max_targets) +
                  " in one request (press.max_targets)");
  }
  if (!std::isfinite(req.hold)) return refuse("hold must be a finite number of seconds (0: the default; < 0: none)");
  if (!req.regions.empty() && req.regions.size() != n) {
    return refuse("regions has " + std::to_string(req.regions.size()) + " entries for " + std::to_string(n) +
                  " targets");
  }
  if (!req.normals.empty() && req.normals.size() != n) {
    return refuse("normals has " + std::to_string(req.normals.size()) + " entries for " + std::to_string(n) +
                  " targets");
  }
  arm::PressRequest press;
  if (req.technique.empty() || req.technique == "press") {
    press.technique = arm::Technique::kPress;
  } else if (req.technique == "knead") {
    press.technique = arm::Technique::kKnead;
  } else {
    return refuse("unknown technique '" + req.technique + "' (press or knead)");
  }
  press.depth = req.depth;
  press.hold = req.hold == 0.0 ? -1.0 : std::max(0.0, req.hold);
  press.speed = req.speed;
  press.repeats = req.repeats == 0 ? 1 : req.repeats;
  std::vector<FrameTarget> frames;
  const arm::BodySurface body = bodySurface();
  for (std::size_t i = 0; i < n; ++i) {
    arm::PressTarget target;
    geometry_msgs::TransformStamped t;
    std::string error;
    if (i < req.frames.size()) {
      const std::string& frame = req.frames[i];
      if (!lookup(frame, ros::Time(0), &t, &error))
        return refuse("target " + std::to_string(i + 1) + ": the frame " + error);
      target.name = frame.rfind(acupoint_prefix_, 0) == 0 ? frame.substr(acupoint_prefix_.size()) : frame;
      target.point = {t.transform.translation.x, t.transform.translation.y, t.transform.translation.z};
      target.region = config_.regionOf(target.name);
      frames.push_back({static_cast<int>(i), frame});
    } else {
      const geometry_msgs::PointStamped& ps = req.points[i - req.frames.size()];
      target.name = "point " + std::to_string(i - req.frames.size() + 1);
      if (ps.header.frame_id.empty()) return refuse(target.name + " has no frame_id");
      if (!lookup(ps.header.frame_id, ps.header.stamp, &t, &error)) {
        return refuse(target.name + ": the frame " + error);
      }
      geometry_msgs::Point p;
      tf2::doTransform(ps.point, p, t);
      target.point = toEigen(p);
    }
    if (!req.regions.empty() && !req.regions[i].empty()) target.region = req.regions[i];
    // A surface point under the skin the arm knows would press deeper than the region allows.
    const double limit = config_.limitsOf(target.region.empty() ? config_.default_region : target.region).max_depth;
    if (std::string why = arm::checkBodyClearance(config_, body, target.point, target.point, limit); !why.empty()) {
      return refuse(target.name + ": " + why);
    }
    if (!req.normals.empty()) {
      const geometry_msgs::Vector3Stamped& ns = req.normals[i];
      if (!lookup(ns.header.frame_id.empty() ? base_frame_ : ns.header.frame_id, ros::Time(0), &t, &error)) {
        return refuse(target.name + ": the normal's frame " + error);
      }
      geometry_msgs::Vector3 v;
      tf2::doTransform(ns.vector, v, t);
      target.normal = toEigen(v);
    }
    press.targets.push_back(target);
  }
  const arm::Accepted accepted = c->massage(press);
  if (accepted) {
    std::lock_guard<std::mutex> lock(targets_mutex_);
    massage_command_ = accepted.id;
    frame_targets_ = frames;
  }
  res.success = wait(accepted, &res.message);
  res.presses_done = accepted ? c->status().presses_done : 0;
  return true;
}

// --------------------------------------------------------------- diagnostics --

void ArmNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using diagnostic_msgs::DiagnosticStatus;
  can::RealtimeStatus rt;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    rt = realtime_;
  }
  arm::Controller* c = controller();
  if (!c) {
    status.summary(DiagnosticStatus::ERROR, unavailable());
    status.add("CAN interface", can_interface_);
    status.add("real-time scheduling", "not started (no CAN interface)");
    return;
  }
  const arm::ArmStatus s = c->status();
  if (s.mode == arm::Mode::kFault) {
    std::string f;
    for (const auto& x : s.faults) f += (f.empty() ? "" : "; ") + x;
    status.summary(DiagnosticStatus::ERROR, "fault: " + f);
  } else if (s.mode == arm::Mode::kEstop || s.mode == arm::Mode::kReleasing) {
    status.summary(DiagnosticStatus::ERROR,
                   s.mode == arm::Mode::kEstop ? "e-stop latched" : "e-stop latched, releasing the pressure");
  } else if (!s.homed || s.mode == arm::Mode::kStarting) {
    status.summary(DiagnosticStatus::WARN, std::string(arm::toString(s.mode)) + ": not homed");
  } else {
    status.summary(DiagnosticStatus::OK, arm::toString(s.mode));
  }
  status.add("mode", arm::toString(s.mode));
  status.add("homed", s.homed);
  status.add("e-stop input", s.estop_input);
  status.add("e-stop latched", s.estop_latched);
  status.add("CAN interface", can_interface_);
  status.add("real-time scheduling", rt.describe());
  status.add("bus state", can::toString(s.bus));
  for (const auto& a : s.axes) {
    status.add("axis " + a.name, fmt("%.6f m", a.position) + ", " + can::toString(a.state) + ", node " +
                                     can::toString(a.node) + (a.homed ? ", homed" : ", not homed"));
  }
  status.add("tool (" + base_frame_ + ")", arm::formatPoint(s.tool));
  status.add("activity", s.activity);
  status.add("last error", s.last_error);
  status.add("controller cycles", s.cycles);
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::ArmNodelet, nodelet::Nodelet)
