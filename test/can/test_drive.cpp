// Layers 3-5 together: the CANopen master with CiA 402 axes against
// simulated drives on a VirtualBus, on a VirtualClock (deterministic, each
// step = 1 ms: drives poll, then the master). Every CiA 402 transition,
// fault + fault reset, quick stop, homing with retries, profile-position
// moves, each fault injection ending in a defined and reported state,
// bus-off recovery, malformed frames, and the threaded mode on a real clock.
#include <gtest/gtest.h>

#include <random>
#include <thread>

#include "massage_cell/can/cia402.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;
using S = Cia402State;
using Status = Cia402Axis::Status;

CanConfig exampleConfig() { return loadCanConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml"); }

struct Rig {
  explicit Rig(CanConfig c = exampleConfig()) : config(std::move(c)) {
    master = std::make_unique<Master>(*master_ep, clock, config);
    for (const AxisConfig& a : config.axes) {
      eps.push_back(bus.open("drive " + a.name));
      drives.push_back(std::make_unique<SimDrive>(*eps.back(), clock, a));
      axes.push_back(std::make_unique<Cia402Axis>(*master, a));
    }
  }
  void step(Duration dt = 1ms) {
    clock.advance(dt);
    for (auto& d : drives) d->poll();
    if (!master_polled) return;  // the master "stops": no heartbeat, no SYNC, nothing received
    master->poll();
    for (Event& e : master->takeEvents()) events.push_back(std::move(e));
  }
  bool runUntil(const std::function<bool()>& pred, Duration limit) {
    for (Duration t{}; t < limit; t += 1ms) {
      if (pred()) return true;
      step();
    }
    return pred();
  }
  void run(Duration d) {
    runUntil([] { return false; }, d);
  }
  // Power, bring-up; true when every node is operational.
  bool start() {
    for (auto& d : drives) d->powerOn();
    step();
    master->bringUp();
    return runUntil(
        [&] { return master->allOperational() && axes[0]->valid() && axes[1]->valid() && axes[2]->valid(); }, 3s);
  }
  // Runs until the axis's operation ends; true when it succeeded.
  bool finish(Cia402Axis& ax, Duration limit = 60s) {
    runUntil([&] { return ax.status() != Status::kRunning; }, limit);
    return ax.status() == Status::kSucceeded;
  }
  bool enable(int i) {
    axes[i]->enable();
    return finish(*axes[i], 5s);
  }
  bool hasEvent(EventType type, std::uint8_t node, const std::string& text) const {
    for (const Event& e : events) {
      if (e.type == type && e.node == node && e.text.find(text) != std::string::npos) return true;
    }
    return false;
  }
  std::string dump() const {
    std::string s;
    for (const Event& e : events) s += std::string(toString(e.type)) + ": " + e.text + "\n";
    return s;
  }

  VirtualClock clock;
  VirtualBus bus{clock};
  std::shared_ptr<VirtualBus::Endpoint> master_ep = bus.open("master");
  CanConfig config;
  std::unique_ptr<Master> master;
  std::vector<std::shared_ptr<VirtualBus::Endpoint>> eps;
  std::vector<std::unique_ptr<SimDrive>> drives;
  std::vector<std::unique_ptr<Cia402Axis>> axes;
  std::vector<Event> events;
  bool master_polled = true;
};

bool contains(const std::vector<S>& h, const std::vector<S>& seq) {
  std::size_t i = 0;
  for (S s : h) {
    if (i < seq.size() && s == seq[i]) ++i;
  }
  return i == seq.size();
}

TEST(Drive, BringUpConfiguresTheDrives) {
  Rig r;
  ASSERT_TRUE(r.start()) << r.dump();
  for (std::size_t i = 0; i < 3; ++i) {
    const SimDrive& d = *r.drives[i];
    const AxisConfig& a = r.config.axes[i];
    EXPECT_EQ(d.nmtState(), NmtState::kOperational);
    EXPECT_EQ(d.object(0x1017, 0), a.heartbeat_ms);
    EXPECT_EQ(d.object(0x1A00, 1), 0x60410010);
    EXPECT_EQ(d.object(0x6060, 0), 1);
    EXPECT_EQ(d.object(0x6081, 0), std::llround(a.profile_velocity * a.counts_per_metre));
    EXPECT_EQ(d.object(0x607D, 2), a.toCounts(a.max_position));
    EXPECT_EQ(d.object(0x6098, 0), a.homing_method);
    EXPECT_EQ(r.axes[i]->state(), S::kSwitchOnDisabled);
    EXPECT_EQ(r.axes[i]->positionCounts(), a.toCounts(a.sim.start_position));
  }
  EXPECT_TRUE(r.master->feedback(1).has_velocity);   // X maps TPDO2
  EXPECT_FALSE(r.master->feedback(3).has_velocity);  // Z does not
}

TEST(Drive, EnableWalksThroughEveryTransition) {
  Rig r;
  ASSERT_TRUE(r.start());
  ASSERT_TRUE(r.enable(0)) << r.axes[0]->error();
  EXPECT_TRUE(contains(r.axes[0]->history(),
                       {S::kSwitchOnDisabled, S::kReadyToSwitchOn, S::kSwitchedOn, S::kOperationEnabled}));
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "switched on -> operation enabled"));
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "axis X (node 1): enable done"));
  // Disable: 9 (operation enabled -> switch on disabled).
  r.axes[0]->disable();
  ASSERT_TRUE(r.finish(*r.axes[0], 2s)) << r.axes[0]->error();
  EXPECT_EQ(r.drives[0]->state(), S::kSwitchOnDisabled);
  // The other axes never moved out of switch on disabled.
  EXPECT_EQ(r.drives[1]->state(), S::kSwitchOnDisabled);
}

