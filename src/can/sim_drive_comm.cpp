// SimDrive, CiA 301 side (see sim_drive.h): the communication objects, NMT
// slave, SDO server, PDOs, heartbeat producer / consumer, EMCY, bus filters.
#include "massage_cell/can/sim_drive.h"

#include <algorithm>

#include "sim_drive_detail.h"

namespace massage_cell::can {

using namespace sim_drive_detail;

namespace {

bool isRpdoComm(std::uint16_t i) { return i >= 0x1400 && i <= 0x1403; }
bool isTpdoComm(std::uint16_t i) { return i >= 0x1800 && i <= 0x1803; }
bool isRpdoMap(std::uint16_t i) { return i >= 0x1600 && i <= 0x1603; }
bool isTpdoMap(std::uint16_t i) { return i >= 0x1A00 && i <= 0x1A03; }

/// SDO abort code (0: accepted) for writing `v` to a PDO communication parameter (0x1400.. / 0x1800..).
std::uint32_t checkPdoCommWrite(const ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, std::uint64_t v) {
  if (sub == 1) {
    const auto cur = static_cast<std::uint32_t>(od.get(index, 1));
    const bool cur_valid = !(cur & kPdoInvalid), new_valid = !(v & kPdoInvalid);
    if (v & 0x20000000u) return sdo_abort::kInvalidValue;  // 29-bit ids not supported
    if (cur_valid && new_valid && (cur & CAN_SFF_MASK) != (v & CAN_SFF_MASK)) return sdo_abort::kInvalidValue;
    return 0;
  }
  if (sub == 2 && v > 240 && v < 254) return sdo_abort::kInvalidValue;
  return 0;
}

/// SDO abort code (0: accepted) for writing `v` to a PDO mapping parameter (0x1600.. / 0x1A00..).
std::uint32_t checkPdoMapWrite(const ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, std::uint64_t v) {
  const bool rx = isRpdoMap(index);
  const std::uint16_t comm = static_cast<std::uint16_t>(index - 0x200);
  if (!(static_cast<std::uint32_t>(od.get(comm, 1)) & kPdoInvalid)) return sdo_abort::kDeviceState;  // PDO valid
  auto entryOk = [&](std::uint32_t raw) -> std::uint32_t {
    const PdoEntry e = decodeMappingEntry(raw);
    const ObjectDictionary::Entry* obj = od.find(e.index, e.subindex);
    if (!obj || !obj->mappable || obj->size * 8 != e.bits) return sdo_abort::kNotMappable;
    if (rx && (obj->access == A::kReadOnly || obj->access == A::kConst)) return sdo_abort::kNotMappable;
    return 0;
  };
  if (sub == 0) {
    if (v > 8) return sdo_abort::kValueTooHigh;
    unsigned bits = 0;
    for (std::uint8_t k = 1; k <= v; ++k) {
      const auto raw = static_cast<std::uint32_t>(od.get(index, k));
      if (const std::uint32_t code = entryOk(raw)) return code;
      bits += raw & 0xFF;
    }
    return bits > 64 ? sdo_abort::kPdoLength : 0;
  }
  if (od.get(index, 0) != 0) return sdo_abort::kDeviceState;
  return v == 0 ? 0 : entryOk(static_cast<std::uint32_t>(v));
}

}  // namespace

// --- object dictionary: communication objects ---------------------------------------------

void SimDrive::resetCommunication() {
  const AxisConfig& c = config_;
  const std::uint32_t id = c.node_id;
  od_.add(0x1000, 0, A::kConst, 4, c.sim.device_type);
  od_.add(0x1001, 0, A::kReadOnly, 1, state_ == Cia402State::kFault ? errorRegisterFor(errorCode()) : 0);
  od_.addString(0x1008, 0, A::kConst, c.sim.device_name);
  od_.addString(0x1009, 0, A::kConst, "sim 1");
  od_.addString(0x100A, 0, A::kConst, "massage_cell 1.0");
  od_.add(0x1016, 0, A::kConst, 1, 1);
  od_.add(0x1016, 1, A::kReadWrite, 4, 0);  // consumer heartbeat time: node id << 16 | ms (0: off)
  consumer_armed_ = false;
  od_.add(0x1017, 0, A::kReadWrite, 2, 0);
  od_.add(0x1018, 0, A::kConst, 1, 4);
  od_.add(0x1018, 1, A::kReadOnly, 4, 0x4D43);  // vendor "MC"
  od_.add(0x1018, 2, A::kReadOnly, 4, 0x0402);
  od_.add(0x1018, 3, A::kReadOnly, 4, 1);
  od_.add(0x1018, 4, A::kReadOnly, 4, id);
  for (std::uint16_t n = 0; n < 4; ++n) {
    od_.add(0x1400 + n, 0, A::kConst, 1, 2);
    od_.add(0x1400 + n, 1, A::kReadWrite, 4, (n == 0 ? 0 : kPdoInvalid) | (kRpdoBase[n] + id));
    od_.add(0x1400 + n, 2, A::kReadWrite, 1, 255);
    od_.add(0x1600 + n, 0, A::kReadWrite, 1, n == 0 ? 1 : 0);
    for (std::uint8_t k = 1; k <= 8; ++k) od_.add(0x1600 + n, k, A::kReadWrite, 4, n == 0 && k == 1 ? 0x60400010 : 0);
    od_.add(0x1800 + n, 0, A::kConst, 1, 5);
    od_.add(0x1800 + n, 1, A::kReadWrite, 4, (n == 0 ? 0 : kPdoInvalid) | (kTpdoBase[n] + id));
    od_.add(0x1800 + n, 2, A::kReadWrite, 1, 255);
    od_.add(0x1800 + n, 3, A::kReadWrite, 2, 0);
    od_.add(0x1800 + n, 5, A::kReadWrite, 2, 0);
    od_.add(0x1A00 + n, 0, A::kReadWrite, 1, n == 0 ? 1 : 0);
    for (std::uint8_t k = 1; k <= 8; ++k) od_.add(0x1A00 + n, k, A::kReadWrite, 4, n == 0 && k == 1 ? 0x60410010 : 0);
  }
  rpdo_latched_ = {};
  tpdo_sync_count_ = {};
  tpdo_last_ = {};
  upload_ = {};
  download_ = {};
  pending_sdo_.clear();
  applyFilters();  // 0x1016 is back to 0: no producer to listen to
}

void SimDrive::applyFilters() {
  const canid_t id = config_.node_id;
  std::vector<can_filter> filters = {
      {kNmtCobId, CAN_SFF_MASK}, {kSyncCobId, CAN_SFF_MASK}, {kSdoRxBase + id, CAN_SFF_MASK}};
  for (canid_t base : kRpdoBase) filters.push_back({base + id, CAN_SFF_MASK});
  const auto producer = static_cast<canid_t>((od_.get(0x1016, 1) >> 16) & 0x7F);
  if (producer != 0) filters.push_back({kHeartbeatBase + producer, CAN_SFF_MASK});
  bus_.setFilters(filters);
}

PdoMapping SimDrive::mapping(std::uint16_t index) const {
  PdoMapping m;
  const auto n = od_.get(index, 0);
  for (std::uint8_t k = 1; k <= n && k <= 8; ++k)
    m.push_back(decodeMappingEntry(static_cast<std::uint32_t>(od_.get(index, k))));
  return m;
}

std::uint32_t SimDrive::checkWrite(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data) const {
  const std::uint64_t v = fromBytes(data);
  if (isRpdoComm(index) || isTpdoComm(index)) return checkPdoCommWrite(od_, index, sub, v);
  if (isRpdoMap(index) || isTpdoMap(index)) return checkPdoMapWrite(od_, index, sub, v);
  if (index == 0x6060) {
    const auto mode = static_cast<std::int8_t>(v);
    if (mode != 0 && mode != 1 && mode != 6 && mode != 8) return sdo_abort::kInvalidValue;
  }
  if (index == 0x1016 && sub == 1) {
    const auto producer = (v >> 16) & 0xFF;
    if ((v >> 24) != 0 || producer > 127 || producer == config_.node_id) return sdo_abort::kInvalidValue;
  }
  if (index == 0x6007) {
    const auto option = static_cast<std::int16_t>(v);
    if (option < 0 || option > 3) return sdo_abort::kValueTooHigh;  // manufacturer-specific codes: not simulated
  }
  return 0;
}

void SimDrive::afterWrite(std::uint16_t index, std::uint8_t sub) {
  if (index == 0x6040) processControlword();
  if (index == 0x6060) {
    od_.set(0x6061, 0, od_.get(0x6060, 0));
    csp_from_ = csp_to_ = demand_;  // a cyclic mode starts where the axis stands
    csp_elapsed_ = csp_period_;
  }
  if (index == 0x1017) next_heartbeat_ = clock_.now() + std::chrono::milliseconds(od_.get(0x1017, 0));
  if (index == 0x1016) {
    consumer_armed_ = false;  // monitoring starts with the producer's next heartbeat
    applyFilters();
  }
  if (isRpdoComm(index) && sub == 1) rpdo_latched_[index - 0x1400].reset();
  if (isTpdoComm(index)) {
    tpdo_sync_count_[index - 0x1800] = 0;
    tpdo_last_[index - 0x1800].reset();
  }
}

// --- frames ------------------------------------------------------------------------------

void SimDrive::send(const can_frame& f) {
  if (!powered_ || silent_) return;
  bus_.send(f);  // a refused frame (bus-off) is lost, as on a real controller
}

void SimDrive::sendEmcy(std::uint16_t code, std::uint8_t reg, std::array<std::uint8_t, 5> manufacturer) {
  if (nmt_ == NmtState::kStopped) return;  // EMCY is not sent in stopped (CiA 301)
  Emcy e;
  e.error_code = code;
  e.error_register = reg;
  e.manufacturer = manufacturer;
  send(encodeEmcy(config_.node_id, e));
  ++stats_.emcys;
}

void SimDrive::bootUp(TimePoint now) {
  nmt_ = NmtState::kPreOperational;
  send(encodeHeartbeat(config_.node_id, NmtState::kBootUp));
  next_heartbeat_ = now + std::chrono::milliseconds(od_.get(0x1017, 0));
}

int SimDrive::rpdoFor(const can_frame& f) const {
  // RPDOs by their configured COB-IDs (they need not be the pre-defined ones).
  if (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) return -1;
  for (int n = 0; n < 4; ++n) {
    const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1400 + n), 1));
    if (!(cob & kPdoInvalid) && (cob & CAN_SFF_MASK) == (f.can_id & CAN_SFF_MASK)) return n;
  }
  return -1;
}

