// Layer 3 tests: SDO client against scripted server frames, and the CANopen
// master against a scripted node on a VirtualBus with a VirtualClock
// (bring-up sequence, SYNC / RPDO timing, TPDO feedback, heartbeat
// consumer, EMCY, boot-up detection, configuration failures, bus state).
#include <gtest/gtest.h>

#include <map>

#include "massage_cell/can/master.h"
#include "massage_cell/can/virtual_bus.h"

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;

// --- SdoClient on its own --------------------------------------------------------

struct SdoFixture : ::testing::Test {
  VirtualClock clock;
  std::vector<can_frame> sent;
  SdoClient client{5, [this](const can_frame& f) { sent.push_back(f); return true; }, clock, 100ms};
  std::vector<SdoResult> results;
  SdoClient::Callback collect() {
    return [this](const SdoResult& r) { results.push_back(r); };
  }
  void reply(const can_frame& f) {
    auto d = decodeSdoResponse(f);
    ASSERT_TRUE(d) << d.error();
    client.handle(*d);
  }
};

TEST_F(SdoFixture, ExpeditedUpload) {
  client.upload(0x6041, 0, collect());
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(formatFrame(sent[0]), "605#4041600000000000");
  reply(sdoInitiateUploadResponse(5, 0x6041, 0, {0x37, 0x02}));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_TRUE(results[0].ok);
  EXPECT_EQ(results[0].data, (std::vector<std::uint8_t>{0x37, 0x02}));
}

TEST_F(SdoFixture, SegmentedUploadWithToggle) {
  const std::string name = "a drive name of 23 bytes";
  const std::vector<std::uint8_t> bytes(name.begin(), name.end());
  client.upload(0x1008, 0, collect());
  reply(sdoInitiateUploadResponse(5, 0x1008, 0, bytes));
  bool t = false;
  for (std::size_t off = 0; off < bytes.size(); off += 7) {
    ASSERT_FALSE(sent.empty());
    EXPECT_TRUE(sameFrame(sent.back(), sdoUploadSegmentRequest(5, t))) << formatFrame(sent.back());
    const std::size_t n = std::min<std::size_t>(7, bytes.size() - off);
    reply(sdoUploadSegmentResponse(5, t, std::vector<std::uint8_t>(bytes.begin() + off, bytes.begin() + off + n),
                                   off + n >= bytes.size()));
    t = !t;
  }
  ASSERT_EQ(results.size(), 1u);
  EXPECT_TRUE(results[0].ok) << results[0].error;
  EXPECT_EQ(std::string(results[0].data.begin(), results[0].data.end()), name);
}

TEST_F(SdoFixture, SegmentedDownload) {
  const std::vector<std::uint8_t> data = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  client.download(0x2000, 1, data, collect());
  EXPECT_EQ(formatFrame(sent.back()), "605#210020010A000000");
  reply(sdoInitiateDownloadResponse(5, 0x2000, 1));
  EXPECT_EQ(formatFrame(sent.back()), "605#0001020304050607");
  EXPECT_TRUE(sameFrame(sent.back(), sdoDownloadSegmentRequest(5, false, {1, 2, 3, 4, 5, 6, 7}, false)));
  reply(sdoDownloadSegmentResponse(5, false));
  EXPECT_TRUE(sameFrame(sent.back(), sdoDownloadSegmentRequest(5, true, {8, 9, 10}, true)));
  EXPECT_TRUE(results.empty());
  reply(sdoDownloadSegmentResponse(5, true));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_TRUE(results[0].ok);
}

TEST_F(SdoFixture, ServerAbortGivesTheAbortText) {
  client.download(0x6041, 0, {0, 0}, collect());
  reply(sdoAbortResponse(5, 0x6041, 0, sdo_abort::kReadOnly));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_FALSE(results[0].ok);
  EXPECT_EQ(results[0].abort_code, sdo_abort::kReadOnly);
  EXPECT_EQ(results[0].error,
            "node 5: SDO download 0x6041:00: aborted by the server: 0x06010002 attempt to write a read only object");
}

TEST_F(SdoFixture, TimeoutSendsAbortAndReports) {
  client.upload(0x1000, 0, collect());
  clock.advance(99ms);
  client.poll();
  EXPECT_TRUE(results.empty());
  clock.advance(1ms);
  client.poll();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].abort_code, sdo_abort::kTimeout);
  EXPECT_NE(results[0].error.find("no response within 100 ms (SDO protocol timed out)"), std::string::npos)
      << results[0].error;
  EXPECT_TRUE(sameFrame(sent.back(), sdoAbortRequest(5, 0x1000, 0, sdo_abort::kTimeout)));
}

