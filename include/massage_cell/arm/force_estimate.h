// The tool's axial force from the Z drive's torque (CiA 402 0x6077), ROS-free.
//
// The motor's force along the axis (through the ball screw: F = 2 pi eta T /
// lead) carries the moving mass (gravity and acceleration), the friction of
// nut, seals and guides, and whatever pushes on the tool. The estimate
// subtracts a baseline of the first two - identified from free motion
// (identifyBaseline: the arm's homing moves) - and what is left is the
// external force: + when the body pushes the tool up. Friction is tracked as
// the drive's would be (a Dahl model: it keeps its last value at a
// standstill), and re-zeroing just before a contact (the tool still, in the
// air) removes what the baseline got wrong then. What remains is the
// estimate's error, measured by arm_bench --force on the simulated drives
// (docs/arm.md "Force from the drives").
#pragma once

#include <string>
#include <vector>

namespace massage_cell::arm {

/// The nominal drive train (config/arm.yaml force:, the motor's rated torque from config/can_axes.yaml).
struct ScrewDrive {
  double lead = 0.0025;       ///< m per revolution
  double efficiency = 0.9;    ///< ball screw, forward
  double rated_torque = 0.0;  ///< N m: 0x6077's 1000 per mille
  /// The motor's force along the axis for a torque in per mille of the rated torque, N.
  double force(double torque_permille) const;
};

/// What the motor carries without contact: F = mass (a + gravity) + friction + viscous v, with the friction a Dahl
/// model of `coulomb` and `friction_stiffness` (the drive's own; sim_mechanics.h).
struct AxisBaseline {
  double mass = 0.0;                ///< kg
  double gravity = 9.81;            ///< m/s^2 toward lower positions (known: the axis is vertical)
  double coulomb = 0.0;             ///< N
  double viscous = 0.0;             ///< N s/m
  double friction_stiffness = 1e6;  ///< N/m (nominal: it only sets how fast the friction turns over)
};

/// One cycle of free motion (nothing touches the tool): the motor's force, the axis' velocity and acceleration.
struct FreeMotionSample {
  double motor_force = 0.0;   ///< N (ScrewDrive::force)
  double velocity = 0.0;      ///< m/s
  double acceleration = 0.0;  ///< m/s^2
};

/// Fits mass, coulomb and viscous friction to free-motion samples by least squares (samples below `min_speed` are
/// left out: there the friction's sign is not known). Needs motion both ways at two or more speeds; `problem` says
/// what is missing otherwise (and the returned baseline is `prior`).
AxisBaseline identifyBaseline(const std::vector<FreeMotionSample>& samples, const AxisBaseline& prior,
                              std::string* problem, double min_speed = 0.002);

class AxialForceEstimate {
 public:
  AxialForceEstimate(ScrewDrive drive, AxisBaseline baseline, double filter_time_constant = 0.02);

  /// One cycle of `dt` s: the drive's torque (per mille), the axis' position (m), velocity (m/s) and acceleration.
  /// Returns the (filtered) external force, N: + when something pushes the tool toward higher positions.
  double update(double torque_permille, double position, double velocity, double acceleration, double dt);
  /// The external force now, N (NaN before the first update).
  double force() const { return force_; }
  /// The raw (unfiltered, not zeroed) external force of the last update, N.
  double raw() const { return raw_; }
  /// Nothing touches the tool now: what the estimate reads (filtered) is taken as its zero from here on.
  void rezero();
  double offset() const { return offset_; }
  /// A new baseline (identified): the friction's state is rescaled to it, the filter restarts (a rezero() then takes
  /// effect once it has settled; the force is unknown, NaN, until then).
  void setBaseline(const AxisBaseline& baseline);
  const AxisBaseline& baseline() const { return baseline_; }
  const ScrewDrive& drive() const { return drive_; }
  /// The motor force of the last update, N (for identification samples).
  double motorForce() const { return motor_force_; }

 private:
  ScrewDrive drive_;
  AxisBaseline baseline_;
  double tau_;
  double friction_ = 0.0;
  double last_position_ = 0.0;
  bool started_ = false;
  /// A rezero() asked while the filter restarts: taken after this many more updates (5 cycles: 2.5 filter time
  /// constants at 100 Hz, the noise averaged down).
  static constexpr int kRezeroUpdates = 5;
  int rezero_updates_ = 0;
  double raw_ = 0.0, filtered_ = 0.0, force_ = 0.0, offset_ = 0.0, motor_force_ = 0.0;
};

}  // namespace massage_cell::arm
