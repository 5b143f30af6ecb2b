// can_kernel_system: the CAN motion stack's system test on a real Linux
// SocketCAN stack (issue 6). Runs inside the qemu guest of
// scripts/qemu_can/run.sh (see cmake/qemu_can.cmake, ctest qemu_can_system)
// as the CANopen master on vcan0, against can_sim_drive running the
// simulated CiA 402 drives of the same config in another process:
//
//   can_sim_drive --interface vcan0 --config can_axes.yaml --fault-frame-id 0x6C0 &
//   can_kernel_system can_axes.yaml [--interface vcan0] [--fault-frame-id 0x6C0]
//
// Steps (each prints its result):
//   1. load the axes config; relax the timeouts for a software-emulated guest
//      (SDO >= 300 ms, boot >= 5 s, heartbeat consumer >= 1 s, CiA 402
//      transitions >= 2 s);
//   2. bring every node up (reset communication, boot-up, SDO PDO mapping and
//      drive parameters, NMT start, operational heartbeat); read the PDO
//      mappings back by SDO (0x1600:00 = 2, 0x1A00:00 = 2);
//   3. enable all CiA 402 axes; 4. home them; 5. move each to a target a few
//      cm away and check the reported position;
//   6. drive fault: a test frame (can_sim_drive --fault-frame-id) tells node
//      2's simulated drive to fail with 0x2310; the master must get the EMCY
//      and see the axis in fault while the others stay enabled; then fault
//      reset (EMCY 0x0000 error reset), enable, move again;
//   7. error-passive and bus-off through the kernel: vcan cannot go bus-off by
//      itself, but a CAN_RAW socket may write a frame whose can_id has
//      CAN_ERR_FLAG set, and af_can delivers it as an error frame to every
//      socket on vcan0 whose CAN_RAW_ERR_FILTER has that class (checked by
//      can_kernel_smoke). A second socket of this process (the "drive side":
//      not the master's) writes them; the test then knows the instant of each
//      injection, and can_sim_drive needs no second test hook. On vcan the
//      drives' sockets (default error mask) see the same frames, so the whole
//      bus goes "bus-off" and every socket recovers by itself.
//      a. CAN_ERR_CRTL / tx error-passive: the master's bus reports
//         error-passive (event) while the TPDOs keep flowing; CAN_ERR_CRTL /
//         back to error-active: it reports error-active again;
//      b. CAN_ERR_BUSOFF while all axes move: the SocketCanBus reports bus-off
//         (state, last_error, bus_off_events + 1, master event), closes the
//         socket and reopens it no earlier than its first back-off (100 ms):
//         recoveries + 1, "(recovered)" event; the outage is shorter than the
//         heartbeat consumer time, so no node is lost: every node stays
//         operational, every drive's TPDO1 flows again (their sockets came
//         back too), the moves started before the bus-off reach their targets
//         and the axes stay operation enabled;
//      c. a second bus-off right after the recovery: the back-off doubles (the
//         outage lasts >= 200 ms and longer than the first), then the same
//         checks; after each the master counts exactly one more outage
//         (MasterStats::bus_outages) and sends its own heartbeat again;
//   8. interface loss: `ip link set <if> down`, the
//      SocketCanBus must report "down" and the heartbeats time out; `ip link
//      set <if> up`: the bus must recover (reopened socket, recoveries + 1),
//      the nodes' heartbeats resume (operational), all axes enabled, and a
//      final move on every axis must reach its target.
// Prints `CAN_KERNEL_SYSTEM OK` and exits 0, or `CAN_KERNEL_SYSTEM FAIL: <why>`
// and exits 1.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "guest_test.h"
#include "massage_cell/can/canopen.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/master.h"
#include "massage_cell/can/socketcan_bus.h"

namespace {

using namespace massage_cell::can;
using std::chrono::milliseconds;
using std::chrono::seconds;

using namespace massage_cell::tools::guest;

std::string hex(unsigned v, int width = 4) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%0*X", width, v);
  return b;
}

class System {
 public:
  System(const std::string& interface, CanConfig config)
      : bus_(makeOptions(interface)), master_(bus_, SteadyClock::instance(), std::move(config)) {
    master_.setEventCallback([this](const Event& e) {  // called under the master's lock
      events_.push_back(e);
      std::printf("[%7.3f]   event %s node %d: %s\n", since(), toString(e.type), e.node, e.text.c_str());
      std::fflush(stdout);
    });
    for (const AxisConfig& a : master_.config().axes) axes_.push_back(std::make_unique<Cia402Axis>(master_, a));
  }
  ~System() { master_.stop(); }

