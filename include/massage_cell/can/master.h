// CANopen master (layer 3; CiA 301 subset) for the configured nodes:
//  - NMT: commands, bring-up (reset communication -> boot-up -> SDO
//    configuration in pre-operational -> start -> operational heartbeat),
//    boot-up detection (a node that reboots on its own is reconfigured);
//  - SYNC producer (bus.sync_period_ms); before each SYNC the owner's
//    before-SYNC hook runs (setBeforeSyncHook: a cyclic controller computes
//    its set-points there), then the RPDO1 of every operational node
//    (controlword 0x6040 + target position 0x607A) is sent, so synchronous
//    drives apply it at that SYNC; sendRpdoNow() sends a node's RPDO1 at
//    once, between two SYNCs (the e-stop's quick stop);
//  - TPDO consumer: TPDO1 = statusword 0x6041 + position actual 0x6064,
//    TPDO2 (velocity_pdo) = velocity actual 0x606C + mode display 0x6061,
//    TPDO3 (torque_pdo) = torque actual 0x6077;
//  - heartbeat consumer per node (timeout -> event, node lost; heartbeat
//    back -> event, node back or reconfigured);
//  - EMCY consumer -> event with the error-code text;
//  - SDO client per node (sdo_client.h);
//  - bus state changes (error-passive, bus-off, recovery) -> events, also
//    for a bus-off or interface loss that came and went between two polls
//    (seen in the bus's bus_off_events / recoveries counters);
//  - bus-off / interface loss recovery: the bus endpoint reopens by itself
//    (SocketCanBus back-off); a node whose bring-up failed because the bus
//    was bus-off or down meanwhile (lost NMT command, SDO timeout, no
//    boot-up) has its bring-up restarted once the bus is back (at once when
//    it already is), so no node stays `failed` because of an outage; nodes
//    that were operational keep their state when the outage is shorter than
//    their heartbeat consumer time, else they are `lost` (running axis
//    operations fail) and come back on their next heartbeat;
//  - heartbeat producer (CiA 301 §7.2.8.3.2): every bus.master_heartbeat_ms
//    the master sends 0x700 + bus.master_node_id with its own NMT state
//    (pre-operational until the first bringUp(), then operational); it
//    stops when the master stops being polled (stop(), destruction), which
//    is what a drive's heartbeat consumer (0x1016) detects.
// PDO mapping is written by SDO at start-up (0x1400/0x1600, 0x1800/0x1A00,
// CiA 301 §7.5.2.35-38), with the PDO disabled while its mapping changes.
//
// Driving: poll() processes every received frame and all timers once and
// never blocks, so tests run the master, the simulated drives and a
// VirtualClock in one thread, deterministically. start() runs the same
// poll in a background thread on a real clock (tools, nodes), optionally
// under SCHED_FIFO (realtime.h). All public
// functions lock one recursive mutex; tick handlers and SDO callbacks run
// under it (from poll), so they may call back into the master.
#pragma once

#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "massage_cell/can/bus.h"
#include "massage_cell/can/config.h"
#include "massage_cell/can/realtime.h"
#include "massage_cell/can/sdo_client.h"

