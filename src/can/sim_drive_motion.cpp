// SimDrive, CiA 402 side (see sim_drive.h): the application objects,
// controlword / statusword, the state machine, profile position, homing, the
// motion step with the axis mechanics, following error monitoring.
#include "massage_cell/can/sim_drive.h"

#include <algorithm>
#include <cmath>

#include "sim_drive_detail.h"

namespace massage_cell::can {

using namespace sim_drive_detail;

// --- object dictionary: application objects -----------------------------------------------

void SimDrive::resetApplication() {
  const AxisConfig& c = config_;
  const double k = c.counts_per_metre;
  od_.add(0x603F, 0, A::kReadOnly, 2, 0, false, true);
  od_.add(0x6040, 0, A::kReadWrite, 2, 0, false, true);
  od_.add(0x6041, 0, A::kReadOnly, 2, 0, false, true);
  od_.add(0x605A, 0, A::kReadWrite, 2, c.quick_stop_option, true);
  od_.add(0x6060, 0, A::kReadWrite, 1, 0, true, true);
  od_.add(0x6061, 0, A::kReadOnly, 1, 0, true, true);
  od_.add(0x6064, 0, A::kReadOnly, 4, 0, true, true);
  od_.add(0x6065, 0, A::kReadWrite, 4, std::llround(c.following_error_window * k));
  od_.add(0x6066, 0, A::kReadWrite, 2, 10);  // ms
  od_.add(0x6067, 0, A::kReadWrite, 4, 1);   // position window, counts
  od_.add(0x606C, 0, A::kReadOnly, 4, 0, true, true);
  od_.add(0x607A, 0, A::kReadWrite, 4, 0, true, true);
  od_.add(0x607C, 0, A::kReadWrite, 4, c.toCounts(c.home_offset), true);
  od_.add(0x607D, 0, A::kConst, 1, 2);
  od_.add(0x607D, 1, A::kReadWrite, 4, c.toCounts(c.min_position), true);
  od_.add(0x607D, 2, A::kReadWrite, 4, c.toCounts(c.max_position), true);
  od_.add(0x607F, 0, A::kReadWrite, 4, std::llround(c.sim.max_velocity * k));
  od_.add(0x6081, 0, A::kReadWrite, 4, std::llround(c.profile_velocity * k), false, true);
  od_.add(0x6083, 0, A::kReadWrite, 4, std::llround(c.profile_acceleration * k));
  od_.add(0x6084, 0, A::kReadWrite, 4, std::llround(c.profile_deceleration * k));
  od_.add(0x6085, 0, A::kReadWrite, 4, std::llround(c.quick_stop_deceleration * k));
  od_.add(0x6098, 0, A::kReadWrite, 1, c.homing_method, true);
  od_.add(0x6099, 0, A::kConst, 1, 2);
  od_.add(0x6099, 1, A::kReadWrite, 4, std::llround(c.homing_speed * k));
  od_.add(0x6099, 2, A::kReadWrite, 4, std::llround(c.homing_speed * k / 4));
  od_.add(0x609A, 0, A::kReadWrite, 4, std::llround(c.profile_acceleration * k));
  od_.add(0x6076, 0, A::kConst, 4, std::llround(c.rated_torque * 1000.0));  // mN m
  od_.add(0x6077, 0, A::kReadOnly, 2, 0, true, true);                       // per mille of 0x6076
  od_.add(0x6502, 0, A::kReadOnly, 4, (1 << 0) | (1 << 5) | (1 << 7));      // supported modes: pp, homing, csp
  od_.add(0x6007, 0, A::kReadWrite, 2, 1, true);                            // abort connection option code: fault
  // The drive restarts: the position reference (homing) is lost, the motor is off.
  actual_ -= offset_;
  demand_ -= offset_;
  switch_pos_ -= offset_;
  offset_ = 0.0;
  state_ = Cia402State::kNotReadyToSwitchOn;
  cw_prev_ = 0;
  velocity_ = 0.0;
  demand_ = actual_;
  pp_target_ = actual_;
  moving_ = setpoint_ack_ = internal_limit_ = halt_ = false;
  target_reached_ = true;
  homing_active_ = homing_attained_ = homing_error_ = homed_ = false;
  following_since_s_ = -1.0;
  mechanics_.reset();
}

// --- statusword ---------------------------------------------------------------------------------

namespace {

/// The statusword's state bits (CiA 402-2 §8.4.1), without voltage enabled (bit 4).
std::uint16_t stateBits(Cia402State state) {
  using namespace sw_bit;
  switch (state) {
    case Cia402State::kNotReadyToSwitchOn:
      return 0;
    case Cia402State::kSwitchOnDisabled:
      return kSwitchOnDisabled;
    case Cia402State::kReadyToSwitchOn:
      return kReadyToSwitchOn | kQuickStop;
    case Cia402State::kSwitchedOn:
      return kReadyToSwitchOn | kSwitchedOn | kQuickStop;
    case Cia402State::kOperationEnabled:
      return kReadyToSwitchOn | kSwitchedOn | kOperationEnabled | kQuickStop;
    case Cia402State::kQuickStopActive:
      return kReadyToSwitchOn | kSwitchedOn | kOperationEnabled;
    case Cia402State::kFaultReactionActive:
      return kReadyToSwitchOn | kSwitchedOn | kOperationEnabled | kFault;
    case Cia402State::kFault:
      return kFault;
    case Cia402State::kUnknown:
      return 0;
  }
  return 0;
}

}  // namespace

std::uint16_t SimDrive::composeStatusword() const {
  std::uint16_t w = stateBits(state_);
  if (state_ == Cia402State::kReadyToSwitchOn || state_ == Cia402State::kSwitchedOn ||
      state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive) {
    w |= sw::kVoltageEnabled;
  }
  w |= sw::kRemote;
  const double window = static_cast<double>(od_.get(0x6065, 0));
  const bool following = std::abs(demand_ - actual_) > window;
  if (state_ == Cia402State::kQuickStopActive) {
    if (velocity_ == 0.0) w |= sw::kTargetReached;
  } else if (state_ != Cia402State::kOperationEnabled) {
    // the operation-mode bits (10, 12, 13) only mean something while enabled
  } else if (od_.get(0x6061, 0) == static_cast<int>(Mode::kHoming)) {
    if (!homing_active_) w |= sw::kTargetReached;
    if (homing_attained_) w |= sw::kHomingAttained;
    if (homing_error_) w |= sw::kHomingError;
  } else {
    const double pos_window = static_cast<double>(od_.get(0x6067, 0));
    const bool reached = (!moving_ && std::abs(actual_ - pp_target_) <= pos_window) || (halt_ && velocity_ == 0.0);
    if (reached) w |= sw::kTargetReached;
    // Bit 12: profile position's set-point acknowledge; in cyclic synchronous position, "drive follows the
    // command value" (always, while enabled).
    if (setpoint_ack_ || od_.get(0x6061, 0) == static_cast<int>(Mode::kCyclicSyncPosition))
      w |= sw::kSetPointAcknowledge;
    if (following) w |= sw::kFollowingError;
    if (internal_limit_) w |= sw::kInternalLimit;
  }
  return w;
}

void SimDrive::updateProcessObjects() {
  od_.set(0x6041, 0, composeStatusword());
  od_.set(0x6064, 0, std::llround(actual_));
  od_.set(0x606C, 0, std::llround(velocity_));
}

// --- state machine -----------------------------------------------------------------------------

void SimDrive::enterState(Cia402State s) {
  const Cia402State prev = state_;
  state_ = s;
  if (s == Cia402State::kQuickStopActive && od_.get(0x605A, 0) == 0) state_ = s = Cia402State::kSwitchOnDisabled;
  if (s == Cia402State::kOperationEnabled && prev != Cia402State::kQuickStopActive) {
    demand_ = actual_;
    velocity_ = 0.0;
    pp_target_ = csp_from_ = csp_to_ = actual_;
  }
  if (s == Cia402State::kOperationEnabled) {
    moving_ = false;
    setpoint_ack_ = false;
    homing_active_ = false;
  }
  if (s != Cia402State::kOperationEnabled && s != Cia402State::kQuickStopActive &&
      s != Cia402State::kFaultReactionActive) {
    velocity_ = 0.0;
    demand_ = actual_;
    moving_ = false;
    homing_active_ = false;
    setpoint_ack_ = false;
  }
}

void SimDrive::enterFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer) {
  const std::uint8_t reg = errorRegisterFor(code);
  od_.set(0x603F, 0, code);
  od_.set(0x1001, 0, reg);
  sendEmcy(code, reg, manufacturer);
  if (state_ == Cia402State::kFault || state_ == Cia402State::kFaultReactionActive) return;
  moving_ = false;
  homing_active_ = false;
  if (state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive) {
    enterState(Cia402State::kFaultReactionActive);  // brake on the quick-stop ramp, then fault
  } else {
    enterState(Cia402State::kFault);
  }
}