TEST(Drive, ProfilePositionMoveReachesItsTarget) {
  Rig r;
  ASSERT_TRUE(r.start());
  ASSERT_TRUE(r.enable(0));
  Cia402Axis& x = *r.axes[0];
  const TimePoint t0 = r.clock.now();
  x.moveTo(0.35);  // from 0.20: 0.15 m at 0.1 m/s, 0.5 m/s^2 -> 1.5 s + 0.2 s
  ASSERT_TRUE(r.finish(x)) << x.error() << "\n" << r.dump();
  const double t = std::chrono::duration<double>(r.clock.now() - t0).count();
  EXPECT_GT(t, 1.65);
  EXPECT_LT(t, 1.85);
  EXPECT_LE(std::abs(x.positionCounts() - x.config().toCounts(0.35)), 1);
  EXPECT_LE(std::abs(r.drives[0]->position() - x.config().toCounts(0.35)), 1);
  EXPECT_NEAR(x.position(), 0.35, 1e-6);
  // Back again, a short move.
  x.moveTo(0.349);
  ASSERT_TRUE(r.finish(x)) << x.error();
  EXPECT_LE(std::abs(x.positionCounts() - x.config().toCounts(0.349)), 1);
  // Out of the configured limits: refused without a frame.
  x.moveTo(0.9);
  EXPECT_EQ(x.status(), Status::kFailed);
  EXPECT_NE(x.error().find("target 0.900000 m is outside the limits [0.000000, 0.800000] m"), std::string::npos)
      << x.error();
  EXPECT_LE(std::abs(r.drives[0]->position() - x.config().toCounts(0.349)), 1);
}

TEST(Drive, CyclicTargetsAreFollowedEverySyncThenProfilePositionAgain) {
  Rig r;
  ASSERT_TRUE(r.start());
  ASSERT_TRUE(r.enable(2));
  Cia402Axis& z = *r.axes[2];
  EXPECT_FALSE(z.setCyclicTarget(z.positionCounts() - 100));  // not streaming: nothing sent
  z.setModeOfOperation(Mode::kCyclicSyncPosition);
  ASSERT_TRUE(r.finish(z, 2s)) << z.error() << r.dump();
  ASSERT_TRUE(z.cyclic());
  EXPECT_EQ(r.drives[2]->modeDisplay(), 8);
  // Down 1 mm per SYNC (0.1 m/s) for 10 SYNCs: the drive follows within a SYNC and a TPDO.
  const std::int32_t start = z.positionCounts();
  const std::int32_t mm = z.config().toCounts(0.001);
  for (int k = 1; k <= 10; ++k) {
    ASSERT_TRUE(z.setCyclicTarget(start - k * mm));
    r.run(10ms);
  }
  r.run(30ms);
  EXPECT_EQ(r.drives[2]->position(), start - 10 * mm);
  EXPECT_EQ(z.positionCounts(), start - 10 * mm);
  // Clamped to the configured limits (Z: 0 .. 0.30 m), never beyond.
  ASSERT_TRUE(z.setCyclicTarget(z.config().toCounts(0.5)));
  r.run(200ms);
  EXPECT_LE(r.drives[2]->position(), z.config().toCounts(0.30));
  // A profile-position move is refused while streaming, and works again once back in mode 1.
  z.moveTo(0.2);
  EXPECT_EQ(z.status(), Status::kFailed);
  EXPECT_NE(z.error().find("cyclic"), std::string::npos) << z.error();
  z.setModeOfOperation(Mode::kProfilePosition);
  ASSERT_TRUE(r.finish(z, 2s)) << z.error();
  EXPECT_FALSE(z.cyclic());
  z.moveTo(0.2);
  ASSERT_TRUE(r.finish(z)) << z.error();
  EXPECT_NEAR(z.position(), 0.2, 1e-6);
}

TEST(Drive, MovesOfAllAxesAtOnce) {
  Rig r;
  ASSERT_TRUE(r.start());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.enable(i)) << r.axes[i]->error();
  const double targets[3] = {0.5, 0.3, 0.1};
  for (int i = 0; i < 3; ++i) r.axes[i]->moveTo(targets[i]);
  ASSERT_TRUE(r.runUntil(
      [&] {
        return r.axes[0]->status() != Status::kRunning && r.axes[1]->status() != Status::kRunning &&
               r.axes[2]->status() != Status::kRunning;
      },
      20s));
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(r.axes[i]->status(), Status::kSucceeded) << r.axes[i]->error();
    EXPECT_LE(std::abs(r.axes[i]->positionCounts() - r.axes[i]->config().toCounts(targets[i])), 1);
  }
}

TEST(Drive, MoveRefusedUnlessEnabled) {
  Rig r;
  ASSERT_TRUE(r.start());
  r.axes[1]->moveTo(0.2);
  EXPECT_FALSE(r.finish(*r.axes[1], 1s));
  EXPECT_NE(r.axes[1]->error().find("move refused: drive is 'switch on disabled', not operation enabled"),
            std::string::npos)
      << r.axes[1]->error();
  EXPECT_EQ(r.drives[1]->position(), r.axes[1]->config().toCounts(0.10));
}

