// CANopen frame codecs (CiA 301 subset); see canopen.h.
#include "massage_cell/can/canopen.h"

#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "massage_cell/can/bus.h"

namespace massage_cell::can {

namespace {

std::string hex(std::uint32_t v, int digits) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%0*X", digits, v);
  return buf;
}

// Plain 11-bit data frame check shared by the decoders.
std::string frameProblem(const can_frame& f) {
  if (f.can_id & CAN_ERR_FLAG) return "error frame";
  if (f.can_id & CAN_EFF_FLAG) return "extended (29-bit) frame " + formatFrame(f);
  if (f.can_id & CAN_RTR_FLAG) return "remote frame " + formatFrame(f);
  if (f.len > CAN_MAX_DLEN) return "DLC " + std::to_string(f.len) + " > 8";
  return {};
}

canid_t cob(const can_frame& f) { return f.can_id & CAN_SFF_MASK; }

void requireNode(std::uint8_t node, bool allow_zero, const char* what) {
  if (node > 127 || (!allow_zero && node == 0)) {
    throw std::invalid_argument(std::string(what) + ": node id " + std::to_string(node) + " outside " +
                                (allow_zero ? "0..127" : "1..127"));
  }
}

can_frame sdoFrame(canid_t id, std::uint8_t cmd, std::uint16_t index, std::uint8_t sub) {
  can_frame f{};
  f.can_id = id;
  f.len = 8;
  f.data[0] = cmd;
  f.data[1] = static_cast<std::uint8_t>(index & 0xFF);
  f.data[2] = static_cast<std::uint8_t>(index >> 8);
  f.data[3] = sub;
  return f;
}

void putU32(can_frame& f, int at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) f.data[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t getU32(const can_frame& f, int at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(f.data[at + i]) << (8 * i);
  return v;
}

can_frame segmentFrame(canid_t id, std::uint8_t cs_bits, bool toggle, const std::vector<std::uint8_t>& data, bool last,
                       const char* what) {
  if (data.size() > 7) throw std::invalid_argument(std::string(what) + ": a segment carries at most 7 bytes");
  can_frame f{};
  f.can_id = id;
  f.len = 8;
  const std::uint8_t n = static_cast<std::uint8_t>(7 - data.size());
  f.data[0] = static_cast<std::uint8_t>(cs_bits | (toggle ? 0x10 : 0) | (n << 1) | (last ? 1 : 0));
  if (!data.empty()) std::memcpy(f.data + 1, data.data(), data.size());  // data() may be null when empty
  return f;
}

// Initiate with data (download request / upload response share the layout).
/// A segment upload request / download response: only the command byte
/// (its toggle bit) carries information.
can_frame toggleFrame(canid_t id, std::uint8_t cs_bits, bool toggle) {
  can_frame f{};
  f.can_id = id;
  f.len = 8;
  f.data[0] = static_cast<std::uint8_t>(cs_bits | (toggle ? 0x10 : 0));
  return f;
}

/// An SDO abort (either direction): index, sub-index and the abort code.
can_frame abortFrame(canid_t id, std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  can_frame f = sdoFrame(id, 0x80, index, sub);
  putU32(f, 4, code);
  return f;
}

can_frame initiateWithData(canid_t id, std::uint8_t cs_bits, std::uint16_t index, std::uint8_t sub,
                           const std::vector<std::uint8_t>& data, const char* what) {
  if (data.empty()) throw std::invalid_argument(std::string(what) + ": no data");
  if (data.size() <= 4) {
    const std::uint8_t n = static_cast<std::uint8_t>(4 - data.size());
    can_frame f = sdoFrame(id, static_cast<std::uint8_t>(cs_bits | (n << 2) | 0x02 | 0x01), index, sub);
    std::memcpy(f.data + 4, data.data(), data.size());
    return f;
  }
  can_frame f = sdoFrame(id, static_cast<std::uint8_t>(cs_bits | 0x01), index, sub);
  putU32(f, 4, static_cast<std::uint32_t>(data.size()));
  return f;
}

void decodeInitiateData(const can_frame& f, SdoFrame& s) {
  s.index = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8));
  s.subindex = f.data[3];
  s.expedited = (f.data[0] & 0x02) != 0;
  s.size_indicated = (f.data[0] & 0x01) != 0;
  if (s.expedited) {
    const unsigned n = s.size_indicated ? ((f.data[0] >> 2) & 0x03) : 0;
    s.size = 4 - n;
    s.data.assign(f.data + 4, f.data + 4 + s.size);
  } else {
    s.size = s.size_indicated ? getU32(f, 4) : 0;
  }
}

