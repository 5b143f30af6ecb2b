// can_sim_drive: runs the simulated CiA 402 drives of a CAN config on a
// SocketCAN interface (one CAN_RAW socket and thread per drive) until
// SIGINT / SIGTERM, so a master (or can_probe, candump) can be tried
// against them on vcan0 without hardware.
// Test hook (opt-in, off by default): --fault-frame-id ID makes it listen for
// frames with that standard id, payload [node, code lo, code hi], and inject
// a drive fault with that EMCY error code into that node's drive
// (SimDrive::injectFault: EMCY, fault reaction -> fault). Used by
// can_kernel_system (ctest qemu_can_system), whose master runs in another
// process and cannot call injectFault directly.
// Body (opt-in, off by default): --body SKIN_Z puts a flat breathing back
// (arm::SimBody::flat, the default Tissue and Breathing) under the Z axis'
// drive as its external force (SimDrive::setExternalForce), as arm::SimCell
// does in-process, so a press by force can be tested against this process
// (can_kernel_force, ctest qemu_can_force).
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "cli.h"
#include "massage_cell/arm/sim_body.h"
#include "massage_cell/can/probe.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/socketcan_bus.h"

namespace {

using namespace massage_cell::can;
using namespace massage_cell::tools;

const char* const kUsage = R"(Usage: can_sim_drive --interface IFACE --config FILE [--nodes LIST] [--status-s N]
                     [--fault-frame-id ID] [--body SKIN_Z [--breathing-mm MM] [--body-axis NAME]]

Runs the simulated CANopen CiA 402 drives configured in FILE (config/can_axes.yaml
format: node ids, scale, sim.* settings) on the SocketCAN interface IFACE until
SIGINT or SIGTERM. Each drive boots (boot-up message), then answers NMT, SDO,
SYNC / PDOs and produces its heartbeat once 0x1017 is set.
  --interface IFACE   SocketCAN interface, e.g. vcan0 (required)
  --config FILE       CAN axes YAML (required)
  --nodes LIST        only these node ids, e.g. 1,3 or 1-2 (default: all in FILE)
  --status-s N        print each drive's state every N seconds (default 0: never)
  --fault-frame-id ID test hook, off by default: a frame with this standard id
                      (e.g. 0x6C0, outside CiA 301's predefined COB-IDs) and
                      payload [node, code lo, code hi] makes that node's drive
                      fail with EMCY error code `code` (then fault; a fault
                      reset clears it)
  --body SKIN_Z       off by default: a flat back under the tool, its skin at rest at
                      SKIN_Z m in the body axis' own physical frame (the frame of
                      sim.start_position / home_switch: Z positions, up +), pushes
                      that drive up (its external force: Hunt-Crossley tissue
                      F = 8.4e4 x^1.5 (1 + 0.5 dx/dt) N for an indentation x m
                      below the skin, breathing --breathing-mm over 4 s from this
                      process' start; arm/sim_body.h's defaults). Homed by its
                      switch as config/can_axes.yaml does (Z: method 18, offset
                      0.30 = home_switch), the drive's physical position is the Z
                      joint's position, so the skin is at tool z
                      SKIN_Z + tool_offset.z of config/arm.yaml (offset 0 there:
                      the tool's z itself), as arm::SimCell::setBody computes it
  --breathing-mm MM   with --body: breathing, mm peak to peak over 4 s (default 3; 0: still)
  --body-axis NAME    with --body: the axis (name in FILE) the body pushes (default Z)
Exit status: 0 after a signal, 1 on a configuration or interface error, 2 on bad options.
)";

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

}  // namespace

