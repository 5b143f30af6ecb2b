// Layer 3 tests: SDO client against scripted server frames, and the CANopen
// master against a scripted node on a VirtualBus with a VirtualClock
// (bring-up sequence, SYNC / RPDO timing, the before-SYNC hook, TPDO
// feedback, heartbeat consumer, EMCY, event listeners, boot-up detection,
// configuration failures, bus state), and its thread on the real clock
// (heartbeat producer, SCHED_FIFO).
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "massage_cell/can/master.h"
#include "massage_cell/can/realtime.h"
#include "massage_cell/can/virtual_bus.h"

namespace {

using namespace massage_cell::can;
using namespace std::chrono_literals;

// --- SdoClient on its own --------------------------------------------------------

struct SdoFixture : ::testing::Test {
  VirtualClock clock;
  std::vector<can_frame> sent;
  SdoClient client{5,
                   [this](const can_frame& f) {
                     sent.push_back(f);
                     return true;
                   },
                   clock, 100ms};
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

TEST_F(MasterFixture, SendRpdoNowSendsTheRpdoAtOnceBetweenSyncs) {
  EXPECT_FALSE(master->sendRpdoNow(1));  // not operational yet
  bringUp();
  auto sniffer = bus.open("sniffer");
  master->setRpdo(1, 0x000F, -1234);
  EXPECT_FALSE(master->rpdoTarget(2));
  EXPECT_FALSE(master->sendRpdoNow(2));  // no RPDO set
  const TimePoint t0 = clock.now();
  while (clock.now() - t0 < 25ms) step();
  while (sniffer->receive(0ns)) {
  }
  const std::uint64_t sent = master->rpdosSent(1);
  const MasterStats stats = master->stats();
  // The target stays; the new controlword goes out now, without a poll or the clock moving on.
  EXPECT_EQ(master->rpdoTarget(1), std::optional<std::int32_t>(-1234));
  master->setRpdo(1, 0x0002, *master->rpdoTarget(1));
  ASSERT_TRUE(master->sendRpdoNow(1));
  const auto f = sniffer->receive(0ns);
  ASSERT_TRUE(f);
  EXPECT_EQ(formatFrame(f->frame), "201#02002EFBFFFF");
  EXPECT_EQ(f->stamp, clock.now());
  EXPECT_FALSE(sniffer->receive(0ns));  // no SYNC with it
  EXPECT_EQ(master->rpdosSent(1), sent + 1);
  EXPECT_EQ(master->stats().rpdos, stats.rpdos + 1);
  EXPECT_EQ(master->stats().syncs, stats.syncs);
  // The next SYNC carries it again, as usual.
  ASSERT_TRUE(runUntil([&] { return master->stats().syncs > stats.syncs; }, 20ms));
  std::vector<std::string> frames;
  while (auto g = sniffer->receive(0ns)) frames.push_back(formatFrame(g->frame));
  ASSERT_GE(frames.size(), 2u);
  EXPECT_EQ(frames[frames.size() - 2], "201#02002EFBFFFF");
  EXPECT_EQ(frames.back(), "080#");
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
  ASSERT_TRUE(
      hasEvent(events, EventType::kEmcy, 2, "node 2 (Y): EMCY 0x2310 continuous over-current (error register 0x03)"));
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

TEST_F(MasterFixture, AStallOfItsOwnIsNotANodesSilence) {
  // The host paused 400 ms (longer than the 150 ms timeout) and the master ran first after it: nothing from the
  // nodes in its queue, yet no node was silent while the master listened.
  bringUp();
  master->takeEvents();
  clock.advance(400ms);
  master->poll();
  for (int i = 0; i < 100; ++i) step();
  const auto events = master->takeEvents();
  for (std::uint8_t id : {1, 2}) {
    EXPECT_EQ(master->nodeState(id), NodeState::kOperational) << "node " << int(id);
    EXPECT_FALSE(hasEvent(events, EventType::kHeartbeatTimeout, id)) << "node " << int(id);
  }
  // A node silent after the stall is still lost within its timeout of the master's running.
  nodes[0]->silent = true;
  const TimePoint t0 = clock.now();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kLost; }, 1s));
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
  EXPECT_EQ(master->stats().bringup_restarts, 0u);  // the bus was fine: a real failure is not retried
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

TEST_F(MasterFixture, ReportsABusOffThatEndedBetweenTwoPolls) {
  bringUp();
  master->takeEvents();
  const MasterStats before = master->stats();
  bus.setBusOff(*master_ep, 500us);  // over before the master's next poll (1 ms later)
  step();
  EXPECT_EQ(master_ep->status().state, BusState::kErrorActive);
  const auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 0,
                       "master: error-active -> bus-off -> error-active (recovered between two polls; 1 outage)"));
  EXPECT_EQ(master->stats().bus_outages, before.bus_outages + 1);
  EXPECT_TRUE(master->allOperational());
  // A normal bus-off is one outage too, with its own two events.
  bus.setBusOff(*master_ep, 20ms);
  runUntil([] { return false; }, 30ms);
  EXPECT_EQ(master->stats().bus_outages, before.bus_outages + 2);
}