void SimDrive::processControlword() {
  const auto cw = static_cast<std::uint16_t>(od_.get(0x6040, 0));
  const std::uint16_t prev = cw_prev_;
  cw_prev_ = cw;
  if ((cw & cw::kFaultReset) && !(prev & cw::kFaultReset) && state_ == Cia402State::kFault) {
    od_.set(0x603F, 0, 0);
    od_.set(0x1001, 0, 0);
    sendEmcy(0x0000, 0);                         // error reset
    enterState(Cia402State::kSwitchOnDisabled);  // 15
    return;
  }
  if (cw & cw::kFaultReset) return;
  applyStateCommand(cw);
  if (state_ != Cia402State::kOperationEnabled) return;
  applyOperationBits(cw, prev);
}

void SimDrive::applyStateCommand(std::uint16_t cw) {
  const bool disable_voltage = !(cw & cw_bit::kEnableVoltage);
  const bool quick_stop = (cw & (cw_bit::kEnableVoltage | cw_bit::kQuickStop)) == cw::kQuickStop;
  const bool shutdown = (cw & (cw_bit::kSwitchOn | cw_bit::kEnableVoltage | cw_bit::kQuickStop)) == cw::kShutdown;
  const bool switch_on = (cw & cw_bit::kCommandMask) == cw::kSwitchOn;
  const bool enable_op = (cw & cw_bit::kCommandMask) == cw::kEnableOperation;
  const auto option = od_.get(0x605A, 0);
  switch (state_) {
    case Cia402State::kSwitchOnDisabled:
      if (shutdown) enterState(Cia402State::kReadyToSwitchOn);  // 2
      break;
    case Cia402State::kReadyToSwitchOn:
      if (disable_voltage || quick_stop)
        enterState(Cia402State::kSwitchOnDisabled);  // 7
      else if (switch_on)
        enterState(Cia402State::kSwitchedOn);  // 3
      else if (enable_op)
        enterState(Cia402State::kOperationEnabled);  // 3 + 4
      break;
    case Cia402State::kSwitchedOn:
      if (disable_voltage || quick_stop)
        enterState(Cia402State::kSwitchOnDisabled);  // 10
      else if (shutdown)
        enterState(Cia402State::kReadyToSwitchOn);  // 6
      else if (enable_op)
        enterState(Cia402State::kOperationEnabled);  // 4
      break;
    case Cia402State::kOperationEnabled:
      if (disable_voltage)
        enterState(Cia402State::kSwitchOnDisabled);  // 9
      else if (quick_stop)
        enterState(Cia402State::kQuickStopActive);  // 11
      else if (shutdown)
        enterState(Cia402State::kReadyToSwitchOn);  // 8
      else if (switch_on)
        enterState(Cia402State::kSwitchedOn);  // 5
      break;
    case Cia402State::kQuickStopActive:
      if (disable_voltage)
        enterState(Cia402State::kSwitchOnDisabled);  // 12
      else if (enable_op && option >= 5 && velocity_ == 0.0)
        enterState(Cia402State::kOperationEnabled);  // 16
      break;
    default:
      break;
  }
}

