// The tool's force along Z (see tool_force.h).
#include "massage_cell/arm/tool_force.h"

#include <cmath>

namespace massage_cell::arm {

namespace {

ScrewDrive screwOf(const ArmConfig& c) {
  ScrewDrive d;
  d.lead = c.force.screw_lead;
  d.efficiency = c.force.screw_efficiency;
  d.rated_torque = c.force.enabled ? c.axis(2).rated_torque : 1.0;
  return d;
}

AxisBaseline priorOf(const ForceConfig& f) {
  AxisBaseline b;
  b.mass = f.mass;
  b.coulomb = f.coulomb_friction;
  b.viscous = f.viscous_friction;
  b.friction_stiffness = f.friction_stiffness;
  return b;
}

}  // namespace

ToolForce::ToolForce(const ArmConfig& config)
    : enabled_(config.force.enabled),
      sync_period_(config.can.sync_period_us / 1e6),
      estimate_(screwOf(config), priorOf(config.force), config.force.filter_time_constant),
      problem_(config.force.enabled ? "not calibrated: the arm has not homed" : "no force sensing configured") {}

void ToolForce::setSensorForce(double force, can::TimePoint stamp) {
  if (!std::isfinite(force)) return;
  if (!sensor_seen_) sensor_offset_ = force;  // its first reading is taken in the air: its zero until a press's
  sensor_seen_ = true;
  sensor_force_ = force;
  sensor_stamp_ = stamp;
}

bool ToolForce::sensorFresh() const {
  return sensor_seen_ && std::chrono::duration<double>(now_ - sensor_stamp_).count() <= kSensorTimeout;
}

void ToolForce::rezero() {
  estimate_.rezero();
  if (sensorFresh()) sensor_offset_ = sensor_force_;
}

void ToolForce::update(const can::DriveFeedback& z, double position, can::TimePoint now, bool calibrating) {
  now_ = now;
  if (!enabled_) return;
  if (!z.valid || !z.has_torque) {
    have_last_ = have_velocity_ = false;
    acceleration_ = 0.0;
    return;
  }
  if (have_last_ && z.count == last_count_) return;  // no new TPDO this cycle
  double velocity = 0.0, acceleration = 0.0, dt = 0.0;
  if (have_last_) {
    // The drive samples at each SYNC: the time between two samples is the SYNC period times the TPDOs between them,
    // whenever they arrive (on a loaded machine two may come in one cycle).
    dt = sync_period_ * static_cast<double>(z.count - last_count_);
    if (!(dt > 0.0)) return;
    velocity = (position - last_position_) / dt;
    // The second difference of positions sampled a few hundred microseconds apart from their nominal instants (the
    // drive's sampling, the bus) swings by metres per second squared; the load's real accelerations in a press are
    // tenths of that and slow: a low-pass (kAccelerationFilterS) keeps the mass term from turning jitter into force.
    if (have_velocity_) {
      const double raw = (velocity - last_velocity_) / dt;
      acceleration_ += dt / (kAccelerationFilterS + dt) * (raw - acceleration_);
      acceleration = acceleration_;
    }
    have_velocity_ = true;
  }
  estimate_.update(z.torque, position, velocity, acceleration, dt);
  if (calibrating && have_velocity_) samples_.push_back({estimate_.motorForce(), velocity, acceleration});
  have_last_ = true;
  last_position_ = position, last_velocity_ = velocity, last_count_ = z.count;
}

std::string ToolForce::finishCalibration() {
  if (!enabled_) return problem_;
  std::string why;
  const AxisBaseline fitted = identifyBaseline(samples_, estimate_.baseline(), &why);
  samples_.clear();
  if (!why.empty()) {
    calibrated_ = false;
    problem_ = "not calibrated: " + why;
    return problem_;
  }
  estimate_.setBaseline(fitted);
  calibrated_ = true;
  problem_.clear();
  estimate_.rezero();
  return {};
}

ForceReading ToolForce::reading() const {
  ForceReading r;
  if (sensorFresh()) {  // the load cell takes precedence while it reports
    r.valid = true;
    r.source = "load cell";
    r.force = sensor_force_ - sensor_offset_;
    r.calibrated = calibrated_;
    r.baseline = estimate_.baseline();
    return r;
  }
  r.source = enabled_ ? "drive torque" : "none";
  r.calibrated = calibrated_;
  r.baseline = estimate_.baseline();
  r.problem = problem_;
  if (enabled_ && calibrated_ && !have_last_) r.problem = "no torque from the Z drive (TPDO3)";
  if (sensor_seen_) r.source += " (the load cell is silent)";
  if (enabled_ && calibrated_ && have_last_ && !std::isfinite(estimate_.force()))
    r.problem = "settling: the estimate's zero is being taken";
  r.valid = enabled_ && calibrated_ && have_last_ && std::isfinite(estimate_.force());
  r.force = r.valid ? estimate_.force() : 0.0;
  return r;
}

}  // namespace massage_cell::arm
