// Layer 1 tests: VirtualBus delivery semantics (SocketCAN loopback / own
// messages / filters), thread safety, fault injection; SocketCanBus error
// path, error-frame decoding and back-off (no vcan on the build machine).
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "massage_cell/can/socketcan_bus.h"
#include "massage_cell/can/virtual_bus.h"

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;

TEST(VirtualBus, DeliversToOtherEndpointsNotToTheSenderByDefault) {
  VirtualClock clock;
  VirtualBus bus(clock);
  auto a = bus.open("a"), b = bus.open("b"), c = bus.open("c");
  ASSERT_TRUE(a->send(makeFrame(0x123, {1, 2, 3})));
  for (auto* ep : {b.get(), c.get()}) {
    auto f = ep->receive(0ns);
    ASSERT_TRUE(f) << ep->name();
    EXPECT_TRUE(sameFrame(f->frame, makeFrame(0x123, {1, 2, 3})));
    EXPECT_FALSE(ep->receive(0ns));
  }
  EXPECT_FALSE(a->receive(0ns));  // CAN_RAW_RECV_OWN_MSGS is off by default
  EXPECT_EQ(a->status().tx_frames, 1u);
  EXPECT_EQ(b->status().rx_frames, 1u);
}

TEST(VirtualBus, ReceiveOwnMessagesWhenEnabled) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  a->setReceiveOwn(true);
  a->send(makeFrame(0x10, {7}));
  auto own = a->receive(0ns);
  ASSERT_TRUE(own);
  EXPECT_EQ(own->frame.can_id, 0x10u);
  EXPECT_TRUE(b->receive(0ns));
}

TEST(VirtualBus, LoopbackOffMeansNobodyElseReceives) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  a->setLoopback(false);
  a->setReceiveOwn(true);  // has no effect without loopback (SocketCAN)
  EXPECT_TRUE(a->send(makeFrame(0x10, {})));
  EXPECT_FALSE(b->receive(0ns));
  EXPECT_FALSE(a->receive(0ns));
  a->setLoopback(true);
  a->send(makeFrame(0x11, {}));
  EXPECT_TRUE(b->receive(0ns));
}

TEST(VirtualBus, KeepsSendOrderAndStampsWithTheClock) {
  VirtualClock clock;
  VirtualBus bus(clock);
  auto a = bus.open("a"), b = bus.open("b");
  for (int i = 0; i < 20; ++i) {
    a->send(makeFrame(0x100 + i, {static_cast<std::uint8_t>(i)}));
    clock.advance(1ms);
  }
  for (int i = 0; i < 20; ++i) {
    auto f = b->receive(0ns);
    ASSERT_TRUE(f);
    EXPECT_EQ(f->frame.can_id, static_cast<canid_t>(0x100 + i));
    EXPECT_EQ(f->stamp, TimePoint(1s + std::chrono::milliseconds(i)));
  }
}

TEST(VirtualBus, FiltersFollowCanRawFilterSemantics) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  b->setFilters({can_filter{0x580, 0x780}});  // 0x580..0x5FF
  for (canid_t id : {0x57Fu, 0x580u, 0x5FFu, 0x600u, 0x581u}) a->send(makeFrame(id, {}));
  std::vector<canid_t> got;
  while (auto f = b->receive(0ns)) got.push_back(f->frame.can_id);
  EXPECT_EQ(got, (std::vector<canid_t>{0x580, 0x5FF, 0x581}));

  b->setFilters({can_filter{0x080 | CAN_INV_FILTER, CAN_SFF_MASK}});  // everything but SYNC
  a->send(makeFrame(0x080, {}));
  a->send(makeFrame(0x081, {}));
  auto f = b->receive(0ns);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->frame.can_id, 0x081u);
  EXPECT_FALSE(b->receive(0ns));

  b->setFilters({});  // empty filter list: receive nothing
  a->send(makeFrame(0x081, {}));
  EXPECT_FALSE(b->receive(0ns));
}

TEST(VirtualBus, ReceiveWaitsForTheTimeoutOrAFrame) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(b->receive(30ms));
  const auto waited = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(waited, 29ms);
  EXPECT_LT(waited, 500ms);
  std::thread sender([&] {
    std::this_thread::sleep_for(10ms);
    a->send(makeFrame(0x1, {}));
  });
  EXPECT_TRUE(b->receive(2s));
  sender.join();
}

