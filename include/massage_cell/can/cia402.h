// CiA 402 drive profile (layer 4), master side: statusword decoding, the
// controlword commands of the drive state machine (CiA 402-2 §8.1), and
// Cia402Axis, one axis driven through a Master by PDO (controlword +
// target position out, statusword + position in) and SDO (modes,
// parameters):
//  - enable / disable / quick stop / fault reset, each with a timeout per
//    state transition; a failed enable says which state it stuck in and the
//    statusword ("could not enable: stuck in 'switch on disabled' (statusword
//    0x0240) for 500 ms waiting for 'ready to switch on'");
//  - profile position moves (0x6060 = 1; 0x607A target, 0x6081 / 0x6083 /
//    0x6084 written at start-up; new set-point bit 4 / set-point
//    acknowledge bit 12 handshake; done on target reached bit 10);
//  - homing (0x6060 = 6, 0x6098 method; homing start bit 4, attained bit 12,
//    error bit 13) with a timeout and retries, then back to profile position;
//  - metres <-> counts from the axis config.
// Operations are asynchronous state machines advanced by the master's poll
// (a tick handler): start one, then watch status() / error() or the kAxis
// events. One operation at a time; a new one replaces the running one
// (which fails with "superseded by ...").
#pragma once

#include <optional>
#include <string>

#include "massage_cell/can/master.h"

namespace massage_cell::can {

/// CiA 402 power drive system states.
enum class Cia402State {
  kNotReadyToSwitchOn,
  kSwitchOnDisabled,
  kReadyToSwitchOn,
  kSwitchedOn,
  kOperationEnabled,
  kQuickStopActive,
  kFaultReactionActive,
  kFault,
  kUnknown,  ///< a statusword pattern the table does not define
};
/// "not ready to switch on", "switch on disabled", ... as in CiA 402.
const char* toString(Cia402State state);
/// State from the statusword (statusword & 0x6F, table in CiA 402-2 §8.4.1:
/// 0x00/0x20 not ready, 0x40/0x60 switch on disabled, 0x21 ready, 0x23
/// switched on, 0x27 enabled, 0x07 quick stop, 0x0F/0x2F fault reaction,
/// 0x08/0x28 fault; anything else kUnknown).
Cia402State decodeStatusword(std::uint16_t statusword);

namespace cw {  // controlword (0x6040) commands and bits
constexpr std::uint16_t kShutdown = 0x0006;
constexpr std::uint16_t kSwitchOn = 0x0007;
constexpr std::uint16_t kDisableOperation = 0x0007;
constexpr std::uint16_t kEnableOperation = 0x000F;
constexpr std::uint16_t kQuickStop = 0x0002;
constexpr std::uint16_t kDisableVoltage = 0x0000;
constexpr std::uint16_t kFaultReset = 0x0080;   ///< acts on the rising edge
constexpr std::uint16_t kNewSetPoint = 0x0010;  ///< bit 4 (PP) / homing start
constexpr std::uint16_t kChangeImmediately = 0x0020;
constexpr std::uint16_t kRelative = 0x0040;
constexpr std::uint16_t kHalt = 0x0100;
}  // namespace cw

namespace sw {  // statusword (0x6041) bits
constexpr std::uint16_t kVoltageEnabled = 1u << 4;
constexpr std::uint16_t kWarning = 1u << 7;
constexpr std::uint16_t kRemote = 1u << 9;
constexpr std::uint16_t kTargetReached = 1u << 10;
constexpr std::uint16_t kInternalLimit = 1u << 11;
constexpr std::uint16_t kSetPointAcknowledge = 1u << 12;  ///< PP
constexpr std::uint16_t kHomingAttained = 1u << 12;       ///< homing
constexpr std::uint16_t kFollowingError = 1u << 13;       ///< PP
constexpr std::uint16_t kHomingError = 1u << 13;          ///< homing
}  // namespace sw

/// The controlword of the next transition from `from` towards operation
/// enabled (2, 3, 4, 16); nullopt where the drive moves by itself (not ready
/// to switch on, fault reaction active) or a fault reset is needed (fault).
std::optional<std::uint16_t> controlwordTowardsEnabled(Cia402State from);
/// The state the command `controlwordTowardsEnabled(from)` leads to.
Cia402State nextStateTowardsEnabled(Cia402State from);

/// Modes of operation (0x6060).
enum class Mode : std::int8_t { kProfilePosition = 1, kProfileVelocity = 3, kHoming = 6, kCyclicSyncPosition = 8 };

/// CiA 402 part of an axis's start-up configuration (SDO, after the PDO
/// mapping): 0x6060 = 1, 0x6081 / 0x6083 / 0x6084 / 0x6085, 0x605A,
/// 0x607D:01/02, 0x6065, 0x6098, 0x607C, 0x6099:01/02, 0x609A.
std::vector<StartupWrite> cia402StartupWrites(const AxisConfig& axis);

/// One CiA 402 axis on a Master; see the file comment.
class Cia402Axis {
 public:
  enum class Operation { kNone, kEnable, kDisable, kQuickStop, kFaultReset, kHoming, kMove, kMode };
  enum class Status { kIdle, kRunning, kSucceeded, kFailed };

  /// Registers the axis's start-up writes and tick handler with `master`
  /// (construct before Master::bringUp). `config.node_id` must be one of the
  /// master's nodes. The axis must not outlive the master.
  Cia402Axis(Master& master, const AxisConfig& config);
  ~Cia402Axis();
  Cia402Axis(const Cia402Axis&) = delete;
  Cia402Axis& operator=(const Cia402Axis&) = delete;

