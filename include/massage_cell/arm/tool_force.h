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
  std::string source;   ///< "drive torque" (or "none")
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
  /// The tool is still and touches nothing: zero the estimate here.
  void rezero() { estimate_.rezero(); }
  ForceReading reading() const;

 private:
  bool enabled_ = false;
  AxialForceEstimate estimate_;
  std::vector<FreeMotionSample> samples_;
  bool calibrated_ = false;
  std::string problem_;
  bool have_last_ = false, have_velocity_ = false;
  double last_position_ = 0.0, last_velocity_ = 0.0;
  can::TimePoint last_stamp_{};
  std::uint64_t last_count_ = 0;
};

}  // namespace massage_cell::arm
