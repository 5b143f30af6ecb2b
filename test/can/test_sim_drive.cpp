// Layer 5 tests: the simulated drive on its own, driven by raw frames on a
// VirtualBus with a VirtualClock (NMT, heartbeat, SDO server edge cases,
// PDO transmission types, CiA 402 state machine and motion profile).
#include <gtest/gtest.h>

#include <cmath>

#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;
using S = Cia402State;

AxisConfig axis() {
  AxisConfig a;
  a.name = "T";
  a.node_id = 5;
  a.counts_per_metre = 100000;   // 10 um
  a.profile_velocity = 0.1;      // 10000 counts/s
  a.profile_acceleration = 0.5;  // 50000 counts/s^2
  a.profile_deceleration = 0.5;
  a.quick_stop_deceleration = 1.0;
  a.min_position = 0.0;
  a.max_position = 0.5;
  a.sim.start_position = 0.1;
  a.sim.device_name = "segmented name!";
  return a;
}

struct SimFixture : ::testing::Test {
  explicit SimFixture(const AxisConfig& config = axis()) : drive{*ep, clock, config} {
    drive.powerOn();
    tick();
  }
  void tick(Duration dt = 1ms) {
    clock.advance(dt);
    drive.poll();
  }
  std::vector<can_frame> received() {
    std::vector<can_frame> out;
    while (auto f = host->receive(0ns)) out.push_back(f->frame);
    return out;
  }
  // One SDO request; returns the drive's response.
  can_frame sdo(const can_frame& request) {
    received();
    host->send(request);
    tick();
    const auto frames = received();
    for (const can_frame& f : frames) {
      if (f.can_id == 0x585) return f;
    }
    ADD_FAILURE() << "no SDO response";
    return {};
  }
  void write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
    const can_frame r = sdo(sdoInitiateDownloadRequest(5, index, sub, data));
    ASSERT_EQ(r.data[0], 0x60) << std::hex << index << ":" << int(sub) << " -> " << formatFrame(r);
  }
  void sync() {
    host->send(encodeSync());
    tick();
  }
  void controlword(std::uint16_t cw, std::int32_t target = 0) {
    host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {cw, static_cast<std::uint32_t>(target)}));
    sync();
  }
  void start() {  // map RPDO1 = cw + target (sync), TPDO1 = statusword + position (every SYNC), operational
    write(0x1400, 1, toBytes(0x80000205u, 4));
    write(0x1600, 0, {0});
    write(0x1600, 1, toBytes(0x60400010u, 4));
    write(0x1600, 2, toBytes(0x607A0020u, 4));
    write(0x1600, 0, {2});
    write(0x1400, 2, {1});
    write(0x1400, 1, toBytes(0x205u, 4));
    write(0x1800, 1, toBytes(0x80000185u, 4));
    write(0x1A00, 0, {0});
    write(0x1A00, 1, toBytes(0x60410010u, 4));
    write(0x1A00, 2, toBytes(0x60640020u, 4));
    write(0x1A00, 0, {2});
    write(0x1800, 2, {1});
    write(0x1800, 1, toBytes(0x185u, 4));
    write(0x6060, 0, {1});
    host->send(encodeNmt(NmtCommand::kStart, 5));
    tick();
  }
  void enable() {
    controlword(0x06);
    controlword(0x07);
    controlword(0x0F);
    ASSERT_EQ(drive.state(), S::kOperationEnabled);
  }

  VirtualClock clock;
  VirtualBus bus{clock};
  std::shared_ptr<VirtualBus::Endpoint> host = bus.open("host");
  std::shared_ptr<VirtualBus::Endpoint> ep = bus.open("drive");
  SimDrive drive;
};

TEST_F(SimFixture, BootUpThenPreOperationalAndHeartbeat) {
  const auto boot = received();
  ASSERT_FALSE(boot.empty());
  EXPECT_EQ(formatFrame(boot[0]), "705#00");
  EXPECT_EQ(drive.nmtState(), NmtState::kPreOperational);
  EXPECT_EQ(drive.state(), S::kSwitchOnDisabled);
  write(0x1017, 0, {50, 0});
  received();
  for (int i = 0; i < 200; ++i) tick();
  int beats = 0;
  for (const can_frame& f : received()) beats += formatFrame(f) == "705#7F";
  EXPECT_EQ(beats, 4);
}