  Master& master() { return master_; }
  SocketCanBus& bus() { return bus_; }
  std::vector<std::unique_ptr<Cia402Axis>>& axes() { return axes_; }
  Cia402Axis& axis(std::uint8_t node) {
    for (auto& a : axes_)
      if (a->node() == node) return *a;
    fail("no axis with node id " + std::to_string(node));
  }

  /// Index of the next event (for find()).
  std::size_t mark() {
    std::lock_guard<RecursivePiMutex> lock(master_.mutex());
    return events_.size();
  }
  /// Waits for an event after `from` matching `pred`.
  bool waitEvent(std::size_t from, const std::function<bool(const Event&)>& pred, milliseconds timeout) {
    return master_.waitUntil(
        [&] {
          for (std::size_t i = from; i < events_.size(); ++i)
            if (pred(events_[i])) return true;
          return false;
        },
        timeout);
  }

  /// Waits until no axis operation runs; fails naming the axes that failed.
  void waitAxes(const std::string& what, milliseconds timeout) {
    const bool done = master_.waitUntil(
        [&] {
          for (auto& a : axes_)
            if (a->busy()) return false;
          return true;
        },
        timeout);
    std::string errors;
    for (auto& a : axes_) {
      if (a->busy())
        errors += " axis " + a->name() + ": still running after " + std::to_string(timeout.count()) + " ms;";
      else if (a->status() == Cia402Axis::Status::kFailed)
        errors += " axis " + a->name() + ": " + a->error() + ";";
    }
    if (!done || !errors.empty()) fail(what + ":" + errors);
  }

  std::size_t countEvents(const std::function<bool(const Event&)>& pred) {
    std::lock_guard<RecursivePiMutex> lock(master_.mutex());
    return static_cast<std::size_t>(std::count_if(events_.begin(), events_.end(), pred));
  }

  SdoResult sdoUpload(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    auto result = std::make_shared<std::optional<SdoResult>>();
    master_.sdoUpload(node, index, sub, [result](const SdoResult& r) { *result = r; });
    if (!master_.waitUntil([&] { return result->has_value(); }, seconds(5)))
      fail("node " + std::to_string(node) + ": SDO upload " + hex(index) + " never completed");
    return **result;
  }

 private:
  static SocketCanOptions makeOptions(const std::string& interface) {
    SocketCanOptions o;
    o.interface = interface;
    return o;
  }

  SocketCanBus bus_;
  Master master_;
  std::vector<std::unique_ptr<Cia402Axis>> axes_;
  std::vector<Event> events_;  // guarded by master_.mutex()
};

std::string describe(Cia402Axis& a) {
  char b[160];
  std::snprintf(b, sizeof b, "%s (node %d): %s, statusword %s, position %.5f m%s", a.name().c_str(), a.node(),
                toString(a.state()), hex(a.statusword()).c_str(), a.position(), a.homed() ? ", homed" : "");
  return b;
}

void checkEnabled(System& s, const std::string& when) {
  for (auto& a : s.axes()) {
    if (a->state() != Cia402State::kOperationEnabled)
      fail(when + ": axis " + describe(*a) + " is not operation enabled");
    ok(describe(*a));
  }
}

void startMoves(System& s, const std::vector<std::pair<std::uint8_t, double>>& targets, const std::string& what) {
  std::string text;
  for (const auto& [node, target] : targets) {
    Cia402Axis& a = s.axis(node);
    a.moveTo(target);
    char b[64];
    std::snprintf(b, sizeof b, " %s->%.3f m", a.name().c_str(), target);
    text += b;
  }
  step(what + ":" + text);
}

void finishMoves(System& s, const std::vector<std::pair<std::uint8_t, double>>& targets, const std::string& what) {
  s.waitAxes(what, seconds(30));
  for (const auto& [node, target] : targets) {
    Cia402Axis& a = s.axis(node);
    // Position as reported by the drive's TPDO1 (0.5 um resolution): within 0.1 mm.
    const double err = std::fabs(a.position() - target);
    if (err > 1e-4 || !(a.statusword() & sw::kTargetReached)) {
      fail(what + ": axis " + describe(a) + " did not reach " + std::to_string(target) + " m (error " +
           std::to_string(err * 1000) + " mm)");
    }
    ok(describe(a) + " reached its target");
  }
}