void SimDrive::process(const can_frame& f, TimePoint now) {
  if (!powered_ || silent_) return;
  if (const int n = rpdoFor(f); n >= 0) return handleRpdo(n, f);
  const Result<CobInfo> cob = classify(f);
  if (!cob) {
    ++stats_.frames_ignored;
    return;
  }
  switch (cob->type) {
    case CobType::kNmt:
      if (auto m = decodeNmt(f)) return handleNmt(*m, now);
      break;
    case CobType::kSync:
      if (auto s = decodeSync(f); s && nmt_ == NmtState::kOperational) return handleSync();
      break;
    case CobType::kSdoRequest: {
      if (cob->node != config_.node_id || nmt_ == NmtState::kStopped) break;
      const Result<SdoFrame> r = decodeSdoRequest(f);
      if (r) return handleSdo(*r, now);
      if (f.len == 8) {  // a full SDO frame with a command specifier we do not know: say so
        ++stats_.sdo_requests;
        abortSdo(static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8)), f.data[3], sdo_abort::kCommandSpecifier,
                 now);
        return;
      }
      break;
    }
    case CobType::kHeartbeat: {
      const auto consumer = od_.get(0x1016, 1);
      const auto producer = static_cast<std::uint8_t>((consumer >> 16) & 0x7F);
      if (producer == 0 || cob->node != producer || !decodeHeartbeat(f)) break;
      ++stats_.master_heartbeats;
      consumer_last_ = now;
      consumer_armed_ = true;
      return;
    }
    default:
      break;
  }
  ++stats_.frames_ignored;
}