void decodeSegment(const can_frame& f, SdoFrame& s) {
  s.toggle = (f.data[0] & 0x10) != 0;
  s.last = (f.data[0] & 0x01) != 0;
  const unsigned n = (f.data[0] >> 1) & 0x07;
  s.data.assign(f.data + 1, f.data + 8 - n);
}

void decodeIndex(const can_frame& f, SdoFrame& s) {
  s.index = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8));
  s.subindex = f.data[3];
}

Result<SdoFrame> sdoCommon(const can_frame& f, canid_t base, const char* what) {
  if (auto p = frameProblem(f); !p.empty()) return Result<SdoFrame>::failure(std::string(what) + ": " + p);
  const canid_t id = cob(f);
  if (id <= base || id > base + 127) {
    return Result<SdoFrame>::failure(std::string(what) + ": COB-ID " + hex(id, 3) + " is not " + hex(base + 1, 3) +
                                     ".." + hex(base + 127, 3));
  }
  if (f.len != 8) {
    return Result<SdoFrame>::failure(std::string(what) + ": DLC " + std::to_string(f.len) + " (SDO frames have 8)");
  }
  SdoFrame s;
  s.node = static_cast<std::uint8_t>(id - base);
  return Result<SdoFrame>::success(s);
}

}  // namespace

// --- classification ----------------------------------------------------------

const char* toString(CobType type) {
  switch (type) {
    case CobType::kNmt:
      return "NMT";
    case CobType::kSync:
      return "SYNC";
    case CobType::kEmcy:
      return "EMCY";
    case CobType::kTpdo:
      return "TPDO";
    case CobType::kRpdo:
      return "RPDO";
    case CobType::kSdoResponse:
      return "SDO response";
    case CobType::kSdoRequest:
      return "SDO request";
    case CobType::kHeartbeat:
      return "heartbeat";
  }
  return "?";
}

Result<CobInfo> classify(const can_frame& f) {
  if (auto p = frameProblem(f); !p.empty()) return Result<CobInfo>::failure(p);
  const canid_t id = cob(f);
  if (id == kNmtCobId) return Result<CobInfo>::success({CobType::kNmt, 0, 0});
  if (id == kSyncCobId) return Result<CobInfo>::success({CobType::kSync, 0, 0});
  const canid_t function = id & 0x780;
  const auto node = static_cast<std::uint8_t>(id & 0x7F);
  if (node == 0) return Result<CobInfo>::failure("COB-ID " + hex(id, 3) + " is not in the pre-defined connection set");
  switch (function) {
    case 0x080:
      return Result<CobInfo>::success({CobType::kEmcy, node, 0});
    case 0x180:
      return Result<CobInfo>::success({CobType::kTpdo, node, 1});
    case 0x280:
      return Result<CobInfo>::success({CobType::kTpdo, node, 2});
    case 0x380:
      return Result<CobInfo>::success({CobType::kTpdo, node, 3});
    case 0x480:
      return Result<CobInfo>::success({CobType::kTpdo, node, 4});
    case 0x200:
      return Result<CobInfo>::success({CobType::kRpdo, node, 1});
    case 0x300:
      return Result<CobInfo>::success({CobType::kRpdo, node, 2});
    case 0x400:
      return Result<CobInfo>::success({CobType::kRpdo, node, 3});
    case 0x500:
      return Result<CobInfo>::success({CobType::kRpdo, node, 4});
    case 0x580:
      return Result<CobInfo>::success({CobType::kSdoResponse, node, 0});
    case 0x600:
      return Result<CobInfo>::success({CobType::kSdoRequest, node, 0});
    case 0x700:
      return Result<CobInfo>::success({CobType::kHeartbeat, node, 0});
    default:
      break;
  }
  return Result<CobInfo>::failure("COB-ID " + hex(id, 3) + " is not in the pre-defined connection set");
}