TEST(Drive, QuickStopThenSwitchOnDisabled) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& x = *r.axes[0];
  ASSERT_TRUE(r.enable(0));
  x.moveTo(0.6);
  r.run(800ms);  // cruising at 0.1 m/s
  ASSERT_GT(std::abs(r.drives[0]->velocity()), 0.09 * x.config().counts_per_metre);
  x.quickStop();
  ASSERT_TRUE(r.finish(x, 2s)) << x.error();
  // Option 2: decelerate on 0x6085 (2 m/s^2: 2.5 mm from 0.1 m/s), then switch on disabled.
  EXPECT_TRUE(contains(x.history(), {S::kOperationEnabled, S::kQuickStopActive, S::kSwitchOnDisabled}));
  EXPECT_EQ(r.drives[0]->state(), S::kSwitchOnDisabled);
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "move superseded by quick stop"));
  const std::int32_t stopped = r.drives[0]->position();
  r.run(200ms);
  EXPECT_EQ(r.drives[0]->position(), stopped);
}

TEST(Drive, QuickStopHeldAndReenabled) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& z = *r.axes[2];  // quick_stop_option 6: stay in quick stop active
  ASSERT_TRUE(r.enable(2));
  z.moveTo(0.15);
  r.run(500ms);
  z.quickStop();
  ASSERT_TRUE(r.finish(z, 2s)) << z.error();
  EXPECT_EQ(r.drives[2]->state(), S::kQuickStopActive);
  r.run(100ms);
  EXPECT_EQ(z.state(), S::kQuickStopActive);
  // Transition 16: quick stop active -> operation enabled.
  ASSERT_TRUE(r.enable(2)) << z.error();
  EXPECT_TRUE(contains(z.history(), {S::kQuickStopActive, S::kOperationEnabled}));
  z.moveTo(0.15);
  ASSERT_TRUE(r.finish(z)) << z.error();
  EXPECT_LE(std::abs(z.positionCounts() - z.config().toCounts(0.15)), 1);
}

TEST(Drive, FaultAndFaultReset) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& y = *r.axes[1];
  ASSERT_TRUE(r.enable(1));
  y.moveTo(0.3);
  r.run(300ms);
  r.drives[1]->injectFault(0x2310);
  ASSERT_FALSE(r.finish(y, 2s));
  EXPECT_NE(y.error().find("move aborted by a drive fault (statusword 0x"), std::string::npos) << y.error();
  EXPECT_NE(y.error().find("last EMCY 0x2310 continuous over-current"), std::string::npos) << y.error();
  r.runUntil([&] { return y.state() == S::kFault; }, 1s);
  EXPECT_EQ(y.state(), S::kFault);
  EXPECT_TRUE(contains(y.history(), {S::kOperationEnabled, S::kFaultReactionActive, S::kFault}));
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 2, "node 2 (Y): EMCY 0x2310 continuous over-current (error register 0x03)"));
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 2, "FAULT"));
  // Enabling a faulted drive says why it cannot.
  y.enable();
  ASSERT_FALSE(r.finish(y, 1s));
  EXPECT_NE(y.error().find("could not enable: drive is in 'fault'"), std::string::npos) << y.error();
  EXPECT_NE(y.error().find("reset the fault first"), std::string::npos);
  // Fault reset (rising edge of bit 7) -> switch on disabled, EMCY 0x0000.
  y.faultReset();
  ASSERT_TRUE(r.finish(y, 2s)) << y.error();
  EXPECT_EQ(r.drives[1]->state(), S::kSwitchOnDisabled);
  EXPECT_EQ(r.drives[1]->errorCode(), 0);
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 2, "EMCY 0x0000 error reset or no error"));
  ASSERT_TRUE(r.enable(1)) << y.error();
  y.moveTo(0.3);
  ASSERT_TRUE(r.finish(y)) << y.error();
}

TEST(Drive, FaultResetWithoutFaultIsANoOp) {
  Rig r;
  ASSERT_TRUE(r.start());
  r.axes[0]->faultReset();
  ASSERT_TRUE(r.finish(*r.axes[0], 1s));
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "no fault to reset"));
}

TEST(Drive, FollowingErrorFaultsTheDrive) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& x = *r.axes[0];
  ASSERT_TRUE(r.enable(0));
  r.drives[0]->setMotionBlocked(true);
  x.moveTo(0.4);
  ASSERT_FALSE(r.finish(x, 5s));
  EXPECT_NE(x.error().find("last EMCY 0x8611 following error"), std::string::npos) << x.error();
  EXPECT_TRUE(r.runUntil([&] { return x.state() == S::kFault; }, 1s));  // through fault reaction active
  EXPECT_EQ(r.drives[0]->state(), S::kFault);
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 1, "EMCY 0x8611 following error"));
  // Stalled in place: the load did not move.
  EXPECT_EQ(r.drives[0]->position(), x.config().toCounts(0.20));
  r.drives[0]->setMotionBlocked(false);
  x.faultReset();
  ASSERT_TRUE(r.finish(x, 2s)) << x.error();
  ASSERT_TRUE(r.enable(0));
  x.moveTo(0.4);
  ASSERT_TRUE(r.finish(x)) << x.error();
}

