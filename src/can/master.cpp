// CANopen master (see master.h).
#include "massage_cell/can/master.h"

#include <algorithm>
#include <cstdio>

#include "massage_cell/can/realtime.h"

namespace massage_cell::can {

namespace {

std::vector<std::uint8_t> u8(std::uint8_t v) { return toBytes(v, 1); }
std::vector<std::uint8_t> u16(std::uint16_t v) { return toBytes(v, 2); }
std::vector<std::uint8_t> u32(std::uint32_t v) { return toBytes(v, 4); }

constexpr std::uint32_t kPdoInvalid = 0x80000000u;  // COB-ID bit 31: PDO does not exist / disabled

/// Registered callbacks (tick handlers, event listeners) by id.
template <typename F>
int addCallback(std::vector<std::pair<int, F>>& callbacks, int& last_id, F f) {
  callbacks.emplace_back(++last_id, std::move(f));
  return last_id;
}
template <typename F>
void removeCallback(std::vector<std::pair<int, F>>& callbacks, int id) {
  callbacks.erase(std::remove_if(callbacks.begin(), callbacks.end(), [id](const auto& c) { return c.first == id; }),
                  callbacks.end());
}

std::string hex4(unsigned v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%04X", v);
  return buf;
}

}  // namespace

const char* toString(NodeState state) {
  switch (state) {
    case NodeState::kUnknown:
      return "unknown";
    case NodeState::kResetting:
      return "resetting";
    case NodeState::kConfiguring:
      return "configuring";
    case NodeState::kStarting:
      return "starting";
    case NodeState::kOperational:
      return "operational";
    case NodeState::kStopped:
      return "stopped";
    case NodeState::kLost:
      return "lost";
    case NodeState::kFailed:
      return "failed";
  }
  return "?";
}

const char* toString(EventType type) {
  switch (type) {
    case EventType::kBootUp:
      return "boot-up";
    case EventType::kNodeOperational:
      return "node operational";
    case EventType::kConfigureFailed:
      return "configure failed";
    case EventType::kHeartbeatTimeout:
      return "heartbeat timeout";
    case EventType::kHeartbeatResumed:
      return "heartbeat resumed";
    case EventType::kNmtStateChanged:
      return "NMT state changed";
    case EventType::kEmcy:
      return "EMCY";
    case EventType::kBusStateChanged:
      return "bus state";
    case EventType::kMalformedFrame:
      return "malformed frame";
    case EventType::kAxis:
      return "axis";
  }
  return "?";
}

PdoMapping rpdo1Mapping() { return {{0x6040, 0, 16}, {0x607A, 0, 32}}; }
PdoMapping tpdo1Mapping() { return {{0x6041, 0, 16}, {0x6064, 0, 32}}; }
PdoMapping tpdo2Mapping() { return {{0x606C, 0, 32}, {0x6061, 0, 8}}; }
PdoMapping tpdo3Mapping() { return {{0x6077, 0, 16}}; }

std::vector<StartupWrite> canopenStartupWrites(const AxisConfig& a) {
  return canopenStartupWrites(a, CanConfig{}.master_node_id);
}

std::vector<StartupWrite> canopenStartupWrites(const AxisConfig& a, std::uint8_t master_node_id) {
  const std::uint32_t id = a.node_id;
  std::vector<StartupWrite> w;
  w.push_back({0x1017, 0, u16(a.heartbeat_ms)});
  if (a.master_heartbeat_timeout_ms > 0) {
    // Consumer of the master's heartbeat (bits 16..23 node id, 0..15 time in ms), and what the drive does on its loss.
    w.push_back(
        {0x1016, 1, u32(static_cast<std::uint32_t>(master_node_id) << 16 | (a.master_heartbeat_timeout_ms & 0xFFFF))});
    w.push_back({0x6007, 0, u16(static_cast<std::uint16_t>(a.abort_connection_option))});
  }
  auto map = [&](std::uint16_t comm, std::uint16_t mapping, std::uint32_t cob, const PdoMapping& entries) {
    w.push_back({comm, 1, u32(kPdoInvalid | cob)});  // disable while the mapping changes
    w.push_back({mapping, 0, u8(0)});
    for (std::size_t i = 0; i < entries.size(); ++i) {
      w.push_back({mapping, static_cast<std::uint8_t>(i + 1), u32(encodeMappingEntry(entries[i]))});
    }
    w.push_back({mapping, 0, u8(static_cast<std::uint8_t>(entries.size()))});
    w.push_back({comm, 2, u8(1)});  // synchronous: every SYNC
    w.push_back({comm, 1, u32(cob)});
  };
  map(0x1400, 0x1600, kRpdoBase[0] + id, rpdo1Mapping());
  map(0x1800, 0x1A00, kTpdoBase[0] + id, tpdo1Mapping());
  if (a.velocity_pdo) {
    map(0x1801, 0x1A01, kTpdoBase[1] + id, tpdo2Mapping());
  } else {
    w.push_back({0x1801, 1, u32(kPdoInvalid | (kTpdoBase[1] + id))});
  }
  if (a.torque_pdo) {
    map(0x1802, 0x1A02, kTpdoBase[2] + id, tpdo3Mapping());
  } else {
    w.push_back({0x1802, 1, u32(kPdoInvalid | (kTpdoBase[2] + id))});
  }
  return w;
}

struct Master::Node {
  Node(const AxisConfig& c, SdoClient::Send send, const Clock& clock, Duration timeout)
      : cfg(c), id(c.node_id), sdo(c.node_id, std::move(send), clock, timeout) {}
  const AxisConfig& cfg;
  std::uint8_t id;
  NodeState state = NodeState::kUnknown;
  std::optional<NmtState> nmt;
  TimePoint last_heartbeat{};
  TimePoint deadline{};
  SdoClient sdo;
  std::vector<StartupWrite> extra_writes;
  unsigned generation = 0;
  std::size_t pending_writes = 0;
  DriveFeedback fb;
  bool rpdo_set = false;
  std::uint16_t controlword = 0;
  std::int32_t target = 0;
  TimePoint last_malformed_event{};
  std::uint64_t rpdos_sent = 0;
  TimePoint reset_sent{};
  std::uint64_t outage_mark = 0;     // stats_.bus_outages when the current bring-up attempt began
  bool restart_on_recovery = false;  // its bring-up failed during an outage: restart when the bus is back
};

Master::Master(Bus& bus, const Clock& clock, CanConfig config) : bus_(bus), clock_(clock), config_(std::move(config)) {
  validate(config_, "master config");
  for (const AxisConfig& a : config_.axes) {
    nodes_[a.node_id] = std::make_unique<Node>(
        a, [this](const can_frame& f) { return send(f); }, clock_, std::chrono::milliseconds(config_.sdo_timeout_ms));
  }
  next_sync_ = clock_.now();
  const BusStatus st = bus_.status();
  bus_state_ = st.state;
  seen_bus_offs_ = st.bus_off_events;
  seen_recoveries_ = st.recoveries;
}

Master::~Master() { stop(); }

Master::Node& Master::node(std::uint8_t id) const {
  auto it = nodes_.find(id);
  if (it == nodes_.end()) throw std::out_of_range("CAN master: node " + std::to_string(id) + " is not configured");
  return *it->second;
}

std::string Master::label(std::uint8_t id) const {
  auto it = nodes_.find(id);
  if (it == nodes_.end()) return "node " + std::to_string(id);
  return "node " + std::to_string(id) + " (" + it->second->cfg.name + ")";
}

bool Master::send(const can_frame& frame) {
  if (bus_.send(frame)) return true;
  ++stats_.send_failures;
  return false;
}

void Master::event(EventType type, std::uint8_t node, std::string text, std::uint16_t code, std::uint8_t reg) {
  Event e;
  e.type = type;
  e.node = node;
  e.stamp = clock_.now();
  e.text = std::move(text);
  e.emcy_code = code;
  e.error_register = reg;
  postEvent(std::move(e));
}

void Master::postEvent(Event e) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  if (e.stamp == TimePoint{}) e.stamp = clock_.now();
  if (events_.size() > 10000) events_.erase(events_.begin(), events_.begin() + 5000);  // nobody reads them
  events_.push_back(e);
  if (event_callback_) event_callback_(e);
  for (std::size_t i = 0; i < event_listeners_.size(); ++i) event_listeners_[i].second(e);
}

