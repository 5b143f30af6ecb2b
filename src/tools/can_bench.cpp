// can_bench: timing of the CAN stack on the in-process virtual bus, with the
// master and one simulated drive in their own threads on the real clock (as
// a node would run them): SDO round trip, SYNC period and SYNC -> TPDO
// latency, and the time from an injected drive fault to the master's EMCY
// event and to the axis seeing the fault state.
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <future>
#include <thread>

#include "cli.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/socketcan_bus.h"
#include "massage_cell/can/virtual_bus.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::can;
using namespace massage_cell::tools;
using Ms = std::chrono::duration<double, std::milli>;

const char* const kUsage = R"(Usage: can_bench [--samples N] [--faults N] [--sync-ms N] [--config FILE] [--interface IFACE] [--csv]

Times the CAN stack on the in-process virtual bus (or, with --interface, over
SocketCAN: one CAN_RAW socket each for the master, the drive and the sniffer):
the master (its own thread) and the first axis of FILE as a simulated drive
(its own thread), real clock.
  SDO round trip      N expedited uploads of 0x6041, one after the other
  SYNC period         SYNC-to-SYNC intervals as sent by the master (N)
  SYNC -> TPDO1       time from each SYNC to the drive's TPDO1 on the bus (N)
  fault -> EMCY       injected drive fault to the master's EMCY event (--faults)
  fault -> axis       injected drive fault to the axis reporting 'fault' (TPDO1)
  --samples N   default 500        --faults N   default 20
  --sync-ms N   SYNC period, default 10
  --config FILE default config/can_axes.yaml of the source tree
  --interface IFACE  run over this SocketCAN interface (e.g. vcan0) instead
  --csv         print metric,value,unit rows instead of the table
)";

struct Stats {
  std::size_t n = 0;
  double p50 = 0, p99 = 0, max = 0;
};