namespace massage_cell::can {

/// The master's view of one node.
enum class NodeState {
  kUnknown,      ///< not brought up yet
  kResetting,    ///< reset communication sent, waiting for boot-up
  kConfiguring,  ///< SDO configuration running (node pre-operational)
  kStarting,     ///< NMT start sent, waiting for an operational heartbeat
  kOperational,  ///< configured, NMT operational, heartbeat alive
  kStopped,      ///< configured but its heartbeat reports stopped / pre-operational
  kLost,         ///< heartbeat timed out
  kFailed,       ///< bring-up failed (see the kConfigureFailed event)
};
const char* toString(NodeState state);

enum class EventType {
  kBootUp,            ///< a node sent its boot-up message
  kNodeOperational,   ///< bring-up finished
  kConfigureFailed,   ///< bring-up failed (text: why)
  kHeartbeatTimeout,  ///< consumer heartbeat time expired
  kHeartbeatResumed,  ///< heartbeat back after a timeout
  kNmtStateChanged,   ///< heartbeat reports another NMT state
  kEmcy,              ///< EMCY received (emcy_code, error_register, text)
  kBusStateChanged,   ///< our endpoint's state changed (text: new state)
  kMalformedFrame,    ///< a frame that did not decode (rate-limited: once per node per second)
  kAxis,              ///< CiA 402 layer: axis state / fault / operation result
};
const char* toString(EventType type);

/// Something the master (or an axis) wants to report.
struct Event {
  EventType type = EventType::kAxis;
  std::uint8_t node = 0;  ///< 0: not node-specific
  TimePoint stamp{};
  std::string text;
  std::uint16_t emcy_code = 0;
  std::uint8_t error_register = 0;
};

/// Latest process data of one drive (from its TPDOs).
struct DriveFeedback {
  bool valid = false;  ///< a TPDO1 arrived since the node became operational
  std::uint16_t statusword = 0;
  std::int32_t position = 0;  ///< counts
  bool has_velocity = false;
  std::int32_t velocity = 0;  ///< counts/s
  std::int8_t mode_display = 0;
  bool has_torque = false;  ///< a TPDO3 arrived (AxisConfig::torque_pdo)
  std::int16_t torque = 0;  ///< 0x6077 torque actual, per mille of the rated torque (AxisConfig::rated_torque)
  TimePoint torque_stamp{};
  TimePoint stamp{};
  std::uint64_t count = 0;      ///< TPDO1s received
  std::uint16_t emcy_code = 0;  ///< last EMCY error code of the node (0x0000: reset / none)
  TimePoint emcy_stamp{};
};

struct MasterStats {
  std::uint64_t syncs = 0, rpdos = 0, tpdos = 0, emcys = 0, heartbeats = 0, sdo_responses = 0;
  std::uint64_t malformed = 0, ignored = 0, send_failures = 0;
  std::uint64_t heartbeats_produced = 0;  ///< own heartbeats sent (bus.master_heartbeat_ms)
  std::uint64_t bus_outages = 0;          ///< bus-off / down periods seen (including ones between two polls)
  std::uint64_t bringup_restarts = 0;     ///< bring-ups restarted because an outage made them fail
};

/// One SDO write of the start-up configuration.
struct StartupWrite {
  std::uint16_t index;
  std::uint8_t sub;
  std::vector<std::uint8_t> data;
};
/// The CANopen part of a node's start-up configuration: 0x1017 heartbeat
/// producer time, RPDO1 (0x6040 + 0x607A, synchronous), TPDO1 (0x6041 +
/// 0x6064, every SYNC), TPDO2 (0x606C + 0x6061, every SYNC) or TPDO2 disabled,
/// TPDO3 (0x6077, every SYNC: torque_pdo) or TPDO3 disabled.
/// (This form assumes the default master node id, 127.)
std::vector<StartupWrite> canopenStartupWrites(const AxisConfig& axis);
/// The same, plus, when axis.master_heartbeat_timeout_ms > 0, the drive's
/// consumer of the master's heartbeat: 0x1016:01 = master_node_id << 16 |
/// timeout (CiA 301 §7.5.2.7) and 0x6007 = abort_connection_option.
std::vector<StartupWrite> canopenStartupWrites(const AxisConfig& axis, std::uint8_t master_node_id);
/// TPDO mappings the master expects.
PdoMapping tpdo1Mapping();
PdoMapping tpdo2Mapping();
PdoMapping tpdo3Mapping();
PdoMapping rpdo1Mapping();

class Master {
 public:
  using TickHandler = std::function<void(TimePoint now)>;
  using EventCallback = std::function<void(const Event&)>;

  /// The master of `config.axes` on `bus`; throws ConfigError for an invalid config.
  Master(Bus& bus, const Clock& clock, CanConfig config);
  ~Master();
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;

  /// The configuration the master runs (validated).
  const CanConfig& config() const { return config_; }
  /// The clock every timeout is measured on.
  const Clock& clock() const { return clock_; }
  /// The lock of all master state (layers above hold it across several calls).
  RecursivePiMutex& mutex() const { return mutex_; }

  // --- driving ---------------------------------------------------------------
  /// Processes every frame waiting on the bus, then timers, tick handlers and
  /// the SYNC producer (with the before-SYNC hook); never blocks.
  void poll();
  /// Runs poll() in a background thread (real clocks only). With
  /// `realtime_priority` > 0 that thread runs under SCHED_FIFO at that
  /// priority (realtime.h); returns "" or why that was refused (the thread
  /// then runs with normal scheduling).
  std::string start(int realtime_priority = 0);
  void stop();
  bool threaded() const { return thread_.joinable(); }
  /// The SCHED_FIFO priority of the thread start() runs (0: normal scheduling, or no thread).
  int threadPriority() const;
  /// Waits until `pred` (evaluated under the lock after each poll) holds;
  /// polls by itself when no thread runs. False on timeout (real time).
  bool waitUntil(const std::function<bool()>& pred, Duration timeout);

  // --- NMT -------------------------------------------------------------------
  /// Sends an NMT command (node 0 = all); false when the bus refused it.
  bool sendNmt(NmtCommand command, std::uint8_t node);
  /// Brings every configured node up (asynchronous; watch nodeState / events).
  void bringUp();
  void bringUp(std::uint8_t node);
  NodeState nodeState(std::uint8_t node) const;
  std::optional<NmtState> nmtState(std::uint8_t node) const;
  bool allOperational() const;
  /// The master's own NMT state as its heartbeat reports it: pre-operational
  /// until the first bringUp(), then operational.
  NmtState ownNmtState() const;

