// CiA 402 master-side drive logic (see cia402.h).
#include "massage_cell/can/cia402.h"

#include <cmath>
#include <cstdio>

namespace massage_cell::can {

namespace {

std::string hex4(unsigned v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%04X", v);
  return buf;
}

std::vector<std::uint8_t> i8(std::int64_t v) { return toBytes(static_cast<std::uint64_t>(v), 1); }
std::vector<std::uint8_t> i16(std::int64_t v) { return toBytes(static_cast<std::uint64_t>(v), 2); }
std::vector<std::uint8_t> i32(std::int64_t v) { return toBytes(static_cast<std::uint64_t>(v), 4); }
std::vector<std::uint8_t> u32(double v) {
  const double r = std::round(std::max(0.0, std::min(v, 4294967295.0)));
  return toBytes(static_cast<std::uint64_t>(r), 4);
}

}  // namespace

const char* toString(Cia402State state) {
  switch (state) {
    case Cia402State::kNotReadyToSwitchOn:
      return "not ready to switch on";
    case Cia402State::kSwitchOnDisabled:
      return "switch on disabled";
    case Cia402State::kReadyToSwitchOn:
      return "ready to switch on";
    case Cia402State::kSwitchedOn:
      return "switched on";
    case Cia402State::kOperationEnabled:
      return "operation enabled";
    case Cia402State::kQuickStopActive:
      return "quick stop active";
    case Cia402State::kFaultReactionActive:
      return "fault reaction active";
    case Cia402State::kFault:
      return "fault";
    case Cia402State::kUnknown:
      return "unknown (invalid statusword)";
  }
  return "?";
}

Cia402State decodeStatusword(std::uint16_t w) {
  switch (w & 0x6F) {
    case 0x00:
    case 0x20:
      return Cia402State::kNotReadyToSwitchOn;
    case 0x40:
    case 0x60:
      return Cia402State::kSwitchOnDisabled;
    case 0x21:
      return Cia402State::kReadyToSwitchOn;
    case 0x23:
      return Cia402State::kSwitchedOn;
    case 0x27:
      return Cia402State::kOperationEnabled;
    case 0x07:
      return Cia402State::kQuickStopActive;
    case 0x0F:
    case 0x2F:
      return Cia402State::kFaultReactionActive;
    case 0x08:
    case 0x28:
      return Cia402State::kFault;
    default:
      return Cia402State::kUnknown;
  }
}

std::optional<std::uint16_t> controlwordTowardsEnabled(Cia402State from) {
  switch (from) {
    case Cia402State::kSwitchOnDisabled:
      return cw::kShutdown;  // 2
    case Cia402State::kReadyToSwitchOn:
      return cw::kSwitchOn;  // 3
    case Cia402State::kSwitchedOn:
      return cw::kEnableOperation;  // 4
    case Cia402State::kQuickStopActive:
      return cw::kEnableOperation;  // 16
    case Cia402State::kOperationEnabled:
      return cw::kEnableOperation;  // stay
    default:
      return std::nullopt;
  }
}

Cia402State nextStateTowardsEnabled(Cia402State from) {
  switch (from) {
    case Cia402State::kNotReadyToSwitchOn:
      return Cia402State::kSwitchOnDisabled;
    case Cia402State::kSwitchOnDisabled:
      return Cia402State::kReadyToSwitchOn;
    case Cia402State::kReadyToSwitchOn:
      return Cia402State::kSwitchedOn;
    case Cia402State::kFaultReactionActive:
      return Cia402State::kFault;
    case Cia402State::kFault:
      return Cia402State::kSwitchOnDisabled;
    default:
      return Cia402State::kOperationEnabled;
  }
}

std::vector<StartupWrite> cia402StartupWrites(const AxisConfig& a) {
  const double c = a.counts_per_metre;
  return {
      {0x6060, 0, i8(static_cast<int>(Mode::kProfilePosition))},
      {0x6081, 0, u32(a.profile_velocity * c)},
      {0x6083, 0, u32(a.profile_acceleration * c)},
      {0x6084, 0, u32(a.profile_deceleration * c)},
      {0x6085, 0, u32(a.quick_stop_deceleration * c)},
      {0x605A, 0, i16(a.quick_stop_option)},
      {0x607D, 1, i32(a.toCounts(a.min_position))},
      {0x607D, 2, i32(a.toCounts(a.max_position))},
      {0x6065, 0, u32(a.following_error_window * c)},
      {0x6098, 0, i8(a.homing_method)},
      {0x607C, 0, i32(a.toCounts(a.home_offset))},
      {0x6099, 1, u32(a.homing_speed * c)},
      {0x6099, 2, u32(a.homing_speed * c / 4.0)},
      {0x609A, 0, u32(a.profile_acceleration * c)},
  };
}

const char* toString(Cia402Axis::Operation op) {
  switch (op) {
    case Cia402Axis::Operation::kNone:
      return "none";
    case Cia402Axis::Operation::kEnable:
      return "enable";
    case Cia402Axis::Operation::kDisable:
      return "disable";
    case Cia402Axis::Operation::kQuickStop:
      return "quick stop";
    case Cia402Axis::Operation::kFaultReset:
      return "fault reset";
    case Cia402Axis::Operation::kHoming:
      return "homing";
    case Cia402Axis::Operation::kMove:
      return "move";
    case Cia402Axis::Operation::kMode:
      return "mode change";
  }
  return "?";
}

Cia402Axis::Cia402Axis(Master& master, const AxisConfig& config) : master_(master), config_(config) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  master_.nodeState(config_.node_id);  // throws std::out_of_range for a node the master does not know
  for (StartupWrite& w : cia402StartupWrites(config_)) master_.addStartupWrite(config_.node_id, std::move(w));
  const double stop_s = config_.profile_velocity / config_.quick_stop_deceleration;
  quick_stop_timeout_ms_ = config_.enable_timeout_ms + static_cast<std::uint32_t>(std::ceil(stop_s * 2000.0));
  tick_id_ = master_.addTickHandler([this](TimePoint now) { tick(now); });
}

