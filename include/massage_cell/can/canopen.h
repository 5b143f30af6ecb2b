// CANopen frame codecs (layer 2; CiA 301 v4.2 subset): pure functions from
// messages to `can_frame`s and back. Decoders never throw: a wrong COB-ID,
// DLC or command specifier gives a failed Result naming the problem.
//
//  - NMT node control (COB-ID 0x000, CiA 301 §7.2.8.3.1)
//  - SYNC (0x080, optional 1-byte counter 1..240, §7.2.5)
//  - EMCY (0x080 + node, 8 bytes: error code, error register 0x1001,
//    5 manufacturer bytes, §7.2.7) and text for the error codes (§7.2.7.1
//    table 21, CiA 402-2 drive codes)
//  - heartbeat / boot-up (0x700 + node, 1 byte state, §7.2.8.3.2)
//  - SDO (client request 0x600 + node, server response 0x580 + node, 8
//    bytes, §7.2.4.3): expedited and segmented upload / download with toggle
//    bit, abort with the abort-code texts (§7.2.4.3.17 table 22)
//  - PDO pack / unpack of mapped objects (mapping entries as in 0x1600 /
//    0x1A00: index << 16 | sub-index << 8 | bit length; §7.2.2)
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "massage_cell/can/result.h"

namespace massage_cell::can {

// --- COB-IDs (pre-defined connection set, CiA 301 §7.3.5) ------------------
constexpr canid_t kNmtCobId = 0x000;
constexpr canid_t kSyncCobId = 0x080;
constexpr canid_t kEmcyBase = 0x080;
constexpr canid_t kTpdoBase[4] = {0x180, 0x280, 0x380, 0x480};
constexpr canid_t kRpdoBase[4] = {0x200, 0x300, 0x400, 0x500};
constexpr canid_t kSdoTxBase = 0x580;  ///< server -> client (responses)
constexpr canid_t kSdoRxBase = 0x600;  ///< client -> server (requests)
constexpr canid_t kHeartbeatBase = 0x700;

/// True for 1..127.
inline bool validNodeId(unsigned node) { return node >= 1 && node <= 127; }

/// What a COB-ID of the pre-defined connection set is.
enum class CobType { kNmt, kSync, kEmcy, kTpdo, kRpdo, kSdoResponse, kSdoRequest, kHeartbeat };
struct CobInfo {
  CobType type;
  std::uint8_t node = 0;  ///< 0 for NMT / SYNC
  int pdo = 0;            ///< 1..4 for PDOs
};
/// Classifies a frame by COB-ID; fails for extended / RTR / error frames and
/// ids outside the pre-defined connection set (e.g. 0x7E5 LSS, 0x100 TIME).
Result<CobInfo> classify(const can_frame& frame);
/// "NMT", "SYNC", "EMCY", "TPDO", "RPDO", "SDO response", "SDO request", "heartbeat".
const char* toString(CobType type);

// --- NMT ---------------------------------------------------------------------
enum class NmtCommand : std::uint8_t {
  kStart = 0x01,
  kStop = 0x02,
  kEnterPreOperational = 0x80,
  kResetNode = 0x81,
  kResetCommunication = 0x82,
};
const char* toString(NmtCommand command);
struct NmtMessage {
  NmtCommand command;
  std::uint8_t node;  ///< 0 = all nodes
};
/// 000#<cmd><node>; throws std::invalid_argument for node > 127.
can_frame encodeNmt(NmtCommand command, std::uint8_t node);
Result<NmtMessage> decodeNmt(const can_frame& frame);

// --- SYNC --------------------------------------------------------------------
/// 080# or 080#<counter>; throws std::invalid_argument for a counter outside 1..240.
can_frame encodeSync(std::optional<std::uint8_t> counter = std::nullopt);
Result<std::optional<std::uint8_t>> decodeSync(const can_frame& frame);

// --- NMT states, heartbeat, boot-up -----------------------------------------
enum class NmtState : std::uint8_t {
  kBootUp = 0x00,
  kStopped = 0x04,
  kOperational = 0x05,
  kPreOperational = 0x7F,
};
/// "boot-up", "stopped", "operational", "pre-operational".
const char* toString(NmtState state);
struct Heartbeat {
  std::uint8_t node;
  NmtState state;
};
/// 7xx#<state> (boot-up is state 0x00).
can_frame encodeHeartbeat(std::uint8_t node, NmtState state);
/// Fails on DLC != 1 or an unknown state (bit 7, the node-guarding toggle, is ignored).
Result<Heartbeat> decodeHeartbeat(const can_frame& frame);

// --- EMCY --------------------------------------------------------------------
struct Emcy {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;  ///< object 0x1001
  std::array<std::uint8_t, 5> manufacturer{};
};
struct EmcyMessage {
  std::uint8_t node;
  Emcy emcy;
};
can_frame encodeEmcy(std::uint8_t node, const Emcy& emcy);
/// Fails on DLC != 8 or a COB-ID that is not 0x081..0x0FF.
Result<EmcyMessage> decodeEmcy(const can_frame& frame);
/// Text of an EMCY error code: the exact CiA 301 / 402 meaning when known
/// ("following error" for 0x8611), else the error class ("monitoring (0x8xxx)").
std::string emcyText(std::uint16_t code);

// --- SDO ---------------------------------------------------------------------
/// SDO abort codes (CiA 301 table 22).
namespace sdo_abort {
constexpr std::uint32_t kToggleBit = 0x05030000;
constexpr std::uint32_t kTimeout = 0x05040000;
constexpr std::uint32_t kCommandSpecifier = 0x05040001;
constexpr std::uint32_t kOutOfMemory = 0x05040005;
constexpr std::uint32_t kUnsupportedAccess = 0x06010000;
constexpr std::uint32_t kWriteOnly = 0x06010001;
constexpr std::uint32_t kReadOnly = 0x06010002;
constexpr std::uint32_t kNoObject = 0x06020000;
constexpr std::uint32_t kNotMappable = 0x06040041;
constexpr std::uint32_t kPdoLength = 0x06040042;
constexpr std::uint32_t kHardware = 0x06060000;
constexpr std::uint32_t kLengthMismatch = 0x06070010;
constexpr std::uint32_t kLengthTooHigh = 0x06070012;
constexpr std::uint32_t kLengthTooLow = 0x06070013;
constexpr std::uint32_t kNoSubIndex = 0x06090011;
constexpr std::uint32_t kInvalidValue = 0x06090030;
constexpr std::uint32_t kValueTooHigh = 0x06090031;
constexpr std::uint32_t kValueTooLow = 0x06090032;
constexpr std::uint32_t kGeneral = 0x08000000;
constexpr std::uint32_t kDeviceState = 0x08000022;
}  // namespace sdo_abort
/// CiA 301 text of an abort code ("SDO protocol timed out"), or "unknown abort code".
std::string sdoAbortText(std::uint32_t code);

/// The SDO services of CiA 301 §7.2.4.3 this stack speaks (no block transfer).
enum class SdoCommand { kInitiateDownload, kDownloadSegment, kInitiateUpload, kUploadSegment, kAbort };
const char* toString(SdoCommand command);

/// One decoded SDO frame (request or response).
struct SdoFrame {
  std::uint8_t node = 0;
  SdoCommand command = SdoCommand::kAbort;
  std::uint16_t index = 0;         ///< initiate / abort
  std::uint8_t subindex = 0;       ///< initiate / abort
  bool expedited = false;          ///< initiate: e bit
  bool size_indicated = false;     ///< initiate: s bit
  std::uint32_t size = 0;          ///< initiate, segmented with s: total bytes
  bool toggle = false;             ///< segments: t bit
  bool last = false;               ///< segments: c bit (no more segments)
  std::vector<std::uint8_t> data;  ///< expedited data or segment data
  std::uint32_t abort_code = 0;    ///< abort
};

// Client -> server (COB-ID 0x600 + node). Throw std::invalid_argument on bad sizes.
/// Initiate download: expedited (with size) for 1..4 bytes, else segmented with the size indicated.
can_frame sdoInitiateDownloadRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                     const std::vector<std::uint8_t>& data);
/// Download segment with 0..7 bytes (padded to 8), toggle and last-segment bits.
can_frame sdoDownloadSegmentRequest(std::uint8_t node, bool toggle, const std::vector<std::uint8_t>& data, bool last);
can_frame sdoInitiateUploadRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
can_frame sdoUploadSegmentRequest(std::uint8_t node, bool toggle);
can_frame sdoAbortRequest(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code);

