// The arm node's massage (issue 45, item 5), served twice on the same code:
//  - the service `~massage` (massage_cell/Massage): the call blocks until the
//    massage is over (or command_timeout), for simple callers;
//  - the actionlib action `~massage` (massage_cell/MassageAction: topics
//    ~massage/goal, cancel, status, feedback, result): feedback while it runs
//    (the target, the arm's activity, the press phase and force, presses done),
//    cancel.
// Both turn their request into an arm::PressRequest with ArmTargets::pressRequest
// and start it with start(); the acupoint frames of the massage under way are
// checked at publish_rate (lost or stale: the controller retracts).
//
// The action is an actionlib::SimpleActionServer in goal-callback /
// preempt-callback style, without an execute thread (a nodelet must not block):
// its own wall timer at publish_rate polls the controller's command, publishes
// feedback and ends the goal. One massage at a time:
//  - a new goal while a goal runs preempts it, as SimpleActionServer does, but
//    only once the old massage is over: the controller stops it (a press in
//    contact backs off, "the pressure is released"), the old goal ends
//    preempted when the arm stands, then the new goal starts;
//  - a goal while the controller runs anything else (a ~massage service call,
//    ~move_to, ~home) is aborted with the controller's refusal ("busy ...; call
//    stop first"); so is any refused goal (no targets, unknown or stale frame,
//    beyond a limit, no CAN interface);
//  - cancel stops the massage; the goal ends preempted, once the arm stands,
//    with the controller's message ("massage goal canceled; tool retracted to
//    ..."); ~stop, an e-stop, a fault or a lost frame end it aborted;
//  - at shutdown an active goal ends aborted ("the arm node shuts down").
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <actionlib/server/simple_action_server.h>
#include <ros/ros.h>

#include "arm_interface.h"
#include "massage_cell/Massage.h"
#include "massage_cell/MassageAction.h"
#include "massage_cell/arm/controller.h"

namespace massage_cell::nodes {

class ArmMassage {
 public:
  /// The controller for the command `what`, or null with the refusal in `message` (no CAN interface).
  using Available = std::function<arm::Controller*(const std::string& what, std::string* message)>;
  /// Waits for an accepted command: its success, and its message in `message` (the services' wait).
  using Wait = std::function<bool(const arm::Accepted& accepted, std::string* message)>;

  /// Advertises the service and the action `~massage` on `pnh` (its callback queue) and starts the timer at `rate`
  /// Hz. `targets` and `controller` outlive this object.
  ArmMassage(ros::NodeHandle pnh, const ArmTargets& targets, const std::atomic<arm::Controller*>& controller,
             double rate, Available available, Wait wait);
  /// shutdown().
  ~ArmMassage();
  ArmMassage(const ArmMassage&) = delete;
  ArmMassage& operator=(const ArmMassage&) = delete;

  /// Stops the timer and the service; an active goal ends aborted. Call with the node's spinner stopped.
  void shutdown();

 private:
  using Server = actionlib::SimpleActionServer<massage_cell::MassageAction>;

  /// The massage of `req` (a service request or an action goal): its targets resolved and checked, the controller's
  /// massage command started, its frame targets monitored. The command, or the refusal; the names of its targets
  /// (frames without the acupoint prefix, "point 1", ...) in `names`.
  template <class Request>
  arm::Accepted start(const Request& req, std::vector<std::string>* names);
  bool serve(massage_cell::Massage::Request& req, massage_cell::Massage::Response& res);
  void onTimer(const ros::WallTimerEvent& event);
  /// The frame of the target being pressed (a stroke: every frame of its path), still there and fresh? Otherwise the
  /// controller retracts.
  void checkPressTarget();
  /// The goal callback and the preempt callback (under the action server's lock): step() now if nobody else runs it.
  void onGoalOrPreempt();
  /// Under mutex_: stops the goal's massage when a preempt is asked; ends the goal when its massage is over, with
  /// feedback meanwhile; accepts and starts the next goal when none is active.
  void step();
  void publishFeedback(const arm::ArmStatus& status);
  massage_cell::MassageResult result(bool success, const std::string& message, int presses) const;

  const ArmTargets& targets_;
  const std::atomic<arm::Controller*>& controller_;
  Available available_;
  Wait wait_;

  // The massage under way, from the service or the action: its frame targets (guarded by monitor_mutex_).
  std::mutex monitor_mutex_;
  std::uint64_t monitored_command_ = 0;
  std::vector<ArmTargets::FrameTarget> frame_targets_;
  bool whole_path_ = false;  ///< a stroke: every frame of its path is watched, not only the target's

  // The action (guarded by mutex_; the server has its own lock, taken after mutex_, never before it).
  std::mutex mutex_;
  std::unique_ptr<Server> server_;
  std::uint64_t goal_command_ = 0;       ///< the active goal's massage command (0: none)
  bool stop_sent_ = false;               ///< the active goal's massage was told to stop
  std::vector<std::string> goal_names_;  ///< its targets' names
  massage_cell::MassageFeedback last_feedback_;
  ros::WallTime last_feedback_time_;

  ros::ServiceServer service_;
  ros::WallTimer timer_;
};

}  // namespace massage_cell::nodes
