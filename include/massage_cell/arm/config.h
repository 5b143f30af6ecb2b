// Configuration of the three-axis massage arm (issue 7): which CAN axes are
// the gantry's x / y / z joints, their soft limits (position, velocity,
// acceleration), the Cartesian workspace envelope of the tool tip, the tool
// offset, the command watchdog, the press routine and the per-region depth
// limits (shared/reference/back_acupoints.md, safety notes). Loaded from
// config/arm.yaml (which documents every field) with yaml-cpp; a problem is
// an ArmConfigError naming the file and the field, e.g.
// "config/arm.yaml: joints.Z.max: 0.35 m is beyond the drive's software limit 0.30 m".
//
// Frames and units: SI (metres, seconds), REP 103. The arm base frame
// (URDF link arm_base_link) has x along the gantry's X axis, y along Y, z up;
// joint q = (qx, qy, qz) puts the tool tip at q + tool_offset.
#pragma once

#include <algorithm>
#include <array>
#include <map>
#include <stdexcept>
#include <string>

#include <Eigen/Core>

#include "massage_cell/arm/force_press.h"
#include "massage_cell/can/config.h"

namespace massage_cell::arm {

class ArmConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Soft limits of one prismatic joint.
struct JointLimits {
  double min = 0.0;                ///< m
  double max = 0.0;                ///< m
  double max_velocity = 0.05;      ///< m/s
  double max_acceleration = 0.25;  ///< m/s^2
};

/// Press limits of one body region (back_acupoints.md, safety notes; massage_forces.md for the forces).
struct RegionLimits {
  double max_depth = 0.002;      ///< m past the surface point along the normal (depth mode)
  double default_depth = 0.001;  ///< m, used when a request gives no depth
  // Force mode (docs/arm.md "Forces and limits per region"):
  double default_force = 0.0;    ///< N, used when a request gives no force
  double max_force = 0.0;        ///< N, the most a press may reach
  double max_pressure = 0.0;     ///< N/cm^2 under the tool (press.contact_area): the force cap is the lower of both
  double max_indentation = 0.0;  ///< m past the contact point: a second guard
  /// The force a press in this region may not pass: max_force or max_pressure x the tool's contact area.
  double forceCap(double contact_area_cm2) const { return std::min(max_force, max_pressure * contact_area_cm2); }
};

/// The press routine: approach above the target, descend along the surface
/// normal to the depth, hold, retract; travel between targets at a safe height.
struct PressConfig {
  double approach_height = 0.03;  ///< m above the surface point along the normal
  /// The last approach_clearance m down to the approach point are at approach_speed (m/s): a body higher than vision
  /// saw is met slowly (the force guard stops it: force_control.move_guard); above them the joints' limits.
  double approach_clearance = 0.03;
  double approach_speed = 0.02;
  double travel_height = 0.28;  ///< m, tool-tip z in the arm base frame for moves between targets
  double speed = 0.01;          ///< m/s, default approach / descent speed
  double max_speed = 0.03;      ///< m/s, the most a request may ask for
  double acceleration = 0.1;    ///< m/s^2 along the press path
  double retract_speed = 0.02;  ///< m/s
  double hold = 2.0;            ///< s, default hold time at depth
  double max_hold = 30.0;       ///< s
  int max_repeats = 10;         ///< presses per target
  int max_targets = 50;         ///< targets in one request
  /// After an e-stop with the tool in contact: back off along the press line to
  /// the approach point at retract_speed, then stay stopped (false: stop in place).
  bool estop_release = true;
  double max_normal_tilt = 0.7854;  ///< rad between the outward normal and +z (config: degrees)
  /// How a press is controlled: kForce (to a force, the Z drive's torque; needs force:) or kDepth (to a depth past
  /// the skin point vision gave). Config `mode: force | depth`; a request may ask for either.
  enum class Mode { kDepth, kForce } mode = Mode::kDepth;
  double contact_area = 2.0;    ///< cm^2 the tool touches (a thumb's pad: 1.5-3 cm^2)
  double knead_radius = 0.004;  ///< m, circle in the tangent plane while kneading
  double knead_period = 1.0;    ///< s per circle
  int knead_segments = 8;       ///< straight segments per circle
};

/// Keeping out of the body (see checkBodyClearance in plan.h).
struct BodyConfig {
  double safe_height = 0.25;   ///< m, tool z: where no body surface is known, motion stays above this
  double radius = 0.05;        ///< m: a surface point speaks for the skin this far around it (in x, y)
  double surface_cell = 0.01;  ///< m: stereo's dense surface binned into cells this wide (HeightGrid)
  /// m: how far a target may lie below stereo's dense surface beyond the region's depth limit: the surface's depth
  /// error on skin (the bundled recording's acupoint depth: median 9 mm, docs/stereo.md)
  double surface_tolerance = 0.01;
};

/// Force from the Z drive's torque (force_estimate.h, tool_force.h): the nominal drive train, a prior of what the
/// axis carries without contact (identified when the arm homes: the calibration moves) and the estimate's filter.
/// Needs the Z axis' torque_pdo and rated_torque (config/can_axes.yaml).
struct ForceConfig {
  bool enabled = false;                ///< the config has a force: section
  double screw_lead = 0.0025;          ///< m per motor revolution (nominal)
  double screw_efficiency = 0.9;       ///< nominal
  double mass = 0.0;                   ///< kg, prior (identified at homing)
  double coulomb_friction = 0.0;       ///< N, prior
  double viscous_friction = 0.0;       ///< N s/m, prior
  double friction_stiffness = 1e6;     ///< N/m, nominal (Dahl)
  double filter_time_constant = 0.02;  ///< s
  double calibration_travel = 0.02;    ///< m: Z goes down and back up this far after homing, at each speed
  std::vector<double> calibration_speeds{0.04, 0.015};  ///< m/s (two or more: viscous and coulomb friction apart)
};

struct ArmConfig {
  std::string source;                                    ///< file it came from (for messages)
  std::string can_config_path;                           ///< resolved path of the CAN configuration
  can::CanConfig can;                                    ///< loaded from can_config_path
  std::array<std::string, 3> axis_names{"X", "Y", "Z"};  ///< CAN axis of the x, y, z joint
  std::array<std::string, 3> joint_names{"arm_x_joint", "arm_y_joint", "arm_z_joint"};  ///< URDF joints
  std::array<JointLimits, 3> joints;
  Eigen::Vector3d tool_offset = Eigen::Vector3d::Zero();    ///< m, tool tip - joint position (arm base frame)
  Eigen::Vector3d workspace_min = Eigen::Vector3d::Zero();  ///< m, envelope of the tool tip (arm base frame)
  Eigen::Vector3d workspace_max = Eigen::Vector3d::Zero();
  double watchdog_timeout = 1.0;     ///< s without keepAlive() that ends a move or massage (0: off)
  double bringup_timeout = 5.0;      ///< s for every node to become operational
  double position_tolerance = 1e-4;  ///< m: a move that ends farther from its goal is a fault
  PressConfig press;
  BodyConfig body;
  ForceConfig force;
  ForceControlConfig force_control;
  std::map<std::string, RegionLimits> regions;
  std::string default_region = "midline";  ///< for targets of no known region (the most conservative)
  std::string acupoints_path;              ///< resolved path of the acupoint model (name -> region); may be empty
  std::map<std::string, std::string> acupoint_regions;  ///< acupoint name -> region, from acupoints_path