TEST_F(MasterFixture, BringUpFailedDuringABusOffRestartsWhenTheBusRecovers) {
  master->bringUp();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kConfiguring; }, 100ms));
  bus.setBusOff(*master_ep, 400ms);  // longer than the SDO timeout (100 ms): the configuration fails meanwhile
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kFailed; }, 300ms));
  auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kConfigureFailed, 1,
                       "no response within 100 ms (SDO protocol timed out) (the bus is bus-off: bring-up restarts "
                       "when it recovers)"));
  EXPECT_EQ(master->nodeState(2), NodeState::kFailed);
  ASSERT_TRUE(runUntil([&] { return master->allOperational(); }, 1500ms));
  events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 0, "bus-off -> error-active (recovered)"));
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 1, "node 1 (X): bus recovered: bring-up restarted"));
  EXPECT_TRUE(hasEvent(events, EventType::kBusStateChanged, 2, "node 2 (Y): bus recovered: bring-up restarted"));
  EXPECT_EQ(master->stats().bringup_restarts, 2u);
  for (auto& n : nodes) {
    EXPECT_EQ(n->nmt_log, (std::vector<NmtCommand>{NmtCommand::kResetCommunication, NmtCommand::kResetCommunication,
                                                   NmtCommand::kStart}))
        << "node " << int(n->id);
  }
}

TEST_F(MasterFixture, BringUpFailedAfterAShortBusOffRestartsAtOnce) {
  master->bringUp();
  ASSERT_TRUE(runUntil([&] { return master->nodeState(1) == NodeState::kConfiguring; }, 100ms));
  bus.setBusOff(*master_ep, 30ms);  // the SDO answer in flight is lost; its timeout fires after the recovery
  ASSERT_TRUE(runUntil([&] { return master->stats().bringup_restarts >= 1; }, 300ms));
  auto events = master->takeEvents();
  EXPECT_TRUE(hasEvent(events, EventType::kConfigureFailed, 1,
                       "(the bus was bus-off or down during this bring-up: bring-up restarted)"));
  ASSERT_TRUE(runUntil([&] { return master->allOperational(); }, 1s));
  // Bus-off once more, now with every node operational: nothing is restarted.
  const std::uint64_t restarts = master->stats().bringup_restarts;
  bus.setBusOff(*master_ep, 30ms);
  runUntil([] { return false; }, 500ms);
  EXPECT_TRUE(master->allOperational());
  EXPECT_EQ(master->stats().bringup_restarts, restarts);
}

// The master's own heartbeat frames seen by another endpoint, with their stamps.
std::vector<TimedFrame> heartbeatsOn(VirtualBus::Endpoint& sniffer, canid_t cob) {
  std::vector<TimedFrame> out;
  while (auto f = sniffer.receive(0ns)) {
    if (f->frame.can_id == cob) out.push_back(*f);
  }
  return out;
}

