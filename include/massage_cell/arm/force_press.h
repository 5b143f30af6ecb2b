// A press by force, cycle by cycle, ROS-free and CAN-free: from the approach
// point above the skin the tool seeks the body at a slow speed, the force it
// reads over its first 0.25 s (the mean of the last 0.1 s, sliding) taken as
// its zero (more than the contact force there, the press stops: something
// touches the tool, or the force is off), until the force says it touches,
// body at a slow speed until the force says it touches, ramps the force up to the target, holds it while the
// back breathes under it (an admittance loop: the tool's height moves with the
// force error), ramps it down and backs off to where it started. The
// controller streams the z it returns to the Z drive (cyclic synchronous
// position) and feeds back the measured force (tool_force.h).
//
// The limits hold whatever was asked: a force above the press's cap (the
// region's force and pressure limits), an indentation past the region's
// guard, a force rising faster than max_force_rate (the tool hit something),
// no contact within no_contact_band below where vision put the skin, or a
// contact more than early_contact_band above it stop the press and back it
// off; the press then ends failed with the reason.
// abort() backs off the same way (a stop, the watchdog, a lost target).
//
// A stroke is a press whose hold glides: with a path (points on the skin,
// the first under the approach point) the tool, once at its force, moves
// along the path at the glide speed (accelerating and braking at
// glide_accel), its height still set by the force, with the skin's slope
// between the path's points (where vision put them) as feed-forward. The
// indentation guard then counts from the skin along the path (shifted by how
// far the contact point lay from where vision put the first point), not from
// one contact height.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace massage_cell::arm {

/// How the loop behaves (config/arm.yaml force_control:).
struct ForceControlConfig {
  double contact_force = 3.0;     ///< N: above this the tool touches
  double seek_speed = 0.005;      ///< m/s down from the approach point until contact
  double no_contact_band = 0.02;  ///< m below the expected skin without contact: the body is not there
  /// m above the expected skin: a contact higher up is not the skin where vision saw it (an arm, a pillow, a body
  /// moved, a force reading off) and stops the press instead of pressing there
  double early_contact_band = 0.015;
  double ramp_rate = 40.0;  ///< N/s of the force set-point, up and down
  /// The admittance loop, normalised by the tissue's local stiffness k (so soft and stiff backs respond alike): the
  /// tool moves at v = (ramp feed-forward + bandwidth e + integral ∫e) / k for a force error e. k is the power law's
  /// slope n F / x at the indentation x past the contact point, within [min_stiffness, max_stiffness].
  double bandwidth = 25.0;         ///< rad/s
  double integral = 156.0;         ///< 1/s^2 (bandwidth^2 / 4: critically damped; follows breathing)
  double tissue_exponent = 1.5;    ///< n of F = k x^n (sim_body.h's tissue; 1.2-1.5 published)
  double min_stiffness = 1000.0;   ///< N/m
  double max_stiffness = 40000.0;  ///< N/m
  double max_speed = 0.02;         ///< m/s the loop may move the tool
  double max_force_rate = 1000.0;  ///< N/s: a faster rise stops the press (a hit, not tissue)
  double release_speed = 0.01;     ///< m/s back to the approach point
  /// m/s backing off a press that failed (a limit, a stop): away from a client pushing up or a hit, faster than a
  /// back rises under a startle (arm_bench --force: 10 mm at 40 mm/s under a 45 N press went to 133 N backing off at
  /// release_speed)
  double escape_speed = 0.04;
  double stroke_speed = 0.015;  ///< m/s along a stroke's path (a request's 0)
  /// N: a massage's moves toward the body (travel, approach) meeting more stop and go straight up (the body is not
  /// where vision saw it); the controller's guard, with the force known
  double move_guard = 10.0;
  double glide_accel = 0.05;  ///< m/s^2 along a stroke's path, starting and braking
};