TEST(Drive, EnableTimeoutNamesTheStuckStateAndStatusword) {
  Rig r;
  ASSERT_TRUE(r.start());
  // Every RPDO to node 2 is lost: the drive never sees the shutdown command.
  r.bus.dropNext(1 << 30, [](const can_frame& f) { return f.can_id == 0x202; });
  Cia402Axis& y = *r.axes[1];
  const TimePoint t0 = r.clock.now();
  y.enable();
  ASSERT_FALSE(r.finish(y, 2s));
  EXPECT_EQ(y.error(),
            "axis Y (node 2): could not enable: stuck in 'switch on disabled' (statusword 0x0240) for 500 ms waiting "
            "for 'ready to switch on' after controlword 0x0006");
  const double t = std::chrono::duration<double>(r.clock.now() - t0).count();
  EXPECT_GT(t, 0.5);
  EXPECT_LT(t, 0.53);
}

TEST(Drive, HomingSetsTheHomeOffsetAndReturnsToProfilePosition) {
  Rig r;
  ASSERT_TRUE(r.start());
  for (int i : {0, 2}) {
    Cia402Axis& a = *r.axes[i];
    ASSERT_TRUE(r.enable(i));
    EXPECT_FALSE(a.homed());
    a.home();
    ASSERT_TRUE(r.finish(a, 30s)) << a.error() << "\n" << r.dump();
    EXPECT_TRUE(a.homed());
    EXPECT_TRUE(r.drives[i]->homed());
    EXPECT_LE(std::abs(a.positionCounts() - a.config().toCounts(a.config().home_offset)), 1);
    EXPECT_EQ(r.drives[i]->modeDisplay(), 1);
    a.moveTo(0.1);
    ASSERT_TRUE(r.finish(a)) << a.error();
    EXPECT_LE(std::abs(a.positionCounts() - a.config().toCounts(0.1)), 1);
  }
  // X homed from 0.20 m to its switch at 0.0 at 0.05 m/s: about 4 s.
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "homing done: homed at 0.000000 m"));
}

CanConfig shortHoming() {
  CanConfig c = exampleConfig();
  c.axes[0].homing_timeout_ms = 6000;
  return c;
}

TEST(Drive, HomingThatTimesOutWorksOnRetry) {
  Rig r(shortHoming());
  ASSERT_TRUE(r.start());
  Cia402Axis& x = *r.axes[0];
  ASSERT_TRUE(r.enable(0));
  r.drives[0]->failHoming(2, SimDrive::HomingFailure::kHang);
  x.home();
  ASSERT_TRUE(r.finish(x, 40s)) << x.error() << "\n" << r.dump();
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "homing attempt 1 of 3 failed (not attained within 6000 ms"));
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "homing attempt 2 of 3 failed"));
  EXPECT_TRUE(x.homed());
  EXPECT_LE(std::abs(x.positionCounts()), 1);
}

TEST(Drive, HomingErrorOnEveryAttemptFailsClearly) {
  Rig r(shortHoming());
  ASSERT_TRUE(r.start());
  Cia402Axis& x = *r.axes[0];
  ASSERT_TRUE(r.enable(0));
  r.drives[0]->failHoming(3, SimDrive::HomingFailure::kError);
  x.home();
  ASSERT_FALSE(r.finish(x, 40s));
  EXPECT_NE(x.error().find("homing failed after 3 attempts: homing error (statusword bit 13"), std::string::npos)
      << x.error();
  EXPECT_FALSE(x.homed());
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);  // defined state: enabled, standing, not homed
}

TEST(Drive, SilentDriveIsReportedLostThenBack) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& y = *r.axes[1];
  ASSERT_TRUE(r.enable(1));
  y.moveTo(0.3);
  r.run(100ms);
  r.drives[1]->setSilent(true);
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kLost; }, 1s));
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatTimeout, 2, "node 2 (Y): no heartbeat for 300 ms"));
  ASSERT_TRUE(r.runUntil([&] { return y.status() != Status::kRunning; }, 1s));
  EXPECT_EQ(y.status(), Status::kFailed);
  EXPECT_NE(y.error().find("move aborted: node is lost"), std::string::npos) << y.error();
  EXPECT_FALSE(y.valid());
  r.drives[1]->setSilent(false);
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kOperational && y.valid(); }, 1s));
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatResumed, 2, "heartbeat resumed (operational)"));
  // The drive kept going on its own (it never lost the set-point): it reports where it is.
  ASSERT_TRUE(r.runUntil([&] { return r.drives[1]->velocity() == 0.0; }, 5s));
  r.run(25ms);  // two more TPDOs
  EXPECT_EQ(y.positionCounts(), r.drives[1]->position());
  y.moveTo(0.1);
  ASSERT_TRUE(r.finish(y)) << y.error();
}

