// The arm node's ROS side of the arm library: its state as messages, and its service requests' targets resolved
// through tf into the arm base frame and checked against the body the arm knows (the acupoints' tf frames).
#pragma once

#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>

#include "massage_cell/AcupointArray.h"
#include "massage_cell/ArmState.h"
#include "massage_cell/Massage.h"
#include "massage_cell/MassageGoal.h"
#include "massage_cell/arm/controller.h"
#include "massage_cell/arm/node_options.h"

namespace massage_cell::nodes {

/// ~state of `status` (in `base_frame`, stamped `stamp`).
massage_cell::ArmState armStateMsg(const arm::ArmStatus& status, const std::string& base_frame, const ros::Time& stamp);

/// ~wrench: the tool's force (ArmStatus::force, + z: the body pushing the tool up) in `tool_frame`.
geometry_msgs::WrenchStamped wrenchMsg(const arm::ArmStatus& status, const std::string& tool_frame,
                                       const ros::Time& stamp);

/// joint_states of `status` (the URDF's joint names from `config`).
sensor_msgs::JointState jointStateMsg(const arm::ArmStatus& status, const arm::ArmConfig& config,
                                      const ros::Time& stamp);

/// The arm's diagnostics: its health (arm::health) as the summary, then its mode, e-stop, bus, axes and tool.
void reportArm(const arm::ArmStatus& status, const arm::NodeOptions& options, const can::RealtimeStatus& realtime,
               diagnostic_updater::DiagnosticStatusWrapper* out);

/// Service targets into the arm base frame. Holds references: `tf`, `options` and `config` outlive it.
class ArmTargets {
 public:
  /// A target of a massage that is a tf frame, monitored while it is pressed: (target index, frame).
  using FrameTarget = std::pair<int, std::string>;

  ArmTargets(const tf2_ros::Buffer& tf, const arm::NodeOptions& options, const arm::ArmConfig& config)
      : tf_(tf), options_(options), config_(config) {}

  /// The transform base_frame <- `frame` at `stamp` (0: the latest), no older than max_target_age; false with the
  /// reason in `error`.
  bool lookup(const std::string& frame, const ros::Time& stamp, geometry_msgs::TransformStamped* out,
              std::string* error) const;

  /// The skin as the arm knows it, in base_frame: every current acupoint frame, and stereo's surface (~surface) if
  /// it is no older than surface_max_age.
  arm::BodySurface body() const;
  /// ~surface: stereo's confident surface (x y z in any frame tf connects to base_frame; the latest transform: the
  /// camera is fixed) binned into the body's height grid: empty, or why it cannot be used.
  std::string setSurface(const sensor_msgs::PointCloud2& cloud);

  /// ~move_to's goal in base_frame for a tool now at `tool`: "" or the refusal (unknown or stale frame, a path into
  /// the body).
  std::string moveGoal(const geometry_msgs::PointStamped& target, const Eigen::Vector3d& tool,
                       Eigen::Vector3d* goal) const;

  /// ~ft_sensor: the force a load cell or F/T sensor reports (the force on the tool, in the message's frame) along
  /// +z of the base frame (tf2: the sensor's rotation; the latest transform). Empty, or why it cannot be used (no
  /// frame, unknown frame, not finite).
  std::string sensorForce(const geometry_msgs::WrenchStamped& wrench, double* force_z) const;
  /// The valid points of `acupoints` in the base frame (tf2 at their stamp, else the latest): empty, or why not.
  std::string pointsInBase(const massage_cell::AcupointArray& acupoints, std::vector<Eigen::Vector3d>* out) const;
  /// ~massage's request with every target resolved and checked, and its targets that are tf frames: "" or why the
  /// request is refused. `Request`: the service's massage_cell::Massage::Request or the action's
  /// massage_cell::MassageGoal (the same fields; arm_interface.cpp instantiates both).
  template <class Request>
  std::string pressRequest(const Request& req, arm::PressRequest* press, std::vector<FrameTarget>* frames) const;

 private:
  /// Why `frame` is not there, beyond tf's "unknown": a model's acupoint CECT has no valid fix for, a name that is
  /// not an acupoint, an acupoint named without the prefix; empty for any other frame.
  std::string whyNoFrame(const std::string& frame) const;
  template <class Request>
  std::string pressTarget(const Request& req, std::size_t i, const arm::BodySurface& body,
                          arm::PressTarget* target) const;

  const tf2_ros::Buffer& tf_;
  const arm::NodeOptions& options_;
  const arm::ArmConfig& config_;
  mutable std::mutex surface_mutex_;  ///< guards the two below (~surface's callback, the services' threads)
  arm::HeightGrid surface_;
  ros::Time surface_stamp_;
};

}  // namespace massage_cell::nodes
