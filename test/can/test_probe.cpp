// can_probe's scan (probe.h) against simulated drives on a VirtualBus in
// real time, node-list parsing and the table.
#include <gtest/gtest.h>

#include <thread>

#include "massage_cell/can/cia402.h"
#include "massage_cell/can/probe.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/virtual_bus.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;

TEST(Probe, ParsesNodeLists) {
  EXPECT_EQ(parseNodeList("5"), (std::vector<std::uint8_t>{5}));
  EXPECT_EQ(parseNodeList("3,1-2,2"), (std::vector<std::uint8_t>{1, 2, 3}));
  EXPECT_EQ(parseNodeList("1-127").size(), 127u);
  EXPECT_THROW(parseNodeList("0-3"), std::invalid_argument);
  EXPECT_THROW(parseNodeList("128"), std::invalid_argument);
  EXPECT_THROW(parseNodeList("5-2"), std::invalid_argument);
  EXPECT_THROW(parseNodeList("a"), std::invalid_argument);
  EXPECT_THROW(parseNodeList(","), std::invalid_argument);
  try {
    parseNodeList("1,x-3");
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'x-3'"), std::string::npos) << e.what();
  }
}

TEST(Probe, FindsTheDrivesWithNameStateAndStatusword) {
  CanConfig c = loadCanConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml");
  const Clock& clock = SteadyClock::instance();
  VirtualBus bus(clock);
  auto e1 = bus.open("drive 1"), e3 = bus.open("drive 3");
  SimDrive d1(*e1, clock, c.axes[0]), d3(*e3, clock, c.axes[2]);  // node 2 is absent
  std::atomic<bool> stop{false};
  std::thread t1([&] { d1.run(stop); }), t3([&] { d3.run(stop); });
  d1.powerOn();
  d3.powerOn();
  {  // Bring node 3 up with a master (heartbeat 100 ms, operational), then let the master go.
    CanConfig only3 = c;
    only3.axes = {c.axes[2]};
    auto mep = bus.open("master");
    Master m(*mep, clock, only3);
    m.start();
    m.bringUp();
    ASSERT_TRUE(m.waitUntil([&] { return m.allOperational(); }, 3s));
    m.stop();
  }
  auto pep = bus.open("probe");
  ProbeOptions o;
  o.nodes = parseNodeList("1-6");
  o.sdo_timeout = 30ms;
  o.listen = 300ms;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<ProbeResult> r = probeNodes(*pep, o);
  const auto took = std::chrono::steady_clock::now() - t0;
  stop = true;
  t1.join();
  t3.join();
  ASSERT_EQ(r.size(), 2u) << formatProbeTable(r);
  EXPECT_EQ(r[0].node, 1);
  EXPECT_EQ(r[0].device_type, 0x00020192u);
  EXPECT_EQ(r[0].device_name, "massage_cell sim drive X");
  EXPECT_FALSE(r[0].nmt);  // no heartbeat configured on node 1
  ASSERT_TRUE(r[0].statusword);
  EXPECT_EQ(decodeStatusword(*r[0].statusword), Cia402State::kSwitchOnDisabled);
  EXPECT_EQ(r[1].node, 3);
  EXPECT_EQ(r[1].device_name, "massage_cell sim drive Z");
  ASSERT_TRUE(r[1].nmt);
  EXPECT_EQ(*r[1].nmt, NmtState::kOperational);
  EXPECT_GE(took, 300ms);
  EXPECT_LT(took, 2s);
  const std::string table = formatProbeTable(r);
  EXPECT_NE(table.find("   1  0x00020192   no heartbeat     0x0240 switch on disabled"), std::string::npos) << table;
  EXPECT_NE(table.find("   3  0x00020192   operational"), std::string::npos) << table;
  EXPECT_NE(table.find("massage_cell sim drive Z"), std::string::npos) << table;
}

TEST(Probe, EmptyBusFindsNothing) {
  VirtualBus bus;
  auto pep = bus.open("probe");
  ProbeOptions o;
  o.nodes = parseNodeList("1-20");
  o.sdo_timeout = 10ms;
  o.listen = 0ms;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(probeNodes(*pep, o).empty());
  // 20 ids, 8 in flight, 10 ms each: about 30 ms.
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 500ms);
  EXPECT_EQ(pep->status().tx_frames, 40u);  // a request and a timeout abort per id
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