TEST(Drive, DelayedAndDroppedSdoResponses) {
  Rig r;
  ASSERT_TRUE(r.start());
  std::vector<SdoResult> got;
  auto collect = [&](const SdoResult& res) { got.push_back(res); };
  r.drives[0]->setSdoResponseDelay(50ms);  // under the 100 ms timeout: fine
  r.master->sdoUpload(1, 0x1000, 0, collect);
  ASSERT_TRUE(r.runUntil([&] { return got.size() == 1; }, 1s));
  EXPECT_TRUE(got[0].ok) << got[0].error;
  EXPECT_EQ(fromBytes(got[0].data), 0x00020192u);
  r.drives[0]->setSdoResponseDelay(150ms);  // over it: timeout, abort sent
  r.master->sdoUpload(1, 0x1000, 0, collect);
  ASSERT_TRUE(r.runUntil([&] { return got.size() == 2; }, 1s));
  EXPECT_FALSE(got[1].ok);
  EXPECT_EQ(got[1].abort_code, sdo_abort::kTimeout);
  EXPECT_NE(got[1].error.find("SDO protocol timed out"), std::string::npos) << got[1].error;
  r.drives[0]->setSdoResponseDelay(0ms);
  r.drives[0]->dropSdoResponses(1);
  r.master->sdoUpload(1, 0x1008, 0, collect);  // dropped: times out
  r.master->sdoUpload(1, 0x1008, 0, collect);  // segmented: works
  ASSERT_TRUE(r.runUntil([&] { return got.size() == 4; }, 1s));
  EXPECT_EQ(got[2].abort_code, sdo_abort::kTimeout);
  ASSERT_TRUE(got[3].ok) << got[3].error;
  EXPECT_EQ(std::string(got[3].data.begin(), got[3].data.end()), "massage_cell sim drive X");
  // The late answer to the timed-out request was discarded by the drive (abort received).
  EXPECT_EQ(r.master->nodeState(1), NodeState::kOperational);
}

TEST(Drive, SdoAbortsComeBackWithText) {
  Rig r;
  ASSERT_TRUE(r.start());
  std::vector<SdoResult> got;
  auto collect = [&](const SdoResult& res) { got.push_back(res); };
  r.master->sdoDownload(1, 0x6041, 0, {0, 0}, collect);
  r.master->sdoUpload(1, 0x2345, 0, collect);
  r.master->sdoUpload(1, 0x1018, 9, collect);
  r.master->sdoDownload(1, 0x6060, 0, {3}, collect);     // profile velocity: not supported
  r.master->sdoDownload(1, 0x6081, 0, {1, 2}, collect);  // 2 bytes for a 4-byte object
  r.master->sdoDownload(1, 0x1A00, 0, {1}, collect);     // mapping while TPDO1 is valid
  ASSERT_TRUE(r.runUntil([&] { return got.size() == 6; }, 1s));
  EXPECT_NE(got[0].error.find("0x06010002 attempt to write a read only object"), std::string::npos) << got[0].error;
  EXPECT_NE(got[1].error.find("0x06020000 object does not exist"), std::string::npos) << got[1].error;
  EXPECT_NE(got[2].error.find("0x06090011 sub-index does not exist"), std::string::npos) << got[2].error;
  EXPECT_NE(got[3].error.find("0x06090030 invalid value"), std::string::npos) << got[3].error;
  EXPECT_NE(got[4].error.find("0x06070013"), std::string::npos) << got[4].error;
  EXPECT_NE(got[5].error.find("0x08000022"), std::string::npos) << got[5].error;
}

TEST(Drive, DriveBusOffIsReportedAndRecovered) {
  Rig r;
  ASSERT_TRUE(r.start());
  ASSERT_TRUE(r.enable(1));
  r.bus.setBusOff(*r.eps[1], 500ms);
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kLost; }, 1s));
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kOperational; }, 1s));
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatTimeout, 2, "no heartbeat"));
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatResumed, 2, "heartbeat resumed"));
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 2, "EMCY 0x8140 recovered from bus off"));
  r.axes[1]->moveTo(0.2);
  ASSERT_TRUE(r.finish(*r.axes[1])) << r.axes[1]->error();
  EXPECT_LE(std::abs(r.axes[1]->positionCounts() - r.axes[1]->config().toCounts(0.2)), 1);
}

TEST(Drive, MasterRecoversFromBusOff) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& x = *r.axes[0];
  ASSERT_TRUE(r.enable(0));
  x.moveTo(0.5);
  r.run(300ms);
  r.bus.setBusOff(*r.master_ep, 1s);  // longer than the heartbeat timeout
  r.run(1100ms);
  EXPECT_TRUE(r.hasEvent(EventType::kBusStateChanged, 0, "master: error-active -> bus-off")) << r.dump();
  EXPECT_TRUE(r.hasEvent(EventType::kBusStateChanged, 0, "bus-off -> error-active (recovered)"));
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatTimeout, 1, "no heartbeat"));
  ASSERT_TRUE(r.runUntil([&] { return r.master->allOperational() && x.valid(); }, 1s)) << r.dump();
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatResumed, 1, "heartbeat resumed"));
  EXPECT_EQ(x.status(), Status::kFailed);  // the move was aborted when the node was lost
  EXPECT_EQ(x.state(), S::kOperationEnabled);
  x.moveTo(0.5);
  ASSERT_TRUE(r.finish(x)) << x.error();
  EXPECT_LE(std::abs(x.positionCounts() - x.config().toCounts(0.5)), 1);
}