std::vector<Event> Master::takeEvents() {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  std::vector<Event> out;
  out.swap(events_);
  return out;
}

void Master::setEventCallback(EventCallback callback) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  event_callback_ = std::move(callback);
}

int Master::addEventListener(EventCallback listener) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return addCallback(event_listeners_, last_callback_id_, std::move(listener));
}

void Master::removeEventListener(int id) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  removeCallback(event_listeners_, id);
}

void Master::setBeforeSyncHook(TickHandler hook) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  before_sync_ = std::move(hook);
}

int Master::addTickHandler(TickHandler handler) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return addCallback(tick_handlers_, last_callback_id_, std::move(handler));
}

void Master::removeTickHandler(int id) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  removeCallback(tick_handlers_, id);
}

std::uint64_t Master::rpdosSent(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return node(id).rpdos_sent;
}

MasterStats Master::stats() const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return stats_;
}

void Master::malformed(std::uint8_t id, const std::string& why) {
  ++stats_.malformed;
  const TimePoint now = clock_.now();
  auto it = nodes_.find(id);
  TimePoint& last = it == nodes_.end() ? last_unknown_malformed_ : it->second->last_malformed_event;
  if (last != TimePoint{} && now - last < std::chrono::seconds(1)) return;
  last = now;
  event(EventType::kMalformedFrame, id, (id ? label(id) + ": " : std::string()) + "malformed frame ignored: " + why);
}

