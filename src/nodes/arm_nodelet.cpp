#include "arm_nodelet.h"

#include <cstdio>

#include <ros/package.h>
#include <sensor_msgs/JointState.h>
#include <pluginlib/class_list_macros.hpp>

#include "massage_cell/ArmState.h"
#include "typed_param.h"

namespace massage_cell::nodes {

namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

ArmNodelet::~ArmNodelet() {
  timer_.stop();
  if (spinner_) spinner_->stop();
  massage_.reset();  // an active goal ends aborted
  if (sim_) sim_->stop();
  if (real_controller_) real_controller_->master().stop();
}

void ArmNodelet::readParameters() {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  config_path_ = ros::package::getPath("massage_cell") + "/config/arm.yaml";
  readParam(pnh, "config", &config_path_);
  options_ = arm::loadNodeOptions(config_path_);  // the file's node: section, then the private parameters
  arm::visitOptions(options_, [&pnh](const char* name, auto& value) { readParam(pnh, name, &value); });
  arm::validate(options_);
}

void ArmNodelet::onInit() {
  try {
    readParameters();
    config_ = arm::loadArmConfig(config_path_);
    if (options_.can_interface == "sim") sim_ = std::make_unique<arm::SimCell>(config_);
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
  targets_ = std::make_unique<ArmTargets>(*tf_buffer_, options_, config_);
  joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 10);
  state_pub_ = pnh.advertise<massage_cell::ArmState>("state", 10);
  wrench_pub_ = pnh.advertise<geometry_msgs::WrenchStamped>("wrench", 10);
  estop_sub_ = pnh.subscribe("estop", 10, &ArmNodelet::estopCb, this);
  sensor_sub_ = pnh.subscribe("ft_sensor", 10, &ArmNodelet::sensorCb, this);
  surface_sub_ = pnh.subscribe("surface", 1, &ArmNodelet::surfaceCb, this);
  if (sim_) fault_sub_ = pnh.subscribe("sim/inject_fault", 10, &ArmNodelet::injectFaultCb, this);
  if (sim_) {  // the simulated drives press a back whose skin is the session's true acupoints
    sim_skin_ = sim_->setSkin(config_.body.radius);
    skin_sub_ = pnh.subscribe("sim/skin", 2, &ArmNodelet::skinCb, this);
  }
  home_srv_ = pnh.advertiseService("home", &ArmNodelet::home, this);
  stop_srv_ = pnh.advertiseService("stop", &ArmNodelet::stop, this);
  reset_srv_ = pnh.advertiseService("reset_fault", &ArmNodelet::resetFault, this);
  move_srv_ = pnh.advertiseService("move_to", &ArmNodelet::moveTo, this);
  massage_ = std::make_unique<ArmMassage>(
      pnh, *targets_, controller_, options_.publish_rate,
      [this](const std::string& what, std::string* message) { return available(what, message); },
      [this](const arm::Accepted& accepted, std::string* message) { return wait(accepted, message); });
  updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
  updater_->setHardwareID(options_.can_interface == "sim" ? "simulated drives (virtual CAN bus)"
                                                          : "CAN " + options_.can_interface);
  updater_->add("arm", this, &ArmNodelet::diagnose);

  if (sim_) {
    startController(sim_->controller());
  } else {
    openInterface();  // on failure: logged; the timer retries
  }
  timer_ = pnh.createWallTimer(ros::WallDuration(1.0 / options_.publish_rate), &ArmNodelet::onTimer, this);
  spinner_ = std::make_unique<ros::AsyncSpinner>(4, &queue_);
  spinner_->start();
  NODELET_INFO_STREAM(
      "arm: " << (sim_ ? "simulated drives on the virtual bus" : "CAN interface " + options_.can_interface)
              << ", config " << config_path_ << ", base frame " << options_.base_frame);
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
    rt = sim_->start(options_.realtime);  // the master's and the drives' threads
  } else {
    rt = c.startThread(options_.realtime);
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
    options.interface = options_.can_interface;
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
                             << options_.can_interface << "': " << error
                             << ". Check can_interface (node.can_interface in " << config_path_
                             << " or ~can_interface; 'sim' runs simulated drives). The node keeps running, refuses "
                                "every command and retries every 2 s.");
      }
      return false;
    }
    if (!open_error_.empty()) NODELET_INFO_STREAM("arm: CAN interface '" << options_.can_interface << "' is open now");
    open_error_.clear();
  }
  startController(*real_controller_);
  return true;
}

