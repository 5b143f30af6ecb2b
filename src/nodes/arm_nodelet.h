// The `massage_cell/arm` nodelet: the three-axis massage arm (issue 7), a
// thin ROS wrapper of the ROS-free controller (include/massage_cell/arm/):
//  - `can_interface`: "sim" runs simulated CiA 402 drives on an in-process
//    virtual bus (arm::SimCell, the default on machines without CAN), any
//    other name opens that SocketCAN interface (can0); when it cannot be
//    opened (missing, down) the node logs one error naming it and the
//    reason, keeps running (~state mode fault, bus down; diagnostics ERROR),
//    refuses every command with that reason, and retries every 2 s;
//  - `realtime_priority` (> 0: the master's SYNC / poll thread, which runs
//    the controller's cycle, and the simulated drives' threads under
//    SCHED_FIFO at that priority; 0: normal scheduling) and `lock_memory`
//    (mlockall), set up by the library (Controller::startThread,
//    SimCell::start; can/realtime.h); a refusal is logged once with the fix
//    and the node runs with normal scheduling; diagnostics report which;
//  - publishes `joint_states` (for robot_state_publisher and urdf/), `~state`
//    (massage_cell/ArmState, with the tool's force), `~wrench`
//    (geometry_msgs/WrenchStamped in tool_frame, while the force is known)
//    and diagnostics;
//  - services `~home`, `~stop`, `~reset_fault` (std_srvs/Trigger), `~move_to`
//    (massage_cell/MoveTo: a PointStamped in any frame, tf2 into the arm base
//    frame) and `~massage` (massage_cell/Massage: acupoint frames and points,
//    refused with a message when outside the envelope, too deep for the
//    region, in an unknown frame or stale), the same massage also as the
//    actionlib action `~massage` (massage_cell/MassageAction: feedback,
//    cancel; ArmMassage, arm_action.h);
//  - topic `~ft_sensor` (geometry_msgs/WrenchStamped): a load cell's / F/T
//    sensor's force on the tool; while it reports (every 50 ms at least) it is
//    the tool's force, in place of the Z drive's estimate;
//  - `sim` only: topic `~sim/skin` (massage_cell/AcupointArray: the session's
//    true acupoints, remapped by cell.launch) is the skin of the back under
//    the simulated tool (arm::SkinPoints; default tissue), so presses by force
//    meet a body;
//  - topic `~estop` (std_msgs/Bool: true latches the e-stop; false releases
//    the input, the latch holds until ~reset_fault);
//  - in sim mode `~sim/inject_fault` (std_msgs/String "Y 0x2310": that axis's
//    drive faults with that EMCY code), the simulator's test hook.
// Service calls block until their command ends (or command_timeout), so they
// run on the nodelet's own callback queue with several threads; a timer at
// publish_rate publishes and feeds the controller's command watchdog;
// ArmMassage's timer checks the acupoint frame of the press under way (lost
// or stale -> the controller retracts) and runs the action.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "arm_action.h"
#include "arm_interface.h"
#include "massage_cell/MoveTo.h"
#include "massage_cell/arm/controller.h"
#include "massage_cell/arm/sim_cell.h"
#include "massage_cell/can/realtime.h"
#include "massage_cell/can/socketcan_bus.h"

namespace massage_cell::nodes {

class ArmNodelet : public nodelet::Nodelet {
 public:
  ArmNodelet() = default;
  ~ArmNodelet() override;

 private:
  void onInit() override;
  void readParameters();
  /// The controller, or null while the CAN interface is not open.
  arm::Controller* controller() const { return controller_.load(); }
  /// Opens the SocketCAN interface and starts the controller on it; false (logged once per reason) when it cannot.
  bool openInterface();
  /// Logs the log lines of `c` through ROS and starts it (threads with the real-time options).
  void startController(arm::Controller& c);
  /// Why commands are refused while there is no controller.
  std::string unavailable() const;
  /// Refuses the service call `what` when there is no controller (message in `message`).
  arm::Controller* available(const std::string& what, std::string* message) const;
  void onTimer(const ros::WallTimerEvent& event);
  void publishState();
  void estopCb(const std_msgs::BoolConstPtr& msg);
  void sensorCb(const geometry_msgs::WrenchStampedConstPtr& msg);
  void surfaceCb(const sensor_msgs::PointCloud2ConstPtr& msg);
  void skinCb(const massage_cell::AcupointArrayConstPtr& msg);
  void injectFaultCb(const std_msgs::StringConstPtr& msg);
  bool home(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool stop(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool resetFault(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool moveTo(massage_cell::MoveTo::Request& req, massage_cell::MoveTo::Response& res);
  /// Waits for the command: its success, and its message in `message`.
  bool wait(const arm::Accepted& accepted, std::string* message);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  // Parameters.
  std::string config_path_;
  arm::NodeOptions options_;  ///< config/arm.yaml's node: section under the private parameters

  // The controller and what it runs on.
  std::unique_ptr<arm::SimCell> sim_;
  std::unique_ptr<can::SocketCanBus> socket_bus_;
  std::unique_ptr<arm::Controller> real_controller_;
  std::atomic<arm::Controller*> controller_{nullptr};
  arm::ArmConfig config_;
  std::atomic<bool> estop_input_{false};  ///< applied to a controller started later
  mutable std::mutex status_mutex_;       ///< guards the three below
  std::string open_error_;                ///< why the CAN interface is not open ("" when it is)
  ros::WallTime next_open_;
  can::RealtimeStatus realtime_;

  // ROS.
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  ros::Publisher joint_pub_, state_pub_, wrench_pub_;
  ros::Subscriber estop_sub_, fault_sub_, sensor_sub_, skin_sub_, surface_sub_;
  std::shared_ptr<arm::SkinPoints> sim_skin_;  ///< sim: the back the simulated drives press (~sim/skin)
  ros::ServiceServer home_srv_, stop_srv_, reset_srv_, move_srv_;
  ros::WallTimer timer_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<ArmTargets> targets_;  ///< the services' targets through tf_buffer_
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  std::unique_ptr<ArmMassage> massage_;  ///< ~massage, the service and the action (arm_action.h)
};

}  // namespace massage_cell::nodes