void Master::setState(Node& n, NodeState s) {
  if (n.state == s) return;
  n.state = s;
  if (s != NodeState::kOperational && s != NodeState::kStopped) n.fb.valid = n.fb.has_torque = false;
}

// --- NMT -----------------------------------------------------------------------

bool Master::sendNmt(NmtCommand command, std::uint8_t node) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return send(encodeNmt(command, node));
}

void Master::bringUp() {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  for (auto& [id, n] : nodes_) bringUp(id);
}

void Master::bringUp(std::uint8_t id) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  Node& n = node(id);
  own_nmt_ = NmtState::kOperational;  // the master has started the network
  n.outage_mark = stats_.bus_outages;
  n.restart_on_recovery = false;
  ++n.generation;
  n.sdo.cancelAll("bring-up restarted");
  n.nmt.reset();
  setState(n, NodeState::kResetting);
  n.deadline = clock_.now() + std::chrono::milliseconds(config_.boot_timeout_ms);
  n.reset_sent = clock_.now();
  send(encodeNmt(NmtCommand::kResetCommunication, id));
}

void Master::startConfiguration(Node& n) {
  ++n.generation;
  const unsigned gen = n.generation;
  n.outage_mark = stats_.bus_outages;
  n.restart_on_recovery = false;
  n.sdo.cancelAll("node rebooted");
  setState(n, NodeState::kConfiguring);
  std::vector<StartupWrite> writes = canopenStartupWrites(n.cfg, config_.master_node_id);
  writes.insert(writes.end(), n.extra_writes.begin(), n.extra_writes.end());
  n.pending_writes = writes.size();
  const std::uint8_t id = n.id;
  for (const StartupWrite& w : writes) {
    n.sdo.download(w.index, w.sub, w.data, [this, id, gen](const SdoResult& r) {
      Node& nn = node(id);
      if (nn.generation != gen || nn.state != NodeState::kConfiguring) return;
      if (!r.ok) {
        ++nn.generation;  // the remaining writes are moot
        nn.sdo.cancelAll("configuration failed");
        bringUpFailed(nn, label(id) + ": configuration failed: " + r.error);
        return;
      }
      if (--nn.pending_writes == 0) {
        setState(nn, NodeState::kStarting);
        nn.deadline = clock_.now() + std::chrono::milliseconds(config_.boot_timeout_ms);
        send(encodeNmt(NmtCommand::kStart, id));
      }
    });
  }
}

NodeState Master::nodeState(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return node(id).state;
}

std::optional<NmtState> Master::nmtState(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return node(id).nmt;
}

NmtState Master::ownNmtState() const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return own_nmt_;
}

void Master::bringUpFailed(Node& n, const std::string& why) {
  setState(n, NodeState::kFailed);
  if (n.outage_mark == stats_.bus_outages && busUsable()) {
    event(EventType::kConfigureFailed, n.id, why);  // a real failure: the bus was fine all along
    return;
  }
  if (busUsable()) {
    event(EventType::kConfigureFailed, n.id,
          why + " (the bus was bus-off or down during this bring-up: bring-up restarted)");
    ++stats_.bringup_restarts;
    bringUp(n.id);
  } else {
    event(EventType::kConfigureFailed, n.id,
          why + " (the bus is " + toString(bus_state_) + ": bring-up restarts when it recovers)");
    n.restart_on_recovery = true;
  }
}

void Master::busRecovered() {
  for (auto& [id, n] : nodes_) {
    if (!n->restart_on_recovery) continue;
    n->restart_on_recovery = false;
    event(EventType::kBusStateChanged, id, label(id) + ": bus recovered: bring-up restarted");
    ++stats_.bringup_restarts;
    bringUp(id);
  }
}