Cia402Axis::~Cia402Axis() { master_.removeTickHandler(tick_id_); }

std::string Cia402Axis::who() const {
  return "axis " + config_.name + " (node " + std::to_string(config_.node_id) + ")";
}

std::string Cia402Axis::faultText(std::uint16_t word) const {
  std::string t = "statusword " + hex4(word);
  const DriveFeedback fb = master_.feedback(config_.node_id);
  if (fb.emcy_code != 0) t += ", last EMCY " + hex4(fb.emcy_code) + " " + emcyText(fb.emcy_code);
  return t;
}

void Cia402Axis::command(std::uint16_t controlword) {
  if (controlword != command_ || !sent_confirmed_) {
    rpdo_mark_ = master_.rpdosSent(config_.node_id);
    sent_confirmed_ = false;
  }
  command_ = controlword;
  master_.setRpdo(config_.node_id, command_, target_);
}

bool Cia402Axis::freshFeedback(const DriveFeedback& fb) {
  if (!sent_confirmed_) {
    if (master_.rpdosSent(config_.node_id) <= rpdo_mark_) return false;
    sent_confirmed_ = true;
    count_mark_ = fb.count;
  }
  return fb.count > count_mark_;
}

void Cia402Axis::phase(Phase p) {
  phase_ = p;
  phase_start_ = master_.clock().now();
}

void Cia402Axis::begin(Operation op) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  if (status_ == Status::kRunning) {
    const Operation old = op_;
    fail(std::string(toString(old)) + " superseded by " + toString(op));
  }
  ++generation_;
  op_ = op;
  status_ = Status::kRunning;
  error_.clear();
  op_start_ = master_.clock().now();
  attempt_ = 0;
  sdo_pending_ = false;
  following_since_.reset();
  phase(Phase::kStart);
}

void Cia402Axis::succeed(const std::string& text) {
  status_ = Status::kSucceeded;
  phase_ = Phase::kDone;
  ++generation_;
  Event e;
  e.type = EventType::kAxis;
  e.node = config_.node_id;
  e.text = who() + ": " + toString(op_) + " done: " + text;
  master_.postEvent(e);
}

void Cia402Axis::fail(const std::string& text) {
  status_ = Status::kFailed;
  phase_ = Phase::kDone;
  ++generation_;
  error_ = who() + ": " + text;
  Event e;
  e.type = EventType::kAxis;
  e.node = config_.node_id;
  e.text = error_;
  master_.postEvent(e);
}

void Cia402Axis::enable() { begin(Operation::kEnable); }
void Cia402Axis::disable() { begin(Operation::kDisable); }
void Cia402Axis::quickStop() { begin(Operation::kQuickStop); }

bool Cia402Axis::quickStopNow() {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  // The target the drive has (a set-point not yet sent, e.g. a move started but not ticked, is dropped).
  if (const auto last = master_.rpdoTarget(config_.node_id)) target_ = *last;
  command(cw::kQuickStop);
  const bool sent = master_.sendRpdoNow(config_.node_id);
  begin(Operation::kQuickStop);  // after the frame: ending the running operation posts its event
  return sent;
}

