// The simulated axis' mechanics (see sim_mechanics.h).
#include "massage_cell/can/sim_mechanics.h"

#include <algorithm>
#include <cmath>

namespace massage_cell::can {

SimMechanics::SimMechanics(const SimDriveSettings::Mechanics& mechanics, double rated_torque)
    : m_(mechanics), rated_torque_(rated_torque), rng_(mechanics.seed) {}

double SimMechanics::step(double dx, double v, double a, double external) {
  if (!enabled()) return 0.0;
  // Dahl: over a travel dx the friction moves toward +-coulomb (against the motion) with the pre-sliding stiffness;
  // solved exactly for the step (an explicit step would overshoot at 1 ms and 50 mm/s).
  if (dx != 0.0 && m_.coulomb_friction > 0.0) {
    const double sliding = dx > 0.0 ? m_.coulomb_friction : -m_.coulomb_friction;
    friction_ = sliding + (friction_ - sliding) * std::exp(-m_.friction_stiffness * std::abs(dx) / m_.coulomb_friction);
  }
  motor_force_ = m_.moving_mass * (a + m_.gravity) + friction_ + m_.viscous_friction * v - external;
  return motor_force_ * m_.screw_lead / (2.0 * M_PI * m_.screw_efficiency);
}

std::int16_t SimMechanics::torquePerMille(double torque) {
  if (!enabled()) return 0;
  double permille = 1000.0 * torque / rated_torque_;
  if (m_.torque_noise > 0.0) permille += m_.torque_noise * noise_(rng_);
  return static_cast<std::int16_t>(std::clamp(std::round(permille), -32768.0, 32767.0));
}

}  // namespace massage_cell::can
