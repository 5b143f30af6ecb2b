// The arm controller (issue 7), ROS-free: the three prismatic axes X, Y, Z
// of the gantry as CiA 402 drives behind one CANopen master
// (include/massage_cell/can/), driven by a cycle that runs once per SYNC
// (100 Hz with the default bus.sync_period_ms = 10): the master's
// before-SYNC hook, called in the poll that sends the SYNC, just before that
// SYNC's RPDOs. So on a VirtualClock everything is deterministic, and on the
// steady clock the cycle runs in the master's thread (startThread(), under
// SCHED_FIFO when asked: can/realtime.h). The controller sees every master
// event as a listener (addEventListener), whoever else drains takeEvents().
//
// What it guarantees:
//  - no motion before homing (home(): enable, Z up to its switch first, then
//    X and Y); moves and massages are refused until every axis is homed;
//  - soft limits: every goal is checked against the joint limits and the
//    Cartesian workspace envelope of the tool tip (config) before any frame
//    is sent; the drives' own 0x607D limits lie outside them (validated);
//  - synchronised point-to-point moves (profile.h): the profile velocity and
//    acceleration of every moving axis are written by SDO (0x6081, 0x6083,
//    0x6084), then all axes get their set-point in the same cycle, so they
//    start at the same SYNC, arrive together and the tool follows the line;
//  - the press routine (plan.h) never goes deeper than its region allows;
//  - e-stop latch: setEstop(true) sends RPDO1 with the quick-stop
//    controlword to every drive at once (Cia402Axis::quickStopNow; the
//    drives, synchronous RPDOs, apply it at the next SYNC) and the axes keep
//    commanding quick stop; the latch holds, whatever the e-stop input does,
//    until resetFault() with the input released;
//  - faults: heartbeat loss, an EMCY, the bus going bus-off / down, an SDO
//    failure (timeout, abort), a drive in fault or an axis operation failing
//    stop all axes (quick stop), end the running command and enter kFault;
//    every command except stop() is refused until resetFault() succeeds
//    (fault reset of the drives, then enable);
//  - command watchdog: while a move or a massage runs, keepAlive() must come
//    at least every watchdog_timeout; otherwise a press in contact retracts
//    and any other motion stops (quick stop, re-enable), and the command fails;
//  - abortMassage() (the press target was lost): a press in contact retracts
//    to its approach point and up to the travel height; the command fails.
// Threading: every public function takes the master's (recursive) lock.
#pragma once

#include <array>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "massage_cell/arm/config.h"
#include "massage_cell/arm/plan.h"
#include "massage_cell/arm/profile.h"
#include "massage_cell/arm/tool_force.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/master.h"
#include "massage_cell/can/realtime.h"

namespace massage_cell::arm {

enum class Mode {
  kStarting,  ///< bringing the CANopen nodes up
  kReady,     ///< nodes up, not homed (drives not enabled)
  kHoming,
  kIdle,  ///< homed, standing, enabled
  kMoving,
  kMassaging,
  kStopping,   ///< quick stop, then re-enable
  kResetting,  ///< fault reset, then enable
  kFault,      ///< stopped; refuses commands until resetFault()
  kEstop,      ///< e-stop latched; refuses commands until resetFault()
  kReleasing,  ///< e-stop latched during a press: the tool backs off to the approach point, then kEstop
};
const char* toString(Mode mode);

struct AxisStatus {
  std::string name;
  bool valid = false;     ///< statusword received
  double position = 0.0;  ///< m
  can::Cia402State state = can::Cia402State::kUnknown;
  can::NodeState node = can::NodeState::kUnknown;
  std::uint16_t statusword = 0;
  bool homed = false;
};

struct ArmStatus {
  Mode mode = Mode::kStarting;
  bool homed = false;
  bool estop_input = false;    ///< the e-stop input as last set
  bool estop_latched = false;  ///< latched until resetFault()
  std::array<AxisStatus, 3> axes;
  Eigen::Vector3d joints = Eigen::Vector3d::Zero();  ///< m
  Eigen::Vector3d tool = Eigen::Vector3d::Zero();    ///< m, arm base frame
  std::vector<std::string> faults;                   ///< why the arm is in fault (empty otherwise)
  std::string activity;                              ///< what the running command does now
  std::string last_error;                            ///< the last failure or refusal
  can::BusState bus = can::BusState::kErrorActive;
  std::uint64_t cycles = 0;
  std::uint64_t command = 0;  ///< id of the running (or last) command
  int target = -1;            ///< index of the massage target being worked on
  int presses_done = 0;       ///< of the running (or last) massage
  ForceReading force;         ///< the tool's force along z (tool_force.h)
  /// A press by force running: its phase ("seek", "ramp", "hold", "release", "back off"; empty otherwise), the force
  /// it asks for now (N, ramps included), its cap (N: the region's force and pressure limits) and its zero (N: the
  /// force read in the air before the seek; the press acts on force.force - force_zero).
  std::string press_phase;
  double force_target = 0.0;
  double force_limit = 0.0;
  double force_zero = 0.0;
};

/// How the arm is, for diagnostics: ERROR in fault or e-stop, WARN until homed, else OK; `text` says which.
struct Health {
  enum class Level { kOk, kWarn, kError };
  Level level = Level::kOk;
  std::string text;
};
Health health(const ArmStatus& status);

/// "12.3 N (drive torque)".
std::string formatForce(const ForceReading& force);

/// "0.123456 m, operation enabled, node operational, homed".
std::string describeAxis(const AxisStatus& axis);

/// The outcome of a command.
struct CommandResult {
  bool done = false;
  bool success = false;
  std::string message;
};

/// A command's acceptance: id != 0, or the refusal.
struct Accepted {
  std::uint64_t id = 0;
  std::string error;
  explicit operator bool() const { return id != 0; }
};

class Controller {
 public:
  using Log = std::function<void(const std::string& text)>;
  using CycleObserver = std::function<void(can::TimePoint now)>;

