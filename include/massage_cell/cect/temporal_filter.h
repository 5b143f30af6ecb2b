// Temporal filtering of localised points across frames (the subject
// breathes): per named point, a robust running estimate. ROS-free.
//
// Each update compares the new 3D position with the filtered one: within
// `gate` metres (Mahalanobis-free: plain distance, the noise being ~mm) it is
// blended in with weight `alpha`; beyond it is an outlier and counted; after
// `reacquire_after` consecutive outliers that agree with each other (within
// `gate`), the filter jumps to them (the subject moved). A point not updated
// for `max_age` seconds is dropped.
#pragma once

#include <map>
#include <string>

#include <Eigen/Core>

namespace massage_cell::cect {

struct TemporalFilterParams {
  double alpha = 0.5;       ///< weight of a new measurement, (0, 1]; 1 = no smoothing
  double gate = 0.01;       ///< metres
  int reacquire_after = 3;  ///< consecutive agreeing outliers before the filter follows them
  double max_age = 2.0;     ///< seconds
};

struct FilteredPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double stamp = 0.0;                                 ///< seconds of the last accepted measurement
  int updates = 0;                                    ///< accepted measurements
  int outliers = 0;                                   ///< consecutive rejected measurements
  Eigen::Vector3d pending = Eigen::Vector3d::Zero();  ///< mean of the current outlier streak
};

class TemporalFilter {
 public:
  explicit TemporalFilter(const TemporalFilterParams& params = {});  ///< throws std::invalid_argument for bad params
  void setParams(const TemporalFilterParams& params);
  /// Feeds one measurement; returns true when it was accepted (or followed).
  bool update(const std::string& name, const Eigen::Vector3d& position, const Eigen::Matrix3d& covariance,
              double stamp);
  /// The filtered point, or nullptr if unknown or older than max_age at `now`.
  const FilteredPoint* get(const std::string& name, double now) const;
  void clear();
  int rejected() const { return rejected_; }  ///< measurements rejected as outliers so far

 private:
  TemporalFilterParams params_;
  std::map<std::string, FilteredPoint> points_;
  int rejected_ = 0;
};

}  // namespace massage_cell::cect