void Cia402Axis::faultReset() { begin(Operation::kFaultReset); }
void Cia402Axis::home() { begin(Operation::kHoming); }

void Cia402Axis::moveTo(double metres) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  if (!(metres >= config_.min_position && metres <= config_.max_position)) {
    begin(Operation::kMove);
    char buf[160];
    std::snprintf(buf, sizeof buf, "target %.6f m is outside the limits [%.6f, %.6f] m", metres, config_.min_position,
                  config_.max_position);
    fail(buf);
    return;
  }
  moveToCounts(config_.toCounts(metres));
}

void Cia402Axis::moveToCounts(std::int32_t counts) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  begin(Operation::kMove);
  target_ = counts;
  if (counts < config_.toCounts(config_.min_position) || counts > config_.toCounts(config_.max_position)) {
    fail("target " + std::to_string(counts) + " counts is outside the configured limits");
  } else if (mode_ == Mode::kCyclicSyncPosition) {
    fail("move refused: the axis streams cyclic targets (mode 8); set profile position first");
  }
}

void Cia402Axis::setModeOfOperation(Mode mode) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  begin(Operation::kMode);
  wanted_mode_ = mode;
}

bool Cia402Axis::setCyclicTarget(std::int32_t counts) {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  if (!cyclic() || status_ == Status::kRunning) return false;
  target_ = std::clamp(counts, config_.toCounts(config_.min_position), config_.toCounts(config_.max_position));
  master_.setRpdo(config_.node_id, command_, target_);
  return true;
}

Mode Cia402Axis::mode() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return mode_;
}

bool Cia402Axis::cyclic() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return mode_ == Mode::kCyclicSyncPosition && state() == Cia402State::kOperationEnabled;
}

Cia402Axis::Operation Cia402Axis::operation() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return op_;
}
Cia402Axis::Status Cia402Axis::status() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return status_;
}
std::string Cia402Axis::error() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return error_;
}
bool Cia402Axis::valid() const { return master_.feedback(config_.node_id).valid; }
Cia402State Cia402Axis::state() const {
  const DriveFeedback fb = master_.feedback(config_.node_id);
  return fb.valid ? decodeStatusword(fb.statusword) : Cia402State::kUnknown;
}
std::uint16_t Cia402Axis::statusword() const { return master_.feedback(config_.node_id).statusword; }
std::int32_t Cia402Axis::positionCounts() const { return master_.feedback(config_.node_id).position; }
double Cia402Axis::position() const { return config_.toMetres(positionCounts()); }
bool Cia402Axis::homed() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return homed_;
}
std::vector<Cia402State> Cia402Axis::history() const {
  std::lock_guard<RecursivePiMutex> lock(master_.mutex());
  return history_;
}

// --- the tick ------------------------------------------------------------------------