  // --- SDO -------------------------------------------------------------------
  void sdoUpload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, SdoClient::Callback done);
  void sdoDownload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                   SdoClient::Callback done);
  /// Adds a write to the node's start-up configuration (after the CANopen part).
  void addStartupWrite(std::uint8_t node, StartupWrite write);

  // --- PDO -------------------------------------------------------------------
  DriveFeedback feedback(std::uint8_t node) const;
  /// RPDO1 content sent before every SYNC while the node is operational.
  void setRpdo(std::uint8_t node, std::uint16_t controlword, std::int32_t target);
  /// The controlword currently being sent.
  std::uint16_t controlword(std::uint8_t node) const;
  /// The target position the node's RPDO1 carries (the last setRpdo; nullopt before the first).
  std::optional<std::int32_t> rpdoTarget(std::uint8_t node) const;
  /// Sends the node's RPDO1 (what setRpdo last set) now instead of waiting
  /// for the next SYNC (a synchronous drive applies it at that SYNC, which
  /// also carries it again as usual): a command that must not wait up to a
  /// SYNC period, the e-stop's quick stop (Cia402Axis::quickStopNow). False
  /// when nothing was sent: node not operational, no RPDO set, bus refused.
  bool sendRpdoNow(std::uint8_t node);

  // --- events / hooks ----------------------------------------------------------
  // Events reach their readers two ways: a queue with ONE reader, who drains
  // it with takeEvents() (a tool or test that owns the master; the queue
  // keeps at most the last 10000 events when nobody reads it), and any
  // number of listeners, each called for every event as it is posted. A
  // layer above that must see every event (arm::Controller) is a listener,
  // so whoever else drains the queue takes nothing from it.
  /// Drains the queue: the events since the last call (oldest first).
  std::vector<Event> takeEvents();
  /// Adds a listener, called for every event under the lock (it may call the
  /// master; it must not remove listeners); returns an id for removeEventListener.
  int addEventListener(EventCallback listener);
  void removeEventListener(int id);
  /// The one replaceable listener of the master's owner (tools); empty removes it.
  void setEventCallback(EventCallback callback);
  /// Records an event (layers above use kAxis).
  void postEvent(Event event);
  /// Runs at the end of every poll, before the SYNC producer (under the
  /// lock); returns an id for removeTickHandler.
  int addTickHandler(TickHandler handler);
  void removeTickHandler(int id);
  /// The owner's before-SYNC hook: called once per SYNC, right before the
  /// master sends that SYNC's RPDOs and the SYNC itself, in the thread that
  /// sends them (start()'s thread, or poll()'s caller), under the lock, with
  /// the poll's time, after the tick handlers; RPDO content set in it
  /// (setRpdo) goes out with this SYNC. One hook; empty removes it.
  void setBeforeSyncHook(TickHandler hook);
  /// RPDO1 frames sent to the node so far (a controlword edge needs one in between).
  std::uint64_t rpdosSent(std::uint8_t node) const;
  MasterStats stats() const;

 private:
  struct Node;
  Node& node(std::uint8_t id) const;
  bool send(const can_frame& frame);
  bool sendRpdo(std::uint8_t id, Node& n);  // its RPDO1 as set; counted
  void process(const TimedFrame& frame);
  void timers(TimePoint now);
  void startConfiguration(Node& n);
  void setState(Node& n, NodeState s);
  void checkBus();
  void bringUpFailed(Node& n, const std::string& why);
  void busRecovered();
  bool busUsable() const { return bus_state_ != BusState::kBusOff && bus_state_ != BusState::kDown; }
  void event(EventType type, std::uint8_t node, std::string text, std::uint16_t code = 0, std::uint8_t reg = 0);
  void malformed(std::uint8_t node, const std::string& why);
  std::string label(std::uint8_t node) const;
  void threadMain();

  Bus& bus_;
  const Clock& clock_;
  CanConfig config_;
  // Callers of every priority take this lock (ROS callbacks reading the
  // status, the SCHED_FIFO thread that sends SYNC): with priority
  // inheritance a preempted holder cannot hold the SYNC thread up.
  mutable RecursivePiMutex mutex_;
  std::condition_variable_any polled_;
  std::map<std::uint8_t, std::unique_ptr<Node>> nodes_;
  std::vector<Event> events_;
  EventCallback event_callback_;
  std::vector<std::pair<int, EventCallback>> event_listeners_;
  std::vector<std::pair<int, TickHandler>> tick_handlers_;
  int last_callback_id_ = 0;  // ids of tick handlers and event listeners
  TickHandler before_sync_;
  MasterStats stats_;
  TimePoint next_sync_{};
  BusState bus_state_ = BusState::kErrorActive;
  std::uint64_t seen_bus_offs_ = 0, seen_recoveries_ = 0;  // the bus's counters at the last check
  TimePoint next_heartbeat_{};
  std::optional<TimePoint> last_timers_;  // the previous timers() run: a longer gap is a stall of the master's own
  NmtState own_nmt_ = NmtState::kPreOperational;
  TimePoint last_unknown_malformed_{};
  std::thread thread_;
  bool stop_ = false;
};

}  // namespace massage_cell::can
