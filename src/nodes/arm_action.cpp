#include "arm_action.h"

#include <geometry_msgs/TransformStamped.h>

namespace massage_cell::nodes {

ArmMassage::ArmMassage(ros::NodeHandle pnh, const ArmTargets& targets, const std::atomic<arm::Controller*>& controller,
                       double rate, Available available, Wait wait)
    : targets_(targets), controller_(controller), available_(std::move(available)), wait_(std::move(wait)) {
  server_ = std::make_unique<Server>(pnh, "massage", false);
  server_->registerGoalCallback([this] { onGoalOrPreempt(); });
  server_->registerPreemptCallback([this] { onGoalOrPreempt(); });
  server_->start();
  service_ = pnh.advertiseService("massage", &ArmMassage::serve, this);
  timer_ = pnh.createWallTimer(ros::WallDuration(1.0 / rate), &ArmMassage::onTimer, this);
}

ArmMassage::~ArmMassage() { shutdown(); }

void ArmMassage::shutdown() {
  timer_.stop();
  service_.shutdown();
  std::lock_guard<std::mutex> lock(mutex_);
  if (!server_) return;
  if (server_->isActive()) {
    const std::string why = "the arm node shuts down";
    server_->setAborted(result(false, why, last_feedback_.presses_done), why);
  }
  server_.reset();
}

// --------------------------------------------------------------- both interfaces --

template <class Request>
arm::Accepted ArmMassage::start(const Request& req, std::vector<std::string>* names) {
  arm::Accepted refused;
  arm::Controller* c = available_("massage", &refused.error);
  if (!c) return refused;
  arm::PressRequest press;
  std::vector<ArmTargets::FrameTarget> frames;
  if (std::string why = targets_.pressRequest(req, &press, &frames); !why.empty()) {
    refused.error = "massage refused: " + why;
    ROS_WARN_STREAM("arm: " << refused.error);
    return refused;
  }
  const arm::Accepted accepted = c->massage(press);
  if (accepted) {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    monitored_command_ = accepted.id;
    frame_targets_ = std::move(frames);
    whole_path_ = press.technique == arm::Technique::kStroke;
  }
  names->clear();
  for (const arm::PressTarget& t : press.targets) names->push_back(t.name);
  return accepted;
}

bool ArmMassage::serve(massage_cell::Massage::Request& req, massage_cell::Massage::Response& res) {
  std::vector<std::string> names;
  const arm::Accepted accepted = start(req, &names);
  res.success = wait_(accepted, &res.message);
  res.presses_done = accepted ? controller_.load()->status().presses_done : 0;
  return true;
}

void ArmMassage::onTimer(const ros::WallTimerEvent&) {
  checkPressTarget();
  std::lock_guard<std::mutex> lock(mutex_);
  if (server_) step();
}

void ArmMassage::checkPressTarget() {
  arm::Controller* c = controller_.load();
  if (!c) return;
  std::vector<std::string> frames;  // the target's frame; a stroke's: every frame of its path
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    if (monitored_command_ == 0 || c->result(monitored_command_).done) return;
    const int index = c->status().target;
    for (const auto& [target, name] : frame_targets_) {
      if (whole_path_ || target == index) frames.push_back(name);
    }
  }
  for (const std::string& frame : frames) {
    geometry_msgs::TransformStamped t;
    std::string error;
    if (!targets_.lookup(frame, ros::Time(0), &t, &error)) {
      c->abortMassage("acupoint frame " + error);
      return;
    }
  }
}

// --------------------------------------------------------------- the action --

void ArmMassage::onGoalOrPreempt() {
  // Called under the server's lock: never wait for mutex_ here (step() takes the server's lock under mutex_). When
  // the timer holds it, its step() or the next one (1 / publish_rate later) does the work.
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (lock && server_) step();
}

void ArmMassage::step() {
  arm::Controller* c = controller_.load();  // set whenever goal_command_ is: a command was accepted
  if (server_->isActive() && goal_command_ != 0) {
    const arm::CommandResult r = c->result(goal_command_);
    if (!r.done) {
      if (server_->isPreemptRequested() && !stop_sent_) {
        stop_sent_ = true;
        c->stop(server_->isNewGoalAvailable() ? "massage goal preempted by a new goal" : "massage goal canceled");
      }
      publishFeedback(c->status());
      return;
    }
    const arm::ArmStatus s = c->status();
    const int presses = s.command == goal_command_ ? s.presses_done : last_feedback_.presses_done;
    goal_command_ = 0;
    const massage_cell::MassageResult res = result(r.success, r.message, presses);
    if (r.success) {
      server_->setSucceeded(res, r.message);
    } else if (server_->isPreemptRequested()) {
      server_->setPreempted(res, r.message);  // the arm stands: the massage is over
    } else {
      server_->setAborted(res, r.message);
    }
  }
  if (server_->isActive() || !server_->isNewGoalAvailable()) return;
  const auto goal = server_->acceptNewGoal();
  if (!goal) return;
  if (server_->isPreemptRequested()) {  // canceled while it waited for the previous goal's massage to end
    const std::string why = "massage goal canceled before it started";
    server_->setPreempted(result(false, why, 0), why);
    return;
  }
  std::vector<std::string> names;
  const arm::Accepted accepted = start(*goal, &names);
  if (!accepted) {
    server_->setAborted(result(false, accepted.error, 0), accepted.error);
    return;
  }
  goal_command_ = accepted.id;
  stop_sent_ = false;
  goal_names_ = std::move(names);
  last_feedback_ = massage_cell::MassageFeedback();
  last_feedback_time_ = ros::WallTime();
  publishFeedback(controller_.load()->status());
}

void ArmMassage::publishFeedback(const arm::ArmStatus& s) {
  massage_cell::MassageFeedback f;
  f.target = s.target;
  if (s.target >= 0 && static_cast<std::size_t>(s.target) < goal_names_.size()) f.target_name = goal_names_[s.target];
  f.activity = s.activity;
  f.press_phase = s.press_phase;
  f.force_valid = s.force.valid;
  f.force = s.force.valid ? s.force.force : 0.0;
  f.force_target = s.force_target;
  f.force_limit = s.force_limit;
  f.presses_done = s.presses_done;
  // At most every 0.1 s, unless the target, the activity, the phase or the count changed.
  const ros::WallTime now = ros::WallTime::now();
  const bool changed = f.target != last_feedback_.target || f.activity != last_feedback_.activity ||
                       f.press_phase != last_feedback_.press_phase || f.presses_done != last_feedback_.presses_done;
  if (!changed && now - last_feedback_time_ < ros::WallDuration(0.1)) return;
  server_->publishFeedback(f);
  last_feedback_ = f;
  last_feedback_time_ = now;
}

massage_cell::MassageResult ArmMassage::result(bool success, const std::string& message, int presses) const {
  massage_cell::MassageResult r;
  r.success = success;
  r.message = message;
  r.presses_done = presses;
  return r;
}

}  // namespace massage_cell::nodes
