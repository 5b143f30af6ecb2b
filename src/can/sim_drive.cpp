// Simulated CiA 402 drive (see sim_drive.h).
#include "massage_cell/can/sim_drive.h"

#include <algorithm>
#include <cmath>
#include <thread>

namespace massage_cell::can {

namespace {

using A = ObjectDictionary::Access;
constexpr double kStepS = 0.001;  // motion integration step
constexpr std::uint32_t kPdoInvalid = 0x80000000u;

bool isRpdoComm(std::uint16_t i) { return i >= 0x1400 && i <= 0x1403; }
bool isTpdoComm(std::uint16_t i) { return i >= 0x1800 && i <= 0x1803; }
bool isRpdoMap(std::uint16_t i) { return i >= 0x1600 && i <= 0x1603; }
bool isTpdoMap(std::uint16_t i) { return i >= 0x1A00 && i <= 0x1A03; }

std::uint8_t errorRegisterFor(std::uint16_t code) {
  std::uint8_t reg = 0x01;  // generic
  switch (code >> 12) {
    case 0x2:
      reg |= 0x02;
      break;
    case 0x3:
      reg |= 0x04;
      break;
    case 0x4:
      reg |= 0x08;
      break;
    default:
      break;
  }
  if ((code & 0xFF00) == 0x8100) reg |= 0x10;
  if ((code & 0xFF00) == 0xFF00) reg |= 0x80;
  return reg;
}

}  // namespace

SimDrive::SimDrive(Bus& bus, const Clock& clock, const AxisConfig& config)
    : bus_(bus), clock_(clock), config_(config), mechanics_(config.sim.mechanics, config.rated_torque) {
  if (!validNodeId(config_.node_id)) throw std::invalid_argument("SimDrive: node id outside 1..127");
  if (!(config_.counts_per_metre > 0)) throw std::invalid_argument("SimDrive: counts_per_metre must be > 0");
  od_.setWriteHook(
      [this](std::uint16_t i, std::uint8_t s, const std::vector<std::uint8_t>& d) { return checkWrite(i, s, d); });
  actual_ = demand_ = config_.toCounts(config_.sim.start_position);
  physical_m_ = config_.sim.start_position;
  pp_target_ = actual_;
  switch_pos_ = config_.toCounts(config_.sim.home_switch);
  resetApplication();
  resetCommunication();
  last_advance_ = clock_.now();
  applyFilters();
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

// --- object dictionary ------------------------------------------------------------------

void SimDrive::resetApplication() {
  const AxisConfig& c = config_;
  const double k = c.counts_per_metre;
  od_.add(0x603F, 0, A::kReadOnly, 2, 0, false, true);
  od_.add(0x6040, 0, A::kReadWrite, 2, 0, false, true);
  od_.add(0x6041, 0, A::kReadOnly, 2, 0, false, true);
  od_.add(0x605A, 0, A::kReadWrite, 2, c.quick_stop_option, true);
  od_.add(0x6060, 0, A::kReadWrite, 1, 0, true, true);
  od_.add(0x6061, 0, A::kReadOnly, 1, 0, true, true);
  od_.add(0x6064, 0, A::kReadOnly, 4, 0, true, true);
  od_.add(0x6065, 0, A::kReadWrite, 4, std::llround(c.following_error_window * k));
  od_.add(0x6066, 0, A::kReadWrite, 2, 10);  // ms
  od_.add(0x6067, 0, A::kReadWrite, 4, 1);   // position window, counts
  od_.add(0x606C, 0, A::kReadOnly, 4, 0, true, true);
  od_.add(0x607A, 0, A::kReadWrite, 4, 0, true, true);
  od_.add(0x607C, 0, A::kReadWrite, 4, c.toCounts(c.home_offset), true);
  od_.add(0x607D, 0, A::kConst, 1, 2);
  od_.add(0x607D, 1, A::kReadWrite, 4, c.toCounts(c.min_position), true);
  od_.add(0x607D, 2, A::kReadWrite, 4, c.toCounts(c.max_position), true);
  od_.add(0x607F, 0, A::kReadWrite, 4, std::llround(c.sim.max_velocity * k));
  od_.add(0x6081, 0, A::kReadWrite, 4, std::llround(c.profile_velocity * k), false, true);
  od_.add(0x6083, 0, A::kReadWrite, 4, std::llround(c.profile_acceleration * k));
  od_.add(0x6084, 0, A::kReadWrite, 4, std::llround(c.profile_deceleration * k));
  od_.add(0x6085, 0, A::kReadWrite, 4, std::llround(c.quick_stop_deceleration * k));
  od_.add(0x6098, 0, A::kReadWrite, 1, c.homing_method, true);
  od_.add(0x6099, 0, A::kConst, 1, 2);
  od_.add(0x6099, 1, A::kReadWrite, 4, std::llround(c.homing_speed * k));
  od_.add(0x6099, 2, A::kReadWrite, 4, std::llround(c.homing_speed * k / 4));
  od_.add(0x609A, 0, A::kReadWrite, 4, std::llround(c.profile_acceleration * k));
  od_.add(0x6076, 0, A::kConst, 4, std::llround(c.rated_torque * 1000.0));  // mN m
  od_.add(0x6077, 0, A::kReadOnly, 2, 0, true, true);                       // per mille of 0x6076
  od_.add(0x6502, 0, A::kReadOnly, 4, (1 << 0) | (1 << 5));                 // supported modes: pp, homing
  od_.add(0x6007, 0, A::kReadWrite, 2, 1, true);                            // abort connection option code: fault
  // The drive restarts: the position reference (homing) is lost, the motor is off.
  actual_ -= offset_;
  demand_ -= offset_;
  switch_pos_ -= offset_;
  offset_ = 0.0;
  state_ = Cia402State::kNotReadyToSwitchOn;
  cw_prev_ = 0;
  velocity_ = 0.0;
  demand_ = actual_;
  pp_target_ = actual_;
  moving_ = setpoint_ack_ = internal_limit_ = halt_ = false;
  target_reached_ = true;
  homing_active_ = homing_attained_ = homing_error_ = homed_ = false;
  following_since_s_ = -1.0;
  mechanics_.reset();
}

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

PdoMapping SimDrive::mapping(std::uint16_t index) const {
  PdoMapping m;
  const auto n = od_.get(index, 0);
  for (std::uint8_t k = 1; k <= n && k <= 8; ++k)
    m.push_back(decodeMappingEntry(static_cast<std::uint32_t>(od_.get(index, k))));
  return m;
}

std::uint32_t SimDrive::checkWrite(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data) const {
  const std::uint64_t v = fromBytes(data);
  if ((isRpdoComm(index) || isTpdoComm(index)) && sub == 1) {
    const auto cur = static_cast<std::uint32_t>(od_.get(index, 1));
    const bool cur_valid = !(cur & kPdoInvalid), new_valid = !(v & kPdoInvalid);
    if (v & 0x20000000u) return sdo_abort::kInvalidValue;  // 29-bit ids not supported
    if (cur_valid && new_valid && (cur & CAN_SFF_MASK) != (v & CAN_SFF_MASK)) return sdo_abort::kInvalidValue;
    return 0;
  }
  if ((isRpdoComm(index) || isTpdoComm(index)) && sub == 2) {
    if (v > 240 && v < 254) return sdo_abort::kInvalidValue;
    return 0;
  }
  if (isRpdoMap(index) || isTpdoMap(index)) {
    const bool rx = isRpdoMap(index);
    const std::uint16_t comm = static_cast<std::uint16_t>(index - 0x200);
    if (!(static_cast<std::uint32_t>(od_.get(comm, 1)) & kPdoInvalid)) return sdo_abort::kDeviceState;  // PDO valid
    auto entryOk = [&](std::uint32_t raw) -> std::uint32_t {
      const PdoEntry e = decodeMappingEntry(raw);
      const ObjectDictionary::Entry* obj = od_.find(e.index, e.subindex);
      if (!obj || !obj->mappable || obj->size * 8 != e.bits) return sdo_abort::kNotMappable;
      if (rx && (obj->access == A::kReadOnly || obj->access == A::kConst)) return sdo_abort::kNotMappable;
      return 0;
    };
    if (sub == 0) {
      if (v > 8) return sdo_abort::kValueTooHigh;
      unsigned bits = 0;
      for (std::uint8_t k = 1; k <= v; ++k) {
        const auto raw = static_cast<std::uint32_t>(od_.get(index, k));
        if (const std::uint32_t code = entryOk(raw)) return code;
        bits += raw & 0xFF;
      }
      return bits > 64 ? sdo_abort::kPdoLength : 0;
    }
    if (od_.get(index, 0) != 0) return sdo_abort::kDeviceState;
    return v == 0 ? 0 : entryOk(static_cast<std::uint32_t>(v));
  }
  if (index == 0x6060) {
    const auto mode = static_cast<std::int8_t>(v);
    if (mode != 0 && mode != 1 && mode != 6) return sdo_abort::kInvalidValue;
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
  if (index == 0x6060) od_.set(0x6061, 0, od_.get(0x6060, 0));
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

void SimDrive::process(const can_frame& f, TimePoint now) {
  if (!powered_ || silent_) return;
  // RPDOs by their configured COB-IDs (they need not be the pre-defined ones).
  if (!(f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG))) {
    for (int n = 0; n < 4; ++n) {
      const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1400 + n), 1));
      if (!(cob & kPdoInvalid) && (cob & CAN_SFF_MASK) == (f.can_id & CAN_SFF_MASK)) {
        handleRpdo(n, f);
        return;
      }
    }
  }
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

// --- SDO server -----------------------------------------------------------------------------

void SimDrive::respondSdo(const can_frame& f, TimePoint now) {
  if (sdo_drop_ > 0) {
    --sdo_drop_;
    ++stats_.sdo_dropped;
    return;
  }
  if (sdo_delay_ > Duration::zero() || !pending_sdo_.empty()) {
    pending_sdo_.push_back({now + sdo_delay_, f});
    return;
  }
  send(f);
}

void SimDrive::abortSdo(std::uint16_t index, std::uint8_t sub, std::uint32_t code, TimePoint now) {
  upload_ = {};
  download_ = {};
  ++stats_.sdo_aborts;
  respondSdo(sdoAbortResponse(config_.node_id, index, sub, code), now);
}

void SimDrive::handleSdo(const SdoFrame& r, TimePoint now) {
  ++stats_.sdo_requests;
  const std::uint8_t id = config_.node_id;
  switch (r.command) {
    case SdoCommand::kAbort:
      upload_ = {};
      download_ = {};
      pending_sdo_.clear();  // the client gave up: late answers would confuse it
      return;
    case SdoCommand::kInitiateUpload: {
      upload_ = {};
      download_ = {};
      updateProcessObjects();
      std::vector<std::uint8_t> data;
      if (const std::uint32_t code = od_.read(r.index, r.subindex, data))
        return abortSdo(r.index, r.subindex, code, now);
      if (data.size() > 4) {
        upload_.active = true;
        upload_.index = r.index;
        upload_.sub = r.subindex;
        upload_.data = data;
      }
      return respondSdo(sdoInitiateUploadResponse(id, r.index, r.subindex, data), now);
    }
    case SdoCommand::kUploadSegment: {
      if (!upload_.active) return abortSdo(0, 0, sdo_abort::kCommandSpecifier, now);
      if (r.toggle != upload_.toggle) return abortSdo(upload_.index, upload_.sub, sdo_abort::kToggleBit, now);
      const std::size_t n = std::min<std::size_t>(7, upload_.data.size() - upload_.offset);
      const std::vector<std::uint8_t> chunk(upload_.data.begin() + static_cast<std::ptrdiff_t>(upload_.offset),
                                            upload_.data.begin() + static_cast<std::ptrdiff_t>(upload_.offset + n));
      upload_.offset += n;
      const bool last = upload_.offset >= upload_.data.size();
      const bool t = upload_.toggle;
      upload_.toggle = !upload_.toggle;
      if (last) upload_ = {};
      return respondSdo(sdoUploadSegmentResponse(id, t, chunk, last), now);
    }
    case SdoCommand::kInitiateDownload: {
      upload_ = {};
      download_ = {};
      if (r.expedited) {
        if (const std::uint32_t code = od_.write(r.index, r.subindex, r.data))
          return abortSdo(r.index, r.subindex, code, now);
        afterWrite(r.index, r.subindex);
        return respondSdo(sdoInitiateDownloadResponse(id, r.index, r.subindex), now);
      }
      const ObjectDictionary::Entry* e = od_.find(r.index, r.subindex);
      if (!e) {
        return abortSdo(r.index, r.subindex, od_.hasIndex(r.index) ? sdo_abort::kNoSubIndex : sdo_abort::kNoObject,
                        now);
      }
      if (e->access == A::kReadOnly || e->access == A::kConst)
        return abortSdo(r.index, r.subindex, sdo_abort::kReadOnly, now);
      if (r.size_indicated && e->size != 0 && r.size != e->size) {
        return abortSdo(r.index, r.subindex, r.size > e->size ? sdo_abort::kLengthTooHigh : sdo_abort::kLengthTooLow,
                        now);
      }
      download_.active = true;
      download_.index = r.index;
      download_.sub = r.subindex;
      download_.size = r.size;
      download_.size_known = r.size_indicated;
      return respondSdo(sdoInitiateDownloadResponse(id, r.index, r.subindex), now);
    }
    case SdoCommand::kDownloadSegment: {
      if (!download_.active) return abortSdo(0, 0, sdo_abort::kCommandSpecifier, now);
      if (r.toggle != download_.toggle) return abortSdo(download_.index, download_.sub, sdo_abort::kToggleBit, now);
      download_.data.insert(download_.data.end(), r.data.begin(), r.data.end());
      if (download_.size_known && download_.data.size() > download_.size) {
        return abortSdo(download_.index, download_.sub, sdo_abort::kLengthTooHigh, now);
      }
      const bool t = download_.toggle;
      download_.toggle = !download_.toggle;
      if (r.last) {
        const Download d = download_;
        download_ = {};
        if (d.size_known && d.data.size() != d.size) return abortSdo(d.index, d.sub, sdo_abort::kLengthMismatch, now);
        if (const std::uint32_t code = od_.write(d.index, d.sub, d.data)) return abortSdo(d.index, d.sub, code, now);
        afterWrite(d.index, d.sub);
      }
      return respondSdo(sdoDownloadSegmentResponse(id, t), now);
    }
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

void SimDrive::sendTpdo(int n) {
  const PdoMapping map = mapping(static_cast<std::uint16_t>(0x1A00 + n));
  if (map.empty()) return;
  std::vector<std::uint64_t> values;
  for (const PdoEntry& e : map) values.push_back(static_cast<std::uint64_t>(od_.get(e.index, e.subindex)));
  const auto cob = static_cast<std::uint32_t>(od_.get(static_cast<std::uint16_t>(0x1800 + n), 1));
  const Result<can_frame> f = packPdo(cob & CAN_SFF_MASK, map, values);
  if (!f) return;
  send(*f);
  tpdo_last_[static_cast<std::size_t>(n)] = *f;
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
    const PdoMapping map = mapping(static_cast<std::uint16_t>(0x1A00 + n));
    if (map.empty()) continue;
    std::vector<std::uint64_t> values;
    for (const PdoEntry& e : map) values.push_back(static_cast<std::uint64_t>(od_.get(e.index, e.subindex)));
    const Result<can_frame> f = packPdo(cob & CAN_SFF_MASK, map, values);
    const auto& last = tpdo_last_[static_cast<std::size_t>(n)];
    if (f && (!last || !sameFrame(*last, *f))) sendTpdo(n);
  }
}

// --- CiA 402 ------------------------------------------------------------------------------------

std::uint16_t SimDrive::composeStatusword() const {
  std::uint16_t w = 0;
  switch (state_) {
    case Cia402State::kNotReadyToSwitchOn:
      w = 0x00;
      break;
    case Cia402State::kSwitchOnDisabled:
      w = 0x40;
      break;
    case Cia402State::kReadyToSwitchOn:
      w = 0x21;
      break;
    case Cia402State::kSwitchedOn:
      w = 0x23;
      break;
    case Cia402State::kOperationEnabled:
      w = 0x27;
      break;
    case Cia402State::kQuickStopActive:
      w = 0x07;
      break;
    case Cia402State::kFaultReactionActive:
      w = 0x0F;
      break;
    case Cia402State::kFault:
      w = 0x08;
      break;
    case Cia402State::kUnknown:
      w = 0x00;
      break;
  }
  if (state_ == Cia402State::kReadyToSwitchOn || state_ == Cia402State::kSwitchedOn ||
      state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive) {
    w |= sw::kVoltageEnabled;
  }
  w |= sw::kRemote;
  const double window = static_cast<double>(od_.get(0x6065, 0));
  const bool following = std::abs(demand_ - actual_) > window;
  if (state_ == Cia402State::kQuickStopActive) {
    if (velocity_ == 0.0) w |= sw::kTargetReached;
  } else if (state_ != Cia402State::kOperationEnabled) {
    // the operation-mode bits (10, 12, 13) only mean something while enabled
  } else if (od_.get(0x6061, 0) == static_cast<int>(Mode::kHoming)) {
    if (!homing_active_) w |= sw::kTargetReached;
    if (homing_attained_) w |= sw::kHomingAttained;
    if (homing_error_) w |= sw::kHomingError;
  } else {
    const double pos_window = static_cast<double>(od_.get(0x6067, 0));
    const bool reached = (!moving_ && std::abs(actual_ - pp_target_) <= pos_window) || (halt_ && velocity_ == 0.0);
    if (reached) w |= sw::kTargetReached;
    if (setpoint_ack_) w |= sw::kSetPointAcknowledge;
    if (following) w |= sw::kFollowingError;
    if (internal_limit_) w |= sw::kInternalLimit;
  }
  return w;
}

void SimDrive::updateProcessObjects() {
  od_.set(0x6041, 0, composeStatusword());
  od_.set(0x6064, 0, std::llround(actual_));
  od_.set(0x606C, 0, std::llround(velocity_));
}

void SimDrive::enterState(Cia402State s) {
  const Cia402State prev = state_;
  state_ = s;
  if (s == Cia402State::kQuickStopActive && od_.get(0x605A, 0) == 0) state_ = s = Cia402State::kSwitchOnDisabled;
  if (s == Cia402State::kOperationEnabled && prev != Cia402State::kQuickStopActive) {
    demand_ = actual_;
    velocity_ = 0.0;
    pp_target_ = actual_;
  }
  if (s == Cia402State::kOperationEnabled) {
    moving_ = false;
    setpoint_ack_ = false;
    homing_active_ = false;
  }
  if (s != Cia402State::kOperationEnabled && s != Cia402State::kQuickStopActive &&
      s != Cia402State::kFaultReactionActive) {
    velocity_ = 0.0;
    demand_ = actual_;
    moving_ = false;
    homing_active_ = false;
    setpoint_ack_ = false;
  }
}

void SimDrive::enterFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer) {
  const std::uint8_t reg = errorRegisterFor(code);
  od_.set(0x603F, 0, code);
  od_.set(0x1001, 0, reg);
  sendEmcy(code, reg, manufacturer);
  if (state_ == Cia402State::kFault || state_ == Cia402State::kFaultReactionActive) return;
  moving_ = false;
  homing_active_ = false;
  if (state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive) {
    enterState(Cia402State::kFaultReactionActive);  // brake on the quick-stop ramp, then fault
  } else {
    enterState(Cia402State::kFault);
  }
}

void SimDrive::processControlword() {
  const auto cw = static_cast<std::uint16_t>(od_.get(0x6040, 0));
  const std::uint16_t prev = cw_prev_;
  cw_prev_ = cw;
  if ((cw & cw::kFaultReset) && !(prev & cw::kFaultReset) && state_ == Cia402State::kFault) {
    od_.set(0x603F, 0, 0);
    od_.set(0x1001, 0, 0);
    sendEmcy(0x0000, 0);                         // error reset
    enterState(Cia402State::kSwitchOnDisabled);  // 15
    return;
  }
  if (cw & cw::kFaultReset) return;
  const bool disable_voltage = !(cw & 0x02);
  const bool quick_stop = (cw & 0x06) == 0x02;
  const bool shutdown = (cw & 0x07) == 0x06;
  const bool switch_on = (cw & 0x0F) == 0x07;
  const bool enable_op = (cw & 0x0F) == 0x0F;
  const auto option = od_.get(0x605A, 0);
  switch (state_) {
    case Cia402State::kSwitchOnDisabled:
      if (shutdown) enterState(Cia402State::kReadyToSwitchOn);  // 2
      break;
    case Cia402State::kReadyToSwitchOn:
      if (disable_voltage || quick_stop)
        enterState(Cia402State::kSwitchOnDisabled);  // 7
      else if (switch_on)
        enterState(Cia402State::kSwitchedOn);  // 3
      else if (enable_op)
        enterState(Cia402State::kOperationEnabled);  // 3 + 4
      break;
    case Cia402State::kSwitchedOn:
      if (disable_voltage || quick_stop)
        enterState(Cia402State::kSwitchOnDisabled);  // 10
      else if (shutdown)
        enterState(Cia402State::kReadyToSwitchOn);  // 6
      else if (enable_op)
        enterState(Cia402State::kOperationEnabled);  // 4
      break;
    case Cia402State::kOperationEnabled:
      if (disable_voltage)
        enterState(Cia402State::kSwitchOnDisabled);  // 9
      else if (quick_stop)
        enterState(Cia402State::kQuickStopActive);  // 11
      else if (shutdown)
        enterState(Cia402State::kReadyToSwitchOn);  // 8
      else if (switch_on)
        enterState(Cia402State::kSwitchedOn);  // 5
      break;
    case Cia402State::kQuickStopActive:
      if (disable_voltage)
        enterState(Cia402State::kSwitchOnDisabled);  // 12
      else if (enable_op && option >= 5 && velocity_ == 0.0)
        enterState(Cia402State::kOperationEnabled);  // 16
      break;
    default:
      break;
  }
  if (state_ != Cia402State::kOperationEnabled) return;
  halt_ = (cw & cw::kHalt) != 0;
  const bool sp = (cw & cw::kNewSetPoint) != 0, sp_prev = (prev & cw::kNewSetPoint) != 0;
  const auto mode = od_.get(0x6061, 0);
  if (mode == static_cast<int>(Mode::kProfilePosition)) {
    if (sp && !sp_prev && !setpoint_ack_) {
      double t = static_cast<double>(od_.get(0x607A, 0));
      if (cw & cw::kRelative) t += pp_target_;
      const double lo = static_cast<double>(od_.get(0x607D, 1)), hi = static_cast<double>(od_.get(0x607D, 2));
      internal_limit_ = false;
      if (lo < hi && (t < lo || t > hi)) {
        t = std::clamp(t, lo, hi);
        internal_limit_ = true;
      }
      pp_target_ = t;
      moving_ = true;
      setpoint_ack_ = true;
    }
    if (!sp) setpoint_ack_ = false;
  } else if (mode == static_cast<int>(Mode::kHoming)) {
    if (sp && !sp_prev) startHoming();
    if (!sp && homing_active_) homing_active_ = false;  // interrupted
  }
}

void SimDrive::startHoming() {
  homing_attained_ = false;
  homing_error_ = false;
  homing_active_ = true;
  homing_started_s_ = sim_time_s_;
  homing_failing_ = homing_fail_count_ > 0;
  if (homing_failing_) --homing_fail_count_;
  const auto method = od_.get(0x6098, 0);
  switch (method) {
    case 1:
    case 2:
    case 17:
    case 18:
      homing_goal_ = switch_pos_;
      break;
    case 33:
    case 34:
    case 35:
    case 37:
      homing_goal_ = actual_;  // home in place
      break;
    default:
      homing_error_ = true;  // method not supported
      homing_active_ = false;
      return;
  }
  if (homing_failing_ && homing_fail_kind_ == HomingFailure::kHang)
    homing_goal_ = actual_ + (homing_goal_ - actual_) * 0.5;
}

void SimDrive::completeHoming() {
  // Called from step() after approach() moved the demand onto the goal but
  // before the step copies the demand into the actual position: take that
  // step first, so the reference lands on the goal itself (not on where the
  // motor stood a step earlier, which left it a step past the offset).
  if (!blocked_) actual_ = demand_;
  const double delta = static_cast<double>(od_.get(0x607C, 0)) - actual_;
  actual_ += delta;
  demand_ += delta;
  switch_pos_ += delta;
  offset_ += delta;
  pp_target_ = actual_;
  velocity_ = 0.0;
  homing_active_ = false;
  homing_attained_ = true;
  homed_ = true;
}

bool SimDrive::approach(double target, double vmax, double acc, double dec, double dt) {
  const double d = target - demand_;
  if (std::abs(d) < 1e-9 && std::abs(velocity_) < 1e-9) {
    demand_ = target;
    velocity_ = 0.0;
    return true;
  }
  const double dir = d > 0 ? 1.0 : -1.0;
  const double vstop = std::sqrt(2.0 * dec * std::abs(d));
  const double vdes = dir * std::min(vmax, vstop);
  const double rate = (velocity_ * dir >= 0 && std::abs(vdes) > std::abs(velocity_)) ? acc : dec;
  velocity_ += std::clamp(vdes - velocity_, -rate * dt, rate * dt);
  const double s = velocity_ * dt;
  if ((d > 0 && s >= d) || (d < 0 && s <= d) || (std::abs(d) <= 0.5 && std::abs(velocity_) <= 2.0 * dec * dt)) {
    demand_ = target;
    velocity_ = 0.0;
    return true;
  }
  demand_ += s;
  return false;
}

void SimDrive::updateMechanics(double dt, double previous_actual, double previous_velocity) {
  const double k = config_.counts_per_metre;
  const double position = (actual_ - offset_) / k;
  physical_m_.store(position, std::memory_order_relaxed);
  if (!mechanics_.enabled()) return;
  const double v = velocity_ / k, a = (velocity_ - previous_velocity) / k / dt;
  external_force_ = external_ ? external_(position, v) : 0.0;
  const double torque = mechanics_.step((actual_ - previous_actual) / k, v, a, external_force_);
  // The motor carries the load while it is energised (holding brake otherwise: no torque).
  const bool energised = state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive ||
                         state_ == Cia402State::kFaultReactionActive;
  od_.set(0x6077, 0, mechanics_.torquePerMille(energised ? torque : 0.0));
}

void SimDrive::step(double dt) {
  const double previous_actual = actual_, previous_velocity = velocity_;
  sim_time_s_ += dt;
  auto brake = [&](double dec) {
    const double dv = std::min(std::abs(velocity_), dec * dt);
    velocity_ -= velocity_ > 0 ? dv : -dv;
    demand_ += velocity_ * dt;
  };
  const double qs_dec = std::max(1.0, static_cast<double>(od_.get(0x6085, 0)));
  switch (state_) {
    case Cia402State::kNotReadyToSwitchOn:
      enterState(Cia402State::kSwitchOnDisabled);  // initialisation done
      break;
    case Cia402State::kOperationEnabled: {
      const auto mode = od_.get(0x6061, 0);
      const double dec = std::max(1.0, static_cast<double>(od_.get(0x6084, 0)));
      if (mode == static_cast<int>(Mode::kProfilePosition) && moving_ && !halt_) {
        const double vmax = static_cast<double>(std::min(od_.get(0x6081, 0), od_.get(0x607F, 0)));
        const double acc = std::max(1.0, static_cast<double>(od_.get(0x6083, 0)));
        if (approach(pp_target_, vmax, acc, dec, dt)) moving_ = false;
      } else if (mode == static_cast<int>(Mode::kHoming) && homing_active_) {
        const double speed = static_cast<double>(od_.get(0x6099, 1));
        const double acc = std::max(1.0, static_cast<double>(od_.get(0x609A, 0)));
        if (homing_failing_ && homing_fail_kind_ == HomingFailure::kError) {
          brake(acc);
          if (sim_time_s_ - homing_started_s_ >= 0.05) {
            homing_error_ = true;
            homing_active_ = false;
          }
        } else if (approach(homing_goal_, speed, acc, acc, dt) && !homing_failing_) {
          completeHoming();
        }
      } else {
        brake(dec);
      }
      break;
    }
    case Cia402State::kQuickStopActive:
      brake(qs_dec);
      if (velocity_ == 0.0) {
        const auto option = od_.get(0x605A, 0);
        if (option < 5) enterState(Cia402State::kSwitchOnDisabled);  // 12 (options 1..4)
      }
      break;
    case Cia402State::kFaultReactionActive:
      brake(qs_dec);
      if (velocity_ == 0.0) enterState(Cia402State::kFault);  // 14
      break;
    default:
      velocity_ = 0.0;
      demand_ = actual_;
      break;
  }
  if (!blocked_) actual_ = demand_;
  updateMechanics(dt, previous_actual, previous_velocity);
  // Following error monitoring (0x6065 window for 0x6066 ms).
  if (state_ == Cia402State::kOperationEnabled || state_ == Cia402State::kQuickStopActive) {
    if (std::abs(demand_ - actual_) > static_cast<double>(od_.get(0x6065, 0))) {
      if (following_since_s_ < 0) following_since_s_ = sim_time_s_;
      if (sim_time_s_ - following_since_s_ >= static_cast<double>(od_.get(0x6066, 0)) / 1000.0) {
        following_since_s_ = -1.0;
        enterFault(0x8611, {});
      }
    } else {
      following_since_s_ = -1.0;
    }
  } else {
    following_since_s_ = -1.0;
  }
}

void SimDrive::advance(TimePoint now) {
  if (!powered_) {
    last_advance_ = now;
    return;
  }
  double left = std::chrono::duration<double>(now - last_advance_).count();
  last_advance_ = now;
  left = std::min(left, 10.0);  // after a long stall, do not replay more than 10 s
  while (left > 1e-12) {
    const double dt = std::min(kStepS, left);
    step(dt);
    left -= dt;
  }
}

// --- public -----------------------------------------------------------------------------------------

void SimDrive::poll() {
  std::lock_guard<std::mutex> lock(mutex_);
  const TimePoint now = clock_.now();
  advance(now);
  while (auto f = bus_.receive(Duration::zero())) process(f->frame, now);
  if (!powered_) return;
  // Delayed SDO responses that are due.
  while (!pending_sdo_.empty() && pending_sdo_.front().due <= now) {
    send(pending_sdo_.front().frame);
    pending_sdo_.pop_front();
  }
  // Heartbeat producer (0x1017).
  const auto period = od_.get(0x1017, 0);
  if (period > 0 && !silent_ && now >= next_heartbeat_) {
    send(encodeHeartbeat(config_.node_id, nmt_));
    ++stats_.heartbeats;
    next_heartbeat_ += std::chrono::milliseconds(period);
    if (next_heartbeat_ <= now) next_heartbeat_ = now + std::chrono::milliseconds(period);
  }
  checkHeartbeatConsumer(now);
  // Back from bus-off: say so (CiA 301 EMCY 0x8140).
  const BusState bs = bus_.status().state;
  if (bus_state_ == BusState::kBusOff && bs == BusState::kErrorActive) {
    sendEmcy(0x8140, static_cast<std::uint8_t>(od_.get(0x1001, 0)));
  }
  bus_state_ = bs;
  checkChangeTpdos();
}

void SimDrive::run(const std::atomic<bool>& stop, Duration wait) {
  while (!stop) {
    std::optional<TimedFrame> f = bus_.receive(wait);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const TimePoint now = clock_.now();
      advance(now);
      if (f) process(f->frame, now);
    }
    poll();
  }
}