TEST_F(SimFixture, NmtStateMachine) {
  host->send(encodeNmt(NmtCommand::kStart, 0));  // all nodes
  tick();
  EXPECT_EQ(drive.nmtState(), NmtState::kOperational);
  host->send(encodeNmt(NmtCommand::kStop, 5));
  tick();
  EXPECT_EQ(drive.nmtState(), NmtState::kStopped);
  received();
  host->send(sdoInitiateUploadRequest(5, 0x1000, 0));  // no SDO in stopped
  tick();
  EXPECT_TRUE(received().empty());
  host->send(encodeNmt(NmtCommand::kEnterPreOperational, 6));  // another node
  tick();
  EXPECT_EQ(drive.nmtState(), NmtState::kStopped);
  host->send(encodeNmt(NmtCommand::kEnterPreOperational, 5));
  tick();
  EXPECT_EQ(drive.nmtState(), NmtState::kPreOperational);
  write(0x1017, 0, {100, 0});
  host->send(encodeNmt(NmtCommand::kResetCommunication, 5));
  tick();
  const auto f = received();
  ASSERT_FALSE(f.empty());
  EXPECT_EQ(formatFrame(f[0]), "705#00");
  EXPECT_EQ(drive.object(0x1017, 0), 0);  // communication objects back to defaults
}

TEST_F(SimFixture, SdoServerSegmentedUploadAndAborts) {
  can_frame r = sdo(sdoInitiateUploadRequest(5, 0x1008, 0));
  EXPECT_EQ(formatFrame(r), "585#410810000F000000");  // 15 bytes, segmented
  r = sdo(sdoUploadSegmentRequest(5, false));
  EXPECT_EQ(formatFrame(r), "585#007365676D656E74");  // "segment"
  r = sdo(sdoUploadSegmentRequest(5, false));         // toggle not alternated
  EXPECT_EQ(formatFrame(r), "585#8008100000000305");  // abort 0x05030000
  r = sdo(sdoUploadSegmentRequest(5, true));          // no transfer running any more
  EXPECT_EQ(formatFrame(r), "585#8000000001000405");  // abort 0x05040001
  r = sdo(sdoInitiateDownloadRequest(5, 0x1000, 0, {1, 2, 3, 4}));
  EXPECT_EQ(formatFrame(r), "585#8000100002000106");                      // read only
  r = sdo(sdoInitiateDownloadRequest(5, 0x6081, 0, {1, 2, 3, 4, 5, 6}));  // 6 bytes for a 4-byte object
  EXPECT_EQ(formatFrame(r), "585#8081600012000706");
  // A command specifier the server does not know (block download).
  r = sdo(makeFrame(0x605, {0xC0, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(formatFrame(r), "585#8000100001000405");
}

TEST_F(SimFixture, SdoServerSegmentedDownload) {
  // 0x6081 (4 bytes) written as a segmented transfer.
  can_frame r = sdo(makeFrame(0x605, {0x21, 0x81, 0x60, 0x00, 0x04, 0, 0, 0}));
  EXPECT_EQ(formatFrame(r), "585#6081600000000000");
  r = sdo(sdoDownloadSegmentRequest(5, false, {0x10, 0x27, 0x00, 0x00}, true));
  EXPECT_EQ(formatFrame(r), "585#2000000000000000");
  EXPECT_EQ(drive.object(0x6081, 0), 10000);
  // Announced 4, sent 3.
  sdo(makeFrame(0x605, {0x21, 0x81, 0x60, 0x00, 0x04, 0, 0, 0}));
  r = sdo(sdoDownloadSegmentRequest(5, false, {1, 2, 3}, true));
  EXPECT_EQ(formatFrame(r), "585#8081600010000706");
  EXPECT_EQ(drive.object(0x6081, 0), 10000);
}

TEST_F(SimFixture, PdoMappingIsValidated) {
  // TPDO1 is valid (default): its mapping cannot change.
  can_frame r = sdo(sdoInitiateDownloadRequest(5, 0x1A00, 0, {0}));
  EXPECT_EQ(formatFrame(r), "585#80001A0022000008");
  write(0x1800, 1, toBytes(0x80000185u, 4));
  write(0x1A00, 0, {0});
  r = sdo(sdoInitiateDownloadRequest(5, 0x1A00, 1, toBytes(0x10080000u | 0x20, 4)));  // 0x1008 not mappable
  EXPECT_EQ(formatFrame(r), "585#80001A0141000406");
  // 3 x 32 bits > 64.
  write(0x1A00, 1, toBytes(0x60640020u, 4));
  write(0x1A00, 2, toBytes(0x606C0020u, 4));
  write(0x1A00, 3, toBytes(0x607A0020u, 4));
  r = sdo(sdoInitiateDownloadRequest(5, 0x1A00, 0, {3}));
  EXPECT_EQ(formatFrame(r), "585#80001A0042000406");
  // A read-only object in an RPDO.
  write(0x1400, 1, toBytes(0x80000205u, 4));
  write(0x1600, 0, {0});
  r = sdo(sdoInitiateDownloadRequest(5, 0x1600, 1, toBytes(0x60410010u, 4)));
  EXPECT_EQ(formatFrame(r), "585#8000160141000406");
}

TEST_F(SimFixture, TpdoEveryNthSyncAndRpdoAtTheSync) {
  start();
  write(0x1800, 1, toBytes(0x80000185u, 4));
  write(0x1800, 2, {3});  // every 3rd SYNC
  write(0x1800, 1, toBytes(0x185u, 4));
  received();
  int tpdos = 0;
  for (int i = 0; i < 9; ++i) {
    sync();
    for (const can_frame& f : received()) tpdos += f.can_id == 0x185;
  }
  EXPECT_EQ(tpdos, 3);
  // A synchronous RPDO waits for the SYNC.
  host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x06, 0}));
  tick();
  EXPECT_EQ(drive.state(), S::kSwitchOnDisabled);
  sync();
  EXPECT_EQ(drive.state(), S::kReadyToSwitchOn);
  // Type 255: at once.
  write(0x1400, 2, {255});
  host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x07, 0}));
  tick();
  EXPECT_EQ(drive.state(), S::kSwitchedOn);
  // Wrong length: not applied, EMCY 0x8210.
  received();
  can_frame bad = *packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x0F, 0});
  bad.len = 5;
  host->send(bad);
  tick();
  EXPECT_EQ(drive.state(), S::kSwitchedOn);
  const auto f = received();
  ASSERT_FALSE(f.empty());
  EXPECT_EQ(f[0].can_id, 0x085u);
  EXPECT_EQ(f[0].data[0] | (f[0].data[1] << 8), 0x8210);
}