TEST_F(MasterFixture, ProducesItsHeartbeatAtThePeriodWithItsState) {
  auto sniffer = bus.open("sniffer");
  EXPECT_EQ(master->ownNmtState(), NmtState::kPreOperational);
  runUntil([] { return false; }, 1000ms);
  auto hb = heartbeatsOn(*sniffer, 0x77F);  // 0x700 + the default master node id 127
  ASSERT_EQ(hb.size(), 10u);
  for (std::size_t i = 0; i < hb.size(); ++i) {
    EXPECT_EQ(formatFrame(hb[i].frame), "77F#7F");  // pre-operational: nothing brought up yet
    if (i > 0) {
      EXPECT_EQ(hb[i].stamp - hb[i - 1].stamp, Duration(100ms));
    }
  }
  const auto decoded = decodeHeartbeat(hb[0].frame);
  ASSERT_TRUE(decoded) << decoded.error();
  EXPECT_EQ(decoded->node, 127);
  bringUp();
  EXPECT_EQ(master->ownNmtState(), NmtState::kOperational);
  heartbeatsOn(*sniffer, 0x77F);
  const std::uint64_t produced = master->stats().heartbeats_produced;
  runUntil([] { return false; }, 500ms);
  hb = heartbeatsOn(*sniffer, 0x77F);
  ASSERT_EQ(hb.size(), 5u);
  for (const TimedFrame& f : hb) EXPECT_EQ(formatFrame(f.frame), "77F#05");  // operational
  EXPECT_EQ(master->stats().heartbeats_produced - produced, 5u);
  // The nodes' heartbeat consumer does not mistake it for a node: nothing malformed, nothing lost.
  EXPECT_EQ(master->stats().malformed, 0u);
  EXPECT_TRUE(master->allOperational());
}

TEST_F(MasterFixture, HeartbeatIdAndPeriodComeFromTheConfig) {
  CanConfig c = config;
  c.master_node_id = 100;
  c.master_heartbeat_ms = 30;
  master = std::make_unique<Master>(*master_ep, clock, c);
  auto sniffer = bus.open("sniffer");
  runUntil([] { return false; }, 300ms);
  const auto hb = heartbeatsOn(*sniffer, 0x764);
  ASSERT_EQ(hb.size(), 10u);
  for (std::size_t i = 1; i < hb.size(); ++i) EXPECT_EQ(hb[i].stamp - hb[i - 1].stamp, Duration(30ms));
  // 0 = no heartbeat at all.
  c.master_heartbeat_ms = 0;
  master = std::make_unique<Master>(*master_ep, clock, c);
  heartbeatsOn(*sniffer, 0x764);
  runUntil([] { return false; }, 300ms);
  while (auto f = sniffer->receive(0ns)) EXPECT_NE(f->frame.can_id & 0x780u, 0x700u) << formatFrame(f->frame);
  EXPECT_EQ(master->stats().heartbeats_produced, 0u);
}

TEST_F(MasterFixture, ConfiguresTheDrivesConsumerOfItsHeartbeat) {
  AxisConfig a = axis("X", 1);
  EXPECT_EQ(canopenStartupWrites(a, 100).size(), canopenStartupWrites(a).size());
  for (const StartupWrite& w : canopenStartupWrites(a, 100)) EXPECT_TRUE(w.index != 0x1016 && w.index != 0x6007);
  a.master_heartbeat_timeout_ms = 300;
  a.abort_connection_option = 3;
  std::map<std::pair<std::uint16_t, std::uint8_t>, std::uint64_t> w;
  for (const StartupWrite& x : canopenStartupWrites(a, 100)) w[{x.index, x.sub}] = fromBytes(x.data);
  EXPECT_EQ((w[{0x1016, 1}]), 0x0064012Cu);  // node 100 << 16 | 300 ms
  EXPECT_EQ((w[{0x6007, 0}]), 3u);
  // Through the master: the configured master node id goes into 0x1016:01.
  CanConfig c = config;
  c.axes[0].master_heartbeat_timeout_ms = 250;
  master = std::make_unique<Master>(*master_ep, clock, c);
  bringUp();
  EXPECT_EQ(fromBytes(nodes[0]->od[{0x1016, 1}]), 0x007F00FAu);  // 127 << 16 | 250
  EXPECT_EQ(fromBytes(nodes[0]->od[{0x6007, 0}]), 1u);
  EXPECT_EQ(nodes[1]->od.count({0x1016, 1}), 0u);  // Y does not monitor the master
}