void SimDrive::applyOperationBits(std::uint16_t cw, std::uint16_t prev) {
  halt_ = (cw & cw::kHalt) != 0;
  const bool sp = (cw & cw::kNewSetPoint) != 0, sp_prev = (prev & cw::kNewSetPoint) != 0;
  const auto mode = od_.get(0x6061, 0);
  if (mode == static_cast<int>(Mode::kProfilePosition)) {
    if (sp && !sp_prev && !setpoint_ack_) acceptSetPoint(cw);
    if (!sp) setpoint_ack_ = false;
  } else if (mode == static_cast<int>(Mode::kHoming)) {
    if (sp && !sp_prev) startHoming();
    if (!sp && homing_active_) homing_active_ = false;  // interrupted
  }
}

void SimDrive::acceptSetPoint(std::uint16_t cw) {
  double t = static_cast<double>(od_.get(0x607A, 0));
  if (cw & cw::kRelative) t += pp_target_;
  const double lo = static_cast<double>(od_.get(0x607D, 1)), hi = static_cast<double>(od_.get(0x607D, 2));
  internal_limit_ = false;
  if (lo < hi && (t < lo || t > hi)) {
    t = std::clamp(t, lo, hi);
    internal_limit_ = true;
  }
  pp_target_ = t;
  moving_ = true;
  setpoint_ack_ = true;
}

// --- homing ------------------------------------------------------------------------------------