int main(int argc, char** argv) {
  std::string interface, config_path, nodes_text;
  int status_s = 0;
  canid_t fault_frame_id = 0;  // 0: no fault test hook
  double body_skin = NAN;      // NaN: no body
  double breathing_mm = massage_cell::arm::Breathing{}.amplitude * 1000.0;
  std::string body_axis = "Z";
  return runTool(
      "can_sim_drive",
      [&] {
        OptionTable t;
        t.values["--interface"] = [&](const std::string&, const std::string& v) { interface = v; };
        t.values["--config"] = [&](const std::string&, const std::string& v) { config_path = v; };
        t.values["--nodes"] = [&](const std::string&, const std::string& v) { nodes_text = v; };
        t.values["--status-s"] = [&](const std::string& o, const std::string& v) {
          status_s = parseInt(o, v);
          require(status_s >= 0, o + ": must be >= 0");
        };
        t.values["--fault-frame-id"] = [&](const std::string& o, const std::string& v) {
          char* end = nullptr;
          const unsigned long id = std::strtoul(v.c_str(), &end, 0);
          require(!v.empty() && *end == '\0' && id >= 1 && id <= CAN_SFF_MASK,
                  o + ": expected a standard CAN id 0x001..0x7FF, got '" + v + "'");
          fault_frame_id = static_cast<canid_t>(id);
        };
        t.values["--body"] = [&](const std::string& o, const std::string& v) { body_skin = parseDouble(o, v); };
        t.values["--breathing-mm"] = [&](const std::string& o, const std::string& v) {
          breathing_mm = parseDouble(o, v);
          require(breathing_mm >= 0.0, o + ": must be >= 0");
        };
        t.values["--body-axis"] = [&](const std::string&, const std::string& v) { body_axis = v; };
        if (!parseArguments(argc, argv, t, kUsage)) return false;
        require(!interface.empty(), "--interface is required (e.g. --interface vcan0)");
        require(!config_path.empty(), "--config is required (e.g. --config config/can_axes.yaml)");
        if (!nodes_text.empty()) {
          try {
            parseNodeList(nodes_text);
          } catch (const std::invalid_argument& e) {
            throw UsageError(std::string("--nodes: ") + e.what());
          }
        }
        return true;
      },
      [&] {
        const CanConfig config = loadCanConfig(config_path);
        std::vector<AxisConfig> axes;
        std::vector<std::uint8_t> wanted;
        if (!nodes_text.empty()) wanted = parseNodeList(nodes_text);
        for (const AxisConfig& a : config.axes) {
          if (wanted.empty() || std::find(wanted.begin(), wanted.end(), a.node_id) != wanted.end()) axes.push_back(a);
        }
        if (axes.empty())
          throw std::runtime_error("--nodes " + nodes_text + ": none of these nodes is in " + config_path);
        std::vector<std::unique_ptr<SocketCanBus>> buses;
        std::vector<std::unique_ptr<SimDrive>> drives;
        for (const AxisConfig& a : axes) {
          SocketCanOptions o;
          o.interface = interface;
          buses.push_back(std::make_unique<SocketCanBus>(o));  // throws BusError naming the interface
          drives.push_back(std::make_unique<SimDrive>(*buses.back(), SteadyClock::instance(), a));
        }
        if (!std::isnan(body_skin)) {
          const auto it =
              std::find_if(drives.begin(), drives.end(), [&](const auto& d) { return d->config().name == body_axis; });
          if (it == drives.end())
            throw std::runtime_error("--body: no axis named " + body_axis + " among this process' drives");
          massage_cell::arm::Breathing breathing;
          breathing.amplitude = breathing_mm / 1000.0;
          const auto body = std::make_shared<const massage_cell::arm::SimBody>(
              massage_cell::arm::SimBody::flat(body_skin, massage_cell::arm::Tissue{}, breathing));
          const TimePoint epoch = SteadyClock::instance().now();
          // Flat: x and y do not matter; z is the drive's physical position.
          (*it)->setExternalForce([body, epoch](double z, double vz) {
            const double t = std::chrono::duration<double>(SteadyClock::instance().now() - epoch).count();
            return body->force(Eigen::Vector3d(0.0, 0.0, z), vz, t);
          });
          std::printf(
              "can_sim_drive: node %d (%s): a flat back under it, skin at %.4f m (its physical frame), "
              "breathing %.1f mm peak to peak over %.0f s\n",
              (*it)->node(), body_axis.c_str(), body_skin, breathing_mm, breathing.period);
        }
        std::signal(SIGINT, onSignal);
        std::signal(SIGTERM, onSignal);
        std::vector<std::thread> threads;
        for (auto& d : drives) {
          d->powerOn();
          threads.emplace_back([&d] { d->run(g_stop); });
          std::printf("can_sim_drive: node %d (%s) on %s: booted\n", d->node(), d->config().name.c_str(),
                      interface.c_str());
        }
        // The fault test hook: its own socket, receiving only its id.
        std::unique_ptr<SocketCanBus> fault_bus;
        if (fault_frame_id) {
          SocketCanOptions o;
          o.interface = interface;
          o.filters = {can_filter{fault_frame_id, CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK}};
          fault_bus = std::make_unique<SocketCanBus>(o);
          std::printf("can_sim_drive: fault test hook on id 0x%03X\n", static_cast<unsigned>(fault_frame_id));
        }
        std::fflush(stdout);
        auto last = std::chrono::steady_clock::now();
        while (!g_stop) {
          if (!fault_bus) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
          } else if (const auto f = fault_bus->receive(std::chrono::milliseconds(50))) {
            const can_frame& fr = f->frame;
            const auto it = std::find_if(drives.begin(), drives.end(),
                                         [&](const auto& d) { return fr.len >= 3 && d->node() == fr.data[0]; });
            if (it == drives.end()) {
              std::printf(
                  "can_sim_drive: fault test frame %s ignored (expected [node, code lo, code hi] of one of "
                  "this process's nodes)\n",
                  formatFrame(fr).c_str());
            } else {
              const auto code = static_cast<std::uint16_t>(fr.data[1] | fr.data[2] << 8);
              (*it)->injectFault(code);
              std::printf("can_sim_drive: node %d: fault 0x%04X injected (test frame %s)\n", (*it)->node(), code,
                          formatFrame(fr).c_str());
            }
            std::fflush(stdout);
          }
          if (status_s > 0 && std::chrono::steady_clock::now() - last >= std::chrono::seconds(status_s)) {
            last = std::chrono::steady_clock::now();
            for (std::size_t i = 0; i < drives.size(); ++i) {
              const SimDrive& d = *drives[i];
              const BusStatus bs = buses[i]->status();
              std::printf("node %d: NMT %s, %s, position %d counts, bus %s (tx %llu rx %llu)", d.node(),
                          toString(d.nmtState()), toString(d.state()), d.position(), toString(bs.state),
                          static_cast<unsigned long long>(bs.tx_frames), static_cast<unsigned long long>(bs.rx_frames));
              if (!std::isnan(body_skin) && d.config().name == body_axis)
                std::printf(", body force %.2f N (physical position %.5f m)", d.externalForce(), d.physicalPosition());
              std::printf("\n");
            }
            std::fflush(stdout);
          }
        }
        for (auto& t : threads) t.join();
        std::printf("can_sim_drive: stopped\n");
      });
}