CanConfig oneAxisConfig() {
  CanConfig c;
  AxisConfig a;
  a.name = "X";
  a.node_id = 1;
  a.counts_per_metre = 1000;
  c.axes.push_back(a);
  return c;
}

TEST(MasterHeartbeat, StopsWhenTheMasterStops) {
  VirtualBus bus;  // real clock
  auto ep = bus.open("master");
  auto sniffer = bus.open("sniffer");
  sniffer->setFilters({{0x77F, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG}});
  CanConfig c = oneAxisConfig();
  c.master_heartbeat_ms = 50;
  auto master = std::make_unique<Master>(*ep, SteadyClock::instance(), c);
  master->start();
  std::this_thread::sleep_for(420ms);
  std::size_t running = 0;
  while (sniffer->receive(0ns)) ++running;
  EXPECT_GE(running, 4u);  // 9 expected (t = 0, 50, ..., 400 ms); a loaded machine may delay a few
  EXPECT_LE(running, 10u);
  master->stop();
  while (sniffer->receive(0ns)) {
  }
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(sniffer->pending(), 0u) << "heartbeats after stop()";
  master->start();  // alive again
  std::this_thread::sleep_for(200ms);
  EXPECT_GE(sniffer->pending(), 1u);
  master.reset();  // destruction stops it too
  while (sniffer->receive(0ns)) {
  }
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(sniffer->pending(), 0u) << "heartbeats after the master was destroyed";
}

// --- before-SYNC hook ---------------------------------------------------------------

TEST_F(MasterFixture, BeforeSyncHookRunsOncePerSyncJustBeforeIt) {
  bringUp();
  auto sniffer = bus.open("sniffer");
  std::vector<TimedFrame> frames;
  auto drain = [&] {
    while (auto f = sniffer->receive(0ns)) frames.push_back(*f);
  };
  auto syncsOnTheBus = [&] {
    return std::count_if(frames.begin(), frames.end(), [](const TimedFrame& f) { return f.frame.can_id == 0x080; });
  };
  std::vector<long> syncs_before;  // SYNCs already on the bus when the hook ran
  std::vector<TimePoint> hook_times;
  master->setBeforeSyncHook([&](TimePoint now) {
    drain();
    syncs_before.push_back(static_cast<long>(syncsOnTheBus()));
    hook_times.push_back(now);
    master->setRpdo(1, 0x000F, static_cast<std::int32_t>(hook_times.size()));  // this SYNC's set-point
  });
  // Polls denser and sparser than the period: still one hook per SYNC.
  const TimePoint t0 = clock.now();
  while (clock.now() - t0 < 60ms) step(250us);
  while (clock.now() - t0 < 120ms) step(3ms);
  drain();
  ASSERT_GE(hook_times.size(), 10u);
  std::vector<std::size_t> sync_at;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].frame.can_id == 0x080) sync_at.push_back(i);
  }
  ASSERT_EQ(sync_at.size(), hook_times.size());
  for (std::size_t k = 0; k < sync_at.size(); ++k) {
    EXPECT_EQ(syncs_before[k], static_cast<long>(k)) << "hook " << k << " did not run before its SYNC";
    EXPECT_EQ(frames[sync_at[k]].stamp, hook_times[k]);  // in the same poll
    // What the hook wrote went out in this SYNC's RPDO, just before it.
    ASSERT_GT(sync_at[k], 0u);
    const can_frame& rpdo = frames[sync_at[k] - 1].frame;
    ASSERT_EQ(rpdo.can_id, 0x201u) << formatFrame(rpdo);
    EXPECT_EQ(static_cast<std::int32_t>(rpdo.data[2] | rpdo.data[3] << 8 | rpdo.data[4] << 16 |
                                        static_cast<std::uint32_t>(rpdo.data[5]) << 24),
              static_cast<std::int32_t>(k + 1));
  }
  master->setBeforeSyncHook({});
  const std::size_t calls = hook_times.size();
  while (clock.now() - t0 < 200ms) step();
  EXPECT_EQ(hook_times.size(), calls);  // removed
}