void moveAll(System& s, const std::vector<std::pair<std::uint8_t, double>>& targets, const std::string& what) {
  startMoves(s, targets, what);
  finishMoves(s, targets, what);
}

// TPDO1 counts of every axis's node.
std::vector<std::uint64_t> tpdoCounts(System& s) {
  std::vector<std::uint64_t> c;
  for (auto& a : s.axes()) c.push_back(s.master().feedback(a->node()).count);
  return c;
}

// Waits until every node's TPDO1 count passed `before` by at least `more`.
void waitTpdos(System& s, const std::vector<std::uint64_t>& before, std::uint64_t more, const std::string& what) {
  const bool flowing = s.master().waitUntil(
      [&] {
        const auto now = tpdoCounts(s);
        for (std::size_t i = 0; i < now.size(); ++i)
          if (now[i] < before[i] + more) return false;
        return true;
      },
      seconds(5));
  if (!flowing) {
    std::string counts;
    const auto now = tpdoCounts(s);
    for (std::size_t i = 0; i < now.size(); ++i)
      counts += " " + s.axes()[i]->name() + " " + std::to_string(before[i]) + " -> " + std::to_string(now[i]) + ";";
    fail(what + ": TPDO1s do not flow from every drive (counts:" + counts + ")");
  }
}

