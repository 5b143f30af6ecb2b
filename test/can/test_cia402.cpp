// Layer 4 pure functions: statusword decoding against the CiA 402 table
// (every 7-bit pattern), the controlword path to operation enabled, and the
// start-up SDO writes in counts; Cia402Axis::quickStopNow on a simulated
// drive (the quick-stop RPDO1 at once, with the last target).
#include <gtest/gtest.h>

#include <functional>
#include <map>

#include "massage_cell/can/cia402.h"
#include "massage_cell/can/config.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;
using S = Cia402State;

TEST(Statusword, TableOfConventionsMd) {
  // statusword & 0x6F (conventions.md / CiA 402-2 §8.4.1)
  const std::map<int, S> table = {{0x00, S::kNotReadyToSwitchOn},
                                  {0x20, S::kNotReadyToSwitchOn},
                                  {0x40, S::kSwitchOnDisabled},
                                  {0x60, S::kSwitchOnDisabled},
                                  {0x21, S::kReadyToSwitchOn},
                                  {0x23, S::kSwitchedOn},
                                  {0x27, S::kOperationEnabled},
                                  {0x07, S::kQuickStopActive},
                                  {0x0F, S::kFaultReactionActive},
                                  {0x2F, S::kFaultReactionActive},
                                  {0x08, S::kFault},
                                  {0x28, S::kFault}};
  for (int low = 0; low < 0x80; ++low) {
    if (low & 0x10) continue;  // bit 4 (voltage enabled) is not part of the state
    const auto it = table.find(low & 0x6F);
    const S want = it == table.end() ? S::kUnknown : it->second;
    for (int high : {0x0000, 0x0200, 0x0400, 0x1000, 0x2000, 0xFF80}) {
      for (int bit4 : {0x00, 0x10}) {
        const auto w = static_cast<std::uint16_t>(high | low | bit4);
        EXPECT_EQ(decodeStatusword(w), want) << std::hex << "statusword 0x" << w;
      }
    }
  }
  // Typical drive values.
  EXPECT_EQ(decodeStatusword(0x0250), S::kSwitchOnDisabled);
  EXPECT_EQ(decodeStatusword(0x0231), S::kReadyToSwitchOn);
  EXPECT_EQ(decodeStatusword(0x0233), S::kSwitchedOn);
  EXPECT_EQ(decodeStatusword(0x1637), S::kOperationEnabled);
  EXPECT_EQ(decodeStatusword(0x0617), S::kQuickStopActive);
  EXPECT_EQ(decodeStatusword(0x0218), S::kFault);
  EXPECT_EQ(decodeStatusword(0x0001), S::kUnknown);
  EXPECT_STREQ(toString(S::kSwitchOnDisabled), "switch on disabled");
}

TEST(Controlword, CommandsAndPathToEnabled) {
  EXPECT_EQ(cw::kShutdown, 0x06);
  EXPECT_EQ(cw::kSwitchOn, 0x07);
  EXPECT_EQ(cw::kEnableOperation, 0x0F);
  EXPECT_EQ(cw::kQuickStop, 0x02);
  EXPECT_EQ(cw::kDisableVoltage, 0x00);
  EXPECT_EQ(cw::kFaultReset, 0x80);
  EXPECT_EQ(controlwordTowardsEnabled(S::kSwitchOnDisabled), cw::kShutdown);
  EXPECT_EQ(controlwordTowardsEnabled(S::kReadyToSwitchOn), cw::kSwitchOn);
  EXPECT_EQ(controlwordTowardsEnabled(S::kSwitchedOn), cw::kEnableOperation);
  EXPECT_EQ(controlwordTowardsEnabled(S::kQuickStopActive), cw::kEnableOperation);
  EXPECT_FALSE(controlwordTowardsEnabled(S::kFault));
  EXPECT_FALSE(controlwordTowardsEnabled(S::kNotReadyToSwitchOn));
  EXPECT_FALSE(controlwordTowardsEnabled(S::kFaultReactionActive));
  EXPECT_EQ(nextStateTowardsEnabled(S::kSwitchOnDisabled), S::kReadyToSwitchOn);
  EXPECT_EQ(nextStateTowardsEnabled(S::kReadyToSwitchOn), S::kSwitchedOn);
  EXPECT_EQ(nextStateTowardsEnabled(S::kSwitchedOn), S::kOperationEnabled);
}