  /// Tool tip of joint position q, and the joint position of a tool tip.
  Eigen::Vector3d toolOf(const Eigen::Vector3d& q) const { return q + tool_offset; }
  Eigen::Vector3d jointsOf(const Eigen::Vector3d& tool) const { return tool - tool_offset; }
  /// The CAN axis configuration of joint i.
  const can::AxisConfig& axis(int i) const;
  /// Region limits of `region` (the default region's when unknown).
  const RegionLimits& limitsOf(const std::string& region) const;
  /// Region of an acupoint name ("BL23_L"); empty when the model does not know it.
  std::string regionOf(const std::string& acupoint) const;
};

/// Parses YAML text; relative paths in it are resolved against `base_dir`;
/// `source` names the text in messages. Throws ArmConfigError.
ArmConfig parseArmConfig(const std::string& yaml_text, const std::string& source, const std::string& base_dir);
/// Loads a file (relative paths in it are relative to its folder). Throws ArmConfigError.
ArmConfig loadArmConfig(const std::string& path);
/// Checks ranges, the envelope inside the joint limits, the joint limits
/// inside the drives' limits. Throws ArmConfigError.
void validate(const ArmConfig& config);
/// Reads `points: [{name, region}, ...]` of an acupoint model file
/// (config/acupoints.yaml). Throws ArmConfigError.
std::map<std::string, std::string> loadAcupointRegions(const std::string& path);

}  // namespace massage_cell::arm