// --- NMT ---------------------------------------------------------------------

const char* toString(NmtCommand command) {
  switch (command) {
    case NmtCommand::kStart:
      return "start remote node";
    case NmtCommand::kStop:
      return "stop remote node";
    case NmtCommand::kEnterPreOperational:
      return "enter pre-operational";
    case NmtCommand::kResetNode:
      return "reset node";
    case NmtCommand::kResetCommunication:
      return "reset communication";
  }
  return "?";
}

can_frame encodeNmt(NmtCommand command, std::uint8_t node) {
  requireNode(node, true, "encodeNmt");
  return makeFrame(kNmtCobId, {static_cast<std::uint8_t>(command), node});
}

Result<NmtMessage> decodeNmt(const can_frame& f) {
  if (auto p = frameProblem(f); !p.empty()) return Result<NmtMessage>::failure("NMT: " + p);
  if (cob(f) != kNmtCobId) return Result<NmtMessage>::failure("NMT: COB-ID " + hex(cob(f), 3) + " is not 0x000");
  if (f.len != 2) return Result<NmtMessage>::failure("NMT: DLC " + std::to_string(f.len) + " (expected 2)");
  const std::uint8_t cs = f.data[0];
  if (cs != 0x01 && cs != 0x02 && cs != 0x80 && cs != 0x81 && cs != 0x82) {
    return Result<NmtMessage>::failure("NMT: unknown command specifier " + hex(cs, 2));
  }
  if (f.data[1] > 127) return Result<NmtMessage>::failure("NMT: node id " + std::to_string(f.data[1]) + " > 127");
  return Result<NmtMessage>::success({static_cast<NmtCommand>(cs), f.data[1]});
}

// --- SYNC --------------------------------------------------------------------

can_frame encodeSync(std::optional<std::uint8_t> counter) {
  if (!counter) return makeFrame(kSyncCobId, {});
  if (*counter < 1 || *counter > 240) throw std::invalid_argument("encodeSync: counter outside 1..240");
  return makeFrame(kSyncCobId, {*counter});
}

Result<std::optional<std::uint8_t>> decodeSync(const can_frame& f) {
  using R = Result<std::optional<std::uint8_t>>;
  if (auto p = frameProblem(f); !p.empty()) return R::failure("SYNC: " + p);
  if (cob(f) != kSyncCobId) return R::failure("SYNC: COB-ID " + hex(cob(f), 3) + " is not 0x080");
  if (f.len == 0) return R::success(std::nullopt);
  if (f.len != 1) return R::failure("SYNC: DLC " + std::to_string(f.len) + " (expected 0 or 1)");
  if (f.data[0] < 1 || f.data[0] > 240)
    return R::failure("SYNC: counter " + std::to_string(f.data[0]) + " outside 1..240");
  return R::success(f.data[0]);
}

// --- heartbeat ---------------------------------------------------------------

const char* toString(NmtState state) {
  switch (state) {
    case NmtState::kBootUp:
      return "boot-up";
    case NmtState::kStopped:
      return "stopped";
    case NmtState::kOperational:
      return "operational";
    case NmtState::kPreOperational:
      return "pre-operational";
  }
  return "?";
}

can_frame encodeHeartbeat(std::uint8_t node, NmtState state) {
  requireNode(node, false, "encodeHeartbeat");
  return makeFrame(kHeartbeatBase + node, {static_cast<std::uint8_t>(state)});
}

Result<Heartbeat> decodeHeartbeat(const can_frame& f) {
  if (auto p = frameProblem(f); !p.empty()) return Result<Heartbeat>::failure("heartbeat: " + p);
  const canid_t id = cob(f);
  if (id <= kHeartbeatBase || id > kHeartbeatBase + 127) {
    return Result<Heartbeat>::failure("heartbeat: COB-ID " + hex(id, 3) + " is not 0x701..0x77F");
  }
  if (f.len != 1) return Result<Heartbeat>::failure("heartbeat: DLC " + std::to_string(f.len) + " (expected 1)");
  const std::uint8_t s = f.data[0] & 0x7F;
  if (s != 0x00 && s != 0x04 && s != 0x05 && s != 0x7F) {
    return Result<Heartbeat>::failure("heartbeat: unknown NMT state " + hex(s, 2));
  }
  return Result<Heartbeat>::success({static_cast<std::uint8_t>(id - kHeartbeatBase), static_cast<NmtState>(s)});
}

