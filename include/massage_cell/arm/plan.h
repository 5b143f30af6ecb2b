// Motion plans of the arm, ROS-free and CAN-free (so they are unit-tested on
// their own): the envelope / joint-limit check of a tool position, and the
// press routine expanded into steps. A press over one target:
//   travel at the safe height over the approach point -> down to the
//   approach point (target + approach_height * n) -> [descend along -n to
//   target - depth * n -> hold (knead: circles in the tangent plane at
//   depth) -> retract to the approach point] x repeats -> up to the safe height,
// n being the outward surface normal (default +z: a vertical press). A
// stroke (by force) takes the targets as one path: over its first point,
// down to the approach point, then a press by force that glides through
// every point in order (force_press.h) and backs off over the last, up to the
// travel height; x repeats. Every
// point a plan visits is inside the workspace envelope and the joint limits,
// and no point is deeper than the target's region allows — or the plan is
// refused with a message naming the target and the problem.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "massage_cell/arm/config.h"

namespace massage_cell::arm {

enum class Technique { kPress, kKnead, kStroke };
const char* toString(Technique t);

/// One surface point to press, in the arm base frame.
struct PressTarget {
  std::string name;                                   ///< for messages (acupoint name, or "point 2")
  std::string region;                                 ///< region key (config regions); empty: the default region
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< on the skin, m
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< outward surface normal
};

struct PressRequest {
  std::vector<PressTarget> targets;  ///< pressed in this order
  Technique technique = Technique::kPress;
  std::optional<PressConfig::Mode> mode;  ///< by force or to a depth; unset: the configuration's press.mode
  double force = 0.0;                     ///< N to hold (force mode); 0: each region's default force
  double depth = 0.0;                     ///< m past the surface point (depth mode); 0: each region's default depth
  double hold = -1.0;                     ///< s at depth; < 0: config default
  double speed = 0.0;                     ///< m/s approach / descent (a stroke: along its path); 0: config default
  int repeats = 1;                        ///< presses per target
};

/// A massage request's settings as a service call carries them (its targets are resolved separately).
struct MassageFields {
  std::size_t targets = 0;  ///< frames + points
  std::size_t regions = 0;  ///< entries of the per-target regions (0: none given)
  std::size_t normals = 0;  ///< entries of the per-target normals (0: none given)
  std::string technique;    ///< "" or "press", "knead", "stroke"
  std::string mode;         ///< "" (the configuration's), "force" or "depth"
  double force = 0.0;       ///< as PressRequest::force
  double depth = 0.0;       ///< as PressRequest::depth
  double hold = 0.0;        ///< s; 0: the default; < 0: none
  double speed = 0.0;       ///< as PressRequest::speed
  int repeats = 0;          ///< 0: once
};

/// `out`'s technique, depth, hold, speed and repeats from `fields` (its targets stay): empty, or why the request is
/// refused (no target, more than press.max_targets, a region or normal count that does not match, an unknown
/// technique, a hold that is not finite).
std::string pressSettings(const ArmConfig& config, const MassageFields& fields, PressRequest* out);

/// One step of a plan.
struct Step {
  /// kForcePress: from the approach point (tool), a press by force (force_press.h), back to it.
  enum class Kind { kMove, kHold, kForcePress };
  Kind kind = Kind::kMove;
  Eigen::Vector3d tool = Eigen::Vector3d::Zero();  ///< goal of a move (tool tip, arm base frame)
  double speed = 0.0;                              ///< m/s along the path (0: joint limits only)
  double accel = 0.0;                              ///< m/s^2 along the path (0: joint limits only)
  double duration = 0.0;                           ///< s, of a hold
  std::string label;                               ///< "press 1/2 BL23_L: descend"
  bool contact = false;                            ///< the tool is below the approach point: an abort retracts first
  bool retract = false;                            ///< part of a retraction (never aborted, not watchdog-guarded)
  int target = -1;                                 ///< index into the request's targets
  bool press_done = false;  ///< finishing this step completes one press (the retract after a hold)
  Eigen::Vector3d retreat = Eigen::Vector3d::Zero();  ///< where an abort during a contact step retracts to
  bool force_calibration = false;  ///< a free move after homing whose torque samples identify the Z axis' baseline
  /// A contact step of a press to a depth: the region's force cap (N; 0: none), which the tool's force, when known,
  /// may not pass (the controller then retracts).
  double force_cap = 0.0;
  ForcePressGoal force;  ///< kForcePress: what to press and its limits
};

/// Empty when `tool` is inside the workspace envelope and its joints inside
/// the joint limits; otherwise why not ("(0.9, 0.1, 0.2) m is outside the
/// workspace envelope: x above 0.76 m").
std::string checkTool(const ArmConfig& config, const Eigen::Vector3d& tool);

/// Expands a massage request into steps starting from tool position `from`;
/// returns the refusal (empty when planned).
std::string planMassage(const ArmConfig& config, const Eigen::Vector3d& from, const PressRequest& request,
                        std::vector<Step>* steps);

/// The steps that take the tool out of contact from a contact step: back to
/// its retreat point, then up to the travel height.
std::vector<Step> retractSteps(const ArmConfig& config, const Step& from_step);

/// A dense surface seen by stereo (the hbds node's `surface`: left-right-confirmed points of the body and the table),
/// binned into square cells of the arm base frame's (x, y); each cell holds its highest point.
class HeightGrid {
 public:
  HeightGrid() = default;
  /// `points` in the base frame, cells of `cell` m (> 0). Points not finite or whose (x, y) lie outside `lo`..`hi`
  /// (where the tool can go: a far point would make the grid as large as the distance) are skipped.
  HeightGrid(const std::vector<Eigen::Vector3d>& points, double cell, const Eigen::Vector2d& lo,
             const Eigen::Vector2d& hi);
  bool empty() const { return z_.empty(); }
  /// The highest point in the cell of (x, y) and its eight neighbours (what lies within a cell of it, whichever side
  /// of a cell boundary), or nullopt when none holds one.
  std::optional<double> heightAt(double x, double y) const;