TEST(StartupWrites, ScaledToCounts) {
  AxisConfig a;
  a.name = "X";
  a.node_id = 1;
  a.counts_per_metre = 2000000;
  a.profile_velocity = 0.1;
  a.profile_acceleration = 0.5;
  a.min_position = -0.01;
  a.max_position = 0.8;
  a.homing_method = 17;
  a.home_offset = 0.001;
  std::map<std::pair<int, int>, std::vector<std::uint8_t>> w;
  for (const StartupWrite& s : cia402StartupWrites(a)) w[{s.index, s.sub}] = s.data;
  EXPECT_EQ((w[{0x6060, 0}]), (std::vector<std::uint8_t>{0x01}));
  EXPECT_EQ(fromBytes(w[{0x6081, 0}]), 200000u);  // 0.1 m/s
  EXPECT_EQ(fromBytes(w[{0x6083, 0}]), 1000000u);
  EXPECT_EQ((w[{0x607D, 1}]), toBytes(static_cast<std::uint32_t>(-20000), 4));
  EXPECT_EQ(fromBytes(w[{0x607D, 2}]), 1600000u);
  EXPECT_EQ((w[{0x6098, 0}]), (std::vector<std::uint8_t>{17}));
  EXPECT_EQ(fromBytes(w[{0x607C, 0}]), 2000u);
  EXPECT_EQ((w[{0x605A, 0}].size()), 2u);
}

// The RPDO1 (controlword, target) a frame carries.
std::pair<std::uint16_t, std::int32_t> rpdo1(const can_frame& f) {
  const auto v = unpackPdo(f, rpdo1Mapping());
  EXPECT_TRUE(v.ok() && v->size() == 2u) << formatFrame(f);
  if (!v.ok() || v->size() != 2u) return {0xFFFF, 0};
  return {static_cast<std::uint16_t>((*v)[0]), static_cast<std::int32_t>(static_cast<std::uint32_t>((*v)[1]))};
}

TEST(QuickStopNow, SendsTheQuickStopRpdoAtOnceWithTheLastTargetAndKeepsCommandingIt) {
  CanConfig config = loadCanConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml");
  config.axes.resize(1);  // X
  const AxisConfig a = config.axes[0];
  VirtualClock clock;
  VirtualBus bus{clock};
  auto master_ep = bus.open("master");
  auto drive_ep = bus.open("drive");
  auto sniffer = bus.open("sniffer");
  sniffer->setFilters({{0x200u + a.node_id, CAN_SFF_MASK}});  // the axis's RPDO1
  Master master(*master_ep, clock, config);
  SimDrive drive(*drive_ep, clock, a);
  Cia402Axis axis(master, a);
  auto step = [&] {
    clock.advance(1ms);
    drive.poll();
    master.poll();
  };
  auto runUntil = [&](const std::function<bool()>& pred, Duration limit) {
    for (Duration t{}; t < limit && !pred(); t += 1ms) step();
    return pred();
  };
  drive.powerOn();
  step();
  master.bringUp();
  ASSERT_TRUE(runUntil([&] { return master.allOperational() && axis.valid(); }, 3s));
  axis.enable();
  ASSERT_TRUE(runUntil([&] { return !axis.busy(); }, 5s));
  ASSERT_EQ(axis.status(), Cia402Axis::Status::kSucceeded) << axis.error();
  // Moving to `goal`, half-way there.
  const std::int32_t start = axis.positionCounts();
  const std::int32_t goal = start + a.toCounts(0.1);
  axis.moveToCounts(goal);
  ASSERT_TRUE(runUntil([&] { return drive.position() > start + a.toCounts(0.05); }, 5s)) << axis.error();
  ASSERT_EQ(drive.state(), S::kOperationEnabled);
  // A new move not yet ticked: the drive has not got its target, so the quick stop must not carry it.
  axis.moveToCounts(start - a.toCounts(0.1));
  std::optional<can_frame> last;
  while (auto f = sniffer->receive(0ns)) last = f->frame;
  ASSERT_TRUE(last);
  ASSERT_EQ(rpdo1(*last).second, goal);
  const std::uint64_t rpdos = master.rpdosSent(a.node_id);

  EXPECT_TRUE(axis.quickStopNow());
  // At once: no poll, the clock where it was.
  const auto now = sniffer->receive(0ns);
  ASSERT_TRUE(now) << "quickStopNow sent no RPDO1 at once";
  EXPECT_EQ(now->stamp, clock.now());
  EXPECT_EQ(now->frame.can_id, 0x200u + a.node_id);
  EXPECT_EQ(rpdo1(now->frame), std::make_pair(cw::kQuickStop, goal));
  EXPECT_FALSE(sniffer->receive(0ns));
  EXPECT_EQ(master.rpdosSent(a.node_id), rpdos + 1);
  EXPECT_EQ(axis.operation(), Cia402Axis::Operation::kQuickStop);
  EXPECT_EQ(master.controlword(a.node_id), cw::kQuickStop);

  // Then it keeps commanding quick stop with that target, SYNC after SYNC, until the drive has stopped.
  ASSERT_TRUE(runUntil([&] { return !axis.busy(); }, 2s));
  EXPECT_EQ(axis.status(), Cia402Axis::Status::kSucceeded) << axis.error();
  int frames = 0;
  while (auto f = sniffer->receive(0ns)) {
    ++frames;
    EXPECT_EQ(rpdo1(f->frame), std::make_pair(cw::kQuickStop, goal)) << formatFrame(f->frame);
  }
  EXPECT_GE(frames, 2);
  EXPECT_NE(drive.state(), S::kOperationEnabled);
  EXPECT_LT(drive.position(), goal);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