// --- EMCY --------------------------------------------------------------------

can_frame encodeEmcy(std::uint8_t node, const Emcy& e) {
  requireNode(node, false, "encodeEmcy");
  can_frame f{};
  f.can_id = kEmcyBase + node;
  f.len = 8;
  f.data[0] = static_cast<std::uint8_t>(e.error_code & 0xFF);
  f.data[1] = static_cast<std::uint8_t>(e.error_code >> 8);
  f.data[2] = e.error_register;
  std::memcpy(f.data + 3, e.manufacturer.data(), 5);
  return f;
}

Result<EmcyMessage> decodeEmcy(const can_frame& f) {
  if (auto p = frameProblem(f); !p.empty()) return Result<EmcyMessage>::failure("EMCY: " + p);
  const canid_t id = cob(f);
  if (id <= kEmcyBase || id > kEmcyBase + 127) {
    return Result<EmcyMessage>::failure("EMCY: COB-ID " + hex(id, 3) + " is not 0x081..0x0FF");
  }
  if (f.len != 8) return Result<EmcyMessage>::failure("EMCY: DLC " + std::to_string(f.len) + " (expected 8)");
  EmcyMessage m{static_cast<std::uint8_t>(id - kEmcyBase), {}};
  m.emcy.error_code = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8));
  m.emcy.error_register = f.data[2];
  std::memcpy(m.emcy.manufacturer.data(), f.data + 3, 5);
  return Result<EmcyMessage>::success(m);
}

std::string emcyText(std::uint16_t code) {
  struct Entry {
    std::uint16_t code;
    const char* text;
  };
  // Exact codes: CiA 301 table 21 and CiA 402-2 (drives).
  static const Entry kExact[] = {
      {0x0000, "error reset or no error"},
      {0x1000, "generic error"},
      {0x2310, "continuous over-current"},
      {0x2311, "continuous over-current no. 1"},
      {0x2320, "short circuit / earth leakage"},
      {0x3110, "mains over-voltage"},
      {0x3120, "mains under-voltage"},
      {0x3210, "DC link over-voltage"},
      {0x3220, "DC link under-voltage"},
      {0x4210, "excess temperature device"},
      {0x4310, "excess temperature drive"},
      {0x5113, "supply low voltage"},
      {0x5530, "data storage (EEPROM / non-volatile memory)"},
      {0x6010, "software reset (watchdog)"},
      {0x6320, "parameter error"},
      {0x7121, "motor blocked"},
      {0x7305, "incremental sensor 1 fault"},
      {0x7306, "incremental sensor 2 fault"},
      {0x8110, "CAN overrun (objects lost)"},
      {0x8120, "CAN in error passive mode"},
      {0x8130, "life guard error or heartbeat error"},
      {0x8140, "recovered from bus off"},
      {0x8150, "CAN-ID collision"},
      {0x8210, "PDO not processed due to length error"},
      {0x8220, "PDO length exceeded"},
      {0x8240, "unexpected SYNC data length"},
      {0x8250, "RPDO timeout"},
      {0x8611, "following error"},
      {0x8612, "reference limit"},
      {0xFF00, "device specific"},
  };
  for (const Entry& e : kExact) {
    if (e.code == code) return e.text;
  }
  static const Entry kClass16[] = {
      {0x2100, "current, device input side"},
      {0x2200, "current inside the device"},
      {0x2300, "current, device output side"},
      {0x3100, "mains voltage"},
      {0x3200, "voltage inside the device"},
      {0x3300, "output voltage"},
      {0x4100, "ambient temperature"},
      {0x4200, "device temperature"},
      {0x4300, "drive temperature"},
      {0x5500, "data storage"},
      {0x6100, "internal software"},
      {0x6200, "user software"},
      {0x6300, "data set"},
      {0x7100, "power"},
      {0x7300, "sensor"},
      {0x8100, "communication"},
      {0x8200, "protocol error"},
      {0x8600, "positioning controller"},
      {0xF000, "additional functions"},
      {0xFF00, "device specific"},
  };
  char suffix[16];
  std::snprintf(suffix, sizeof suffix, " (0x%04X)", code);
  for (const Entry& e : kClass16) {
    if ((code & 0xFF00) == e.code) return std::string(e.text) + suffix;
  }
  static const char* const kClass[16] = {"error reset or no error",
                                         "generic error",
                                         "current",
                                         "voltage",
                                         "temperature",
                                         "device hardware",
                                         "device software",
                                         "additional modules",
                                         "monitoring",
                                         "external error",
                                         "unknown",
                                         "unknown",
                                         "unknown",
                                         "unknown",
                                         "unknown",
                                         "additional functions / device specific"};
  return std::string(kClass[code >> 12]) + suffix;
}