void SimDrive::startHoming() {
  homing_attained_ = false;
  homing_error_ = false;
  homing_active_ = true;
  homing_started_s_ = sim_time_s_;
  homing_failing_ = homing_fail_count_ > 0;
  if (homing_failing_) --homing_fail_count_;
  const auto method = od_.get(0x6098, 0);
  switch (method) {
    case 1:
    case 2:
    case 17:
    case 18:
      homing_goal_ = switch_pos_;
      break;
    case 33:
    case 34:
    case 35:
    case 37:
      homing_goal_ = actual_;  // home in place
      break;
    default:
      homing_error_ = true;  // method not supported
      homing_active_ = false;
      return;
  }
  if (homing_failing_ && homing_fail_kind_ == HomingFailure::kHang)
    homing_goal_ = actual_ + (homing_goal_ - actual_) * 0.5;
}

void SimDrive::completeHoming() {
  // Called from step() after approach() moved the demand onto the goal but
  // before the step copies the demand into the actual position: take that
  // step first, so the reference lands on the goal itself (not on where the
  // motor stood a step earlier, which left it a step past the offset).
  if (!blocked_) actual_ = demand_;
  const double delta = static_cast<double>(od_.get(0x607C, 0)) - actual_;
  actual_ += delta;
  demand_ += delta;
  switch_pos_ += delta;
  offset_ += delta;
  pp_target_ = actual_;
  velocity_ = 0.0;
  homing_active_ = false;
  homing_attained_ = true;
  homed_ = true;
}

// --- motion ------------------------------------------------------------------------------------

bool SimDrive::approach(double target, double vmax, double acc, double dec, double dt) {
  const double d = target - demand_;
  if (std::abs(d) < 1e-9 && std::abs(velocity_) < 1e-9) {
    demand_ = target;
    velocity_ = 0.0;
    return true;
  }
  const double dir = d > 0 ? 1.0 : -1.0;
  const double vstop = std::sqrt(2.0 * dec * std::abs(d));
  const double vdes = dir * std::min(vmax, vstop);
  const double rate = (velocity_ * dir >= 0 && std::abs(vdes) > std::abs(velocity_)) ? acc : dec;
  velocity_ += std::clamp(vdes - velocity_, -rate * dt, rate * dt);
  const double s = velocity_ * dt;
  if ((d > 0 && s >= d) || (d < 0 && s <= d) || (std::abs(d) <= 0.5 && std::abs(velocity_) <= 2.0 * dec * dt)) {
    demand_ = target;
    velocity_ = 0.0;
    return true;
  }
  demand_ += s;
  return false;
}

void SimDrive::brake(double dec, double dt) {
  const double dv = std::min(std::abs(velocity_), dec * dt);
  velocity_ -= velocity_ > 0 ? dv : -dv;
  demand_ += velocity_ * dt;
}

void SimDrive::updateMechanics(double dt, double previous_actual, double previous_velocity) {
  const double k = config_.counts_per_metre;
  const double position = (actual_ - offset_) / k;
  physical_m_.store(position, std::memory_order_relaxed);
  if (!mechanics_.enabled()) return;
  (void)previous_velocity;
  // The acceleration the motor gives the load: the demand's velocity through the servo's own lag (kServoLagS), not
  // its step-to-step difference, which a step of microseconds (the real clock's remainder) would make unbounded.
  const double v = velocity_ / k;
  const double before = servo_velocity_;
  servo_velocity_ += (v - servo_velocity_) * std::min(1.0, dt / kServoLagS);
  const double a = (servo_velocity_ - before) / dt;
  external_force_ = external_ ? external_(position, v) : 0.0;
  const double torque = mechanics_.step((actual_ - previous_actual) / k, v, a, external_force_);
  // The motor carries the load while it is energised (holding brake otherwise: no torque).
  const bool energised = state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive ||
                         state_ == Cia402State::kFaultReactionActive;
  od_.set(0x6077, 0, mechanics_.torquePerMille(energised ? torque : 0.0));
}

void SimDrive::step(double dt) {
  const double previous_actual = actual_, previous_velocity = velocity_;
  sim_time_s_ += dt;
  const double qs_dec = std::max(1.0, static_cast<double>(od_.get(0x6085, 0)));
  switch (state_) {
    case Cia402State::kNotReadyToSwitchOn:
      enterState(Cia402State::kSwitchOnDisabled);  // initialisation done
      break;
    case Cia402State::kOperationEnabled:
      stepOperationEnabled(dt);
      break;
    case Cia402State::kQuickStopActive:
      brake(qs_dec, dt);
      if (velocity_ == 0.0) {
        const auto option = od_.get(0x605A, 0);
        if (option < 5) enterState(Cia402State::kSwitchOnDisabled);  // 12 (options 1..4)
      }
      break;
    case Cia402State::kFaultReactionActive:
      brake(qs_dec, dt);
      if (velocity_ == 0.0) enterState(Cia402State::kFault);  // 14
      break;
    default:
      velocity_ = 0.0;
      demand_ = actual_;
      break;
  }
  if (!blocked_) actual_ = demand_;
  updateMechanics(dt, previous_actual, previous_velocity);
  monitorFollowingError();
}