TEST(Drive, PowerCycleIsDetectedAndReconfigured) {
  Rig r;
  ASSERT_TRUE(r.start());
  Cia402Axis& y = *r.axes[1];
  ASSERT_TRUE(r.enable(1));
  y.home();
  ASSERT_TRUE(r.finish(y, 30s)) << y.error();
  ASSERT_TRUE(y.homed());
  r.drives[1]->powerOff();
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kLost; }, 1s));
  r.drives[1]->powerOn();
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(2) == NodeState::kOperational && y.valid(); }, 2s));
  EXPECT_TRUE(r.hasEvent(EventType::kBootUp, 2, "unexpected boot-up (node was lost): reconfiguring")) << r.dump();
  EXPECT_FALSE(y.homed());
  EXPECT_EQ(y.state(), S::kSwitchOnDisabled);
  EXPECT_EQ(r.drives[1]->object(0x6060, 0), 1);  // reconfigured
  ASSERT_TRUE(r.enable(1));
}

TEST(Drive, MalformedFramesNeverMoveAnAxis) {
  Rig r;
  ASSERT_TRUE(r.start());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.enable(i));
  std::int32_t before[3];
  for (int i = 0; i < 3; ++i) before[i] = r.drives[i]->position();
  auto rogue = r.bus.open("rogue");
  std::mt19937 rng(11);
  const std::uint64_t rejected_before = r.drives[0]->stats().rpdos_rejected;
  for (int k = 0; k < 3000; ++k) {
    const std::uint8_t node = static_cast<std::uint8_t>(1 + rng() % 3);
    can_frame f{};
    for (auto& b : f.data) b = static_cast<std::uint8_t>(rng());
    switch (rng() % 7) {
      case 0:  // RPDO1 "enable + new set-point, target far away" with a wrong DLC
        f = *packPdo(0x200 + node, rpdo1Mapping(), {0x1F, 400000});
        f.len = static_cast<std::uint8_t>(rng() % 2 ? 5 : 7 + rng() % 2);
        break;
      case 1:  // the same as an extended frame
        f = *packPdo(0x200 + node, rpdo1Mapping(), {0x1F, 400000});
        f.can_id |= CAN_EFF_FLAG;
        break;
      case 2:  // ... and as a remote frame
        f = *packPdo(0x200 + node, rpdo1Mapping(), {0x1F, 400000});
        f.can_id |= CAN_RTR_FLAG;
        break;
      case 3:  // NMT reset with a wrong DLC
        f.can_id = 0x000;
        f.data[0] = 0x81;
        f.data[1] = node;
        f.len = 3;
        break;
      case 4:  // SYNC with 2 bytes
        f.can_id = 0x080;
        f.len = 2;
        break;
      case 5:  // short SDO download of a controlword
        f = sdoInitiateDownloadRequest(node, 0x6040, 0, {0x1F, 0x00});
        f.len = static_cast<std::uint8_t>(rng() % 8);
        break;
      default:  // a TPDO to the master with a wrong DLC
        f = *packPdo(0x180 + node, tpdo1Mapping(), {0x0027, 12345});
        f.len = 4;
        break;
    }
    rogue->send(f);
    if (k % 10 == 0) r.step();
  }
  r.run(200ms);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(r.drives[i]->position(), before[i]) << i;
    EXPECT_EQ(r.axes[i]->positionCounts(), before[i]) << i;
    EXPECT_EQ(r.drives[i]->state(), S::kOperationEnabled) << i;
    EXPECT_EQ(r.drives[i]->nmtState(), NmtState::kOperational) << i;
  }
  EXPECT_TRUE(r.master->allOperational());
  EXPECT_GT(r.drives[0]->stats().rpdos_rejected, rejected_before);
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 1, "0x8210 PDO not processed due to length error"));
  EXPECT_TRUE(r.hasEvent(EventType::kMalformedFrame, 1, "DLC 4 but 6 bytes mapped"));
  // And the axes still work.
  r.axes[0]->moveTo(0.25);
  ASSERT_TRUE(r.finish(*r.axes[0])) << r.axes[0]->error();
}

// The drives' consumer of the master's heartbeat (0x1016, 0x6007): X faults,
// Z (quick-stop option 6) holds in quick stop active, Y does not monitor the master.
CanConfig consumerConfig() {
  CanConfig c = exampleConfig();
  c.axes[0].master_heartbeat_timeout_ms = 300;  // abort connection option 1 (default): fault
  c.axes[2].master_heartbeat_timeout_ms = 300;
  c.axes[2].abort_connection_option = 3;  // quick stop
  return c;
}

TEST(Drive, AStallOfTheSimulatedDrivesOwnIsNotTheMastersSilence) {
  // The host paused 1 s (the consumers' timeout is 300 ms) and the drives ran first after it: nothing from the master
  // in their queues, yet the master was not silent while they ran; neither side faults.
  Rig r(consumerConfig());
  ASSERT_TRUE(r.start()) << r.dump();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.enable(i)) << r.axes[i]->error();
  r.step(1s);
  r.run(500ms);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(r.drives[i]->state(), S::kOperationEnabled) << i;
    EXPECT_EQ(r.drives[i]->stats().master_heartbeat_losses, 0u) << i;
  }
  EXPECT_FALSE(r.hasEvent(EventType::kHeartbeatTimeout, 1, "no heartbeat")) << r.dump();
}