 private:
  double cell_ = 0.01, x0_ = 0.0, y0_ = 0.0;
  int nx_ = 0, ny_ = 0;
  std::vector<float> z_;  ///< ny_ x nx_, NaN: no point
};

/// What the arm knows of the body's surface in the arm base frame: the acupoints' points (the arm node: their tf
/// frames), the skin at (x, y) being the z of the nearest one within BodyConfig::radius; and, where stereo sees it,
/// the dense surface.
struct BodySurface {
  std::vector<Eigen::Vector3d> points;
  HeightGrid dense;
  /// The skin's z under (x, y) from the acupoints, or nullopt when no point lies within `radius`.
  std::optional<double> heightAt(double x, double y, double radius) const;
};

/// Empty when the straight line from `from` to `to` keeps out of the body:
/// wherever an acupoint knows the surface the tool stays at most `max_depth` below it, wherever stereo's dense
/// surface does at most `max_depth` + BodyConfig::surface_tolerance (its depth error on skin); where neither
/// does, no lower than BodyConfig::safe_height (or than `from`, when
/// the tool is already lower: it may move at its height or up). Otherwise why
/// not ("the target (0.563, 0.211, 0.118) m is 49.0 mm below the body's surface
/// (limit 2.0 mm)").
std::string checkBodyClearance(const ArmConfig& config, const BodySurface& body, const Eigen::Vector3d& from,
                               const Eigen::Vector3d& to, double max_depth);

/// The fastest a straight line of the tool can go within the joints'
/// velocity limits (all three at their limits: their norm), m/s.
double maxLineSpeed(const ArmConfig& config);

/// How far `p` lies across the skin (x, y) from the polyline through `path` (a stroke's), m; infinite for an empty
/// path.
double distanceFromPath(const Eigen::Vector2d& p, const std::vector<Eigen::Vector3d>& path);

/// Formats a point "(x, y, z) m" with mm resolution.
std::string formatPoint(const Eigen::Vector3d& p);

}  // namespace massage_cell::arm