/// A Bus that notes which thread sent each SYNC.
class SyncThreadTap final : public Bus {
 public:
  explicit SyncThreadTap(Bus& inner) : inner_(inner) {}
  std::string name() const override { return inner_.name(); }
  bool send(const can_frame& f) override {
    if (f.can_id == 0x080) {
      std::lock_guard<std::mutex> lock(mutex_);
      threads_.push_back(std::this_thread::get_id());
    }
    return inner_.send(f);
  }
  std::optional<TimedFrame> receive(Duration timeout) override { return inner_.receive(timeout); }
  void setFilters(const std::vector<can_filter>& filters) override { inner_.setFilters(filters); }
  BusStatus status() const override { return inner_.status(); }
  std::vector<std::thread::id> threads() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return threads_;
  }

 private:
  Bus& inner_;
  mutable std::mutex mutex_;
  std::vector<std::thread::id> threads_;
};

TEST(MasterThread, BeforeSyncHookRunsInTheThreadThatSendsTheSync) {
  VirtualBus bus;  // real clock
  auto ep = bus.open("master");
  SyncThreadTap tap(*ep);
  Master master(tap, SteadyClock::instance(), oneAxisConfig());
  std::vector<std::thread::id> hook_threads;
  std::vector<std::uint64_t> syncs_sent;  // master's SYNC count when the hook ran
  master.setBeforeSyncHook([&](TimePoint) {
    hook_threads.push_back(std::this_thread::get_id());
    syncs_sent.push_back(master.stats().syncs);
  });
  master.start();
  ASSERT_TRUE(master.waitUntil([&] { return hook_threads.size() >= 20; }, 5s));
  master.stop();
  const std::vector<std::thread::id> sync_threads = tap.threads();
  ASSERT_EQ(sync_threads.size(), hook_threads.size());
  for (std::size_t k = 0; k < hook_threads.size(); ++k) {
    EXPECT_EQ(hook_threads[k], sync_threads[k]);
    EXPECT_NE(hook_threads[k], std::this_thread::get_id());
    EXPECT_EQ(syncs_sent[k], k);
  }
}

// --- events: a one-reader queue and any number of listeners ---------------------------

TEST_F(MasterFixture, EveryListenerSeesEveryEventWhoeverDrainsTheQueue) {
  std::vector<std::string> a, b;
  const int id_a = master->addEventListener([&](const Event& e) { a.push_back(e.text); });
  master->addEventListener([&](const Event& e) { b.push_back(e.text); });
  bringUp();
  const std::vector<Event> queued = master->takeEvents();
  ASSERT_FALSE(queued.empty());
  ASSERT_EQ(a.size(), queued.size());
  EXPECT_EQ(a, b);
  for (std::size_t i = 0; i < queued.size(); ++i) EXPECT_EQ(a[i], queued[i].text);
  master->removeEventListener(id_a);
  nodes[1]->silent = true;
  ASSERT_TRUE(runUntil([&] { return master->nodeState(2) == NodeState::kLost; }, 1s));
  EXPECT_EQ(a.size(), queued.size());  // removed: saw nothing more
  ASSERT_GT(b.size(), queued.size());
  EXPECT_NE(b.back().find("node 2 (Y): no heartbeat"), std::string::npos) << b.back();
  EXPECT_TRUE(hasEvent(master->takeEvents(), EventType::kHeartbeatTimeout, 2));  // the queue has it too
}

// --- real-time scheduling of the master's thread ----------------------------------------

/// Whether this process may use SCHED_FIFO (CAP_SYS_NICE or an rtprio limit >= 50).
bool mayUseFifo() {
  std::string error;
  std::thread t([&] { error = setRealtimePriority(pthread_self(), 50); });
  t.join();
  return error.empty();
}