void Cia402Axis::tick(TimePoint now) {
  const DriveFeedback fb = master_.feedback(config_.node_id);
  if (!fb.valid) {
    have_state_ = false;
    const NodeState ns = master_.nodeState(config_.node_id);
    if (ns == NodeState::kResetting || ns == NodeState::kConfiguring)
      homed_ = false;  // a rebooted drive lost its reference
    if (status_ != Status::kRunning) return;
    if (ns != NodeState::kOperational && ns != NodeState::kStarting) {
      fail(std::string(toString(op_)) + " aborted: node is " + toString(ns));
    } else if (timedOut(now, config_.enable_timeout_ms)) {
      fail(std::string(toString(op_)) + " failed: no statusword (TPDO1) from the drive within " +
           std::to_string(config_.enable_timeout_ms) + " ms");
    }
    return;
  }
  const Cia402State s = decodeStatusword(fb.statusword);
  if (!have_state_ || s != last_state_) {
    Event e;
    e.type = EventType::kAxis;
    e.node = config_.node_id;
    e.text = who() + ": " + (have_state_ ? std::string(toString(last_state_)) + " -> " : std::string("state ")) +
             toString(s) + " (statusword " + hex4(fb.statusword) + ")";
    if (s == Cia402State::kFault) e.text += ": FAULT (" + faultText(fb.statusword) + ")";
    master_.postEvent(e);
    history_.push_back(s);
    if (history_.size() > 1000) history_.erase(history_.begin());
    if (status_ == Status::kRunning &&
        (op_ == Operation::kEnable || op_ == Operation::kDisable || op_ == Operation::kFaultReset)) {
      phase_start_ = now;  // every transition gets its own timeout
    }
    last_state_ = s;
    have_state_ = true;
  }
  last_word_ = fb.statusword;
  if (status_ != Status::kRunning) return;

  const std::uint16_t word = fb.statusword;
  const bool faulted = s == Cia402State::kFault || s == Cia402State::kFaultReactionActive;
  switch (op_) {
    case Operation::kEnable:
      tickEnable(now, s, word);
      return;
    case Operation::kDisable:
      command(cw::kDisableVoltage);
      if (s == Cia402State::kSwitchOnDisabled) return succeed("switch on disabled");
      if (timedOut(now, config_.enable_timeout_ms)) {
        fail("could not disable: stuck in '" + std::string(toString(s)) + "' (statusword " + hex4(word) + ") for " +
             std::to_string(config_.enable_timeout_ms) + " ms");
      }
      return;
    case Operation::kQuickStop:
      command(cw::kQuickStop);
      if (s == Cia402State::kSwitchOnDisabled) return succeed("stopped, switch on disabled");
      if (s == Cia402State::kQuickStopActive && (word & sw::kTargetReached))
        return succeed("stopped in quick stop active");
      if (faulted) return fail("quick stop ended in a drive fault (" + faultText(word) + ")");
      if (timedOut(now, quick_stop_timeout_ms_)) {
        fail("quick stop did not complete within " + std::to_string(quick_stop_timeout_ms_) + " ms (state '" +
             toString(s) + "', statusword " + hex4(word) + ")");
      }
      return;
    case Operation::kFaultReset:
      if (phase_ == Phase::kStart) {
        if (!faulted) return succeed("no fault to reset (state '" + std::string(toString(s)) + "')");
        command(cw::kDisableVoltage);  // bit 7 low first: the reset acts on the rising edge
        phase(Phase::kWaitEdgeLow);
        return;
      }
      if (phase_ == Phase::kWaitEdgeLow) {
        if (freshFeedback(fb)) {
          command(cw::kFaultReset);
          phase(Phase::kWaitAck);
        }
        return;
      }
      if (s == Cia402State::kSwitchOnDisabled) return succeed("fault cleared, switch on disabled");
      if (timedOut(now, config_.enable_timeout_ms)) {
        fail("fault persists " + std::to_string(config_.enable_timeout_ms) + " ms after fault reset (state '" +
             toString(s) + "', " + faultText(word) + ")");
      }
      return;
    case Operation::kHoming:
      tickHoming(now, s, word);
      return;
    case Operation::kMove:
      tickMove(now, s, word, fb.position);
      return;
    case Operation::kMode:
      tickMode(now, s, word);
      return;
    case Operation::kNone:
      return;
  }
}

void Cia402Axis::tickEnable(TimePoint now, Cia402State s, std::uint16_t word) {
  if (phase_ == Phase::kStart) {
    target_ = master_.feedback(config_.node_id).position;  // a PP set-point, if any, holds position
    phase(Phase::kWaitReached);
  }
  if (s == Cia402State::kOperationEnabled) {
    command(cw::kEnableOperation);
    return succeed("operation enabled");
  }
  if (s == Cia402State::kFault || s == Cia402State::kFaultReactionActive) {
    return fail("could not enable: drive is in '" + std::string(toString(s)) + "' (" + faultText(word) +
                "); reset the fault first");
  }
  const std::optional<std::uint16_t> c = controlwordTowardsEnabled(s);
  if (c) command(*c);
  if (timedOut(now, config_.enable_timeout_ms)) {
    fail("could not enable: stuck in '" + std::string(toString(s)) + "' (statusword " + hex4(word) + ") for " +
         std::to_string(config_.enable_timeout_ms) + " ms waiting for '" + toString(nextStateTowardsEnabled(s)) + "'" +
         (c ? " after controlword " + hex4(*c) : std::string(" (the drive has to get there by itself)")));
  }
}