TEST_F(SimFixture, StateMachineTransitions) {
  start();
  struct Step {
    std::uint16_t cw;
    S want;
  };
  // 2, 3, 4, 5, 4, 8, 3+4, 9, 2, 7, 2, 3, 10, 2, 3, 4, 11, 12
  const Step steps[] = {{0x06, S::kReadyToSwitchOn},  {0x07, S::kSwitchedOn},       {0x0F, S::kOperationEnabled},
                        {0x07, S::kSwitchedOn},       {0x0F, S::kOperationEnabled}, {0x06, S::kReadyToSwitchOn},
                        {0x0F, S::kOperationEnabled}, {0x00, S::kSwitchOnDisabled}, {0x06, S::kReadyToSwitchOn},
                        {0x00, S::kSwitchOnDisabled}, {0x06, S::kReadyToSwitchOn},  {0x07, S::kSwitchedOn},
                        {0x02, S::kSwitchOnDisabled}, {0x06, S::kReadyToSwitchOn},  {0x07, S::kSwitchedOn},
                        {0x0F, S::kOperationEnabled}, {0x02, S::kSwitchOnDisabled}};  // option 2: QSA, stopped, SOD
  for (const Step& s : steps) {
    controlword(s.cw);
    tick();
    EXPECT_EQ(drive.state(), s.want) << "controlword 0x" << std::hex << s.cw;
  }
  // Fault: only a rising edge of bit 7 resets it.
  enable();
  drive.injectFault(0x4310);
  for (int i = 0; i < 5; ++i) tick();
  EXPECT_EQ(drive.state(), S::kFault);
  EXPECT_EQ(drive.object(0x1001, 0), 0x09);  // generic + temperature
  controlword(0x80);
  EXPECT_EQ(drive.state(), S::kSwitchOnDisabled);
  drive.injectFault(0x1000);
  controlword(0x80);  // bit 7 was already high: no edge
  EXPECT_EQ(drive.state(), S::kFault);
  controlword(0x00);
  controlword(0x80);
  EXPECT_EQ(drive.state(), S::kSwitchOnDisabled);
}

