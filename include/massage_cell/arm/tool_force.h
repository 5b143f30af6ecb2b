// The tool's force along Z as the arm controller knows it, cycle by cycle:
// the Z drive's torque (TPDO3, 0x6077) turned into the external force by
// AxialForceEstimate, the axis' baseline identified from the calibration
// moves after homing (Step::force_calibration), re-zeroed when a press
// leaves its approach point. ROS-free; the controller owns one and calls it
// under the master's lock.
#pragma once

#include <string>
#include <vector>

#include "massage_cell/arm/config.h"
#include "massage_cell/arm/force_estimate.h"
#include "massage_cell/can/master.h"

namespace massage_cell::arm {

/// What the arm reports of the tool's force.
struct ForceReading {
  bool valid = false;   ///< a force is known (enabled, torque arriving, calibrated)
  double force = 0.0;   ///< N along +z on the tool: + when the body pushes it up (the tool's pressing force)
  std::string source;   ///< "load cell" (an external sensor, while it reports), "drive torque", or "none"
  std::string problem;  ///< why not valid ("not calibrated: the arm has not homed", "no torque from Z")
  bool calibrated = false;
  AxisBaseline baseline;  ///< what the axis carries without contact (identified or the config's prior)
};

class ToolForce {
 public:
  /// Disabled (problem says so) without config.force.
  explicit ToolForce(const ArmConfig& config);
  bool enabled() const { return enabled_; }

  /// One cycle: the Z drive's feedback and its position in metres. `calibrating`: the axis moves freely for the
  /// calibration (its samples feed the baseline's fit).
  void update(const can::DriveFeedback& z, double position, can::TimePoint now, bool calibrating);
  /// The calibration moves begin: the samples of an earlier, unfinished one are dropped.
  void startCalibration() { samples_.clear(); }
  /// The calibration moves ended: fits the baseline to their samples. Returns an empty string, else why not (the
  /// prior stays; the force is then not valid).
  std::string finishCalibration();
  /// A load cell's or F/T sensor's reading (N along +z on the tool, + when the body pushes it up) taken at `stamp`:
  /// while readings keep coming (each within kSensorTimeout of the last cycle) they are the force, not the drive's.
  void setSensorForce(double force, can::TimePoint stamp);
  /// The tool is still and touches nothing: zero the estimate (and the sensor, which drifts too) here.
  void rezero();
  ForceReading reading() const;
  /// A sensor silent longer than this no longer counts: the drive's estimate takes over (and the reading says so).
  static constexpr double kSensorTimeout = 0.05;

 private:
  bool enabled_ = false;
  double sync_period_;  ///< s between two TPDOs of the drive
  AxialForceEstimate estimate_;
  std::vector<FreeMotionSample> samples_;
  bool calibrated_ = false;
  std::string problem_;
  bool have_last_ = false, have_velocity_ = false;
  double last_position_ = 0.0, last_velocity_ = 0.0;
  double acceleration_ = 0.0;  ///< low-passed
  static constexpr double kAccelerationFilterS = 0.05;
  std::uint64_t last_count_ = 0;
  can::TimePoint now_{};  ///< the last cycle's time
  // The external sensor:
  bool sensor_seen_ = false;
  double sensor_force_ = 0.0, sensor_offset_ = 0.0;
  can::TimePoint sensor_stamp_{};
  bool sensorFresh() const;
};

}  // namespace massage_cell::arm