  /// Builds the master (on `bus`) and the three axes.
  /// Throws ArmConfigError / can::ConfigError on a bad configuration.
  Controller(can::Bus& bus, const can::Clock& clock, ArmConfig config);
  ~Controller();
  Controller(const Controller&) = delete;
  Controller& operator=(const Controller&) = delete;

  can::Master& master() { return *master_; }
  const ArmConfig& config() const { return config_; }
  can::Cia402Axis& axis(int i) { return *axes_.at(static_cast<std::size_t>(i)); }

  /// Brings the nodes up (asynchronous: kStarting -> kReady, or kFault).
  void start();
  /// Runs the master (and with it the cycle) in its own thread, real clocks
  /// only: mlockall first when options.lock_memory, SCHED_FIFO at
  /// options.priority when > 0. A refusal is in the status (with the fix);
  /// the thread then runs with normal scheduling.
  can::RealtimeStatus startThread(const can::RealtimeOptions& options = {});

  // --- commands (asynchronous; poll result(id)) -------------------------------------------
  Accepted home();
  /// Moves the tool tip (arm base frame) in a synchronised straight line;
  /// `speed` > 0 limits the tool's speed (m/s), else the joint limits rule.
  Accepted moveTo(const Eigen::Vector3d& tool, double speed = 0.0);
  Accepted massage(const PressRequest& request);
  /// Stops the motion: a press in contact retracts; anything else quick-stops
  /// and re-enables. In fault / e-stop there is nothing to stop: done at once.
  Accepted stop(const std::string& why = "stop requested");
  /// Clears faults and the e-stop latch (input released), fault-resets and enables the drives.
  Accepted resetFault();
  /// The e-stop input (true = pressed). Pressing latches at once.
  void setEstop(bool pressed);
  /// Feeds the command watchdog.
  void keepAlive();
  /// A load cell's / F/T sensor's force on the tool now (N along +z of the arm base, + when the body pushes the tool
  /// up): while such readings keep coming they are the tool's force, in place of the Z drive's estimate.
  void setSensorForce(double force);
  /// The running massage's target cannot be trusted any more (tf lost / stale).
  void abortMassage(const std::string& reason);

  CommandResult result(std::uint64_t id) const;
  ArmStatus status() const;
  Mode mode() const;

  // --- hooks -----------------------------------------------------------------------------------
  /// Every event and decision as a text line (called under the master's lock: do not call back).
  void setLog(Log log);
  /// Called at the start of every cycle (under the lock, in the thread that sends the SYNC).
  void setCycleObserver(CycleObserver observer);

 private:
  struct Action {
    /// kProfileMode: every axis left streaming cyclic targets (a force press cut short) back to profile position.
    enum class Kind { kEnableAll, kQuickStopAll, kWaitStopped, kFaultResetAll, kHome, kStep, kProfileMode };
    explicit Action(Kind k = Kind::kStep, unsigned m = 0b111) : kind(k), mask(m) {}
    Kind kind = Kind::kStep;
    unsigned mask = 0b111;  ///< axes (kHome)
    Step step;
  };
  enum class Phase { kStart, kProfiles, kRunning };