Stats stats(std::vector<double> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.p50 = v[v.size() / 2];
  s.p99 = v[std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(v.size()))) - 1)];
  s.max = v.back();
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  int samples = 500, faults = 20, sync_ms = 10;
  bool csv = false;
  std::string interface;
  std::string config_path = std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml";
  return runTool(
      "can_bench",
      [&] {
        OptionTable t;
        t.values["--samples"] = [&](const std::string& o, const std::string& v) {
          samples = parseInt(o, v);
          require(samples >= 10 && samples <= 100000, o + ": must be 10..100000");
        };
        t.values["--faults"] = [&](const std::string& o, const std::string& v) {
          faults = parseInt(o, v);
          require(faults >= 1 && faults <= 10000, o + ": must be 1..10000");
        };
        t.values["--sync-ms"] = [&](const std::string& o, const std::string& v) {
          sync_ms = parseInt(o, v);
          require(sync_ms >= 1 && sync_ms <= 1000, o + ": must be 1..1000");
        };
        t.values["--config"] = [&](const std::string&, const std::string& v) { config_path = v; };
        t.values["--interface"] = [&](const std::string&, const std::string& v) { interface = v; };
        t.flags["--csv"] = [&] { csv = true; };
        return parseArguments(argc, argv, t, kUsage);
      },
      [&] {
        CanConfig config = loadCanConfig(config_path);
        config.axes.resize(1);
        config.sync_period_us = static_cast<std::uint32_t>(sync_ms) * 1000u;
        const AxisConfig& a = config.axes[0];
        const Clock& clock = SteadyClock::instance();
        VirtualBus vbus(clock, 1 << 16);
        std::shared_ptr<Bus> mep, dep, sniff;
        if (interface.empty()) {
          mep = vbus.open("master");
          dep = vbus.open("drive");
          sniff = vbus.open("sniffer");
        } else {
          SocketCanOptions o;
          o.interface = interface;
          mep = std::make_shared<SocketCanBus>(o);
          dep = std::make_shared<SocketCanBus>(o);
          sniff = std::make_shared<SocketCanBus>(o);
        }
        Master master(*mep, clock, config);
        Cia402Axis axis(master, a);
        SimDrive drive(*dep, clock, a);
        std::atomic<bool> stop{false};
        std::thread drive_thread([&] { drive.run(stop, std::chrono::microseconds(500)); });
        drive.powerOn();
        master.start();
        master.bringUp();
        if (!master.waitUntil([&] { return master.allOperational() && axis.valid(); }, std::chrono::seconds(5))) {
          stop = true;
          drive_thread.join();
          throw std::runtime_error("the simulated drive did not come up");
        }

        // SDO round trip.
        std::vector<double> sdo;
        for (int i = 0; i < samples; ++i) {
          std::promise<std::chrono::steady_clock::time_point> done;
          auto fut = done.get_future();
          const auto t0 = std::chrono::steady_clock::now();
          master.sdoUpload(a.node_id, 0x6041, 0, [&](const SdoResult& r) {
            if (r.ok) done.set_value(std::chrono::steady_clock::now());
            else done.set_exception(std::make_exception_ptr(std::runtime_error(r.error)));
          });
          sdo.push_back(Ms(fut.get() - t0).count());
        }

        // SYNC period and SYNC -> TPDO1 (bus stamps of the sniffer endpoint).
        while (sniff->receive(Duration::zero())) {
        }
        std::vector<double> period, latency;
        std::optional<TimePoint> last_sync;
        const canid_t tpdo = kTpdoBase[0] + a.node_id;
        while (static_cast<int>(period.size()) < samples) {
          auto f = sniff->receive(std::chrono::seconds(1));
          if (!f) throw std::runtime_error("no SYNC on the bus");
          if (f->frame.can_id == kSyncCobId) {
            if (last_sync) period.push_back(Ms(f->stamp - *last_sync).count());
            last_sync = f->stamp;
          } else if (f->frame.can_id == tpdo && last_sync) {
            latency.push_back(Ms(f->stamp - *last_sync).count());
          }
        }

        // Injected fault -> EMCY event / axis fault state.
        std::mutex m;
        std::condition_variable cv;
        std::optional<std::chrono::steady_clock::time_point> emcy_at;
        master.setEventCallback([&](const Event& e) {
          if (e.type == EventType::kEmcy && e.emcy_code == 0x2310) {
            std::lock_guard<std::mutex> l(m);
            emcy_at = std::chrono::steady_clock::now();
            cv.notify_all();
          }
        });
        std::vector<double> to_emcy, to_state;
        for (int i = 0; i < faults; ++i) {
          {
            std::lock_guard<std::mutex> l(m);
            emcy_at.reset();
          }
          const auto t0 = std::chrono::steady_clock::now();
          drive.injectFault(0x2310);
          if (!master.waitUntil([&] { return axis.state() == Cia402State::kFault; }, std::chrono::seconds(2))) {
            throw std::runtime_error("the axis did not report the injected fault");
          }
          to_state.push_back(Ms(std::chrono::steady_clock::now() - t0).count());
          {
            std::unique_lock<std::mutex> l(m);
            if (!cv.wait_for(l, std::chrono::seconds(2), [&] { return emcy_at.has_value(); })) {
              throw std::runtime_error("no EMCY event for the injected fault");
            }
            to_emcy.push_back(Ms(*emcy_at - t0).count());
          }
          axis.faultReset();
          if (!master.waitUntil([&] { return axis.status() != Cia402Axis::Status::kRunning; }, std::chrono::seconds(2)) ||
              axis.status() != Cia402Axis::Status::kSucceeded) {
            throw std::runtime_error("fault reset failed: " + axis.error());
          }
        }
        master.setEventCallback({});
        master.stop();
        stop = true;
        drive_thread.join();

        struct Row {
          const char* key;
          const char* label;
          Stats s;
        };
        const Row rows[] = {
            {"sdo_round_trip", "SDO expedited upload round trip", stats(sdo)},
            {"sync_period", "SYNC period", stats(period)},
            {"sync_to_tpdo1", "SYNC -> TPDO1 on the bus", stats(latency)},
            {"fault_to_emcy_event", "injected fault -> master EMCY event", stats(to_emcy)},
            {"fault_to_axis_fault", "injected fault -> axis state 'fault'", stats(to_state)},
        };
        if (csv) {
          std::printf("metric,value,unit\n");
          for (const Row& r : rows) {
            std::printf("%s_p50,%.4f,ms\n%s_p99,%.4f,ms\n%s_max,%.4f,ms\n%s_samples,%zu,count\n", r.key, r.s.p50, r.key,
                        r.s.p99, r.key, r.s.max, r.key, r.s.n);
          }
          return;
        }
        std::printf("can_bench: %s, master + simulated drive (node %d) in threads, SYNC %d ms, real clock\n",
                    interface.empty() ? "virtual bus" : ("SocketCAN " + interface).c_str(), a.node_id, sync_ms);
        std::printf("%-40s %7s %10s %10s %10s\n", "", "n", "p50 ms", "p99 ms", "max ms");
        for (const Row& r : rows) {
          std::printf("%-40s %7zu %10.3f %10.3f %10.3f\n", r.label, r.s.n, r.s.p50, r.s.p99, r.s.max);
        }
      });
}