TEST_F(SdoFixture, ToggleErrorAborts) {
  client.upload(0x1008, 0, collect());
  reply(sdoInitiateUploadResponse(5, 0x1008, 0, std::vector<std::uint8_t>(20, 'x')));
  reply(sdoUploadSegmentResponse(5, true, {1, 2, 3, 4, 5, 6, 7}, false));  // toggle should be 0
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].abort_code, sdo_abort::kToggleBit);
  EXPECT_TRUE(sameFrame(sent.back(), sdoAbortRequest(5, 0x1008, 0, sdo_abort::kToggleBit)));
}

TEST_F(SdoFixture, WrongObjectAndWrongCommandAbort) {
  client.upload(0x6041, 0, collect());
  reply(sdoInitiateUploadResponse(5, 0x6064, 0, {1, 2, 3, 4}));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_NE(results[0].error.find("response names object 0x6064:00"), std::string::npos) << results[0].error;
  client.upload(0x6041, 0, collect());
  reply(sdoInitiateDownloadResponse(5, 0x6041, 0));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[1].abort_code, sdo_abort::kCommandSpecifier);
}

TEST_F(SdoFixture, SizeMismatchFails) {
  client.upload(0x1008, 0, collect());
  reply(sdoInitiateUploadResponse(5, 0x1008, 0, std::vector<std::uint8_t>(10, 'x')));
  reply(sdoUploadSegmentResponse(5, false, {1, 2, 3}, true));  // 3 of 10
  ASSERT_EQ(results.size(), 1u);
  EXPECT_FALSE(results[0].ok);
  EXPECT_NE(results[0].error.find("received 3 of the announced 10 bytes"), std::string::npos) << results[0].error;
}

TEST_F(SdoFixture, QueuesTransfersInOrder) {
  client.download(0x6040, 0, {6, 0}, collect());
  client.download(0x6040, 0, {7, 0}, collect());
  client.upload(0x6041, 0, collect());
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_EQ(client.queued(), 2u);
  reply(sdoInitiateDownloadResponse(5, 0x6040, 0));
  EXPECT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1].data[4], 7);
  reply(sdoInitiateDownloadResponse(5, 0x6040, 0));
  reply(sdoInitiateUploadResponse(5, 0x6041, 0, {0x40, 0x02}));
  ASSERT_EQ(results.size(), 3u);
  for (auto& r : results) EXPECT_TRUE(r.ok);
  client.upload(0x6041, 0, collect());
  client.upload(0x6064, 0, collect());
  client.cancelAll("node lost");
  ASSERT_EQ(results.size(), 5u);
  EXPECT_NE(results[4].error.find("0x6064:00: node lost"), std::string::npos) << results[4].error;
}

// --- Master against a scripted node ---------------------------------------------------

// A minimal CANopen slave written directly against the codecs: answers
// expedited SDO downloads / uploads from a map, NMT, heartbeat, and lets a
// test script aborts, silence and extra frames.
struct ScriptedNode {
  ScriptedNode(VirtualBus& bus, std::uint8_t node, const Clock& c) : ep(bus.open("node")), id(node), clock(c) {}
  std::shared_ptr<VirtualBus::Endpoint> ep;
  std::uint8_t id;
  const Clock& clock;
  std::map<std::pair<std::uint16_t, std::uint8_t>, std::vector<std::uint8_t>> od;
  std::vector<std::pair<std::uint16_t, std::uint8_t>> writes;
  std::vector<NmtCommand> nmt_log;
  std::optional<std::pair<std::uint16_t, std::uint8_t>> abort_on;
  bool silent = false, booted = false, answer_reset = true;
  NmtState state = NmtState::kPreOperational;
  TimePoint next_hb{};