TEST(Drive, DrivesReactWhenTheMasterHeartbeatStops) {
  Rig r(consumerConfig());
  ASSERT_TRUE(r.start()) << r.dump();
  EXPECT_EQ(r.drives[0]->object(0x1016, 1), (127 << 16) | 300);
  EXPECT_EQ(r.drives[1]->object(0x1016, 1), 0);
  EXPECT_EQ(r.drives[2]->object(0x6007, 0), 3);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.enable(i)) << r.axes[i]->error();
  // While the master runs, its heartbeat (every 100 ms) keeps the consumers happy.
  r.run(1s);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(r.drives[i]->state(), S::kOperationEnabled) << i;
  EXPECT_GE(r.drives[0]->stats().master_heartbeats, 10u);
  EXPECT_EQ(r.drives[0]->stats().master_heartbeat_losses, 0u);
  Cia402Axis& x = *r.axes[0];
  x.moveTo(0.5);
  r.run(200ms);
  ASSERT_EQ(x.status(), Status::kRunning);
  const std::int32_t moving_at = r.drives[0]->position();
  // The master stops (hangs, crashes): 300 ms after its last heartbeat the drives react.
  r.master_polled = false;
  r.run(190ms);                                           // its last heartbeat was at most 100 ms before it stopped
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);  // not yet
  r.run(260ms);
  EXPECT_EQ(r.drives[0]->state(), S::kFault);
  EXPECT_EQ(r.drives[0]->errorCode(), 0x8130);
  EXPECT_EQ(r.drives[0]->stats().master_heartbeat_losses, 1u);
  EXPECT_EQ(r.drives[2]->state(), S::kQuickStopActive);
  EXPECT_EQ(r.drives[1]->state(), S::kOperationEnabled);  // Y is not told to watch the master
  EXPECT_NE(r.drives[0]->position(), moving_at);          // it was moving and braked to a stop
  const std::int32_t stopped_at = r.drives[0]->position(), z_at = r.drives[2]->position();
  r.run(300ms);
  EXPECT_EQ(r.drives[0]->position(), stopped_at);
  // The master comes back: the EMCYs waiting in its queue, then the drives' states by TPDO1.
  // Z's quick stop option 6 keeps it in quick stop active until the master's cyclic
  // "enable operation" controlword (RPDO1) takes it back (CiA 402 transition 16),
  // standing where it stopped; X stays in fault until a fault reset.
  r.master_polled = true;
  ASSERT_TRUE(r.runUntil([&] { return x.state() == S::kFault; }, 500ms)) << r.dump();
  ASSERT_TRUE(r.runUntil([&] { return r.drives[2]->state() == S::kOperationEnabled; }, 100ms));
  EXPECT_EQ(r.axes[2]->state(), S::kOperationEnabled);
  EXPECT_EQ(r.drives[2]->position(), z_at);
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 1, "EMCY 0x8130 life guard error or heartbeat error")) << r.dump();
  EXPECT_TRUE(r.hasEvent(EventType::kEmcy, 3, "EMCY 0x8130"));
  EXPECT_EQ(x.status(), Status::kFailed);
  EXPECT_NE(x.error().find("move aborted by a drive fault"), std::string::npos) << x.error();
  EXPECT_NE(x.error().find("last EMCY 0x8130"), std::string::npos) << x.error();
  // Brought back: fault reset + enable (X), enable from quick stop active (Z), then move.
  x.faultReset();
  ASSERT_TRUE(r.finish(x, 2s)) << x.error();
  ASSERT_TRUE(r.enable(0)) << x.error();
  ASSERT_TRUE(r.enable(2)) << r.axes[2]->error();
  x.moveTo(0.5);
  ASSERT_TRUE(r.finish(x)) << x.error();
  EXPECT_LE(std::abs(x.positionCounts() - x.config().toCounts(0.5)), 1);
  EXPECT_EQ(r.drives[0]->stats().master_heartbeat_losses, 1u);  // re-armed by the heartbeats, no new loss
}

TEST(Drive, HeartbeatConsumerWaitsForTheFirstHeartbeatAndChecksItsObjects) {
  CanConfig c = consumerConfig();
  c.master_heartbeat_ms = 0;  // (not a valid config for a master: written by hand below)
  c.axes[0].master_heartbeat_timeout_ms = 0;
  c.axes[2].master_heartbeat_timeout_ms = 0;
  Rig r(c);
  ASSERT_TRUE(r.start());
  ASSERT_TRUE(r.enable(0));
  std::vector<SdoResult> got;
  auto collect = [&](const SdoResult& res) { got.push_back(res); };
  r.master->sdoDownload(1, 0x1016, 1, toBytes((127u << 16) | 200u, 4), collect);  // monitor node 127, 200 ms
  r.master->sdoDownload(1, 0x1016, 1, toBytes((1u << 16) | 200u, 4), collect);    // itself: refused
  r.master->sdoDownload(1, 0x1016, 1, toBytes(0x01000000u | (5u << 16) | 200u, 4), collect);  // reserved bits
  r.master->sdoDownload(1, 0x6007, 0, toBytes(4, 2), collect);                                // no such reaction here
  ASSERT_TRUE(r.runUntil([&] { return got.size() == 4; }, 1s));
  EXPECT_TRUE(got[0].ok) << got[0].error;
  EXPECT_NE(got[1].error.find("0x06090030"), std::string::npos) << got[1].error;
  EXPECT_NE(got[2].error.find("0x06090030"), std::string::npos) << got[2].error;
  EXPECT_NE(got[3].error.find("0x06090031"), std::string::npos) << got[3].error;
  // No heartbeat from node 127 ever came: the consumer is not armed, nothing happens.
  r.run(1s);
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);
  EXPECT_EQ(r.drives[0]->stats().master_heartbeat_losses, 0u);
  // One heartbeat arms it; 200 ms of silence after it faults the drive.
  auto other = r.bus.open("another master");
  other->send(encodeHeartbeat(127, NmtState::kOperational));
  r.run(150ms);
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);
  other->send(encodeHeartbeat(127, NmtState::kOperational));
  r.run(150ms);
  EXPECT_EQ(r.drives[0]->state(), S::kOperationEnabled);
  r.run(100ms);
  EXPECT_EQ(r.drives[0]->state(), S::kFault);
  EXPECT_EQ(r.drives[0]->stats().master_heartbeats, 2u);
  // Reset communication clears 0x1016: no monitoring after a reboot until configured again.
  EXPECT_EQ(r.drives[0]->object(0x1016, 1), (127 << 16) | 200);
  r.master->sendNmt(NmtCommand::kResetCommunication, 1);
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(1) == NodeState::kConfiguring; }, 100ms));
  ASSERT_TRUE(r.runUntil([&] { return r.master->nodeState(1) == NodeState::kOperational; }, 1s));
  EXPECT_EQ(r.drives[0]->object(0x1016, 1), 0);
}