TEST(VirtualBus, IsThreadSafeAndKeepsPerSenderOrder) {
  VirtualBus bus;
  auto r = bus.open("r");
  constexpr int kN = 2000;
  std::vector<std::thread> senders;
  for (int s = 0; s < 2; ++s) {
    senders.emplace_back([&, s] {
      auto ep = bus.open("s" + std::to_string(s));
      for (int i = 0; i < kN; ++i) {
        can_frame f = makeFrame(0x100 + s, {static_cast<std::uint8_t>(i & 0xFF), static_cast<std::uint8_t>(i >> 8)});
        ep->send(f);
      }
    });
  }
  int next[2] = {0, 0};
  int total = 0;
  while (total < 2 * kN) {
    auto f = r->receive(2s);
    ASSERT_TRUE(f) << "lost frames after " << total;
    const int s = static_cast<int>(f->frame.can_id - 0x100);
    const int i = f->frame.data[0] | (f->frame.data[1] << 8);
    ASSERT_EQ(i, next[s]) << "sender " << s;
    ++next[s];
    ++total;
  }
  for (auto& t : senders) t.join();
  EXPECT_EQ(r->status().rx_overflow, 0u);
}

TEST(VirtualBus, WholeBusOffForADurationThenRecovers) {
  VirtualClock clock;
  VirtualBus bus(clock);
  auto a = bus.open("a"), b = bus.open("b");
  a->send(makeFrame(0x1, {}));  // in b's queue: lost with bus-off
  bus.setBusOff(100ms);
  EXPECT_EQ(a->status().state, BusState::kBusOff);
  EXPECT_EQ(b->status().state, BusState::kBusOff);
  EXPECT_FALSE(a->send(makeFrame(0x2, {})));
  EXPECT_NE(a->status().last_error.find("bus-off"), std::string::npos);
  EXPECT_EQ(a->status().tx_failed, 1u);
  EXPECT_FALSE(b->receive(0ns));
  clock.advance(99ms);
  EXPECT_FALSE(b->send(makeFrame(0x3, {})));
  clock.advance(1ms);
  EXPECT_TRUE(a->send(makeFrame(0x4, {})));
  auto f = b->receive(0ns);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->frame.can_id, 0x4u);
  const BusStatus s = b->status();
  EXPECT_EQ(s.state, BusState::kErrorActive);
  EXPECT_EQ(s.bus_off_events, 1u);
  EXPECT_EQ(s.recoveries, 1u);
}

TEST(VirtualBus, OneEndpointBusOffIsolatesOnlyThatEndpoint) {
  VirtualClock clock;
  VirtualBus bus(clock);
  auto a = bus.open("a"), b = bus.open("b"), c = bus.open("c");
  bus.setBusOff(*b, 50ms);
  EXPECT_TRUE(a->send(makeFrame(0x7, {})));
  EXPECT_FALSE(b->receive(0ns));
  EXPECT_TRUE(c->receive(0ns));
  EXPECT_FALSE(b->send(makeFrame(0x8, {})));
  EXPECT_EQ(a->status().state, BusState::kErrorActive);
  clock.advance(50ms);
  EXPECT_TRUE(b->send(makeFrame(0x8, {})));
  EXPECT_TRUE(a->receive(0ns));
  EXPECT_EQ(b->status().recoveries, 1u);
}

TEST(VirtualBus, DropsTheNextMatchingFrames) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  bus.dropNext(2, [](const can_frame& f) { return f.can_id == 0x581; });
  for (canid_t id : {0x581u, 0x182u, 0x581u, 0x581u}) EXPECT_TRUE(a->send(makeFrame(id, {})));
  std::vector<canid_t> got;
  while (auto f = b->receive(0ns)) got.push_back(f->frame.can_id);
  EXPECT_EQ(got, (std::vector<canid_t>{0x182, 0x581}));
  EXPECT_EQ(bus.dropped(), 2u);
}

TEST(VirtualBus, DropProbabilityIsSeededAndRoughlyRight) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  bus.setDropProbability(0.25, 42);
  for (int i = 0; i < 4000; ++i) a->send(makeFrame(0x1, {}));
  const double frac = static_cast<double>(bus.dropped()) / 4000.0;
  EXPECT_NEAR(frac, 0.25, 0.03);
  EXPECT_EQ(b->pending(), 4000u - bus.dropped());
}

TEST(VirtualBus, CountsReceiveQueueOverflow) {
  VirtualBus bus(SteadyClock::instance(), 8);
  auto a = bus.open("a"), b = bus.open("b");
  for (int i = 0; i < 10; ++i) a->send(makeFrame(0x1, {}));
  EXPECT_EQ(b->pending(), 8u);
  EXPECT_EQ(b->status().rx_overflow, 2u);
}