  void poll() {
    while (auto tf = ep->receive(0ns)) {
      if (silent) continue;
      const can_frame& f = tf->frame;
      if (auto n = decodeNmt(f); n && (n->node == 0 || n->node == id)) {
        nmt_log.push_back(n->command);
        if (n->command == NmtCommand::kResetCommunication || n->command == NmtCommand::kResetNode) {
          if (answer_reset) bootUp();
        } else if (n->command == NmtCommand::kStart) {
          state = NmtState::kOperational;
        } else if (n->command == NmtCommand::kEnterPreOperational) {
          state = NmtState::kPreOperational;
        }
      } else if (auto s = decodeSdoRequest(f); s && s->node == id) {
        const auto key = std::make_pair(s->index, s->subindex);
        if (abort_on && *abort_on == key) {
          ep->send(sdoAbortResponse(id, s->index, s->subindex, sdo_abort::kNotMappable));
        } else if (s->command == SdoCommand::kInitiateDownload) {
          od[key] = s->data;
          writes.push_back(key);
          ep->send(sdoInitiateDownloadResponse(id, s->index, s->subindex));
        } else if (s->command == SdoCommand::kInitiateUpload) {
          auto it = od.find(key);
          if (it == od.end()) {
            ep->send(sdoAbortResponse(id, s->index, s->subindex, sdo_abort::kNoObject));
          } else {
            ep->send(sdoInitiateUploadResponse(id, s->index, s->subindex, it->second));
          }
        }
      }
    }
    const auto hb = od.find({0x1017, 0});
    if (!silent && booted && hb != od.end() && clock.now() >= next_hb) {
      ep->send(encodeHeartbeat(id, state));
      next_hb = clock.now() + std::chrono::milliseconds(fromBytes(hb->second));
    }
  }
  void bootUp() {
    od.erase({0x1017, 0});
    state = NmtState::kPreOperational;
    booted = true;
    ep->send(encodeHeartbeat(id, NmtState::kBootUp));
  }
};

struct MasterFixture : ::testing::Test {
  MasterFixture() {
    config.axes.push_back(axis("X", 1));
    config.axes.push_back(axis("Y", 2));
    master = std::make_unique<Master>(*master_ep, clock, config);
    for (const AxisConfig& a : config.axes) nodes.push_back(std::make_unique<ScriptedNode>(bus, a.node_id, clock));
  }
  static AxisConfig axis(const std::string& name, std::uint8_t id) {
    AxisConfig a;
    a.name = name;
    a.node_id = id;
    a.counts_per_metre = 1000;
    a.heartbeat_ms = 50;
    a.heartbeat_timeout_ms = 150;
    return a;
  }
  void step(Duration dt = 1ms) {
    clock.advance(dt);
    for (auto& n : nodes) n->poll();
    master->poll();
  }
  bool runUntil(const std::function<bool()>& pred, Duration limit) {
    for (Duration t{}; t < limit; t += 1ms) {
      if (pred()) return true;
      step();
    }
    return pred();
  }
  bool hasEvent(const std::vector<Event>& events, EventType type, std::uint8_t node, const std::string& text = {}) {
    for (const Event& e : events) {
      if (e.type == type && e.node == node && e.text.find(text) != std::string::npos) return true;
    }
    return false;
  }
  void bringUp() {
    master->bringUp();
    ASSERT_TRUE(runUntil([&] { return master->allOperational(); }, 1s));
  }

  VirtualClock clock;
  VirtualBus bus{clock};
  std::shared_ptr<VirtualBus::Endpoint> master_ep = bus.open("master");
  CanConfig config;
  std::unique_ptr<Master> master;
  std::vector<std::unique_ptr<ScriptedNode>> nodes;
};

TEST_F(MasterFixture, BringUpResetsConfiguresAndStartsEveryNode) {
  master->addStartupWrite(2, {0x6060, 0, {1}});
  master->bringUp();
  EXPECT_EQ(master->nodeState(1), NodeState::kResetting);
  ASSERT_TRUE(runUntil([&] { return master->allOperational(); }, 1s));
  for (auto& n : nodes) {
    EXPECT_EQ(n->nmt_log, (std::vector<NmtCommand>{NmtCommand::kResetCommunication, NmtCommand::kStart}));
    std::vector<std::pair<std::uint16_t, std::uint8_t>> want;
    for (const StartupWrite& w : canopenStartupWrites(config.axes[n->id - 1])) want.emplace_back(w.index, w.sub);
    if (n->id == 2) want.emplace_back(0x6060, 0);
    EXPECT_EQ(n->writes, want) << "node " << int(n->id);
    // The final state of the mapping objects.
    EXPECT_EQ(fromBytes(n->od[{0x1600, 1}]), 0x60400010u);
    EXPECT_EQ(fromBytes(n->od[{0x1600, 2}]), 0x607A0020u);
    EXPECT_EQ(fromBytes(n->od[{0x1A00, 1}]), 0x60410010u);
    EXPECT_EQ(fromBytes(n->od[{0x1A00, 2}]), 0x60640020u);
    EXPECT_EQ(fromBytes(n->od[{0x1A00, 0}]), 2u);
    EXPECT_EQ(fromBytes(n->od[{0x1400, 1}]), 0x200u + n->id);
    EXPECT_EQ(fromBytes(n->od[{0x1800, 1}]), 0x180u + n->id);
    EXPECT_EQ(fromBytes(n->od[{0x1801, 1}]), 0x80000280u + n->id);  // TPDO2 disabled (no velocity)
    EXPECT_EQ(fromBytes(n->od[{0x1017, 0}]), 50u);
  }
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBootUp, 1));
  EXPECT_TRUE(hasEvent(events, EventType::kNodeOperational, 2, "node 2 (Y): configured and operational"));
  EXPECT_EQ(master->nmtState(1), NmtState::kOperational);
}