void SimDrive::sendDueSdoResponses(TimePoint now) {
  while (!pending_sdo_.empty() && pending_sdo_.front().due <= now) {
    send(pending_sdo_.front().frame);
    pending_sdo_.pop_front();
  }
}

void SimDrive::checkBusRecovery() {
  // Back from bus-off: say so (CiA 301 EMCY 0x8140).
  const BusState bs = bus_.status().state;
  if (bus_state_ == BusState::kBusOff && bs == BusState::kErrorActive) {
    sendEmcy(0x8140, static_cast<std::uint8_t>(od_.get(0x1001, 0)));
  }
  bus_state_ = bs;
}

// --- NMT, heartbeat ---------------------------------------------------------------------------

void SimDrive::handleNmt(const NmtMessage& m, TimePoint now) {
  if (m.node != 0 && m.node != config_.node_id) return;
  switch (m.command) {
    case NmtCommand::kStart:
      nmt_ = NmtState::kOperational;
      break;
    case NmtCommand::kStop:
      nmt_ = NmtState::kStopped;
      break;
    case NmtCommand::kEnterPreOperational:
      nmt_ = NmtState::kPreOperational;
      break;
    case NmtCommand::kResetNode:
      resetApplication();
      resetCommunication();
      bootUp(now);
      break;
    case NmtCommand::kResetCommunication:
      resetCommunication();
      bootUp(now);
      break;
  }
}