// --- SDO ---------------------------------------------------------------------

std::string sdoAbortText(std::uint32_t code) {
  struct Entry {
    std::uint32_t code;
    const char* text;
  };
  static const Entry kTable[] = {
      {0x05030000, "toggle bit not alternated"},
      {0x05040000, "SDO protocol timed out"},
      {0x05040001, "client/server command specifier not valid or unknown"},
      {0x05040002, "invalid block size (block mode only)"},
      {0x05040003, "invalid sequence number (block mode only)"},
      {0x05040004, "CRC error (block mode only)"},
      {0x05040005, "out of memory"},
      {0x06010000, "unsupported access to an object"},
      {0x06010001, "attempt to read a write only object"},
      {0x06010002, "attempt to write a read only object"},
      {0x06020000, "object does not exist in the object dictionary"},
      {0x06040041, "object cannot be mapped to the PDO"},
      {0x06040042, "the number and length of the objects to be mapped would exceed PDO length"},
      {0x06040043, "general parameter incompatibility reason"},
      {0x06040047, "general internal incompatibility in the device"},
      {0x06060000, "access failed due to a hardware error"},
      {0x06070010, "data type does not match, length of service parameter does not match"},
      {0x06070012, "data type does not match, length of service parameter too high"},
      {0x06070013, "data type does not match, length of service parameter too low"},
      {0x06090011, "sub-index does not exist"},
      {0x06090030, "invalid value for parameter (download only)"},
      {0x06090031, "value of parameter written too high (download only)"},
      {0x06090032, "value of parameter written too low (download only)"},
      {0x06090036, "maximum value is less than minimum value"},
      {0x060A0023, "resource not available: SDO connection"},
      {0x08000000, "general error"},
      {0x08000020, "data cannot be transferred or stored to the application"},
      {0x08000021, "data cannot be transferred or stored to the application because of local control"},
      {0x08000022, "data cannot be transferred or stored to the application because of the present device state"},
      {0x08000023, "object dictionary dynamic generation fails or no object dictionary is present"},
      {0x08000024, "no data available"},
  };
  for (const Entry& e : kTable) {
    if (e.code == code) return e.text;
  }
  return "unknown abort code " + hex(code, 8);
}

const char* toString(SdoCommand command) {
  switch (command) {
    case SdoCommand::kInitiateDownload:
      return "initiate download";
    case SdoCommand::kDownloadSegment:
      return "download segment";
    case SdoCommand::kInitiateUpload:
      return "initiate upload";
    case SdoCommand::kUploadSegment:
      return "upload segment";
    case SdoCommand::kAbort:
      return "abort";
  }
  return "?";
}

can_frame sdoInitiateDownloadRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                     const std::vector<std::uint8_t>& data) {
  requireNode(node, false, "sdoInitiateDownloadRequest");
  return initiateWithData(kSdoRxBase + node, 0x20, index, sub, data, "sdoInitiateDownloadRequest");
}

can_frame sdoDownloadSegmentRequest(std::uint8_t node, bool toggle, const std::vector<std::uint8_t>& data, bool last) {
  requireNode(node, false, "sdoDownloadSegmentRequest");
  return segmentFrame(kSdoRxBase + node, 0x00, toggle, data, last, "sdoDownloadSegmentRequest");
}