TEST_F(MasterFixture, VelocityPdoMapsTpdo2) {
  AxisConfig a = axis("X", 1);
  a.velocity_pdo = true;
  const auto w = canopenStartupWrites(a);
  std::map<std::pair<std::uint16_t, std::uint8_t>, std::uint64_t> last;
  for (const auto& x : w) last[{x.index, x.sub}] = fromBytes(x.data);
  EXPECT_EQ((last[{0x1A01, 1}]), 0x606C0020u);
  EXPECT_EQ((last[{0x1A01, 2}]), 0x60610008u);
  EXPECT_EQ((last[{0x1801, 1}]), 0x281u);
  // The mapping is written while the PDO is disabled (bit 31 set first).
  std::size_t disable = 0, enable = 0;
  for (std::size_t i = 0; i < w.size(); ++i) {
    if (w[i].index == 0x1801 && w[i].sub == 1) (fromBytes(w[i].data) & 0x80000000u ? disable : enable) = i;
  }
  EXPECT_LT(disable, enable);
}

TEST_F(MasterFixture, SendsRpdoBeforeEachSyncAtThePeriod) {
  bringUp();
  auto sniffer = bus.open("sniffer");
  master->setRpdo(1, 0x000F, -1234);
  const TimePoint t0 = clock.now();
  while (clock.now() - t0 < 100ms) step();
  std::vector<TimedFrame> frames;
  while (auto f = sniffer->receive(0ns)) frames.push_back(*f);
  std::vector<TimePoint> syncs;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].frame.can_id != 0x080) continue;
    syncs.push_back(frames[i].stamp);
    ASSERT_GT(i, 0u);
    // The RPDO of node 1 (node 2 has no RPDO set yet) goes out just before the SYNC.
    EXPECT_EQ(formatFrame(frames[i - 1].frame), "201#0F002EFBFFFF");
  }
  ASSERT_GE(syncs.size(), 9u);
  for (std::size_t i = 1; i < syncs.size(); ++i) EXPECT_EQ(syncs[i] - syncs[i - 1], Duration(10ms));
  EXPECT_EQ(master->controlword(1), 0x000F);
}

TEST_F(MasterFixture, TpdoUpdatesFeedbackAndMalformedOnesAreIgnored) {
  bringUp();
  master->takeEvents();
  nodes[0]->ep->send(*packPdo(0x181, tpdo1Mapping(), {0x0637, static_cast<std::uint32_t>(-5000)}));
  step();
  DriveFeedback fb = master->feedback(1);
  ASSERT_TRUE(fb.valid);
  EXPECT_EQ(fb.statusword, 0x0637);
  EXPECT_EQ(fb.position, -5000);
  nodes[0]->ep->send(makeFrame(0x181, {0x27, 0x02, 0x00}));  // DLC 3
  step();
  fb = master->feedback(1);
  EXPECT_EQ(fb.statusword, 0x0637);
  EXPECT_EQ(fb.position, -5000);
  EXPECT_EQ(master->stats().malformed, 1u);
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kMalformedFrame, 1, "DLC 3 but 6 bytes mapped"));
  nodes[0]->ep->send(makeFrame(0x7E5, {0x04}));  // LSS: not ours
  nodes[0]->ep->send(makeFrame(0x705, {0x05}));  // heartbeat of an unconfigured node
  step();
  EXPECT_EQ(master->stats().malformed, 2u);
  EXPECT_EQ(master->stats().ignored, 1u);
}

TEST_F(MasterFixture, EmcyBecomesAnEventWithText) {
  bringUp();
  master->takeEvents();
  Emcy e;
  e.error_code = 0x2310;
  e.error_register = 0x03;
  nodes[1]->ep->send(encodeEmcy(2, e));
  step();
  const auto events = master->takeEvents();
  ASSERT_TRUE(hasEvent(events, EventType::kEmcy, 2,
                       "node 2 (Y): EMCY 0x2310 continuous over-current (error register 0x03)"));
  EXPECT_EQ(master->feedback(2).emcy_code, 0x2310);
}