TEST_F(SimFixture, TrapezoidalMoveTimingAndLimits) {
  start();
  enable();
  // 0.1 m -> 0.3 m: 20000 counts at 10000 counts/s, 50000 counts/s^2: t = 2 + 0.2 s.
  controlword(0x0F, 30000);
  controlword(0x1F, 30000);
  EXPECT_TRUE(drive.statusword() & sw::kSetPointAcknowledge);
  EXPECT_FALSE(drive.statusword() & sw::kTargetReached);
  controlword(0x0F, 30000);
  EXPECT_FALSE(drive.statusword() & sw::kSetPointAcknowledge);
  double peak = 0;
  int ms = 0;
  while (!(drive.statusword() & sw::kTargetReached) && ms < 5000) {
    tick();
    ++ms;
    peak = std::max(peak, std::abs(drive.velocity()));
  }
  EXPECT_NEAR(ms, 2200 - 20, 25);  // started 2 SYNC ticks ago
  EXPECT_NEAR(peak, 10000, 1);
  EXPECT_EQ(drive.position(), 30000);
  // A target beyond the software limit (0x607D:02 = 50000) is clamped, bit 11 set.
  controlword(0x1F, 90000);
  controlword(0x0F, 90000);
  EXPECT_TRUE(drive.statusword() & sw::kInternalLimit);
  for (int i = 0; i < 5000; ++i) tick();
  EXPECT_EQ(drive.position(), 50000);
}

TEST_F(SimFixture, QuickStopStopsOnItsRamp) {
  start();
  enable();
  controlword(0x1F, 40000);
  controlword(0x0F, 40000);
  for (int i = 0; i < 1000; ++i) tick();  // cruising at 10000 counts/s
  ASSERT_NEAR(drive.velocity(), 10000, 1);
  const std::int32_t at = drive.position();
  controlword(0x02, 40000);
  EXPECT_EQ(drive.state(), S::kQuickStopActive);
  for (int i = 0; i < 300; ++i) tick();
  EXPECT_EQ(drive.state(), S::kSwitchOnDisabled);
  // v^2 / (2 a) = 1e8 / 2e5 = 500 counts at 0x6085 = 100000 counts/s^2, plus 1 ms at cruise speed before the SYNC.
  EXPECT_NEAR(drive.position() - at, 500 + 10, 5);
}

TEST_F(SimFixture, HomingInPlace) {
  start();
  write(0x6098, 0, {35});  // current position
  write(0x607C, 0, toBytes(static_cast<std::uint32_t>(-1234), 4));
  write(0x6060, 0, {6});
  enable();
  controlword(0x1F);
  tick();
  EXPECT_TRUE(drive.homed());
  EXPECT_EQ(drive.position(), -1234);
  const std::uint16_t w = drive.statusword();
  EXPECT_TRUE(w & sw::kHomingAttained);
  EXPECT_TRUE(w & sw::kTargetReached);
  EXPECT_FALSE(w & sw::kHomingError);
  write(0x6098, 0, {99});  // unsupported method -> homing error
  controlword(0x0F);
  controlword(0x1F);
  EXPECT_TRUE(drive.statusword() & sw::kHomingError);
  EXPECT_EQ(drive.modeDisplay(), 6);
}

