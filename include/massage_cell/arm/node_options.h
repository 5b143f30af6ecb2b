// The arm node's own settings: config/arm.yaml's `node:` section, which the node's private parameters override.
#pragma once

#include <string>

#include "massage_cell/arm/config.h"
#include "massage_cell/can/realtime.h"

namespace massage_cell::arm {

struct NodeOptions {
  std::string can_interface = "sim";          ///< "sim": simulated drives; else a SocketCAN interface (can0)
  std::string base_frame = "arm_base_link";   ///< the frame targets are expressed in
  std::string tool_frame = "tool_tip";        ///< ~wrench's frame (the URDF's tool tip)
  double publish_rate = 50.0;                 ///< Hz of ~state, joint_states and the command watchdog
  double max_target_age = 0.5;                ///< s: an older target transform is stale
  double tf_timeout = 0.2;                    ///< s a target lookup waits for its transform
  std::string acupoint_prefix = "acupoint/";  ///< tf frames of the body's acupoints
  double command_timeout = 300.0;             ///< s a service call waits for its command's result
  double surface_max_age = 5.0;               ///< s: ~surface (stereo's dense surface) older than this is not used
  can::RealtimeOptions realtime;              ///< realtime_priority, lock_memory
};

/// Calls `visit(name, member)` for every option: the names are the YAML keys and the node's private parameters.
template <class Visit>
void visitOptions(NodeOptions& o, Visit&& visit) {
  visit("can_interface", o.can_interface);
  visit("base_frame", o.base_frame);
  visit("tool_frame", o.tool_frame);
  visit("publish_rate", o.publish_rate);
  visit("max_target_age", o.max_target_age);
  visit("tf_timeout", o.tf_timeout);
  visit("acupoint_prefix", o.acupoint_prefix);
  visit("command_timeout", o.command_timeout);
  visit("surface_max_age", o.surface_max_age);
  visit("realtime_priority", o.realtime.priority);
  visit("lock_memory", o.realtime.lock_memory);
}

/// The defaults overridden by the `node:` section of the YAML file at `path` (none: the defaults). Throws
/// ArmConfigError naming the file and the key.
NodeOptions loadNodeOptions(const std::string& path);

/// Throws ArmConfigError naming the first unusable option and what it must be.
void validate(const NodeOptions& options);

}  // namespace massage_cell::arm