can_frame sdoInitiateUploadRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  requireNode(node, false, "sdoInitiateUploadRequest");
  return sdoFrame(kSdoRxBase + node, 0x40, index, sub);
}

can_frame sdoUploadSegmentRequest(std::uint8_t node, bool toggle) {
  requireNode(node, false, "sdoUploadSegmentRequest");
  return toggleFrame(kSdoRxBase + node, 0x60, toggle);
}

can_frame sdoAbortRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  requireNode(node, false, "sdoAbortRequest");
  return abortFrame(kSdoRxBase + node, index, sub, code);
}

can_frame sdoInitiateDownloadResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  requireNode(node, false, "sdoInitiateDownloadResponse");
  return sdoFrame(kSdoTxBase + node, 0x60, index, sub);
}

can_frame sdoDownloadSegmentResponse(std::uint8_t node, bool toggle) {
  requireNode(node, false, "sdoDownloadSegmentResponse");
  return toggleFrame(kSdoTxBase + node, 0x20, toggle);
}

can_frame sdoInitiateUploadResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                    const std::vector<std::uint8_t>& data) {
  requireNode(node, false, "sdoInitiateUploadResponse");
  return initiateWithData(kSdoTxBase + node, 0x40, index, sub, data, "sdoInitiateUploadResponse");
}

can_frame sdoUploadSegmentResponse(std::uint8_t node, bool toggle, const std::vector<std::uint8_t>& data, bool last) {
  requireNode(node, false, "sdoUploadSegmentResponse");
  return segmentFrame(kSdoTxBase + node, 0x00, toggle, data, last, "sdoUploadSegmentResponse");
}

can_frame sdoAbortResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  requireNode(node, false, "sdoAbortResponse");
  return abortFrame(kSdoTxBase + node, index, sub, code);
}

Result<SdoFrame> decodeSdoRequest(const can_frame& f) {
  Result<SdoFrame> base = sdoCommon(f, kSdoRxBase, "SDO request");
  if (!base) return base;
  SdoFrame s = *base;
  const unsigned ccs = f.data[0] >> 5;
  switch (ccs) {
    case 0:
      s.command = SdoCommand::kDownloadSegment;
      decodeSegment(f, s);
      break;
    case 1:
      s.command = SdoCommand::kInitiateDownload;
      decodeInitiateData(f, s);  // segmented without size is allowed (CiA 301): size stays 0
      break;
    case 2:
      s.command = SdoCommand::kInitiateUpload;
      decodeIndex(f, s);
      break;
    case 3:
      s.command = SdoCommand::kUploadSegment;
      s.toggle = (f.data[0] & 0x10) != 0;
      break;
    case 4:
      s.command = SdoCommand::kAbort;
      decodeIndex(f, s);
      s.abort_code = getU32(f, 4);
      break;
    default:
      return Result<SdoFrame>::failure("SDO request: client command specifier " + std::to_string(ccs) +
                                       (ccs == 5 || ccs == 6 ? " (block transfer) not supported" : " not valid"));
  }
  return Result<SdoFrame>::success(s);
}

Result<SdoFrame> decodeSdoResponse(const can_frame& f) {
  Result<SdoFrame> base = sdoCommon(f, kSdoTxBase, "SDO response");
  if (!base) return base;
  SdoFrame s = *base;
  const unsigned scs = f.data[0] >> 5;
  switch (scs) {
    case 0:
      s.command = SdoCommand::kUploadSegment;
      decodeSegment(f, s);
      break;
    case 1:
      s.command = SdoCommand::kDownloadSegment;
      s.toggle = (f.data[0] & 0x10) != 0;
      break;
    case 2:
      s.command = SdoCommand::kInitiateUpload;
      decodeInitiateData(f, s);
      break;
    case 3:
      s.command = SdoCommand::kInitiateDownload;
      decodeIndex(f, s);
      break;
    case 4:
      s.command = SdoCommand::kAbort;
      decodeIndex(f, s);
      s.abort_code = getU32(f, 4);
      break;
    default:
      return Result<SdoFrame>::failure("SDO response: server command specifier " + std::to_string(scs) +
                                       (scs == 5 || scs == 6 ? " (block transfer) not supported" : " not valid"));
  }
  return Result<SdoFrame>::success(s);
}