/// One press: where it starts and what it may do.
struct ForcePressGoal {
  double start_z = 0.0;        ///< m, the approach point's height (the tool is there, still, when it starts)
  double expected_skin_z = 0;  ///< m, where vision put the skin under the tool
  double force = 0.0;          ///< N to hold
  double max_force = 0.0;      ///< N: the cap (the region's force and pressure limits); above it the press stops
  double max_indentation = 0;  ///< m past the contact point: beyond it the press stops
  /// A stroke: the indentation guard at each point of `path` (its region's), m past the skin; along a leg the lower
  /// of its two ends. Empty: max_indentation everywhere.
  std::vector<double> path_max_indentation;
  double hold = 0.0;  ///< s at the force (a press; a stroke holds while it glides)
  /// A stroke: points on the skin (arm base frame; z where vision put the skin), the first under the approach point;
  /// empty: a press in place.
  std::vector<Eigen::Vector3d> path;
  double glide_speed = 0.0;  ///< m/s along the path
};

class ForcePress {
 public:
  enum class Phase { kSeek, kRamp, kHold, kGlide, kRelease, kBackOff, kDone, kFailed };

  ForcePress(const ForceControlConfig& config, const ForcePressGoal& goal);
  /// One cycle of `dt` s: the measured force (N, + pushing the tool up) and the tool's measured height (m). Returns
  /// the height to command (m).
  double update(double force, double z, double dt);
  /// Stop pressing: ramp nothing down, back off at escape_speed (straight up, to the approach height over the skin
  /// where the tool is); the press then ends failed with `why`.
  void abort(const std::string& why);

  Phase phase() const { return phase_; }
  bool finished() const { return phase_ == Phase::kDone || phase_ == Phase::kFailed; }
  /// Why it failed (or is backing off to fail); empty otherwise.
  const std::string& failure() const { return failure_; }
  /// The force set-point now, N (0 before contact).
  double setPoint() const { return set_point_; }
  /// The press's force cap (the region's force and pressure limits), N.
  double limit() const { return g_.max_force; }
  /// The press's zero, N: the force read in the air before the seek (0 until measured); update() acts on force - zero.
  double zero() const;
  /// Where contact was found (m; NaN before).
  double contactZ() const { return contact_z_; }
  /// Where the tool should be across the skin now (x, y; m): the path's first point until the glide, then along it.
  /// A press: its path is empty, (NaN, NaN).
  Eigen::Vector2d xy() const { return xy_; }
  /// How far along the path the glide has come (0..1; 0 for a press).
  double progress() const;
  /// Where backing off ends: the approach height over the skin vision gave under the tool (a press: start_z).
  double backOffZ() const;
  /// "seeking the skin", "ramping to 30 N", "holding 30 N", "releasing", "backing off: <why>".
  std::string describe() const;

 private:
  double admittance(double force, double z, double feed_forward, double dt);
  double localStiffness(double force, double z) const;
  std::string checkLimits(double force, double z, double dt);
  void fail(const std::string& why);
  /// Where vision put the skin under the tool now (the path's height at the current arc length), m.
  double expectedSkin() const;
  /// How deep the tool is past the skin as found at contact, m (0 before contact).
  double indentation(double z) const;
  /// The indentation guard where the tool is, m.
  double maxIndentation() const;
  /// The path's leg the tool is on: i, the leg from point i - 1 to i (a path has at least two points).
  std::size_t leg() const;
  /// One of the seek's first cycles, in the air, averaging the force once settled: whether the measuring goes on
  /// (false once the air's force is known, or the press failed: above contact_force in the air, none known, or
  /// above the cap at any cycle).
  bool measureAir(double force);
  /// One cycle along the path; returns how far the skin's expected height changed (m).
  double glide(double dt);

  ForceControlConfig c_;
  ForcePressGoal g_;
  Phase phase_ = Phase::kSeek;
  std::string failure_;
  double z_cmd_;
  double set_point_ = 0.0;
  double integral_ = 0.0;
  double contact_z_;
  double held_ = 0.0;
  int above_ = 0;   ///< cycles in a row the force has been above contact_force while seeking
  int rising_ = 0;  ///< cycles in a row the force has risen faster than max_force_rate
  double last_force_;
  std::vector<double> arc_;  ///< arc length (x, y) at each point of the path, m
  double s_ = 0.0;           ///< arc length reached, m
  double speed_ = 0.0;       ///< m/s along the path now
  double air_ = 0.0;         ///< N the force read in the air before the seek (its mean): the press's zero
  int air_cycles_ = 0;       ///< cycles of it measured
  Eigen::Vector2d xy_;
};

const char* toString(ForcePress::Phase phase);

}  // namespace massage_cell::arm