TEST(MasterRealtime, ThreadRunsUnderFifoAtThePriority) {
  if (!mayUseFifo()) GTEST_SKIP() << "no CAP_SYS_NICE / rtprio limit here";
  VirtualBus bus;
  auto ep = bus.open("master");
  Master master(*ep, SteadyClock::instance(), oneAxisConfig());
  int in_hook = -1;
  master.setBeforeSyncHook([&](TimePoint) { in_hook = realtimePriority(pthread_self()); });
  EXPECT_EQ(master.start(50), "");
  EXPECT_EQ(master.threadPriority(), 50);
  ASSERT_TRUE(master.waitUntil([&] { return in_hook >= 0; }, 2s));
  EXPECT_EQ(in_hook, 50);                          // the SYNC / cycle thread itself
  EXPECT_EQ(realtimePriority(pthread_self()), 0);  // the caller is left alone
  master.stop();
  EXPECT_EQ(master.threadPriority(), 0);
  EXPECT_EQ(master.start(), "");  // 0: normal scheduling
  EXPECT_EQ(master.threadPriority(), 0);
}

/// The calling thread's scheduling priority as the kernel applies it now
/// (/proc .../stat field 18: 20 for nice 0, -1 - p under SCHED_FIFO p, also when boosted).
int kernelPriority() {
  std::ifstream in("/proc/self/task/" + std::to_string(static_cast<long>(syscall(SYS_gettid))) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(stat.substr(stat.rfind(')') + 2));
  std::string field;
  for (int i = 3; i <= 18 && fields >> field; ++i) {
  }
  return std::stoi(field);
}

TEST(MasterRealtime, ALockHolderInheritsTheWaitingThreadsPriority) {
  if (!mayUseFifo()) GTEST_SKIP() << "no CAP_SYS_NICE / rtprio limit here";
  VirtualBus bus;
  auto ep = bus.open("master");
  Master master(*ep, SteadyClock::instance(), oneAxisConfig());
  std::atomic<bool> locked{false};
  int before = 0, boosted = 0;
  std::thread holder([&] {  // normal scheduling, e.g. a ROS callback reading the status
    std::lock_guard<RecursivePiMutex> lock(master.mutex());
    before = kernelPriority();
    locked = true;
    const auto end = std::chrono::steady_clock::now() + 2s;
    while ((boosted = kernelPriority()) != -51 && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(1ms);
  });
  while (!locked) std::this_thread::sleep_for(1ms);
  std::thread waiter([&] {  // the SYNC thread under SCHED_FIFO 50
    ASSERT_EQ(setRealtimePriority(pthread_self(), 50), "");
    std::lock_guard<RecursivePiMutex> lock(master.mutex());
  });
  holder.join();
  waiter.join();
  EXPECT_EQ(before, 20);
  EXPECT_EQ(boosted, -51);  // SCHED_FIFO 50 while the FIFO thread waited for the lock
}

TEST(MasterRealtime, RefusalNamesTheProblemAndTheFixAndTheThreadRunsOn) {
  // A child process without the privilege: rtprio limit 0 and, when root, an
  // unprivileged user (setresuid drops CAP_SYS_NICE).
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const rlimit none{0, 0};
    if (setrlimit(RLIMIT_RTPRIO, &none) != 0) _exit(10);
    if (geteuid() == 0 && setresuid(65534, 65534, 65534) != 0) _exit(11);
    VirtualBus bus;
    auto ep = bus.open("master");
    Master master(*ep, SteadyClock::instance(), oneAxisConfig());
    const std::string error = master.start(50);
    if (error.empty()) _exit(12);
    for (const char* part : {"SCHED_FIFO priority 50 refused", "CAP_SYS_NICE", "ulimit -r 50", "limits.conf"}) {
      if (error.find(part) == std::string::npos) {
        std::fprintf(stderr, "missing '%s' in: %s\n", part, error.c_str());
        _exit(13);
      }
    }
    if (master.threadPriority() != 0) _exit(14);
    const std::uint64_t before = master.stats().syncs;  // runs on, with normal scheduling
    if (!master.waitUntil([&] { return master.stats().syncs >= before + 3; }, 2s)) _exit(15);
    master.stop();
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "child failed at step " << WEXITSTATUS(status);
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
