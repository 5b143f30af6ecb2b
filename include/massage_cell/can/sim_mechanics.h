// What a simulated drive's motor feels (SimDrive's torque actual, 0x6077): the
// axis' moving mass and gravity, its friction, and an external force on the
// axis (a body under the tool), turned into motor torque through the ball
// screw, with the drive's noise and per-mille quantisation. The position
// follows the demand (a servo far stiffer than what it pushes), so the torque
// is what carries the load. ROS-free, deterministic for a seed.
//
// Friction is a Dahl model: sliding, it opposes the motion with
// coulomb_friction (+ viscous); at a standstill it keeps the value it last had
// (the pre-sliding state), so the torque of a tool held still depends on how
// it got there - the reason a static force read from a ball screw's motor
// current is uncertain by the friction (massage_forces.md: 0.1 N m of drag is
// ~57 N at 10 mm lead).
#pragma once

#include <cstdint>
#include <random>

#include "massage_cell/can/config.h"

namespace massage_cell::can {

class SimMechanics {
 public:
  /// `rated_torque`: N m, 0x6076 (the per-mille scale). With mechanics.screw_lead 0 the axis has no torque model.
  SimMechanics(const SimDriveSettings::Mechanics& mechanics, double rated_torque);

  bool enabled() const { return m_.screw_lead > 0.0 && rated_torque_ > 0.0; }
  /// One integration step: the axis moved `dx` m (velocity `v` m/s, acceleration `a` m/s^2) with `external` N acting
  /// on it (+: toward higher positions; a body pushing the tool up on a vertical axis). Updates the friction and
  /// returns the motor torque, N m (+: toward higher positions).
  double step(double dx, double v, double a, double external);
  /// The motor force along the axis of the last step, N (what the torque carries).
  double motorForce() const { return motor_force_; }
  /// The friction force of the last step, N (+: the axis resists motion toward higher positions).
  double friction() const { return friction_; }
  /// 0x6077 for `torque`: per mille of the rated torque, plus the noise, rounded, within INT16.
  std::int16_t torquePerMille(double torque);
  /// A power cycle: the friction's pre-sliding state is forgotten.
  void reset() { friction_ = 0.0; }

 private:
  SimDriveSettings::Mechanics m_;
  double rated_torque_;
  double friction_ = 0.0;
  double motor_force_ = 0.0;
  std::mt19937 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
};

}  // namespace massage_cell::can