TEST(Drive, MasterBusOffLongerThanTheDrivesConsumerTimeEndsInADefinedState) {
  Rig r(consumerConfig());
  ASSERT_TRUE(r.start());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(r.enable(i));
  r.bus.setBusOff(*r.master_ep, 1s);  // no heartbeat from the master for 1 s: X faults, Z quick-stops
  r.run(1100ms);
  EXPECT_TRUE(r.hasEvent(EventType::kBusStateChanged, 0, "master: error-active -> bus-off")) << r.dump();
  EXPECT_TRUE(r.hasEvent(EventType::kBusStateChanged, 0, "bus-off -> error-active (recovered)"));
  ASSERT_TRUE(r.runUntil([&] { return r.master->allOperational() && r.axes[0]->valid() && r.axes[2]->valid(); }, 1s));
  // The EMCYs were sent while the master was bus-off and are lost; the states come by
  // TPDO1: X in fault, Y untouched, Z back in operation enabled (the master's cyclic
  // "enable operation" after its quick stop, transition 16), standing still.
  EXPECT_FALSE(r.hasEvent(EventType::kEmcy, 1, "0x8130"));
  EXPECT_EQ(r.drives[0]->stats().master_heartbeat_losses, 1u);
  EXPECT_EQ(r.drives[2]->stats().master_heartbeat_losses, 1u);
  EXPECT_EQ(r.axes[0]->state(), S::kFault);
  EXPECT_EQ(r.axes[1]->state(), S::kOperationEnabled);
  EXPECT_EQ(r.axes[2]->state(), S::kOperationEnabled);
  EXPECT_TRUE(r.hasEvent(EventType::kHeartbeatTimeout, 1, "no heartbeat"));
  EXPECT_TRUE(r.hasEvent(EventType::kAxis, 1, "FAULT (statusword")) << r.dump();
  r.axes[0]->faultReset();
  ASSERT_TRUE(r.finish(*r.axes[0], 2s)) << r.axes[0]->error();
  ASSERT_TRUE(r.enable(0)) << r.axes[0]->error();
  r.axes[2]->moveTo(0.2);
  ASSERT_TRUE(r.finish(*r.axes[2])) << r.axes[2]->error();
  EXPECT_LE(std::abs(r.axes[2]->positionCounts() - r.axes[2]->config().toCounts(0.2)), 1);
}

TEST(Drive, ThreadedMasterAndDrivesOnTheRealClock) {
  CanConfig c = exampleConfig();
  c.axes.resize(1);
  c.axes[0].profile_velocity = 0.5;
  c.axes[0].profile_acceleration = 5.0;
  c.axes[0].profile_deceleration = 5.0;
  const Clock& clock = SteadyClock::instance();
  VirtualBus bus(clock);
  auto mep = bus.open("master"), dep = bus.open("drive");
  Master master(*mep, clock, c);
  Cia402Axis x(master, c.axes[0]);
  SimDrive drive(*dep, clock, c.axes[0]);
  std::atomic<bool> stop{false};
  std::thread dt([&] { drive.run(stop); });
  drive.powerOn();
  master.start();
  master.bringUp();
  const bool up = master.waitUntil([&] { return master.allOperational() && x.valid(); }, 3s);
  std::string log;
  for (const Event& e : master.takeEvents()) log += e.text + "\n";
  EXPECT_TRUE(up) << log << toString(master.nodeState(1)) << " drive nmt " << toString(drive.nmtState());
  x.enable();
  EXPECT_TRUE(master.waitUntil([&] { return x.status() != Status::kRunning; }, 3s));
  EXPECT_EQ(x.status(), Status::kSucceeded) << x.error();
  x.moveTo(0.25);
  EXPECT_TRUE(master.waitUntil([&] { return x.status() != Status::kRunning; }, 5s));
  EXPECT_EQ(x.status(), Status::kSucceeded) << x.error();
  EXPECT_LE(std::abs(x.positionCounts() - c.axes[0].toCounts(0.25)), 1);
  master.stop();
  stop = true;
  dt.join();
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