void Master::checkBus() {
  const BusStatus st = bus_.status();
  const std::uint64_t offs = st.bus_off_events - seen_bus_offs_, recs = st.recoveries - seen_recoveries_;
  seen_bus_offs_ = st.bus_off_events;
  seen_recoveries_ = st.recoveries;
  const BusState old = bus_state_, cur = st.state;
  if (cur == old && recs == 0) return;
  auto usable = [](BusState s) { return s != BusState::kBusOff && s != BusState::kDown; };
  // Outages that began and ended since the last check (the bus recovered more
  // often than the outage we knew of, if any, can explain), and whether a new
  // one is going on now.
  const std::uint64_t hidden = recs - (usable(old) || recs == 0 ? 0 : 1);
  const bool started = !usable(cur) && (usable(old) || recs > 0);
  stats_.bus_outages += hidden + (started ? 1 : 0);
  bus_state_ = cur;
  std::string text = bus_.name() + ": " + toString(old) + " -> ";
  if (hidden > 0) {
    text += std::string(offs ? "bus-off" : "down") + " -> " + toString(cur) +
            (usable(cur) ? " (recovered" : " (recovered and lost again") + " between two polls; " +
            std::to_string(hidden) + (hidden == 1 ? " outage)" : " outages)");
  } else {
    text += toString(cur);
    if (usable(cur) && !usable(old)) text += " (recovered)";
  }
  if (!usable(cur) && !st.last_error.empty()) text += ": " + st.last_error;
  event(EventType::kBusStateChanged, 0, text);
  if (usable(cur) && (!usable(old) || hidden > 0)) busRecovered();
}

bool Master::allOperational() const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  for (const auto& [id, n] : nodes_) {
    if (n->state != NodeState::kOperational) return false;
  }
  return true;
}

// --- SDO / PDO ------------------------------------------------------------------

void Master::sdoUpload(std::uint8_t id, std::uint16_t index, std::uint8_t sub, SdoClient::Callback done) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  node(id).sdo.upload(index, sub, std::move(done));
}

void Master::sdoDownload(std::uint8_t id, std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                         SdoClient::Callback done) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  node(id).sdo.download(index, sub, std::move(data), std::move(done));
}

void Master::addStartupWrite(std::uint8_t id, StartupWrite write) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  node(id).extra_writes.push_back(std::move(write));
}

DriveFeedback Master::feedback(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return node(id).fb;
}

void Master::setRpdo(std::uint8_t id, std::uint16_t controlword, std::int32_t target) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  Node& n = node(id);
  n.rpdo_set = true;
  n.controlword = controlword;
  n.target = target;
}

std::uint16_t Master::controlword(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return node(id).controlword;
}

std::optional<std::int32_t> Master::rpdoTarget(std::uint8_t id) const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  const Node& n = node(id);
  if (!n.rpdo_set) return std::nullopt;
  return n.target;
}

bool Master::sendRpdoNow(std::uint8_t id) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  Node& n = node(id);
  if (n.state != NodeState::kOperational || !n.rpdo_set) return false;
  return sendRpdo(id, n);
}

bool Master::sendRpdo(std::uint8_t id, Node& n) {
  const Result<can_frame> f =
      packPdo(kRpdoBase[0] + id, rpdo1Mapping(), {n.controlword, static_cast<std::uint32_t>(n.target)});
  if (!f || !send(*f)) return false;
  ++stats_.rpdos;
  ++n.rpdos_sent;
  return true;
}

// --- receive ---------------------------------------------------------------------

