// The tool's axial force from the drive's torque (see force_estimate.h).
#include "massage_cell/arm/force_estimate.h"

#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

namespace massage_cell::arm {

double ScrewDrive::force(double torque_permille) const {
  return 2.0 * M_PI * efficiency * (torque_permille / 1000.0 * rated_torque) / lead;
}

AxisBaseline identifyBaseline(const std::vector<FreeMotionSample>& samples, const AxisBaseline& prior,
                              std::string* problem, double min_speed) {
  // motor_force - mass gravity ... the regressors: [a + g, sign(v), v] -> [mass, coulomb, viscous].
  std::vector<const FreeMotionSample*> used;
  double slowest_up = INFINITY, fastest_up = 0.0, slowest_down = INFINITY, fastest_down = 0.0;
  for (const FreeMotionSample& s : samples) {
    if (!(std::abs(s.velocity) >= min_speed) || !std::isfinite(s.motor_force) || !std::isfinite(s.acceleration))
      continue;
    used.push_back(&s);
    const double speed = std::abs(s.velocity);
    double& slowest = s.velocity > 0 ? slowest_up : slowest_down;
    double& fastest = s.velocity > 0 ? fastest_up : fastest_down;
    slowest = std::min(slowest, speed), fastest = std::max(fastest, speed);
  }
  auto refuse = [&](const std::string& why) {
    if (problem) *problem = why;
    return prior;
  };
  if (used.size() < 10) return refuse("too few moving samples (" + std::to_string(used.size()) + ", need 10)");
  if (fastest_up == 0.0 || fastest_down == 0.0) return refuse("the axis moved one way only: friction and mass mix");
  // Two speeds a way apart by a quarter at least, else viscous and coulomb friction mix.
  if (fastest_up < 1.25 * slowest_up && fastest_down < 1.25 * slowest_down)
    return refuse("one speed only: coulomb and viscous friction mix");
  Eigen::MatrixXd A(used.size(), 3);
  Eigen::VectorXd b(used.size());
  for (std::size_t i = 0; i < used.size(); ++i) {
    const FreeMotionSample& s = *used[i];
    A(static_cast<Eigen::Index>(i), 0) = s.acceleration + prior.gravity;
    A(static_cast<Eigen::Index>(i), 1) = s.velocity > 0 ? 1.0 : -1.0;
    A(static_cast<Eigen::Index>(i), 2) = s.velocity;
    b(static_cast<Eigen::Index>(i)) = s.motor_force;
  }
  const Eigen::Vector3d x = A.colPivHouseholderQr().solve(b);
  if (!(x(0) > 0.0) || !(x(1) >= 0.0) || !(x(2) >= 0.0))
    return refuse("the fit is not physical (mass " + std::to_string(x(0)) + " kg, coulomb " + std::to_string(x(1)) +
                  " N, viscous " + std::to_string(x(2)) + " N s/m)");
  AxisBaseline out = prior;
  out.mass = x(0), out.coulomb = x(1), out.viscous = x(2);
  if (problem) problem->clear();
  return out;
}

AxialForceEstimate::AxialForceEstimate(ScrewDrive drive, AxisBaseline baseline, double filter_time_constant)
    : drive_(drive), baseline_(baseline), tau_(filter_time_constant) {
  if (!(drive_.lead > 0.0) || !(drive_.efficiency > 0.0) || !(drive_.rated_torque > 0.0))
    throw std::invalid_argument("AxialForceEstimate: lead, efficiency and rated torque must be > 0");
  force_ = filtered_ = NAN;
}

double AxialForceEstimate::update(double torque_permille, double position, double velocity, double acceleration,
                                  double dt) {
  const AxisBaseline& b = baseline_;
  const double dx = started_ ? position - last_position_ : 0.0;
  last_position_ = position;
  started_ = true;
  if (dx != 0.0 && b.coulomb > 0.0) {
    const double sliding = dx > 0.0 ? b.coulomb : -b.coulomb;
    friction_ = sliding + (friction_ - sliding) * std::exp(-b.friction_stiffness * std::abs(dx) / b.coulomb);
  }
  motor_force_ = drive_.force(torque_permille);
  const double carried = b.mass * (acceleration + b.gravity) + friction_ + b.viscous * velocity;
  raw_ = carried - motor_force_;
  const double alpha = tau_ > 0.0 ? dt / (tau_ + dt) : 1.0;
  filtered_ = std::isfinite(filtered_) ? filtered_ + alpha * (raw_ - filtered_) : raw_;
  if (rezero_updates_ > 0) {
    // Zeroing after the filter restarted: over kRezeroUpdates updates (the filter's settling), unknown until then.
    if (--rezero_updates_ > 0) return force_ = NAN;
    offset_ = filtered_;
  }
  force_ = filtered_ - offset_;
  return force_;
}

void AxialForceEstimate::rezero() {
  if (!std::isfinite(filtered_)) {
    rezero_updates_ = kRezeroUpdates;
    return;
  }
  offset_ = filtered_;
  force_ = 0.0;
}

void AxialForceEstimate::setBaseline(const AxisBaseline& baseline) {
  // The friction's state keeps its direction at the new level; what was filtered under the old baseline is dropped
  // (a zero taken from it would carry the old baseline's error).
  friction_ = baseline_.coulomb > 0.0 ? friction_ * baseline.coulomb / baseline_.coulomb : 0.0;
  baseline_ = baseline;
  filtered_ = force_ = NAN;
}

}  // namespace massage_cell::arm
