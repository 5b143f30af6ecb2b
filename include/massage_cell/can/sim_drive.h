// Simulated CANopen CiA 402 servo drive (layer 5, the slave side), on any
// Bus (a VirtualBus endpoint in tests, SocketCAN in can_sim_drive):
//  - object dictionary (object_dictionary.h) with the CiA 301 communication
//    objects (0x1000, 0x1001, 0x1008, 0x1017, 0x1018, RPDO/TPDO 1..4
//    communication and mapping parameters) and the CiA 402 objects the
//    master uses (0x603F, 0x6040, 0x6041, 0x605A, 0x6060/61, 0x6064/65/66/67,
//    0x606C, 0x607A, 0x607C, 0x607D, 0x607F, 0x6081/83/84/85, 0x6098/99/9A);
//  - NMT slave state machine with boot-up message, reset node / reset
//    communication (CiA 301 §7.3.2);
//  - SDO server: expedited and segmented upload / download, aborts with
//    CiA 301 codes (object missing, read-only, length, toggle, mapping);
//  - PDOs: RPDOs applied at the next SYNC (transmission type 0..240) or at
//    once (254/255); TPDOs sent on every n-th SYNC (type n = 1..240) or on
//    change (254/255); DLC errors -> EMCY 0x8210, the frame is not applied;
//  - heartbeat producer (0x1017);
//  - heartbeat consumer of the master (0x1016:01 = producer node id << 16 |
//    time in ms; 0 = off): monitoring starts with the first heartbeat of that
//    node (CiA 301 §7.2.8.2.2.3); when none comes within the time the drive
//    sends EMCY 0x8130 (heartbeat error) and reacts per 0x6007 abort
//    connection option code (CiA 402): 1 fault (error code 0x8130, fault
//    reaction -> fault), 2 disable voltage (-> switch on disabled), 3 quick
//    stop (from operation enabled -> quick stop active, then per 0x605A),
//    0 nothing but the EMCY. The next heartbeat re-arms it; a fault stays
//    until a fault reset;
//  - CiA 402 state machine (transitions 2..16, fault reset on the rising
//    edge of controlword bit 7), profile position mode with a trapezoidal
//    profile (0x6081 limited by 0x607F, 0x6083 / 0x6084), software position
//    limits (0x607D), new set-point / set-point acknowledge handshake,
//    halt (bit 8), quick stop on 0x6085 with option 0x605A, following error
//    monitoring (0x6065 window, 0x6066 time) -> fault 0x8611;
//  - torque actual 0x6077 (per mille of the rated torque 0x6076) from the
//    axis' mechanics (sim_mechanics.h: mass, gravity, friction, ball screw)
//    and an external force on the axis (setExternalForce: a body under the
//    tool), mappable into a TPDO;
//  - cyclic synchronous position (mode 8): the target 0x607A of each SYNC's
//    RPDO is reached by the next SYNC, linearly (clamped to 0x607D and to
//    0x607F per SYNC period, bit 11 set);
//  - homing mode (0x6098: 1, 2, 17, 18 move to the home switch at
//    0x6099:01, then the position becomes 0x607C; 33, 34, 35, 37 home in
//    place); other methods end in a homing error.
// Fault injection: injectFault (EMCY + fault reaction -> fault), setSilent
// (no frames in or out: heartbeat stops), SDO responses delayed or dropped,
// motion blocked (following error), failing homing attempts, power cycle.
// Bus-off of the drive's endpoint is VirtualBus::setBusOff(endpoint, d); on
// recovery the drive sends EMCY 0x8140 "recovered from bus off".
// The constructor sets the endpoint's receive filters to the drive's COB-IDs
// (NMT, SYNC, its RPDOs and SDO requests). Thread-safe (one mutex); poll()
// is deterministic on a VirtualClock.
#pragma once

#include <atomic>
#include <deque>
#include <functional>
#include <mutex>

#include "massage_cell/can/bus.h"
#include "massage_cell/can/canopen.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/config.h"
#include "massage_cell/can/object_dictionary.h"
#include "massage_cell/can/sim_mechanics.h"

namespace massage_cell::can {

class SimDrive {
 public:
  enum class HomingFailure { kHang, kError };

  struct Stats {
    std::uint64_t syncs = 0, rpdos_applied = 0, rpdos_rejected = 0, tpdos = 0, sdo_requests = 0, sdo_aborts = 0;
    std::uint64_t emcys = 0, heartbeats = 0, frames_ignored = 0, sdo_dropped = 0;
    std::uint64_t master_heartbeats = 0;        ///< heartbeats of the consumed producer (0x1016:01) received
    std::uint64_t master_heartbeat_losses = 0;  ///< consumer timeouts (EMCY 0x8130)
  };