  void cycle(can::TimePoint now);
  void handleEvents();
  void checkFaults();
  void fault(const std::string& why);
  void runQueue(can::TimePoint now);
  bool startAction(Action& a, can::TimePoint now);  // false: failed (fault raised)
  /// true when done (ok), false when running; faults on failure.
  bool tickAction(Action& a, can::TimePoint now);
  bool waitOps(const std::string& what);  // ops of started_ axes: true when all done ok
  void startMove(const Step& s);
  Accepted begin(Mode mode, std::deque<Action> actions, const std::string& what);
  void finish(bool success, const std::string& message);
  void setResult(std::uint64_t id, bool success, const std::string& message);
  Accepted refuse(const std::string& why);
  std::string refusal(bool needs_homed) const;
  void quickStopAll();
  void stopAndReenable(const std::string& why);
  void retract(const std::string& why);
  void startRelease(const Step& from);  ///< e-stop in contact: back off (config press.estop_release)
  Eigen::Vector3d joints() const;
  bool allHomed() const;
  void log(const std::string& text);
  void senseForce(can::TimePoint now);
  // A press by force (controller_force.cpp): the Z drive streams the heights ForcePress returns.
  void startForcePress(const Step& s);
  bool tickForcePress(const Step& s);  ///< true when done (ok); faults or fails the command otherwise
  /// The axes a press by force streams: Z, a stroke X, Y and Z (a bit per axis).
  static unsigned streamingAxes(const Step& s);
  /// Whether every streaming axis has taken its new mode of operation; faults (naming the axis and `what`) on failure.
  bool streamingModeSet(const Step& s, const std::string& what);
  void abortForcePress(const std::string& why);
  void finishForceCalibration();
  /// With the tool's force known, guards a massage's steps that are not presses by force (those guard themselves):
  /// a move toward the body (travel, approach) meeting more than force_control.move_guard quick-stops and goes
  /// straight up to the travel height; a press to a depth meeting its region's cap retracts. The command fails with
  /// the reason.
  void guardForce();
  /// After homing, with force sensing: Z down and back up by force.calibration_travel at each calibration speed.
  std::deque<Action> forceCalibration() const;

  ArmConfig config_;
  const can::Clock& clock_;
  can::Bus& bus_;
  std::unique_ptr<can::Master> master_;
  std::array<std::unique_ptr<can::Cia402Axis>, 3> axes_;
  int listener_id_ = 0;
  std::vector<can::Event> events_;  ///< master events since the last cycle (our listener's queue)
  std::uint64_t cycles_ = 0;

  Mode mode_ = Mode::kStarting;
  can::TimePoint start_time_{};
  bool started_ = false;
  bool estop_input_ = false, estop_latched_ = false;
  std::vector<std::string> faults_;
  std::string last_error_;
  can::BusState bus_state_ = can::BusState::kErrorActive;

  // Running command.
  std::deque<Action> queue_;
  std::optional<Action> current_;
  Phase phase_ = Phase::kStart;
  can::TimePoint action_start_{};
  unsigned started_axes_ = 0;
  int sdo_pending_ = 0;
  std::string sdo_error_;
  unsigned sdo_generation_ = 0;
  std::array<std::int32_t, 3> goal_counts_{};
  std::array<std::optional<std::array<std::uint32_t, 3>>, 3> written_profile_;  // 0x6081/83/84 last written
  SyncProfile profile_;
  std::uint64_t command_ = 0, next_id_ = 1;
  std::string command_what_;
  std::string abort_reason_;  ///< set when the command is being aborted (it then fails with this)
  bool aborting_ = false;
  int presses_done_ = 0;
  can::TimePoint last_keepalive_{};
  std::map<std::uint64_t, CommandResult> results_;

  Log log_;
  CycleObserver cycle_observer_;

  std::unique_ptr<ToolForce> tool_force_;
  bool calibrating_force_ = false;  ///< a force calibration runs (its first move started, its last not ended)
  bool in_contact_ = false;         ///< the running step is a contact step (a press below its approach point)
  enum class ForcePhase { kEnterCyclic, kPressing, kLeaveCyclic };
  ForcePhase force_phase_ = ForcePhase::kEnterCyclic;
  std::unique_ptr<ForcePress> press_;  ///< the running press by force
};

}  // namespace massage_cell::arm