// Server -> client (COB-ID 0x580 + node).
can_frame sdoInitiateDownloadResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
can_frame sdoDownloadSegmentResponse(std::uint8_t node, bool toggle);
/// Expedited for 1..4 bytes, else a segmented initiate with the total size (data is not sent here).
can_frame sdoInitiateUploadResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                    const std::vector<std::uint8_t>& data);
can_frame sdoUploadSegmentResponse(std::uint8_t node, bool toggle, const std::vector<std::uint8_t>& data, bool last);
can_frame sdoAbortResponse(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code);

/// Decodes a client request (0x601..0x67F, DLC 8). Block transfer and
/// unknown command specifiers fail ("command specifier ... not valid").
Result<SdoFrame> decodeSdoRequest(const can_frame& frame);
/// Decodes a server response (0x581..0x5FF, DLC 8).
Result<SdoFrame> decodeSdoResponse(const can_frame& frame);

// --- PDO ---------------------------------------------------------------------
/// One mapped object.
struct PdoEntry {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::uint8_t bits = 0;  ///< 1..64
  bool operator==(const PdoEntry& o) const { return index == o.index && subindex == o.subindex && bits == o.bits; }
};
using PdoMapping = std::vector<PdoEntry>;
/// 0x1600/0x1A00 sub-index value: index << 16 | sub << 8 | bits.
std::uint32_t encodeMappingEntry(const PdoEntry& entry);
PdoEntry decodeMappingEntry(std::uint32_t value);
/// Total bits; fails when an entry has 0 or > 64 bits or the total exceeds 64.
Result<unsigned> mappingBits(const PdoMapping& mapping);
/// Packs values (low bits of each) LSB-first in mapping order into a frame of ceil(bits/8) bytes.
Result<can_frame> packPdo(canid_t cob_id, const PdoMapping& mapping, const std::vector<std::uint64_t>& values);
/// Unpacks the mapped values; fails unless the DLC equals the mapped length.
Result<std::vector<std::uint64_t>> unpackPdo(const can_frame& frame, const PdoMapping& mapping);

// --- little-endian values ----------------------------------------------------
/// The low `bytes` bytes of v, little-endian.
std::vector<std::uint8_t> toBytes(std::uint64_t v, std::size_t bytes);
/// Little-endian bytes (up to 8) to an unsigned value.
std::uint64_t fromBytes(const std::vector<std::uint8_t>& bytes);
/// Sign-extends the low `bits` bits of v.
std::int64_t signExtend(std::uint64_t v, unsigned bits);

}  // namespace massage_cell::can