  /// A powered-off drive for `config` (node id, scale, sim.* settings, and
  /// the profile values as power-up defaults). Call powerOn().
  SimDrive(Bus& bus, const Clock& clock, const AxisConfig& config);

  /// Power-up: initialisation, boot-up message, pre-operational.
  void powerOn();
  /// Power cut: nothing is sent or received until powerOn() (the position
  /// reference is lost; motion stops).
  void powerOff();
  /// Receives every pending frame, then advances the simulation to clock.now()
  /// (motion, heartbeat, delayed SDO responses, change-driven TPDOs).
  void poll();
  /// Runs poll() until `stop` is set, waiting for frames up to `wait` (real time).
  void run(const std::atomic<bool>& stop, Duration wait = std::chrono::milliseconds(1));

  // --- fault injection -----------------------------------------------------------
  /// A drive error: EMCY with `code` and the error register, then fault reaction -> fault.
  void injectFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer = {});
  /// Silence: no frame is sent and every received frame is ignored.
  void setSilent(bool silent);
  /// SDO responses leave `delay` after the request.
  void setSdoResponseDelay(Duration delay);
  /// A force on the axis from outside (N, + toward higher positions) as a function of the axis' physical position
  /// (m, the frame of sim.start_position / home_switch) and velocity (m/s): a body under the tool. Called in every
  /// integration step under the drive's lock: it must not call back into this drive. Empty: none.
  using ExternalForce = std::function<double(double position_m, double velocity_mps)>;
  void setExternalForce(ExternalForce force);
  /// The next `count` SDO responses are never sent.
  void dropSdoResponses(int count);
  /// The motor cannot move (blocked load): the following error grows until fault 0x8611.
  void setMotionBlocked(bool blocked);
  /// The next `attempts` homing runs fail: kHang stops before the switch (never
  /// attained), kError sets the homing error bit.
  void failHoming(int attempts, HomingFailure kind);

  // --- observation --------------------------------------------------------------------
  bool powered() const;
  NmtState nmtState() const;
  Cia402State state() const;
  std::uint16_t statusword() const;
  std::int32_t position() const;  ///< counts (0x6064)
  double velocity() const;        ///< counts/s
  std::int8_t modeDisplay() const;
  bool homed() const;
  std::uint16_t errorCode() const;  ///< 0x603F
  /// The axis' physical position, m (lock-free: what another drive's external force may read).
  double physicalPosition() const { return physical_m_.load(std::memory_order_relaxed); }
  /// The true external force of the last step, N (setExternalForce), and the motor's force along the axis, N.
  double externalForce() const;
  double motorForce() const;
  std::int64_t object(std::uint16_t index, std::uint8_t sub) const;  ///< OD value (device-internal read)
  Stats stats() const;
  std::uint8_t node() const { return config_.node_id; }
  const AxisConfig& config() const { return config_; }

 private:
  struct PendingSdo {
    TimePoint due;
    can_frame frame;
  };
  struct Upload {
    bool active = false;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;
    std::size_t offset = 0;
    bool toggle = false;
  };
  struct Download {
    bool active = false;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::uint32_t size = 0;
    bool size_known = false;
    std::vector<std::uint8_t> data;
    bool toggle = false;
  };