void SimDrive::powerOn() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (powered_) return;
  powered_ = true;
  resetApplication();
  resetCommunication();
  last_advance_ = clock_.now();
  bootUp(clock_.now());
}

void SimDrive::powerOff() {
  std::lock_guard<std::mutex> lock(mutex_);
  powered_ = false;
  resetApplication();  // drops the homing reference
}

void SimDrive::setExternalForce(ExternalForce force) {
  std::lock_guard<std::mutex> lock(mutex_);
  external_ = std::move(force);
}

double SimDrive::externalForce() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return external_force_;
}

double SimDrive::motorForce() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return mechanics_.motorForce();
}

void SimDrive::injectFault(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer) {
  std::lock_guard<std::mutex> lock(mutex_);
  enterFault(code, manufacturer);
}

void SimDrive::setSilent(bool silent) {
  std::lock_guard<std::mutex> lock(mutex_);
  silent_ = silent;
  if (!silent) next_heartbeat_ = clock_.now();
}

void SimDrive::setSdoResponseDelay(Duration delay) {
  std::lock_guard<std::mutex> lock(mutex_);
  sdo_delay_ = delay;
}

void SimDrive::dropSdoResponses(int count) {
  std::lock_guard<std::mutex> lock(mutex_);
  sdo_drop_ = std::max(0, count);
}

