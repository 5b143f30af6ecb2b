// Synchronised trapezoid profiles (see profile.h).
#include "massage_cell/arm/profile.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace massage_cell::arm {

double trapezoidDuration(double distance, double v, double a) {
  distance = std::abs(distance);
  if (distance == 0.0) return 0.0;
  if (v * v / a >= distance) return 2.0 * std::sqrt(distance / a);  // triangle: never reaches v
  return distance / v + v / a;
}

double SyncProfile::progress(double t) const {
  if (duration <= 0.0) return 1.0;
  t = std::clamp(t, 0.0, duration);
  const double ta = accel_time;
  if (t < ta) return 0.5 * accel * t * t;
  if (t > duration - ta) {
    const double r = duration - t;
    return 1.0 - 0.5 * accel * r * r;
  }
  return 0.5 * accel * ta * ta + peak * (t - ta);
}

SyncProfile planSyncProfile(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                            const Eigen::Vector3d& max_velocity, const Eigen::Vector3d& max_acceleration,
                            double path_speed, double path_accel) {
  for (int i = 0; i < 3; ++i) {
    if (!(max_velocity[i] > 0.0) || !(max_acceleration[i] > 0.0)) {
      throw std::invalid_argument("planSyncProfile: axis limits must be positive");
    }
  }
  SyncProfile p;
  p.start = start;
  p.goal = goal;
  const Eigen::Vector3d d = (goal - start).cwiseAbs();
  const double length = d.norm();
  if (length == 0.0) return p;
  double V = std::numeric_limits<double>::infinity(), A = V;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0.0) continue;
    V = std::min(V, max_velocity[i] / d[i]);
    A = std::min(A, max_acceleration[i] / d[i]);
  }
  if (path_speed > 0.0) V = std::min(V, path_speed / length);
  if (path_accel > 0.0) A = std::min(A, path_accel / length);
  if (V * V / A >= 1.0) {  // triangle
    p.accel_time = std::sqrt(1.0 / A);
    p.peak = A * p.accel_time;
    p.duration = 2.0 * p.accel_time;
  } else {
    p.accel_time = V / A;
    p.peak = V;
    p.duration = 1.0 / V + V / A;
  }
  p.accel = A;
  p.velocity = d * p.peak;
  p.acceleration = d * A;
  return p;
}

}  // namespace massage_cell::arm