std::string ArmNodelet::unavailable() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return "the CAN interface '" + options_.can_interface + "' is not available (" + open_error_ +
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
  joint_pub_.publish(jointStateMsg(s, config_, now));
  state_pub_.publish(armStateMsg(s, options_.base_frame, now));
  if (s.force.valid) wrench_pub_.publish(wrenchMsg(s, options_.tool_frame, now));  // only a force that is known
}

// --------------------------------------------------------------- inputs --

void ArmNodelet::estopCb(const std_msgs::BoolConstPtr& msg) {
  estop_input_ = msg->data;
  if (arm::Controller* c = controller()) c->setEstop(msg->data);
}

void ArmNodelet::sensorCb(const geometry_msgs::WrenchStampedConstPtr& msg) {
  double force = 0.0;
  if (const std::string why = targets_->sensorForce(*msg, &force); !why.empty()) {
    NODELET_WARN_STREAM_THROTTLE(5.0, "arm: ~ft_sensor reading not used: " << why);
    return;
  }
  if (arm::Controller* c = controller()) c->setSensorForce(force);
}

void ArmNodelet::surfaceCb(const sensor_msgs::PointCloud2ConstPtr& msg) {
  if (const std::string why = targets_->setSurface(*msg); !why.empty())
    NODELET_WARN_STREAM_THROTTLE(5.0, "arm: ~surface not used: " << why);
}

void ArmNodelet::skinCb(const massage_cell::AcupointArrayConstPtr& msg) {
  std::vector<Eigen::Vector3d> points;
  if (const std::string why = targets_->pointsInBase(*msg, &points); !why.empty()) {
    NODELET_WARN_STREAM_THROTTLE(5.0, "arm: ~sim/skin not used: " << why);
    return;
  }
  sim_skin_->set(std::move(points));
}

void ArmNodelet::injectFaultCb(const std_msgs::StringConstPtr& msg) {
  int axis = -1;
  std::uint16_t code = 0;
  if (!arm::parseFaultInjection(config_, msg->data, &axis, &code)) {
    NODELET_ERROR_STREAM("arm: ~sim/inject_fault wants '<axis> <EMCY code>', e.g. 'Y 0x2310'; got '" << msg->data
                                                                                                     << "'");
    return;
  }
  NODELET_WARN_STREAM("arm: simulator: injecting fault " << msg->data);
  sim_->drive(axis).injectFault(code);
}

// --------------------------------------------------------------- services --

bool ArmNodelet::wait(const arm::Accepted& accepted, std::string* message) {
  if (!accepted) {
    *message = accepted.error;
    return false;
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(options_.command_timeout);
  arm::Controller* c = controller();  // set: a command was accepted
  arm::CommandResult r = c->result(accepted.id);
  while (!r.done && ros::WallTime::now() < deadline && ros::ok()) {
    ros::WallDuration(0.01).sleep();
    r = c->result(accepted.id);
  }
  if (!r.done) {
    *message = "no result within " + fmt("%.0f", options_.command_timeout) + " s (the command goes on; see ~state)";
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
  Eigen::Vector3d goal;
  if (std::string why = targets_->moveGoal(req.target, c->status().tool, &goal); !why.empty()) {
    res.success = false;
    res.message = why;
    NODELET_WARN_STREAM("arm: " << res.message);
    return true;
  }
  res.success = wait(c->moveTo(goal, req.speed), &res.message);
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
    status.add("CAN interface", options_.can_interface);
    status.add("real-time scheduling", "not started (no CAN interface)");
    return;
  }
  reportArm(c->status(), options_, rt, &status);
}

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::ArmNodelet, nodelet::Nodelet)