  // CiA 301 side (sim_drive_comm.cpp): frames, NMT, PDOs, heartbeat, EMCY, bus filters.
  void send(const can_frame& f);
  void process(const can_frame& f, TimePoint now);
  int rpdoFor(const can_frame& f) const;  // the RPDO (0..3) with the frame's COB-ID, -1 if none
  void handleNmt(const NmtMessage& m, TimePoint now);
  void handleRpdo(int n, const can_frame& f);
  void applyRpdo(int n, const std::vector<std::uint64_t>& values);
  void handleSync();
  std::optional<can_frame> packTpdo(int n) const;
  void sendTpdo(int n);
  void checkChangeTpdos();
  void bootUp(TimePoint now);
  void resetCommunication();
  std::uint32_t checkWrite(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data) const;
  void afterWrite(std::uint16_t index, std::uint8_t sub);
  PdoMapping mapping(std::uint16_t mapping_index) const;
  void sendEmcy(std::uint16_t code, std::uint8_t reg, std::array<std::uint8_t, 5> manufacturer = {});
  void applyFilters();
  void sendDueSdoResponses(TimePoint now);
  void produceHeartbeat(TimePoint now);
  void checkHeartbeatConsumer(TimePoint now);
  void checkBusRecovery();
  // SDO server (sim_drive_sdo.cpp).
  void handleSdo(const SdoFrame& r, TimePoint now);
  void sdoInitiateUpload(const SdoFrame& r, TimePoint now);
  void sdoUploadSegment(const SdoFrame& r, TimePoint now);
  void sdoInitiateDownload(const SdoFrame& r, TimePoint now);
  void sdoDownloadSegment(const SdoFrame& r, TimePoint now);
  void respondSdo(const can_frame& f, TimePoint now);
  void abortSdo(std::uint16_t index, std::uint8_t sub, std::uint32_t code, TimePoint now);
  // CiA 402 side (sim_drive_motion.cpp): state machine, profile position, homing, motion.
  void resetApplication();
  void processControlword();
  void applyStateCommand(std::uint16_t cw);                       // controlword bits 0..3: transitions
  void applyOperationBits(std::uint16_t cw, std::uint16_t prev);  // bits 4..8 while operation enabled
  void acceptSetPoint(std::uint16_t cw);                          // profile position: new set-point
  void enterState(Cia402State s);
  void enterFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer);
  void startHoming();
  void completeHoming();
  void step(double dt);
  void stepOperationEnabled(double dt);
  void stepHoming(double dt);
  void syncCyclicTarget();  ///< at each SYNC in cyclic synchronous position: the next target from 0x607A
  void stepCyclic(double dt);
  void brake(double dec, double dt);
  bool approach(double target, double vmax, double acc, double dec, double dt);  // true when arrived
  void monitorFollowingError();
  void updateProcessObjects();
  std::uint16_t composeStatusword() const;
  double countsPerSecond(double metres_per_second) const { return metres_per_second * config_.counts_per_metre; }
  void updateMechanics(double dt, double previous_actual, double previous_velocity);
  // sim_drive.cpp
  void advance(TimePoint now);

  Bus& bus_;
  const Clock& clock_;
  AxisConfig config_;
  SimMechanics mechanics_;
  ExternalForce external_;
  double external_force_ = 0.0;
  std::atomic<double> physical_m_{0.0};
  mutable std::mutex mutex_;
  ObjectDictionary od_;
  Stats stats_;

  bool powered_ = false;
  bool silent_ = false;
  NmtState nmt_ = NmtState::kPreOperational;
  TimePoint next_heartbeat_{};
  TimePoint last_advance_{};
  BusState bus_state_ = BusState::kErrorActive;
  // heartbeat consumer (0x1016:01)
  bool consumer_armed_ = false;  // a heartbeat of the producer arrived since (re)configuration / the last loss
  TimePoint consumer_last_{};

  // SDO server
  Upload upload_;
  Download download_;
  std::deque<PendingSdo> pending_sdo_;
  Duration sdo_delay_{};
  int sdo_drop_ = 0;

  // PDO
  std::array<std::optional<std::vector<std::uint64_t>>, 4> rpdo_latched_{};
  std::array<unsigned, 4> tpdo_sync_count_{};
  std::array<std::optional<can_frame>, 4> tpdo_last_{};

  // CiA 402
  Cia402State state_ = Cia402State::kNotReadyToSwitchOn;
  std::uint16_t cw_prev_ = 0;
  double actual_ = 0.0;    // counts, in the reported frame
  double demand_ = 0.0;    // counts
  double velocity_ = 0.0;  // counts/s (of the demand)
  double switch_pos_ = 0.0;
  double offset_ = 0.0;  // reported - physical (set by homing)
  double pp_target_ = 0.0;
  bool moving_ = false;
  // cyclic synchronous position: from where to where the demand goes between two SYNCs
  double csp_from_ = 0.0, csp_to_ = 0.0, csp_elapsed_ = 0.0, csp_period_ = 0.01, last_sync_s_ = 0.0;
  /// The load's velocity as the servo gives it (the demand's, lagging by kServoLagS): its change is the
  /// acceleration the motor's torque carries (sim_mechanics.h).
  double servo_velocity_ = 0.0;
  static constexpr double kServoLagS = 0.002;
  static constexpr double kCspExtrapolation = 1.5;  ///< how far past its target a late SYNC's segment goes on
  bool setpoint_ack_ = false;
  bool target_reached_ = true;
  bool internal_limit_ = false;
  bool halt_ = false;
  bool blocked_ = false;
  double following_since_s_ = -1.0;
  double sim_time_s_ = 0.0;
  // homing
  bool homing_active_ = false;
  bool homing_attained_ = false;
  bool homing_error_ = false;
  bool homed_ = false;
  int homing_fail_count_ = 0;
  HomingFailure homing_fail_kind_ = HomingFailure::kHang;
  bool homing_failing_ = false;
  double homing_started_s_ = 0.0;
  double homing_goal_ = 0.0;
};

}  // namespace massage_cell::can