void Cia402Axis::tickMove(TimePoint now, Cia402State s, std::uint16_t word, std::int32_t pos) {
  if (s != Cia402State::kOperationEnabled) {
    if (s == Cia402State::kFault || s == Cia402State::kFaultReactionActive) {
      return fail("move aborted by a drive fault (" + faultText(word) + ")");
    }
    return fail("move " + std::string(phase_ == Phase::kStart ? "refused" : "aborted") + ": drive is '" + toString(s) +
                "', not operation enabled");
  }
  if (now - op_start_ > std::chrono::milliseconds(config_.move_timeout_ms)) {
    return fail("move did not reach the target within " + std::to_string(config_.move_timeout_ms) + " ms (at " +
                std::to_string(pos) + " of " + std::to_string(target_) + " counts, statusword " + hex4(word) + ")");
  }
  const DriveFeedback fb = master_.feedback(config_.node_id);
  switch (phase_) {
    case Phase::kStart: {
      // Bit 4 has to be seen low before the rising edge that carries the new set-point.
      const std::int32_t wanted = target_;
      target_ = pos;
      command(cw::kEnableOperation);
      // Wait for a statusword that answers this very RPDO, even when the controlword did not change (the axis' last
      // move ended on it): every axis of a synchronised move then takes the same cycles to its rising edge.
      rpdo_mark_ = master_.rpdosSent(config_.node_id);
      sent_confirmed_ = false;
      target_ = wanted;
      phase(Phase::kWaitEdgeLow);
      return;
    }
    case Phase::kWaitEdgeLow:
      if (freshFeedback(fb) && !(word & sw::kSetPointAcknowledge)) {
        command(cw::kEnableOperation | cw::kNewSetPoint);
        phase(Phase::kWaitAck);
      } else if (timedOut(now, config_.enable_timeout_ms)) {
        fail("drive keeps the set-point acknowledge (bit 12) set with new set-point low (statusword " + hex4(word) +
             ")");
      }
      return;
    case Phase::kWaitAck:
      if (freshFeedback(fb) && (word & sw::kSetPointAcknowledge)) {
        command(cw::kEnableOperation);
        phase(Phase::kWaitAckClear);
      } else if (timedOut(now, config_.enable_timeout_ms)) {
        fail("drive did not acknowledge the set-point (statusword bit 12) within " +
             std::to_string(config_.enable_timeout_ms) + " ms (statusword " + hex4(word) + ")");
      }
      return;
    case Phase::kWaitAckClear:
      if (freshFeedback(fb) && !(word & sw::kSetPointAcknowledge)) phase(Phase::kWaitReached);
      return;
    case Phase::kWaitReached:
      if (word & sw::kFollowingError) {
        // Give the drive its fault reaction (the fault then names the EMCY); fail here only if it does not come.
        if (!following_since_) following_since_ = now;
        if (now - *following_since_ > std::chrono::milliseconds(config_.enable_timeout_ms)) {
          return fail("following error (statusword bit 13) for " + std::to_string(config_.enable_timeout_ms) +
                      " ms without a drive fault (statusword " + hex4(word) + ")");
        }
        return;
      }
      following_since_.reset();
      if (word & sw::kTargetReached) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "at %.6f m (%d counts, %d from the target)", config_.toMetres(pos), pos,
                      pos - target_);
        return succeed(buf);
      }
      return;
    default:
      return;
  }
}

void Cia402Axis::tickMode(TimePoint now, Cia402State s, std::uint16_t word) {
  if (s != Cia402State::kOperationEnabled) {
    return fail("mode change " + std::string(phase_ == Phase::kStart ? "refused" : "aborted") + ": drive is '" +
                toString(s) + "' (" + faultText(word) + "), not operation enabled");
  }
  switch (phase_) {
    case Phase::kStart: {
      // Hold where the axis stands whichever mode comes: a PP set-point or the first cyclic target.
      target_ = master_.feedback(config_.node_id).position;
      command(cw::kEnableOperation);
      const Mode wanted = wanted_mode_;
      setMode(wanted, Phase::kDone);
      return;
    }
    case Phase::kSetMode:
    case Phase::kCheckMode:
      if (!modeConfirmed(now)) return;
      mode_ = wanted_mode_;
      return succeed("mode of operation " + std::to_string(static_cast<int>(mode_)));
    default:
      return;
  }
}

bool Cia402Axis::modeConfirmed(TimePoint now) {
  if (sdo_pending_) return false;
  if (phase_ != Phase::kCheckMode) {  // the write (kSetMode, kRestoreMode) answered
    if (!sdo_ok_)
      fail("could not set the mode of operation: " + sdo_error_);
    else
      readMode();
    return false;
  }
  if (!sdo_ok_) {
    fail("could not read the mode display: " + sdo_error_);
    return false;
  }
  if (mode_read_ == static_cast<std::int8_t>(wanted_mode_)) return true;
  if (timedOut(now, config_.enable_timeout_ms)) {
    fail("mode display 0x6061 stays " + std::to_string(mode_read_) + ", wanted " +
         std::to_string(static_cast<int>(wanted_mode_)));
    return false;
  }
  readMode();
  return false;
}