void SimDrive::produceHeartbeat(TimePoint now) {
  const auto period = od_.get(0x1017, 0);
  if (period <= 0 || silent_ || now < next_heartbeat_) return;
  send(encodeHeartbeat(config_.node_id, nmt_));
  ++stats_.heartbeats;
  next_heartbeat_ += std::chrono::milliseconds(period);
  if (next_heartbeat_ <= now) next_heartbeat_ = now + std::chrono::milliseconds(period);
}

void SimDrive::checkHeartbeatConsumer(TimePoint now) {
  const auto consumer = od_.get(0x1016, 1);
  const auto time_ms = consumer & 0xFFFF;
  if (!consumer_armed_ || time_ms == 0 || ((consumer >> 16) & 0x7F) == 0) return;
  if (now - consumer_last_ <= std::chrono::milliseconds(time_ms)) return;
  consumer_armed_ = false;  // one event per loss; the next heartbeat re-arms
  ++stats_.master_heartbeat_losses;
  const auto option = od_.get(0x6007, 0);
  if (option == 1) {
    enterFault(0x8130, {});  // EMCY 0x8130 + fault reaction
    return;
  }
  sendEmcy(0x8130, static_cast<std::uint8_t>(od_.get(0x1001, 0) | 0x11));
  if (option == 2 && (state_ == Cia402State::kReadyToSwitchOn || state_ == Cia402State::kSwitchedOn ||
                      state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive)) {
    enterState(Cia402State::kSwitchOnDisabled);
  } else if (option == 3 && state_ == Cia402State::kOperationEnabled) {
    enterState(Cia402State::kQuickStopActive);
  }
}

// --- PDO -------------------------------------------------------------------------------------