void Master::process(const TimedFrame& tf) {
  const can_frame& f = tf.frame;
  const Result<CobInfo> cob = classify(f);
  if (!cob) {
    malformed(0, cob.error());
    return;
  }
  const std::uint8_t id = cob->node;
  const bool known = nodes_.count(id) != 0;
  switch (cob->type) {
    case CobType::kSdoResponse: {
      if (!known) break;
      const Result<SdoFrame> r = decodeSdoResponse(f);
      if (!r) return malformed(id, r.error());
      ++stats_.sdo_responses;
      node(id).sdo.handle(*r);
      return;
    }
    case CobType::kTpdo: {
      if (!known || cob->pdo < 1 || cob->pdo > 3) break;
      Node& n = node(id);
      if (n.state != NodeState::kOperational && n.state != NodeState::kStopped && n.state != NodeState::kStarting) {
        ++stats_.ignored;
        return;
      }
      const Result<std::vector<std::uint64_t>> v = unpackPdo(f, cob->pdo == 1   ? tpdo1Mapping()
                                                                : cob->pdo == 2 ? tpdo2Mapping()
                                                                                : tpdo3Mapping());
      if (!v) return malformed(id, v.error());
      ++stats_.tpdos;
      if (cob->pdo == 1) {
        n.fb.statusword = static_cast<std::uint16_t>((*v)[0]);
        n.fb.position = static_cast<std::int32_t>(signExtend((*v)[1], 32));
        n.fb.stamp = tf.stamp;
        n.fb.valid = true;
        ++n.fb.count;
      } else if (cob->pdo == 2) {
        n.fb.velocity = static_cast<std::int32_t>(signExtend((*v)[0], 32));
        n.fb.mode_display = static_cast<std::int8_t>(signExtend((*v)[1], 8));
        n.fb.has_velocity = true;
      } else {
        n.fb.torque = static_cast<std::int16_t>(signExtend((*v)[0], 16));
        n.fb.has_torque = true;
        n.fb.torque_stamp = tf.stamp;
      }
      return;
    }
    case CobType::kEmcy: {
      if (!known) break;
      const Result<EmcyMessage> m = decodeEmcy(f);
      if (!m) return malformed(id, m.error());
      ++stats_.emcys;
      node(id).fb.emcy_code = m->emcy.error_code;
      node(id).fb.emcy_stamp = tf.stamp;
      char reg[8];
      std::snprintf(reg, sizeof reg, "0x%02X", m->emcy.error_register);
      event(EventType::kEmcy, id,
            label(id) + ": EMCY " + hex4(m->emcy.error_code) + " " + emcyText(m->emcy.error_code) +
                " (error register " + reg + ")",
            m->emcy.error_code, m->emcy.error_register);
      return;
    }
    case CobType::kHeartbeat: {
      if (!known) break;
      const Result<Heartbeat> h = decodeHeartbeat(f);
      if (!h) return malformed(id, h.error());
      ++stats_.heartbeats;
      Node& n = node(id);
      n.last_heartbeat = clock_.now();
      const std::optional<NmtState> before = n.nmt;
      if (h->state == NmtState::kBootUp) {
        n.nmt = NmtState::kPreOperational;     // a booted node enters pre-operational by itself
        if (n.state == NodeState::kUnknown) {  // not brought up yet: bringUp() will reset it anyway
          event(EventType::kBootUp, id, label(id) + ": boot-up (not brought up yet)");
          return;
        }
        if (n.state == NodeState::kResetting && tf.stamp < n.reset_sent) {
          return;  // sent before our reset command: the boot-up that answers it is still to come
        }
        if (n.state == NodeState::kResetting) {
          event(EventType::kBootUp, id, label(id) + ": boot-up");
        } else {
          event(EventType::kBootUp, id,
                label(id) + ": unexpected boot-up (node was " + toString(n.state) + "): reconfiguring");
        }
        startConfiguration(n);
        return;
      }
      n.nmt = h->state;
      if (n.state == NodeState::kLost) {
        event(EventType::kHeartbeatResumed, id, label(id) + ": heartbeat resumed (" + toString(h->state) + ")");
        if (h->state == NmtState::kOperational) {
          setState(n, NodeState::kOperational);
        } else {
          // It lost its configuration or its state: do it again.
          n.deadline = clock_.now() + std::chrono::milliseconds(config_.boot_timeout_ms);
          startConfiguration(n);
        }
        return;
      }
      if (n.state == NodeState::kStarting && h->state == NmtState::kOperational) {
        setState(n, NodeState::kOperational);
        event(EventType::kNodeOperational, id, label(id) + ": configured and operational");
        return;
      }
      if (before && *before != h->state && (n.state == NodeState::kOperational || n.state == NodeState::kStopped)) {
        event(EventType::kNmtStateChanged, id,
              label(id) + ": NMT state " + toString(*before) + " -> " + toString(h->state));
        setState(n, h->state == NmtState::kOperational ? NodeState::kOperational : NodeState::kStopped);
      }
      return;
    }
    case CobType::kNmt:
    case CobType::kSync:
    case CobType::kRpdo:
    case CobType::kSdoRequest:
      break;  // another master's traffic (or our own echo): not ours to consume
  }
  ++stats_.ignored;
}

// --- timers ------------------------------------------------------------------------