void SimDrive::setMotionBlocked(bool blocked) {
  std::lock_guard<std::mutex> lock(mutex_);
  blocked_ = blocked;
}

void SimDrive::failHoming(int attempts, HomingFailure kind) {
  std::lock_guard<std::mutex> lock(mutex_);
  homing_fail_count_ = std::max(0, attempts);
  homing_fail_kind_ = kind;
}

bool SimDrive::powered() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return powered_;
}
NmtState SimDrive::nmtState() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return nmt_;
}
Cia402State SimDrive::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}
std::uint16_t SimDrive::statusword() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return composeStatusword();
}
std::int32_t SimDrive::position() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<std::int32_t>(std::llround(actual_));
}
double SimDrive::velocity() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return velocity_;
}
std::int8_t SimDrive::modeDisplay() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<std::int8_t>(od_.get(0x6061, 0));
}
bool SimDrive::homed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return homed_;
}
std::uint16_t SimDrive::errorCode() const {
  // Called with or without the lock held by internal code paths: read-only access.
  const ObjectDictionary::Entry* e = od_.find(0x603F, 0);
  return e ? static_cast<std::uint16_t>(fromBytes(e->value)) : 0;
}
std::int64_t SimDrive::object(std::uint16_t index, std::uint8_t sub) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return od_.get(index, sub);
}
SimDrive::Stats SimDrive::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace massage_cell::can