TEST_F(SimFixture, HomingToTheSwitchEndsExactlyAtTheOffset) {
  // Method 17 runs to the switch (here at 0 m, 10000 counts away) and sets
  // the position there to the home offset: exactly, not a step past it. (A
  // steep ramp makes the last 1 ms step a few counts long, as on the arm's Z.)
  start();
  write(0x6098, 0, {17});
  write(0x6099, 1, toBytes(20000u, 4));    // counts/s
  write(0x609A, 0, toBytes(1000000u, 4));  // counts/s^2
  write(0x607C, 0, toBytes(static_cast<std::uint32_t>(-1234), 4));
  write(0x6060, 0, {6});
  enable();
  controlword(0x1F);
  int ms = 0;
  while (!(drive.statusword() & sw::kHomingAttained) && ms < 10000) {
    tick();
    ++ms;
  }
  ASSERT_TRUE(drive.homed());
  EXPECT_GT(ms, 400);  // it did run to the switch
  EXPECT_EQ(drive.position(), -1234);
  EXPECT_EQ(drive.velocity(), 0.0);
  for (int i = 0; i < 100; ++i) tick();
  EXPECT_EQ(drive.position(), -1234);  // and stays
  received();
  sync();  // the TPDO reports the same
  bool seen = false;
  for (const can_frame& f : received()) {
    if (f.can_id != 0x185) continue;
    seen = true;
    EXPECT_EQ(static_cast<std::int32_t>(f.data[2] | f.data[3] << 8 | f.data[4] << 16 |
                                        static_cast<std::uint32_t>(f.data[5]) << 24),
              -1234);
  }
  EXPECT_TRUE(seen);
}