  const std::string& name() const { return config_.name; }
  std::uint8_t node() const { return config_.node_id; }
  const AxisConfig& config() const { return config_; }

  // --- operations (asynchronous) ------------------------------------------------
  /// Drives the state machine to operation enabled (fails from fault: reset first).
  void enable();
  /// Disable voltage: to switch on disabled.
  void disable();
  /// Quick stop: done when stopped in quick stop active, or switch on
  /// disabled (quick stop option 0..3).
  void quickStop();
  /// Quick stop (as quickStop()) whose first RPDO1 leaves at once
  /// (Master::sendRpdoNow), not with the next SYNC: the quick-stop
  /// controlword with the target the drive last got, which the axis then
  /// keeps commanding (the e-stop). True when that frame was sent (the node
  /// operational and the bus took it); else it goes with the next SYNC.
  bool quickStopNow();
  /// Rising edge of controlword bit 7: fault -> switch on disabled.
  void faultReset();
  /// Homing with retries (config homing.*), then back to profile position.
  void home();
  /// Profile-position move to an absolute position in metres (must be within
  /// the configured limits; needs operation enabled).
  void moveTo(double metres);
  void moveToCounts(std::int32_t counts);
  /// Switches the mode of operation (0x6060, read back from 0x6061), holding the position the axis stands at
  /// (needs operation enabled): kCyclicSyncPosition to stream targets with setCyclicTarget, kProfilePosition to
  /// move again with moveTo.
  void setModeOfOperation(Mode mode);
  /// In cyclic synchronous position (setModeOfOperation done): the target the next SYNC's RPDO carries, counts,
  /// clamped to the configured limits. False (nothing sent) when the axis is not streaming.
  bool setCyclicTarget(std::int32_t counts);
  /// Cyclic synchronous position set and confirmed by the drive, and operation enabled.
  bool cyclic() const;
  /// The mode of operation last set and confirmed (profile position after homing).
  Mode mode() const;

  Operation operation() const;
  Status status() const;
  /// Message of the last failure (empty when none).
  std::string error() const;
  bool busy() const { return status() == Status::kRunning; }

  // --- state -------------------------------------------------------------------------
  /// A statusword has been received since the node became operational.
  bool valid() const;
  Cia402State state() const;
  std::uint16_t statusword() const;
  std::int32_t positionCounts() const;
  double position() const;  ///< metres
  bool homed() const;
  /// Transitions seen so far (for tests / diagnostics), oldest first.
  std::vector<Cia402State> history() const;

 private:
  enum class Phase {
    kStart,
    kWaitEdgeLow,
    kWaitAck,
    kWaitAckClear,
    kWaitReached,
    kSetMode,
    kCheckMode,
    kHomingRun,
    kRestoreMode,
    kRestoreCheck,
    kDone
  };
  void begin(Operation op);
  void tick(TimePoint now);
  void succeed(const std::string& text);
  void fail(const std::string& text);
  void tickEnable(TimePoint now, Cia402State s, std::uint16_t word);
  void tickMove(TimePoint now, Cia402State s, std::uint16_t word, std::int32_t pos);
  void tickHoming(TimePoint now, Cia402State s, std::uint16_t word);
  void tickMode(TimePoint now, Cia402State s, std::uint16_t word);
  void setMode(Mode mode, Phase next);
  /// A mode change (setMode) step by step: the write answered, then 0x6061 read back until it shows wanted_mode_;
  /// true once it does; failed (with the reason) on an SDO error or after enable_timeout_ms.
  bool modeConfirmed(TimePoint now);
  void readMode();
  void startHomingAttempt();
  void homingAttemptFailed(const std::string& why);
  bool freshFeedback(const DriveFeedback& fb);
  void command(std::uint16_t controlword);
  std::string who() const;
  std::string faultText(std::uint16_t word) const;
  bool timedOut(TimePoint now, std::uint32_t ms) const { return now - phase_start_ > std::chrono::milliseconds(ms); }
  void phase(Phase p);

  Master& master_;
  AxisConfig config_;
  int tick_id_ = 0;
  Operation op_ = Operation::kNone;
  Status status_ = Status::kIdle;
  std::string error_;
  Phase phase_ = Phase::kDone;
  TimePoint phase_start_{};
  TimePoint op_start_{};
  std::uint64_t rpdo_mark_ = 0;
  unsigned generation_ = 0;
  // state tracking
  bool have_state_ = false;
  Cia402State last_state_ = Cia402State::kNotReadyToSwitchOn;
  std::uint16_t last_word_ = 0;
  std::vector<Cia402State> history_;
  // operation data
  std::int32_t target_ = 0;
  std::uint16_t command_ = cw::kDisableVoltage;
  int attempt_ = 0;
  bool homed_ = false;
  bool sdo_pending_ = false;
  bool sdo_ok_ = false;
  std::string sdo_error_;
  std::int8_t mode_read_ = 0;
  Mode wanted_mode_ = Mode::kProfilePosition;
  Phase after_mode_ = Phase::kDone;
  Mode mode_ = Mode::kProfilePosition;  ///< the mode last confirmed by setModeOfOperation (homing restores PP)
  bool sent_confirmed_ = false;
  std::uint64_t count_mark_ = 0;
  std::uint32_t quick_stop_timeout_ms_ = 0;
  std::optional<TimePoint> following_since_;
};

/// "enable", "disable", "quick stop", "fault reset", "homing", "move".
const char* toString(Cia402Axis::Operation op);

}  // namespace massage_cell::can