// --- PDO ---------------------------------------------------------------------

std::uint32_t encodeMappingEntry(const PdoEntry& e) {
  return (static_cast<std::uint32_t>(e.index) << 16) | (static_cast<std::uint32_t>(e.subindex) << 8) | e.bits;
}

PdoEntry decodeMappingEntry(std::uint32_t v) {
  return {static_cast<std::uint16_t>(v >> 16), static_cast<std::uint8_t>((v >> 8) & 0xFF),
          static_cast<std::uint8_t>(v & 0xFF)};
}

Result<unsigned> mappingBits(const PdoMapping& mapping) {
  unsigned total = 0;
  for (const PdoEntry& e : mapping) {
    if (e.bits == 0 || e.bits > 64) {
      return Result<unsigned>::failure("PDO mapping: object " + hex(e.index, 4) + ":" + std::to_string(e.subindex) +
                                       " has " + std::to_string(e.bits) + " bits");
    }
    total += e.bits;
  }
  if (total > 64) return Result<unsigned>::failure("PDO mapping: " + std::to_string(total) + " bits exceed 64");
  return Result<unsigned>::success(total);
}

Result<can_frame> packPdo(canid_t cob_id, const PdoMapping& mapping, const std::vector<std::uint64_t>& values) {
  const Result<unsigned> bits = mappingBits(mapping);
  if (!bits) return Result<can_frame>::failure(bits.error());
  if (values.size() != mapping.size()) {
    return Result<can_frame>::failure("PDO pack: " + std::to_string(values.size()) + " values for " +
                                      std::to_string(mapping.size()) + " mapped objects");
  }
  can_frame f{};
  f.can_id = cob_id & CAN_SFF_MASK;
  f.len = static_cast<std::uint8_t>((*bits + 7) / 8);
  unsigned pos = 0;
  for (std::size_t i = 0; i < mapping.size(); ++i) {
    for (unsigned b = 0; b < mapping[i].bits; ++b, ++pos) {
      if ((values[i] >> b) & 1u) f.data[pos / 8] |= static_cast<std::uint8_t>(1u << (pos % 8));
    }
  }
  return Result<can_frame>::success(f);
}

Result<std::vector<std::uint64_t>> unpackPdo(const can_frame& f, const PdoMapping& mapping) {
  using R = Result<std::vector<std::uint64_t>>;
  if (auto p = frameProblem(f); !p.empty()) return R::failure("PDO: " + p);
  const Result<unsigned> bits = mappingBits(mapping);
  if (!bits) return R::failure(bits.error());
  const unsigned bytes = (*bits + 7) / 8;
  if (f.len != bytes) {
    return R::failure("PDO " + hex(cob(f), 3) + ": DLC " + std::to_string(f.len) + " but " + std::to_string(bytes) +
                      " bytes mapped");
  }
  std::vector<std::uint64_t> out;
  unsigned pos = 0;
  for (const PdoEntry& e : mapping) {
    std::uint64_t v = 0;
    for (unsigned b = 0; b < e.bits; ++b, ++pos) {
      if ((f.data[pos / 8] >> (pos % 8)) & 1u) v |= std::uint64_t{1} << b;
    }
    out.push_back(v);
  }
  return R::success(out);
}

// --- values --------------------------------------------------------------------

std::vector<std::uint8_t> toBytes(std::uint64_t v, std::size_t bytes) {
  std::vector<std::uint8_t> out(bytes);
  for (std::size_t i = 0; i < bytes && i < 8; ++i) out[i] = static_cast<std::uint8_t>(v >> (8 * i));
  return out;
}

std::uint64_t fromBytes(const std::vector<std::uint8_t>& bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) v |= static_cast<std::uint64_t>(bytes[i]) << (8 * i);
  return v;
}

std::int64_t signExtend(std::uint64_t v, unsigned bits) {
  if (bits == 0 || bits >= 64) return static_cast<std::int64_t>(v);
  const std::uint64_t m = std::uint64_t{1} << (bits - 1);
  v &= (std::uint64_t{1} << bits) - 1;
  return static_cast<std::int64_t>((v ^ m) - m);
}

}  // namespace massage_cell::can