void Master::timers(TimePoint now) {
  checkBus();
  const Duration gap = last_timers_ ? now - *last_timers_ : Duration::zero();
  last_timers_ = now;
  for (auto& [id, np] : nodes_) {
    Node& n = *np;
    n.last_heartbeat = pastOwnStall(n.last_heartbeat, gap, now);  // the master's own stall is no node's silence
    n.sdo.poll();
    switch (n.state) {
      case NodeState::kResetting:
        if (now >= n.deadline) {
          bringUpFailed(n, label(id) + ": no boot-up within " + std::to_string(config_.boot_timeout_ms) +
                               " ms after reset communication (node absent, wrong node id or bitrate?)");
        }
        break;
      case NodeState::kStarting:
        if (now >= n.deadline) {
          bringUpFailed(n, label(id) + ": no operational heartbeat within " + std::to_string(config_.boot_timeout_ms) +
                               " ms after NMT start");
        }
        break;
      case NodeState::kOperational:
      case NodeState::kStopped:
        if (now - n.last_heartbeat > std::chrono::milliseconds(n.cfg.heartbeatTimeoutMs())) {
          setState(n, NodeState::kLost);
          n.sdo.cancelAll("node lost (heartbeat timeout)");
          event(EventType::kHeartbeatTimeout, id,
                label(id) + ": no heartbeat for " + std::to_string(n.cfg.heartbeatTimeoutMs()) + " ms");
        }
        break;
      default:
        break;
    }
  }
  for (std::size_t i = 0; i < tick_handlers_.size(); ++i) tick_handlers_[i].second(now);
  // Heartbeat producer (before the RPDO + SYNC group, which stays together).
  if (config_.master_heartbeat_ms > 0 && now >= next_heartbeat_) {
    if (send(encodeHeartbeat(config_.master_node_id, own_nmt_))) ++stats_.heartbeats_produced;
    const Duration hb = std::chrono::milliseconds(config_.master_heartbeat_ms);
    next_heartbeat_ += hb;                                   // the first one (at the first poll) sets the phase
    if (next_heartbeat_ <= now) next_heartbeat_ = now + hb;  // fell behind: do not burst
  }
  // SYNC producer: the owner's hook, then RPDOs, so synchronous drives apply
  // what the hook wrote at this SYNC.
  const Duration period = std::chrono::microseconds(config_.sync_period_us);
  if (now >= next_sync_) {
    if (before_sync_) before_sync_(now);
    for (auto& [id, np] : nodes_) {
      Node& n = *np;
      if (n.state != NodeState::kOperational || !n.rpdo_set) continue;
      sendRpdo(id, n);
    }
    if (send(encodeSync())) ++stats_.syncs;
    next_sync_ += period;
    if (next_sync_ <= now) next_sync_ = now + period;  // fell behind: do not burst
  }
}

void Master::poll() {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  while (auto f = bus_.receive(Duration::zero())) process(*f);
  timers(clock_.now());
  polled_.notify_all();
}

std::string Master::start(int realtime_priority) {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  if (!thread_.joinable()) {
    stop_ = false;
    thread_ = std::thread([this] { threadMain(); });
  }
  return realtime_priority > 0 ? setRealtimePriority(thread_.native_handle(), realtime_priority) : std::string();
}

int Master::threadPriority() const {
  std::lock_guard<RecursivePiMutex> lock(mutex_);
  return thread_.joinable() ? realtimePriority(const_cast<std::thread&>(thread_).native_handle()) : 0;
}

void Master::stop() {
  {
    std::lock_guard<RecursivePiMutex> lock(mutex_);
    stop_ = true;
  }
  if (thread_.joinable()) thread_.join();
}

void Master::threadMain() {
  while (true) {
    Duration wait;
    {
      std::lock_guard<RecursivePiMutex> lock(mutex_);
      if (stop_) return;
      wait = std::clamp<Duration>(next_sync_ - clock_.now(), Duration::zero(), std::chrono::milliseconds(2));
    }
    std::optional<TimedFrame> f = bus_.receive(wait);  // outside the lock: callers stay responsive
    std::lock_guard<RecursivePiMutex> lock(mutex_);
    if (f) process(*f);
    while (auto g = bus_.receive(Duration::zero())) process(*g);
    timers(clock_.now());
    polled_.notify_all();
  }
}

bool Master::waitUntil(const std::function<bool()>& pred, Duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::unique_lock<RecursivePiMutex> lock(mutex_);
  while (!pred()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    if (thread_.joinable()) {
      polled_.wait_until(lock, std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(20)));
    } else {
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      lock.lock();
      poll();
    }
  }
  return true;
}

}  // namespace massage_cell::can