void SimDrive::handleRpdo(int n, const can_frame& f) {
  if (nmt_ != NmtState::kOperational) {
    ++stats_.frames_ignored;
    return;
  }
  const PdoMapping map = mapping(static_cast<std::uint16_t>(0x1600 + n));
  if (map.empty()) {
    ++stats_.frames_ignored;
    return;
  }
  const Result<std::vector<std::uint64_t>> values = unpackPdo(f, map);
  if (!values) {
    ++stats_.rpdos_rejected;
    const std::uint8_t reg = static_cast<std::uint8_t>(od_.get(0x1001, 0) | 0x10);
    sendEmcy(0x8210, reg);  // PDO not processed due to length error
    return;
  }
  const auto type = od_.get(static_cast<std::uint16_t>(0x1400 + n), 2);
  if (type <= 240) {
    rpdo_latched_[static_cast<std::size_t>(n)] = *values;  // applied at the next SYNC
  } else {
    applyRpdo(n, *values);
  }
}

void SimDrive::applyRpdo(int n, const std::vector<std::uint64_t>& values) {
  const PdoMapping map = mapping(static_cast<std::uint16_t>(0x1600 + n));
  if (map.size() != values.size()) return;  // mapping changed since it was latched
  bool cw = false;
  for (std::size_t i = 0; i < map.size(); ++i) {
    od_.set(map[i].index, map[i].subindex, static_cast<std::int64_t>(values[i]));
    cw = cw || map[i].index == 0x6040;
    if (map[i].index == 0x6060) afterWrite(0x6060, 0);
  }
  ++stats_.rpdos_applied;
  if (cw) processControlword();
}

void SimDrive::handleSync() {
  ++stats_.syncs;
  for (int n = 0; n < 4; ++n) {
    auto& latched = rpdo_latched_[static_cast<std::size_t>(n)];
    if (latched) {
      const std::vector<std::uint64_t> v = *latched;
      latched.reset();
      applyRpdo(n, v);
    }
  }
  syncCyclicTarget();
  updateProcessObjects();
  for (int n = 0; n < 4; ++n) {
    const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1800 + n), 1));
    if (cob & kPdoInvalid) continue;
    const auto type = static_cast<unsigned>(od_.get(static_cast<std::uint16_t>(0x1800 + n), 2));
    if (type == 0 || type > 240) continue;
    if (++tpdo_sync_count_[static_cast<std::size_t>(n)] >= type) {
      tpdo_sync_count_[static_cast<std::size_t>(n)] = 0;
      sendTpdo(n);
    }
  }
}

std::optional<can_frame> SimDrive::packTpdo(int n) const {
  const PdoMapping map = mapping(static_cast<std::uint16_t>(0x1A00 + n));
  if (map.empty()) return std::nullopt;
  std::vector<std::uint64_t> values;
  for (const PdoEntry& e : map) values.push_back(static_cast<std::uint64_t>(od_.get(e.index, e.subindex)));
  const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1800 + n), 1));
  const Result<can_frame> f = packPdo(cob & CAN_SFF_MASK, map, values);
  if (!f) return std::nullopt;
  return *f;
}

void SimDrive::sendTpdo(int n) {
  const std::optional<can_frame> f = packTpdo(n);
  if (!f) return;
  send(*f);
  tpdo_last_[static_cast<std::size_t>(n)] = f;
  ++stats_.tpdos;
}

void SimDrive::checkChangeTpdos() {
  if (nmt_ != NmtState::kOperational) return;
  bool updated = false;
  for (int n = 0; n < 4; ++n) {
    const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1800 + n), 1));
    const auto type = od_.get(static_cast<std::uint16_t>(0x1800 + n), 2);
    if ((cob & kPdoInvalid) || type < 254) continue;
    if (!updated) {
      updateProcessObjects();
      updated = true;
    }
    const std::optional<can_frame> f = packTpdo(n);
    const auto& last = tpdo_last_[static_cast<std::size_t>(n)];
    if (f && (!last || !sameFrame(*last, *f))) sendTpdo(n);
  }
}

}  // namespace massage_cell::can