TEST(VirtualBus, RejectsOversizedFrames) {
  VirtualBus bus;
  auto a = bus.open("a"), b = bus.open("b");
  can_frame f = makeFrame(0x1, {});
  f.len = 9;
  EXPECT_FALSE(a->send(f));
  EXPECT_FALSE(b->receive(0ns));
}

TEST(Frames, MakeAndFormat) {
  EXPECT_EQ(formatFrame(makeFrame(0x181, {0x27, 0x00, 0xE8, 0x03})), "181#2700E803");
  EXPECT_EQ(formatFrame(makeFrame(0x12345, {0xAB})), "00012345#AB");
  EXPECT_TRUE(makeFrame(0x12345, {}).can_id & CAN_EFF_FLAG);
  EXPECT_EQ(formatFrame(makeFrame(0x80, {})), "080#");
  EXPECT_THROW(makeFrame(0x1, std::vector<std::uint8_t>(9, 0)), std::invalid_argument);
  can_frame err{};
  err.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  EXPECT_FALSE(matchesFilters(err, acceptAllFilters()));  // error frames only via the error mask
}

TEST(SocketCanBus, MissingInterfaceGivesAClearError) {
  try {
    SocketCanBus bus(SocketCanOptions{"mcnocan7"});
    FAIL() << "opened a nonexistent interface";
  } catch (const BusError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'mcnocan7' does not exist"), std::string::npos) << what;
  }
}

TEST(SocketCanBus, NonCanInterfaceGivesAClearError) {
  try {
    SocketCanBus bus(SocketCanOptions{"lo"});
    FAIL() << "opened the loopback interface as CAN";
  } catch (const BusError& e) {
    EXPECT_NE(std::string(e.what()).find("'lo' is not a CAN interface"), std::string::npos) << e.what();
  }
}

TEST(SocketCanBus, RejectsEmptyAndOverlongNames) {
  EXPECT_THROW(SocketCanBus(SocketCanOptions{""}), BusError);
  try {
    SocketCanBus bus(SocketCanOptions{"averyveryverylonginterfacename"});
    FAIL();
  } catch (const BusError& e) {
    EXPECT_NE(std::string(e.what()).find("longer than 15"), std::string::npos) << e.what();
  }
}

TEST(SocketCanBus, DecodesErrorFrames) {
  can_frame f{};
  EXPECT_FALSE(decodeErrorFrame(f).valid);

  f.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  f.len = CAN_ERR_DLC;
  ErrorFrameInfo i = decodeErrorFrame(f);
  EXPECT_TRUE(i.valid);
  ASSERT_TRUE(i.state);
  EXPECT_EQ(*i.state, BusState::kBusOff);
  EXPECT_NE(i.text.find("bus-off"), std::string::npos);

  f.can_id = CAN_ERR_FLAG | CAN_ERR_CRTL;
  f.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  i = decodeErrorFrame(f);
  ASSERT_TRUE(i.state);
  EXPECT_EQ(*i.state, BusState::kErrorPassive);
  EXPECT_NE(i.text.find("tx error-passive"), std::string::npos);

  f.data[1] = CAN_ERR_CRTL_RX_WARNING;
  i = decodeErrorFrame(f);
  ASSERT_TRUE(i.state);
  EXPECT_EQ(*i.state, BusState::kErrorWarning);

  f.data[1] = CAN_ERR_CRTL_ACTIVE;
  EXPECT_EQ(decodeErrorFrame(f).state, BusState::kErrorActive);

  f.can_id = CAN_ERR_FLAG | CAN_ERR_RESTARTED;
  EXPECT_EQ(decodeErrorFrame(f).state, BusState::kErrorActive);

  f.can_id = CAN_ERR_FLAG | CAN_ERR_ACK;
  i = decodeErrorFrame(f);
  EXPECT_FALSE(i.state);
  EXPECT_NE(i.text.find("no ACK"), std::string::npos);
}

TEST(SocketCanBus, BackoffDoublesUpToTheCap) {
  Backoff b(100ms, 1s);
  std::vector<Duration> got;
  for (int i = 0; i < 6; ++i) got.push_back(b.next());
  EXPECT_EQ(got, (std::vector<Duration>{100ms, 200ms, 400ms, 800ms, 1s, 1s}));
  b.reset();
  EXPECT_EQ(b.next(), Duration(100ms));
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