void SimDrive::stepOperationEnabled(double dt) {
  const auto mode = od_.get(0x6061, 0);
  const double dec = std::max(1.0, static_cast<double>(od_.get(0x6084, 0)));
  if (mode == static_cast<int>(Mode::kCyclicSyncPosition) && !halt_) {
    stepCyclic(dt);
  } else if (mode == static_cast<int>(Mode::kProfilePosition) && moving_ && !halt_) {
    const double vmax = static_cast<double>(std::min(od_.get(0x6081, 0), od_.get(0x607F, 0)));
    const double acc = std::max(1.0, static_cast<double>(od_.get(0x6083, 0)));
    if (approach(pp_target_, vmax, acc, dec, dt)) moving_ = false;
  } else if (mode == static_cast<int>(Mode::kHoming) && homing_active_) {
    stepHoming(dt);
  } else {
    brake(dec, dt);
  }
}

// --- cyclic synchronous position (mode 8) ------------------------------------------------------

void SimDrive::syncCyclicTarget() {
  const double now = sim_time_s_;
  const double period = now - last_sync_s_;
  last_sync_s_ = now;
  if (period > 1e-4 && period < 0.1) csp_period_ = period;  // the SYNC interval the targets come at
  if (state_ != Cia402State::kOperationEnabled || od_.get(0x6061, 0) != static_cast<int>(Mode::kCyclicSyncPosition))
    return;
  // The new target is reached by the next SYNC, linearly; beyond the software limits or the maximum velocity
  // (0x607F) per SYNC it is clamped and bit 11 (internal limit active) says so.
  double t = static_cast<double>(od_.get(0x607A, 0));
  const double lo = static_cast<double>(od_.get(0x607D, 1)), hi = static_cast<double>(od_.get(0x607D, 2));
  const double step = static_cast<double>(od_.get(0x607F, 0)) * csp_period_;
  internal_limit_ = false;
  const double clamped = std::clamp(lo < hi ? std::clamp(t, lo, hi) : t, demand_ - step, demand_ + step);
  if (clamped != t) internal_limit_ = true;
  csp_from_ = demand_;
  csp_to_ = pp_target_ = clamped;
  csp_elapsed_ = 0.0;
}

void SimDrive::stepCyclic(double dt) {
  csp_elapsed_ += dt;
  // A SYNC that comes late (the bus, the master's thread): the drive goes on at the segment's speed for up to half a
  // period (extrapolation, as drives do), then holds; the next target starts from where it is.
  const double f = std::min(kCspExtrapolation, csp_elapsed_ / csp_period_);
  double next = csp_from_ + (csp_to_ - csp_from_) * f;
  const double lo = static_cast<double>(od_.get(0x607D, 1)), hi = static_cast<double>(od_.get(0x607D, 2));
  if (lo < hi) next = std::clamp(next, lo, hi);
  // The step's own motion (the last step of a segment moves like the others; a stream that stops, stops).
  velocity_ = (next - demand_) / dt;
  demand_ = next;
}

void SimDrive::stepHoming(double dt) {
  const double speed = static_cast<double>(od_.get(0x6099, 1));
  const double acc = std::max(1.0, static_cast<double>(od_.get(0x609A, 0)));
  if (homing_failing_ && homing_fail_kind_ == HomingFailure::kError) {
    brake(acc, dt);
    if (sim_time_s_ - homing_started_s_ >= 0.05) {
      homing_error_ = true;
      homing_active_ = false;
    }
  } else if (approach(homing_goal_, speed, acc, acc, dt) && !homing_failing_) {
    completeHoming();
  }
}

void SimDrive::monitorFollowingError() {
  // Following error monitoring (0x6065 window for 0x6066 ms).
  if (state_ != Cia402State::kOperationEnabled && state_ != Cia402State::kQuickStopActive) {
    following_since_s_ = -1.0;
    return;
  }
  if (std::abs(demand_ - actual_) <= static_cast<double>(od_.get(0x6065, 0))) {
    following_since_s_ = -1.0;
    return;
  }
  if (following_since_s_ < 0) following_since_s_ = sim_time_s_;
  if (sim_time_s_ - following_since_s_ >= static_cast<double>(od_.get(0x6066, 0)) / 1000.0) {
    following_since_s_ = -1.0;
    enterFault(0x8611, {});
  }
}

}  // namespace massage_cell::can