TEST_F(SimFixture, PowerOffIsSilentAndLosesTheReference) {
  drive.powerOff();
  received();
  host->send(sdoInitiateUploadRequest(5, 0x1000, 0));
  for (int i = 0; i < 10; ++i) tick();
  EXPECT_TRUE(received().empty());
  drive.powerOn();
  tick();
  const auto f = received();
  ASSERT_FALSE(f.empty());
  EXPECT_EQ(formatFrame(f[0]), "705#00");
  EXPECT_FALSE(drive.homed());
  EXPECT_EQ(drive.position(), 10000);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

namespace {

/// A vertical axis with a 4 kg carriage, 15 N of coulomb and 150 N s/m of viscous friction behind a 2.5 mm ball screw
/// (90 %), a 0.32 N m motor, no noise: the torque actual is exact.
AxisConfig verticalAxis() {
  AxisConfig a = axis();
  a.rated_torque = 0.32;
  SimDriveSettings::Mechanics& m = a.sim.mechanics;
  m.screw_lead = 0.0025;
  m.screw_efficiency = 0.9;
  m.moving_mass = 4.0;
  m.gravity = 9.81;
  m.coulomb_friction = 15.0;
  m.viscous_friction = 150.0;
  return a;
}

/// The motor force (N) that 0x6077 says, back through the screw.
double motorForceOf(const SimDrive& d) {
  const AxisConfig& a = d.config();
  const double torque = static_cast<double>(d.object(0x6077, 0)) / 1000.0 * a.rated_torque;
  return 2.0 * M_PI * a.sim.mechanics.screw_efficiency * torque / a.sim.mechanics.screw_lead;
}

struct MechanicsFixture : SimFixture {
  MechanicsFixture() : SimFixture(verticalAxis()) {}
  void run(int ms) {
    for (int i = 0; i < ms; ++i) tick();
  }
};

}  // namespace

TEST_F(MechanicsFixture, TorqueActualCarriesGravityFrictionAndWhatPushesTheAxis) {
  EXPECT_EQ(drive.object(0x6076, 0), 320);  // mN m
  write(0x1A02, 0, {0});
  write(0x1A02, 1, toBytes(0x60770010u, 4));  // mappable into a TPDO
  write(0x1A02, 0, {1});
  start();
  enable();
  for (int i = 0; i < 10; ++i) sync();
  const double weight = 4.0 * 9.81;
  EXPECT_NEAR(motorForceOf(drive), weight, 1.0);  // still, no friction yet: the weight (a per mille is 0.72 N)

  // Up at 0.1 m/s: weight + coulomb + viscous.
  controlword(0x0F, 40000);
  controlword(0x1F, 40000);
  controlword(0x0F, 40000);
  run(1000);
  ASSERT_NEAR(drive.velocity(), 10000, 1);
  EXPECT_NEAR(motorForceOf(drive), weight + 15.0 + 15.0, 1.0);
  run(3000);
  ASSERT_EQ(drive.position(), 40000);
  // Stopped after going up: the friction keeps its last value (what makes a static force hard to read).
  EXPECT_NEAR(motorForceOf(drive), weight + 15.0, 1.0);

  // Something pushes the axis up by 30 N: the motor carries 30 N less.
  drive.setExternalForce([](double position, double) { return position > 0.35 ? 30.0 : 0.0; });
  tick();
  EXPECT_NEAR(drive.externalForce(), 30.0, 1e-9);
  EXPECT_NEAR(motorForceOf(drive), weight + 15.0 - 30.0, 1.0);

  // Down at 0.1 m/s, below the push (to 0.31 m in 1 s): the friction turns over.
  controlword(0x1F, 20000);
  controlword(0x0F, 20000);
  run(1000);
  ASSERT_NEAR(drive.velocity(), -10000, 1);
  EXPECT_NEAR(motorForceOf(drive), weight - 15.0 - 15.0, 1.0);

  // Switched off (holding brake): no torque.
  controlword(0x06, 20000);
  tick();
  EXPECT_EQ(drive.object(0x6077, 0), 0);
}

TEST_F(SimFixture, CyclicSynchronousPositionReachesEachTargetByTheNextSync) {
  start();
  write(0x6060, 0, {8});
  EXPECT_EQ(drive.modeDisplay(), 8);
  enable();
  EXPECT_TRUE(drive.statusword() & sw::kSetPointAcknowledge);  // bit 12: the drive follows the command value
  // A SYNC every 10 ms, the target 1 mm further each time: the drive moves 0.1 m/s, linearly between SYNCs.
  std::int32_t target = drive.position();
  for (int k = 0; k < 20; ++k) {
    target += 100;  // 1 mm
    host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x0F, static_cast<std::uint32_t>(target)}));
    sync();
    for (int i = 0; i < 9; ++i) tick();
  }
  EXPECT_NEAR(drive.position(), target - 10, 11);  // within a ms of the last target, one SYNC late at most
  tick();
  EXPECT_EQ(drive.position(), target);
  // A jump beyond 0x607F per SYNC (1 m/s: 10 mm) is clamped, bit 11 set; beyond the software limit too.
  // (This SYNC comes 11 ms after the last: the drive went on 1 ms past `target` at the old speed, 10 counts, and takes
  // 11 ms as the period: the step allowed is 1100 counts, reached by the next SYNC's time, 10 ms after it.)
  host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x0F, static_cast<std::uint32_t>(target + 5000)}));
  sync();
  for (int i = 0; i < 10; ++i) tick();
  EXPECT_TRUE(drive.statusword() & sw::kInternalLimit);
  EXPECT_EQ(drive.position(), target + 10 + 1000);
  // No SYNC comes: the drive goes on at the segment's speed for half a period (extrapolation), then holds.
  for (int i = 0; i < 20; ++i) tick();
  EXPECT_EQ(drive.position(), target + 10 + 1650);
  // A mode other than 0, 1, 6 or 8 is refused.
  const can_frame r = sdo(sdoInitiateDownloadRequest(5, 0x6060, 0, {3}));
  EXPECT_EQ(r.data[0], 0x80);
}

TEST_F(MechanicsFixture, StreamedAtAConstantSpeedTheTorqueIsSteady) {
  start();
  write(0x6060, 0, {8});
  enable();
  // Down at 5 mm/s in cyclic synchronous position: the torque every SYNC carries the weight less the sliding
  // friction, no acceleration (a segment's last step once read as a stop: +-20 N spikes at the SYNC).
  std::int32_t target = drive.position();
  std::vector<double> forces;
  for (int k = 0; k < 300; ++k) {
    target -= 5;  // 50 um per 10 ms
    host->send(*packPdo(0x205, {{0x6040, 0, 16}, {0x607A, 0, 32}}, {0x0F, static_cast<std::uint32_t>(target)}));
    sync();
    if (k > 20) forces.push_back(motorForceOf(drive));
    for (int i = 0; i < 9; ++i) tick();
  }
  for (double f : forces) EXPECT_NEAR(f, 4.0 * 9.81 - 15.0 - 150.0 * 0.005, 1.0);
}