void Cia402Axis::setMode(Mode mode, Phase next) {
  wanted_mode_ = mode;
  after_mode_ = next;
  phase(Phase::kSetMode);
  sdo_pending_ = true;
  const unsigned gen = generation_;
  master_.sdoDownload(config_.node_id, 0x6060, 0, i8(static_cast<int>(mode)), [this, gen](const SdoResult& r) {
    if (gen != generation_) return;
    sdo_pending_ = false;
    sdo_ok_ = r.ok;
    sdo_error_ = r.error;
  });
}

void Cia402Axis::readMode() {
  phase(Phase::kCheckMode);
  sdo_pending_ = true;
  const unsigned gen = generation_;
  master_.sdoUpload(config_.node_id, 0x6061, 0, [this, gen](const SdoResult& r) {
    if (gen != generation_) return;
    sdo_pending_ = false;
    sdo_ok_ = r.ok && r.data.size() == 1;
    sdo_error_ = r.ok ? "0x6061 returned " + std::to_string(r.data.size()) + " bytes" : r.error;
    mode_read_ = r.data.empty() ? 0 : static_cast<std::int8_t>(r.data[0]);
  });
}

void Cia402Axis::startHomingAttempt() {
  command(cw::kEnableOperation);  // bit 4 low first
  phase(Phase::kWaitEdgeLow);
}

void Cia402Axis::homingAttemptFailed(const std::string& why) {
  if (attempt_ < config_.homing_retries) {
    ++attempt_;
    Event e;
    e.type = EventType::kAxis;
    e.node = config_.node_id;
    e.text = who() + ": homing attempt " + std::to_string(attempt_) + " of " +
             std::to_string(config_.homing_retries + 1) + " failed (" + why + "); retrying";
    master_.postEvent(e);
    startHomingAttempt();
    return;
  }
  command(cw::kEnableOperation);
  fail("homing failed after " + std::to_string(attempt_ + 1) + " attempt" + (attempt_ ? "s" : "") + ": " + why);
}

void Cia402Axis::tickHoming(TimePoint now, Cia402State s, std::uint16_t word) {
  if (s != Cia402State::kOperationEnabled) {
    if (s == Cia402State::kFault || s == Cia402State::kFaultReactionActive) {
      return fail("homing aborted by a drive fault (" + faultText(word) + ")");
    }
    return fail("homing " + std::string(phase_ == Phase::kStart ? "refused" : "aborted") + ": drive is '" +
                toString(s) + "', not operation enabled");
  }
  const DriveFeedback fb = master_.feedback(config_.node_id);
  switch (phase_) {
    case Phase::kStart:
      target_ = fb.position;
      command(cw::kEnableOperation);
      homed_ = false;
      mode_ = Mode::kHoming;
      setMode(Mode::kHoming, Phase::kHomingRun);
      return;
    case Phase::kSetMode:
    case Phase::kRestoreMode:
    case Phase::kCheckMode: {
      if (!modeConfirmed(now)) return;
      if (after_mode_ == Phase::kHomingRun) return startHomingAttempt();
      mode_ = Mode::kProfilePosition;
      char buf[96];
      std::snprintf(buf, sizeof buf, "homed at %.6f m (%d counts), back in profile position mode",
                    config_.toMetres(fb.position), fb.position);
      return succeed(buf);
    }
    case Phase::kWaitEdgeLow:
      if (freshFeedback(fb)) {
        command(cw::kEnableOperation | cw::kNewSetPoint);  // homing start (rising edge of bit 4)
        phase(Phase::kHomingRun);
      }
      return;
    case Phase::kHomingRun:
      if (!freshFeedback(fb)) return;
      if (word & sw::kHomingError) return homingAttemptFailed("homing error (statusword bit 13, " + hex4(word) + ")");
      if ((word & sw::kHomingAttained) && (word & sw::kTargetReached)) {
        homed_ = true;
        target_ = fb.position;
        command(cw::kEnableOperation);
        setMode(Mode::kProfilePosition, Phase::kDone);
        return;
      }
      if (timedOut(now, config_.homing_timeout_ms)) {
        return homingAttemptFailed("not attained within " + std::to_string(config_.homing_timeout_ms) +
                                   " ms, statusword " + hex4(word));
      }
      return;
    default:
      return;
  }
}

}  // namespace massage_cell::can
