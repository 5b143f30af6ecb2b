// Synchronised point-to-point profiles of the three prismatic joints: one
// normalised trapezoid s(t) in [0, 1] shared by every axis, scaled by each
// axis's distance, so all axes start and arrive together and the tool moves
// on the straight line between start and goal (the joints are a pure
// translation of the tool). The peak normalised velocity and acceleration
// are the largest that keep every axis within its velocity / acceleration
// limit and the tool within an optional path speed / acceleration.
// Each drive runs its share as a CiA 402 profile-position move with profile
// velocity |d_i| V and acceleration = deceleration |d_i| A.
#pragma once

#include <Eigen/Core>

namespace massage_cell::arm {

struct SyncProfile {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      ///< per-axis peak speed, m/s (>= 0)
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();  ///< per-axis acceleration = deceleration, m/s^2 (>= 0)
  double peak = 0.0;                                       ///< normalised peak velocity V (1/s)
  double accel = 0.0;                                      ///< normalised acceleration A (1/s^2)
  double accel_time = 0.0;                                 ///< s of acceleration (= of deceleration)
  double duration = 0.0;                                   ///< s, start to arrival (0 for a null move)

  /// Normalised progress s(t) in [0, 1] (t clamped to [0, duration]).
  double progress(double t) const;
  /// Ideal joint position at t.
  Eigen::Vector3d positionAt(double t) const { return start + progress(t) * (goal - start); }
};

/// Plans the synchronised profile from `start` to `goal`. `max_velocity`,
/// `max_acceleration`: per-axis limits (> 0); `path_speed`, `path_accel`:
/// limits on the tool's speed / acceleration along the line (<= 0: none).
/// Throws std::invalid_argument for non-positive axis limits.
SyncProfile planSyncProfile(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                            const Eigen::Vector3d& max_velocity, const Eigen::Vector3d& max_acceleration,
                            double path_speed = 0.0, double path_accel = 0.0);

/// Duration of a single-axis trapezoid over `distance` with limits v, a.
double trapezoidDuration(double distance, double v, double a);

}  // namespace massage_cell::arm
