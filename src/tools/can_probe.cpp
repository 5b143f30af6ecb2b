// can_probe: scans a SocketCAN bus for CANopen nodes (SDO upload of 0x1000
// and 0x1008, statusword 0x6041, NMT state from heartbeats) and prints a table.
#include <cstdio>

#include "cli.h"
#include "massage_cell/can/probe.h"
#include "massage_cell/can/socketcan_bus.h"

namespace {

using namespace massage_cell::can;
using namespace massage_cell::tools;

const char* const kUsage = R"(Usage: can_probe --interface IFACE [--nodes 1-127] [--timeout-ms 100] [--listen-ms 500]

Scans CANopen node ids on a SocketCAN interface: an SDO upload of 0x1000 (device
type) to each id (8 in flight at a time); for every node that answers, 0x1008
(device name) and 0x6041 (statusword, decoded as a CiA 402 state), plus the NMT
state from its heartbeat or boot-up seen during the scan.
  --interface IFACE   SocketCAN interface, e.g. vcan0 or can0 (required)
  --nodes LIST        node ids: 5, 1-127, 1,3,10-12 (default 1-127)
  --timeout-ms N      SDO response timeout per frame (default 100)
  --listen-ms N       minimum scan time, to catch heartbeats (default 500)
Exit status: 0 when a node answered, 3 when none did, 1 on an interface error,
2 on bad options.
)";

}  // namespace

int main(int argc, char** argv) {
  std::string interface;
  ProbeOptions options;
  options.nodes = parseNodeList("1-127");
  int found = 0;
  bool scanned = false;
  const int rc = runTool(
      "can_probe",
      [&] {
        OptionTable t;
        t.values["--interface"] = [&](const std::string&, const std::string& v) { interface = v; };
        t.values["--nodes"] = [&](const std::string& o, const std::string& v) {
          try {
            options.nodes = parseNodeList(v);
          } catch (const std::invalid_argument& e) {
            throw UsageError(o + ": " + e.what());
          }
        };
        t.values["--timeout-ms"] = [&](const std::string& o, const std::string& v) {
          const int ms = parseInt(o, v);
          require(ms >= 1 && ms <= 60000, o + ": must be 1..60000");
          options.sdo_timeout = std::chrono::milliseconds(ms);
        };
        t.values["--listen-ms"] = [&](const std::string& o, const std::string& v) {
          const int ms = parseInt(o, v);
          require(ms >= 0 && ms <= 600000, o + ": must be 0..600000");
          options.listen = std::chrono::milliseconds(ms);
        };
        if (!parseArguments(argc, argv, t, kUsage)) return false;
        require(!interface.empty(), "--interface is required (e.g. --interface vcan0)");
        return true;
      },
      [&] {
        SocketCanOptions o;
        o.interface = interface;
        SocketCanBus bus(o);  // throws BusError naming the interface
        const std::vector<ProbeResult> results = probeNodes(bus, options);
        found = static_cast<int>(results.size());
        scanned = true;
        if (results.empty()) {
          std::printf("can_probe: no CANopen node answered on %s (ids %d..%d)\n", interface.c_str(),
                      options.nodes.front(), options.nodes.back());
          return;
        }
        std::fputs(formatProbeTable(results).c_str(), stdout);
      });
  if (rc != 0 || !scanned) return rc;
  return found > 0 ? 0 : 3;
}