TEST_F(MasterFixture, HeartbeatTimeoutAndResume) {
  bringUp();
  master->takeEvents();
  nodes[0]->silent = true;
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kLost; }, 1s));
  EXPECT_EQ(master->nodeState(2), NodeState::kOperational);
  auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kHeartbeatTimeout, 1, "no heartbeat for 150 ms"));
  nodes[0]->silent = false;
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kOperational; }, 1s));
  events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kHeartbeatResumed, 1));
}

TEST_F(MasterFixture, TimeoutIsNotDeclaredEarly) {
  bringUp();
  nodes[0]->silent = true;
  const TimePoint t0 = clock.now();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kLost; }, 1s));
  // Last heartbeat was at most 50 ms before t0; timeout 150 ms.
  EXPECT_GE(clock.now() - t0, 100ms);
  EXPECT_LE(clock.now() - t0, 152ms);
}

TEST_F(MasterFixture, UnexpectedBootUpIsReconfigured) {
  bringUp();
  master->takeEvents();
  nodes[1]->writes.clear();
  nodes[1]->bootUp();  // power cycle
  ASSERT_TRUE(runUntil([&] { return master->nodeState(2) == NodeState::kConfiguring; }, 10ms));
  ASSERT_TRUE(runUntil([&] { return master->nodeState(2) == NodeState::kOperational; }, 1s));
  EXPECT_EQ(nodes[1]->writes.size(), canopenStartupWrites(config.axes[1]).size());
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBootUp, 2, "unexpected boot-up"));
}

TEST_F(MasterFixture, ConfigurationAbortFailsTheNodeWithTheReason) {
  nodes[0]->abort_on = std::make_pair<std::uint16_t, std::uint8_t>(0x1A00, 2);
  master->bringUp();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kFailed; }, 1s));
  ASSERT_TRUE(runUntil([&] { return master->nodeState(2) == NodeState::kOperational; }, 1s));
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kConfigureFailed, 1,
                       "node 1 (X): configuration failed: node 1: SDO download 0x1A00:02: aborted by the server: "
                       "0x06040041 object cannot be mapped to the PDO"));
  EXPECT_EQ(nodes[0]->nmt_log.back(), NmtCommand::kResetCommunication);  // never started
}

TEST_F(MasterFixture, MissingNodeFailsAfterTheBootTimeout) {
  nodes[1]->answer_reset = false;
  master->bringUp();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(2) == NodeState::kFailed; }, 3s));
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kConfigureFailed, 2, "no boot-up within 2000 ms after reset communication"));
  EXPECT_EQ(master->nodeState(1), NodeState::kOperational);
}

TEST_F(MasterFixture, SdoThroughTheMaster) {
  bringUp();
  nodes[0]->od[{0x1008, 0}] = {'X', '1'};
  std::optional<SdoResult> got, missing;
  master->sdoUpload(1, 0x1008, 0, [&](const SdoResult& r) { got = r; });
  master->sdoUpload(1, 0x2222, 0, [&](const SdoResult& r) { missing = r; });
  ASSERT_TRUE(runUntil([&] { return got && missing; }, 100ms));
  EXPECT_TRUE(got->ok);
  EXPECT_EQ(got->data, (std::vector<std::uint8_t>{'X', '1'}));
  EXPECT_FALSE(missing->ok);
  EXPECT_NE(missing->error.find("object does not exist"), std::string::npos);
  EXPECT_THROW(master->sdoUpload(9, 0x1000, 0, {}), std::out_of_range);
}

TEST_F(MasterFixture, ReportsBusOffAndRecovery) {
  bringUp();
  master->takeEvents();
  bus.setBusOff(*master_ep, 40ms);
  step();
  auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 0, "error-active -> bus-off"));
  runUntil([] { return false; }, 50ms);
  EXPECT_GE(master->stats().send_failures, 3u);  // the SYNCs (and RPDOs) it could not send
  events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 0, "bus-off -> error-active (recovered)"));
  // 40 ms is shorter than the heartbeat timeout: the nodes are still operational.
  EXPECT_TRUE(master->allOperational());
}

TEST(MasterConfig, RejectsInvalidConfig) {
  VirtualBus bus;
  auto ep = bus.open("m");
  CanConfig c;
  EXPECT_THROW(Master(*ep, SteadyClock::instance(), c), ConfigError);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