using SteadyTime = std::chrono::steady_clock::time_point;
double msSince(SteadyTime t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

// One error frame written by `injector` (a second CAN_RAW socket on the interface).
void injectError(SocketCanBus& injector, canid_t error_class, std::uint8_t controller = 0) {
  can_frame f{};
  f.can_id = CAN_ERR_FLAG | error_class;
  f.len = CAN_ERR_DLC;
  f.data[1] = controller;
  if (!injector.send(f)) fail("writing the error frame " + formatFrame(f) + " failed: " + injector.status().last_error);
}

// A bus-off injected now; returns the outage (injection -> the master's bus back to error-active) in ms.
double busOff(System& s, SocketCanBus& injector, const std::string& what, double min_outage_ms) {
  const BusStatus before = s.bus().status();
  const MasterStats mbefore = s.master().stats();
  const std::size_t m = s.mark();
  const SteadyTime t0 = std::chrono::steady_clock::now();
  injectError(injector, CAN_ERR_BUSOFF);
  if (!s.master().waitUntil([&] { return s.bus().status().bus_off_events > before.bus_off_events; }, seconds(2)))
    fail(what + ": the master's SocketCanBus did not see the bus-off error frame within 2 s (state " +
         toString(s.bus().status().state) + ")");
  const double detect_ms = msSince(t0);
  const BusStatus off = s.bus().status();
  if (off.last_error.find("bus-off") == std::string::npos)
    fail(what + ": last_error does not name the bus-off: '" + off.last_error + "'");
  ok("bus-off detected after " + std::to_string(detect_ms) + " ms: state " + toString(off.state) + ", " +
     off.last_error);
  if (!s.master().waitUntil([&] { return s.bus().status().recoveries > before.recoveries; }, seconds(10)))
    fail(what + ": the SocketCanBus did not reopen within 10 s: " + s.bus().status().last_error);
  const double outage_ms = msSince(t0);
  const BusStatus back = s.bus().status();
  if (back.state != BusState::kErrorActive) fail(what + ": after the reopen the bus is " + toString(back.state));
  if (back.bus_off_events != before.bus_off_events + 1)
    fail(what + ": bus_off_events " + std::to_string(before.bus_off_events) + " -> " +
         std::to_string(back.bus_off_events) + ", expected + 1");
  if (outage_ms < min_outage_ms)
    fail(what + ": the socket was back after " + std::to_string(outage_ms) + " ms, before its back-off of " +
         std::to_string(min_outage_ms) + " ms");
  ok("reopened after " + std::to_string(outage_ms) + " ms (back-off >= " + std::to_string(min_outage_ms) +
     " ms), recoveries " + std::to_string(before.recoveries) + " -> " + std::to_string(back.recoveries));
  if (!s.waitEvent(
          m,
          [](const Event& e) {
            return e.type == EventType::kBusStateChanged && e.text.find("-> bus-off") != std::string::npos;
          },
          seconds(2)))
    fail(what + ": the master reported no 'bus-off' event");
  if (!s.waitEvent(
          m,
          [](const Event& e) {
            return e.type == EventType::kBusStateChanged && e.text.find("(recovered)") != std::string::npos;
          },
          seconds(2)))
    fail(what + ": the master reported no '(recovered)' event");
  ok("master events: bus-off, then recovered");
  // The master's own heartbeat goes out again (it could not while the socket was closed).
  const std::uint64_t produced = s.master().stats().heartbeats_produced;
  if (!s.master().waitUntil([&] { return s.master().stats().heartbeats_produced > produced; }, seconds(2)))
    fail(what + ": the master produces no heartbeat after the recovery");
  const MasterStats mafter = s.master().stats();
  ok("frames the master could not send meanwhile: " + std::to_string(mafter.send_failures - mbefore.send_failures) +
     "; its heartbeat goes out again; bus outages seen by the master " + std::to_string(mbefore.bus_outages) + " -> " +
     std::to_string(mafter.bus_outages));
  if (mafter.bus_outages != mbefore.bus_outages + 1)
    fail(what + ": the master counted " + std::to_string(mafter.bus_outages - mbefore.bus_outages) +
         " outages, expected 1");
  return outage_ms;
}

void waitAllOperational(System& s, const std::string& what, milliseconds timeout) {
  if (!s.master().waitUntil([&] { return s.master().allOperational(); }, timeout)) {
    std::string states;
    for (auto& a : s.axes())
      states += " node " + std::to_string(a->node()) + " " + toString(s.master().nodeState(a->node())) + ";";
    fail(what + ": not all nodes operational within " + std::to_string(timeout.count()) + " ms:" + states);
  }
}

/// The configuration with the timeouts an emulated CPU needs.
CanConfig systemConfig(const std::string& config_path) {
  // 1. config
  step("load " + config_path);
  CanConfig config = loadCanConfig(config_path);
  if (config.axes.size() < 2) fail(config_path + ": the test needs at least two axes");
  relaxTimeouts(&config);
  ok(std::to_string(config.axes.size()) + " axes; SDO timeout " + std::to_string(config.sdo_timeout_ms) +
     " ms, boot timeout " + std::to_string(config.boot_timeout_ms) + " ms, heartbeat consumer >= 1000 ms, SYNC " +
     std::to_string(config.sync_period_us / 1000) + " ms");
  return config;
}

/// Moves of every axis `d` metres away from home (the other way where the limit is near), inside the limits.
std::vector<std::pair<std::uint8_t, double>> targetsAway(System& s, double d) {
  std::vector<std::pair<std::uint8_t, double>> t;
  for (auto& a : s.axes()) {
    const AxisConfig& c = a->config();
    const double home = c.home_offset;
    const double to = home + d <= c.max_position ? home + d : home - d;
    t.emplace_back(a->node(), std::clamp(to, c.min_position, c.max_position));
  }
  return t;
}

void bringUp(System& s, const std::string& interface) {
  // 2. bring-up
  step("bring up all nodes on " + interface + " (NMT reset communication, SDO PDO mapping, NMT start)");
  s.master().bringUp();
  waitAllOperational(s, "bring-up", seconds(20));
  for (auto& a : s.axes()) {
    const std::uint8_t n = a->node();
    const SdoResult rpdo = s.sdoUpload(n, 0x1600, 0), tpdo = s.sdoUpload(n, 0x1A00, 0);
    if (!rpdo.ok || !tpdo.ok)
      fail("node " + std::to_string(n) + ": reading the PDO mapping back failed: " + rpdo.error + tpdo.error);
    if (rpdo.data.at(0) != 2 || tpdo.data.at(0) != 2) {
      fail("node " + std::to_string(n) + ": PDO mapping has " + std::to_string(rpdo.data.at(0)) + " RPDO1 / " +
           std::to_string(tpdo.data.at(0)) + " TPDO1 entries, expected 2 / 2");
    }
    ok("node " + std::to_string(n) + " (" + a->name() +
       ") operational; RPDO1 and TPDO1 mapping read back: 2 entries each");
  }
}

void enableAndHome(System& s) {
  // 3. enable
  step("enable all CiA 402 axes");
  for (auto& a : s.axes()) a->enable();
  s.waitAxes("enable", seconds(15));
  checkEnabled(s, "enable");

  // 4. homing
  step("home all axes");
  for (auto& a : s.axes()) a->home();
  s.waitAxes("homing", seconds(60));
  for (auto& a : s.axes()) {
    if (!a->homed() || std::fabs(a->position() - a->config().home_offset) > 1e-4)
      fail("homing: axis " + describe(*a) + " is not homed at " + std::to_string(a->config().home_offset) + " m");
    ok(describe(*a));
  }
}

void driveFault(System& s, const std::string& interface, canid_t fault_id) {
  // 6. drive fault on the second axis.
  Cia402Axis& victim = *s.axes().at(1);
  const std::uint8_t vn = victim.node();
  const std::uint16_t code = 0x2310;  // continuous over-current
  step("drive fault: tell node " + std::to_string(vn) + " (" + victim.name() + ") to fail with EMCY " + hex(code) +
       " (test frame " + hex(fault_id, 3) + " to can_sim_drive)");
  {
    SocketCanOptions o;
    o.interface = interface;
    o.filters = {};  // send only
    SocketCanBus trigger(o);
    std::size_t m = s.mark();
    if (!trigger.send(
            makeFrame(fault_id, {vn, static_cast<std::uint8_t>(code & 0xFF), static_cast<std::uint8_t>(code >> 8)})))
      fail("sending the fault test frame failed: " + trigger.status().last_error);
    if (!s.waitEvent(
            m, [&](const Event& e) { return e.type == EventType::kEmcy && e.node == vn && e.emcy_code == code; },
            seconds(5)))
      fail("drive fault: no EMCY " + hex(code) + " from node " + std::to_string(vn) +
           " within 5 s (is can_sim_drive running with --fault-frame-id " + hex(fault_id, 3) + "?)");
    ok("EMCY " + hex(code) + " (" + emcyText(code) + ") from node " + std::to_string(vn));
    if (!s.master().waitUntil([&] { return victim.state() == Cia402State::kFault; }, seconds(5)))
      fail("drive fault: axis " + describe(victim) + " did not reach 'fault' within 5 s");
    ok(describe(victim));
    if (s.master().feedback(vn).emcy_code != code) fail("drive fault: feedback.emcy_code is not " + hex(code));
    for (auto& a : s.axes()) {
      if (a.get() == &victim) continue;
      if (a->state() != Cia402State::kOperationEnabled)
        fail("drive fault: unrelated axis " + describe(*a) + " left operation enabled");
    }
    ok("the other axes stay operation enabled");

    step("fault reset on " + victim.name() + ", enable again");
    m = s.mark();
    victim.faultReset();
    s.waitAxes("fault reset", seconds(10));
    if (!s.waitEvent(
            m, [&](const Event& e) { return e.type == EventType::kEmcy && e.node == vn && e.emcy_code == 0; },
            seconds(5)))
      fail("fault reset: no EMCY 0x0000 (error reset) from node " + std::to_string(vn));
    ok("EMCY 0x0000 (error reset); " + describe(victim));
    victim.enable();
    s.waitAxes("enable after fault reset", seconds(15));
    checkEnabled(s, "after fault reset");
  }
  moveAll(s,
          {{vn, victim.config().home_offset +
                    (victim.config().home_offset + 0.06 <= victim.config().max_position ? 0.06 : -0.06)}},
          "move after fault recovery");
}

void errorStates(System& s, const std::string& interface) {
  // 7. error-passive and bus-off, injected as error frames by a second socket.
  {
    SocketCanOptions o;
    o.interface = interface;
    o.filters = {};    // it only writes
    o.error_mask = 0;  // and does not take part in the bus-off itself
    SocketCanBus injector(o);
    const Duration first_backoff = SocketCanOptions{}.reopen_initial;

    step("error-passive: a second socket writes an error frame CAN_ERR_CRTL / tx error-passive on " + interface);
    std::size_t m = s.mark();
    std::vector<std::uint64_t> counts = tpdoCounts(s);
    injectError(injector, CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE);
    if (!s.master().waitUntil([&] { return s.bus().status().state == BusState::kErrorPassive; }, seconds(2)))
      fail("error-passive: the master's bus still reports " + std::string(toString(s.bus().status().state)));
    if (!s.waitEvent(
            m,
            [](const Event& e) {
              return e.type == EventType::kBusStateChanged &&
                     e.text.find("error-active -> error-passive") != std::string::npos;
            },
            seconds(2)))
      fail("error-passive: no 'error-active -> error-passive' event from the master");
    waitTpdos(s, counts, 10, "error-passive");
    if (s.bus().status().state != BusState::kErrorPassive) fail("error-passive: the state did not stay error-passive");
    ok("master reports error-passive (" + s.bus().status().last_error + "); TPDO1s keep flowing");
    m = s.mark();
    injectError(injector, CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE);
    if (!s.master().waitUntil([&] { return s.bus().status().state == BusState::kErrorActive; }, seconds(2)))
      fail("back to error-active: the master's bus still reports " + std::string(toString(s.bus().status().state)));
    if (!s.waitEvent(
            m,
            [](const Event& e) {
              return e.type == EventType::kBusStateChanged &&
                     e.text.find("error-passive -> error-active") != std::string::npos;
            },
            seconds(2)))
      fail("back to error-active: no 'error-passive -> error-active' event from the master");
    ok("master reports error-active again");

    // b. bus-off while every axis moves.
    auto moves = targetsAway(s, 0.01);
    std::vector<double> from;
    for (auto& a : s.axes()) from.push_back(a->position());
    startMoves(s, moves, "moves across the bus-off");
    if (!s.master().waitUntil(
            [&] {
              for (std::size_t i = 0; i < s.axes().size(); ++i)
                if (!s.axes()[i]->busy() || std::fabs(s.axes()[i]->position() - from[i]) < 0.002) return false;
              return true;
            },
            seconds(5)))
      fail("moves across the bus-off: the axes did not all start moving (2 mm) within 5 s");
    std::string where;
    for (auto& a : s.axes()) where += " " + a->name() + " " + std::to_string(a->position()) + " m;";
    ok("all axes in motion:" + where);
    step("bus-off: a second socket writes an error frame CAN_ERR_BUSOFF while the axes move");
    m = s.mark();
    const double outage1 = busOff(s, injector, "bus-off", toMs(first_backoff));
    waitTpdos(s, tpdoCounts(s), 5, "after the bus-off");
    ok("every drive's TPDO1 flows again (the drives' sockets saw the error frame too and came back)");
    finishMoves(s, moves, "moves across the bus-off");
    if (s.waitEvent(
            m, [](const Event& e) { return e.type == EventType::kHeartbeatTimeout; }, milliseconds(0)))
      fail("bus-off: a heartbeat timed out although the outage was shorter than the consumer time");
    if (!s.master().allOperational()) fail("bus-off: not all nodes are operational");
    checkEnabled(s, "after the bus-off");
    ok("no node lost, all operational, every axis operation enabled at its target");

    // c. a second bus-off at once: the back-off doubles.
    step("a second bus-off right after the recovery: the back-off doubles");
    m = s.mark();
    const double outage2 = busOff(s, injector, "second bus-off", 2 * toMs(first_backoff));
    if (!(outage2 > outage1))
      fail("second bus-off: outage " + std::to_string(outage2) + " ms is not longer than the first (" +
           std::to_string(outage1) + " ms): no exponential back-off");
    waitTpdos(s, tpdoCounts(s), 5, "after the second bus-off");
    if (!s.master().allOperational()) fail("second bus-off: not all nodes are operational");
    checkEnabled(s, "after the second bus-off");
    // For information: the drives (their sockets went bus-off too) send EMCY 0x8140 when
    // they are back; whether the master's socket is open by then is a race on vcan.
    const std::size_t recovered_emcys =
        s.countEvents([](const Event& e) { return e.type == EventType::kEmcy && e.emcy_code == 0x8140; });
    ok(std::to_string(recovered_emcys) + " EMCY 0x8140 (recovered from bus off) from the drives reached the master");
    ok("outages " + std::to_string(outage1) + " ms then " + std::to_string(outage2) +
       " ms; nodes operational, axes enabled");
  }
}

void interfaceLoss(System& s, const std::string& interface) {
  // 8. interface down / up: the SocketCanBus handles it like a bus-off (close,
  // reopen with back-off, recovered).
  const BusStatus before = s.bus().status();
  step("interface loss: ip link set " + interface + " down");
  std::size_t m = s.mark();
  if (std::system(("ip link set " + interface + " down").c_str()) != 0)
    fail("`ip link set " + interface + " down` failed");
  if (!s.master().waitUntil([&] { return s.bus().status().state == BusState::kDown; }, seconds(5)))
    fail("interface down: the SocketCanBus still reports " + std::string(toString(s.bus().status().state)));
  ok("SocketCanBus state down: " + s.bus().status().last_error);
  if (!s.waitEvent(
          m, [](const Event& e) { return e.type == EventType::kBusStateChanged; }, seconds(5)))
    fail("interface down: no bus state event from the master");
  if (!s.waitEvent(
          m, [](const Event& e) { return e.type == EventType::kHeartbeatTimeout; }, seconds(5)))
    fail("interface down: no heartbeat timeout while the interface was down");
  ok("master reported the bus state change and heartbeat timeouts");
  step("ip link set " + interface + " up: wait for the reopen");
  m = s.mark();
  if (std::system(("ip link set " + interface + " up").c_str()) != 0) fail("`ip link set " + interface + " up` failed");
  if (!s.master().waitUntil(
          [&] {
            const BusStatus st = s.bus().status();
            return st.state == BusState::kErrorActive && st.recoveries > before.recoveries;
          },
          seconds(15)))
    fail("interface up: the SocketCanBus did not recover within 15 s: " + s.bus().status().last_error);
  ok("SocketCanBus back to error-active, recoveries " + std::to_string(before.recoveries) + " -> " +
     std::to_string(s.bus().status().recoveries));
  waitAllOperational(s, "after the interface came back", seconds(15));
  if (!s.waitEvent(
          m, [](const Event& e) { return e.type == EventType::kHeartbeatResumed; }, seconds(1)))
    fail("interface up: no heartbeat-resumed event");
  if (!s.master().waitUntil(
          [&] {
            for (auto& a : s.axes())
              if (!a->valid()) return false;
            return true;
          },
          seconds(5)))
    fail("interface up: no TPDO1 from every drive after recovery");
  ok("all nodes operational again, heartbeats and TPDOs flowing");
  for (auto& a : s.axes()) a->enable();  // a no-op for drives that stayed enabled
  s.waitAxes("enable after interface recovery", seconds(15));
  checkEnabled(s, "after interface recovery");
  moveAll(s, targetsAway(s, 0.02), "move after interface recovery");
}

int run(const std::string& config_path, const std::string& interface, canid_t fault_id) {
  System s(interface, systemConfig(config_path));
  s.master().start();
  bringUp(s, interface);
  enableAndHome(s);
  // 5. moves a few cm away from home, inside the limits.
  moveAll(s, targetsAway(s, 0.04), "move");
  driveFault(s, interface, fault_id);
  errorStates(s, interface);
  interfaceLoss(s, interface);
  const MasterStats st = s.master().stats();
  std::printf("master stats: syncs %llu rpdos %llu tpdos %llu emcys %llu heartbeats %llu sdo %llu send_failures %llu\n",
              static_cast<unsigned long long>(st.syncs), static_cast<unsigned long long>(st.rpdos),
              static_cast<unsigned long long>(st.tpdos), static_cast<unsigned long long>(st.emcys),
              static_cast<unsigned long long>(st.heartbeats), static_cast<unsigned long long>(st.sdo_responses),
              static_cast<unsigned long long>(st.send_failures));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_path, interface = "vcan0";
  canid_t fault_id = 0x6C0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--interface" && i + 1 < argc) {
      interface = argv[++i];
    } else if (a == "--fault-frame-id" && i + 1 < argc) {
      fault_id = static_cast<canid_t>(std::strtoul(argv[++i], nullptr, 0));
    } else if (a == "-h" || a == "--help") {
      std::printf("Usage: can_kernel_system CONFIG.yaml [--interface vcan0] [--fault-frame-id 0x6C0]\n");
      return 0;
    } else if (config_path.empty() && a.rfind("-", 0) != 0) {
      config_path = a;
    } else {
      std::printf("CAN_KERNEL_SYSTEM FAIL: bad argument '%s'\n", a.c_str());
      return 1;
    }
  }
  if (config_path.empty()) {
    std::printf("CAN_KERNEL_SYSTEM FAIL: no config file given\n");
    return 1;
  }
  try {
    run(config_path, interface, fault_id);
  } catch (const Failure& f) {
    std::printf("CAN_KERNEL_SYSTEM FAIL: %s\n", f.why.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::printf("CAN_KERNEL_SYSTEM FAIL: %s\n", e.what());
    return 1;
  }
  std::printf("CAN_KERNEL_SYSTEM OK\n");
  return 0;
}
