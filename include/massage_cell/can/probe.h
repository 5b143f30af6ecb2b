// Bus scan for can_probe (layer 3 tool logic, kept in the library so it is
// tested on a VirtualBus): SDO upload of 0x1000 (device type) from each
// node id (a few requests in flight at once, so a SocketCAN transmit queue
// is not flooded), then for the nodes that answered 0x1008 (device name,
// segmented) and 0x6041 (statusword, CiA 402 drives only), while listening
// for heartbeats / boot-ups to report each node's NMT state.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "massage_cell/can/bus.h"
#include "massage_cell/can/canopen.h"

namespace massage_cell::can {

struct ProbeResult {
  std::uint8_t node = 0;
  std::uint32_t device_type = 0;
  std::optional<NmtState> nmt;              ///< from a heartbeat / boot-up seen during the scan
  std::optional<std::uint16_t> statusword;  ///< 0x6041, when the node has one
  std::string device_name;                  ///< 0x1008 (empty when it has none)
  std::string notes;                        ///< why a field is missing
};

struct ProbeOptions {
  std::vector<std::uint8_t> nodes;                        ///< ids to scan
  Duration sdo_timeout = std::chrono::milliseconds(100);  ///< per SDO frame
  Duration listen = std::chrono::milliseconds(500);       ///< minimum scan time (heartbeats)
  std::size_t in_flight = 8;                              ///< parallel requests
};

/// Scans the bus (real time: uses bus.receive with timeouts). Nodes that did
/// not answer 0x1000 are not in the result; results are sorted by node id.
std::vector<ProbeResult> probeNodes(Bus& bus, const ProbeOptions& options);

/// "1-127", "5", "1,3,10-12" -> ids; throws std::invalid_argument naming the bad part.
std::vector<std::uint8_t> parseNodeList(const std::string& text);

/// The table can_probe prints.
std::string formatProbeTable(const std::vector<ProbeResult>& results);

}  // namespace massage_cell::can
