// can_bench: timing of the CAN stack on the in-process virtual bus, with the
// master and one simulated drive in their own threads on the real clock (as
// a node would run them): SDO round trip, SYNC period and SYNC -> TPDO
// latency, the master's heartbeat period, and the time from an injected
// drive fault to the master's EMCY event and to the axis seeing the fault
// state.
// With --interface the same runs over Linux SocketCAN (vcan0 in the qemu
// guest: ctest qemu_can_bench): master, drive and sniffer each get their own
// CAN_RAW socket in this one process, so every frame goes through the kernel
// (af_can loopback) while the drive's fault can still be injected at a known
// instant (SimDrive::injectFault) for the fault -> EMCY / axis timings.
// The table ends with `CAN_BENCH OK` when every sample was collected (and,
// with --max-p99-ms, within the limits); any failure prints
// `CAN_BENCH FAIL: <why>` and exits 1.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cli.h"
#include "massage_cell/can/cia402.h"
#include "massage_cell/can/sim_drive.h"
#include "massage_cell/can/socketcan_bus.h"
#include "massage_cell/can/virtual_bus.h"
#include "package_paths.h"

namespace {

using namespace massage_cell::can;
using namespace massage_cell::tools;
using Ms = std::chrono::duration<double, std::milli>;

const char* const kUsage =
    R"(Usage: can_bench [--samples N] [--faults N] [--sync-ms N] [--config FILE] [--interface IFACE]
                 [--sdo-timeout-ms N] [--heartbeat-timeout-ms N] [--max-p99-ms X] [--csv]

Times the CAN stack on the in-process virtual bus (or, with --interface, over
SocketCAN: one CAN_RAW socket each for the master, the drive and the sniffer):
the master (its own thread) and the first axis of FILE as a simulated drive
(its own thread), real clock.
  SDO round trip      N expedited uploads of 0x6041, one after the other
  SYNC period         SYNC-to-SYNC intervals as sent by the master (N)
  SYNC -> TPDO1       time from each SYNC to the drive's TPDO1 answering it (N)
  heartbeat period    the master's own heartbeat (bus.master_heartbeat_ms), meanwhile
  fault -> EMCY       injected drive fault to the master's EMCY event (--faults)
  fault -> axis       injected drive fault to the axis reporting 'fault' (TPDO1)
  --samples N   default 500        --faults N   default 20
  --sync-ms N   SYNC period, default 10
  --config FILE default the package's config/can_axes.yaml
  --interface IFACE  run over this SocketCAN interface (e.g. vcan0) instead
  --sdo-timeout-ms N        SDO timeout (default: the config's bus.sdo_timeout_ms)
  --heartbeat-timeout-ms N  the master's consumer timeout of the drive's heartbeat
                            (default: the config's); raise both on a slow machine
  --max-p99-ms X  also fail when the p99 of the SDO round trip, SYNC -> TPDO1 or
                  fault -> EMCY exceeds X ms, or the SYNC period's median is more
                  than 10 % off (default: no limits)
  --csv         print metric,value,unit rows instead of the table
The table ends with the line `CAN_BENCH OK`; a failure prints `CAN_BENCH FAIL: ...`
and exits 1.
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

struct Options {
  int samples = 500, faults = 20, sync_ms = 10, sdo_timeout_ms = 0, heartbeat_timeout_ms = 0;
  double max_p99_ms = 0.0;
  bool csv = false;
  std::string interface;
  std::string config_path;  // default: the package's config/can_axes.yaml
};

OptionTable optionTable(Options& o) {
  OptionTable t;
  auto bounded = [&t](const char* name, int* value, int lo, int hi) {
    t.values[name] = [value, lo, hi](const std::string& opt, const std::string& v) {
      *value = parseInt(opt, v);
      require(*value >= lo && *value <= hi, opt + ": must be " + std::to_string(lo) + ".." + std::to_string(hi));
    };
  };
  bounded("--samples", &o.samples, 10, 100000);
  bounded("--faults", &o.faults, 1, 10000);
  bounded("--sync-ms", &o.sync_ms, 1, 1000);
  bounded("--sdo-timeout-ms", &o.sdo_timeout_ms, 1, 60000);
  bounded("--heartbeat-timeout-ms", &o.heartbeat_timeout_ms, 1, 600000);
  t.values["--max-p99-ms"] = [&o](const std::string& opt, const std::string& v) {
    o.max_p99_ms = parseDouble(opt, v);
    require(o.max_p99_ms > 0, opt + ": must be > 0");
  };
  t.values["--config"] = [&o](const std::string&, const std::string& v) { o.config_path = v; };
  t.values["--interface"] = [&o](const std::string&, const std::string& v) { o.interface = v; };
  t.flags["--csv"] = [&o] { o.csv = true; };
  return t;
}

/// The configuration's first axis alone, with the options' SYNC period and timeouts; validated.
CanConfig benchConfig(Options& o) {
  if (o.config_path.empty()) o.config_path = packageFile("config/can_axes.yaml");
  CanConfig config = loadCanConfig(o.config_path);
  config.axes.resize(1);
  config.sync_period_us = static_cast<std::uint32_t>(o.sync_ms) * 1000u;
  if (o.sdo_timeout_ms > 0) config.sdo_timeout_ms = static_cast<std::uint32_t>(o.sdo_timeout_ms);
  if (o.heartbeat_timeout_ms > 0) {
    if (static_cast<std::uint32_t>(o.heartbeat_timeout_ms) <= config.axes[0].heartbeat_ms) {
      throw std::runtime_error("--heartbeat-timeout-ms " + std::to_string(o.heartbeat_timeout_ms) +
                               ": must be longer than the drive's heartbeat_ms (" +
                               std::to_string(config.axes[0].heartbeat_ms) + ")");
    }
    config.axes[0].heartbeat_timeout_ms = static_cast<std::uint32_t>(o.heartbeat_timeout_ms);
  }
  validate(config, o.config_path);
  return config;
}

/// Master, CiA 402 axis and simulated drive (its own thread) on one bus - the virtual one or a SocketCAN
/// interface - and a sniffer endpoint on it; the drive's thread stops with the bench.
class Bench {
 public:
  Bench(const CanConfig& config, const std::string& interface)
      : config_(config), a_(config.axes[0]), clock_(SteadyClock::instance()), vbus_(clock_, 1 << 16) {
    if (interface.empty()) {
      mep_ = vbus_.open("master");
      dep_ = vbus_.open("drive");
      sniff_ = vbus_.open("sniffer");
    } else {
      SocketCanOptions o;
      o.interface = interface;
      mep_ = std::make_shared<SocketCanBus>(o);
      dep_ = std::make_shared<SocketCanBus>(o);
      sniff_ = std::make_shared<SocketCanBus>(o);
    }
    master_ = std::make_unique<Master>(*mep_, clock_, config_);
    axis_ = std::make_unique<Cia402Axis>(*master_, a_);
    drive_ = std::make_unique<SimDrive>(*dep_, clock_, a_);
    drive_thread_ = std::thread([this] { drive_->run(stop_, std::chrono::microseconds(500)); });
  }
  ~Bench() { stop(); }  // a failure must not leave the threads running (std::terminate)

  void stop() {
    master_->stop();
    stop_ = true;
    if (drive_thread_.joinable()) drive_thread_.join();
  }

  void bringUp() {
    drive_->powerOn();
    master_->start();
    master_->bringUp();
    if (!master_->waitUntil([&] { return master_->allOperational() && axis_->valid(); }, std::chrono::seconds(5))) {
      throw std::runtime_error("the simulated drive did not come up within 5 s (node " +
                               std::string(toString(master_->nodeState(a_.node_id))) + ")");
    }
  }

  /// SDO expedited upload round trips (statusword), ms.
  std::vector<double> sdoRoundTrips(int samples) {
    std::vector<double> sdo;
    for (int i = 0; i < samples; ++i) {
      std::promise<std::chrono::steady_clock::time_point> done;
      auto fut = done.get_future();
      const auto t0 = std::chrono::steady_clock::now();
      master_->sdoUpload(a_.node_id, 0x6041, 0, [&](const SdoResult& r) {
        if (r.ok)
          done.set_value(std::chrono::steady_clock::now());
        else
          done.set_exception(std::make_exception_ptr(std::runtime_error(r.error)));
      });
      sdo.push_back(Ms(fut.get() - t0).count());
    }
    return sdo;
  }

  /// SYNC period, SYNC -> TPDO1 and the master's heartbeat period (bus stamps of the sniffer endpoint), ms. The
  /// drive answers every SYNC with one TPDO1 (transmission type 1), so the k-th TPDO1 after a SYNC belongs to the
  /// k-th SYNC still unanswered, even when an answer takes longer than a SYNC period.
  void syncTiming(int samples, std::vector<double>* period, std::vector<double>* latency,
                  std::vector<double>* heartbeat) {
    while (sniff_->receive(Duration::zero())) {
    }
    std::optional<TimePoint> last_sync, last_heartbeat;
    std::deque<TimePoint> unanswered;
    const canid_t tpdo = kTpdoBase[0] + a_.node_id;
    const canid_t own_heartbeat = kHeartbeatBase + config_.master_node_id;
    while (static_cast<int>(period->size()) < samples) {
      auto f = sniff_->receive(std::chrono::seconds(1));
      if (!f) throw std::runtime_error("no SYNC on the bus for 1 s");
      if (f->frame.can_id == kSyncCobId) {
        if (last_sync) period->push_back(Ms(f->stamp - *last_sync).count());
        last_sync = f->stamp;
        unanswered.push_back(f->stamp);
      } else if (f->frame.can_id == tpdo && !unanswered.empty()) {
        latency->push_back(Ms(f->stamp - unanswered.front()).count());
        unanswered.pop_front();
      } else if (f->frame.can_id == own_heartbeat) {
        if (last_heartbeat) heartbeat->push_back(Ms(f->stamp - *last_heartbeat).count());
        last_heartbeat = f->stamp;
      }
    }
    // A SYNC the drive never answered stays unanswered; more than the last few means lost TPDO1s.
    if (unanswered.size() > 3 || static_cast<int>(latency->size()) < samples - 3) {
      throw std::runtime_error(std::to_string(samples + 1) + " SYNCs but only " + std::to_string(latency->size()) +
                               " TPDO1 answers");
    }
    if (config_.master_heartbeat_ms > 0 && heartbeat->empty()) {
      char cob[16];
      std::snprintf(cob, sizeof cob, "0x%03X", static_cast<unsigned>(own_heartbeat));
      throw std::runtime_error(std::string("no heartbeat of the master (COB-ID ") + cob + ") during " +
                               std::to_string(samples) + " SYNC periods");
    }
  }

  /// Injected drive faults -> the master's EMCY event and the axis' fault state, ms; each fault reset.
  void faultTimes(int faults, std::vector<double>* to_emcy, std::vector<double>* to_state) {
    std::mutex m;
    std::condition_variable cv;
    std::optional<std::chrono::steady_clock::time_point> emcy_at;
    master_->setEventCallback([&](const Event& e) {
      if (e.type == EventType::kEmcy && e.emcy_code == 0x2310) {
        std::lock_guard<std::mutex> l(m);
        emcy_at = std::chrono::steady_clock::now();
        cv.notify_all();
      }
    });
    for (int i = 0; i < faults; ++i) {
      {
        std::lock_guard<std::mutex> l(m);
        emcy_at.reset();
      }
      const auto t0 = std::chrono::steady_clock::now();
      drive_->injectFault(0x2310);
      if (!master_->waitUntil([&] { return axis_->state() == Cia402State::kFault; }, std::chrono::seconds(2))) {
        throw std::runtime_error("the axis did not report the injected fault");
      }
      to_state->push_back(Ms(std::chrono::steady_clock::now() - t0).count());
      {
        std::unique_lock<std::mutex> l(m);
        if (!cv.wait_for(l, std::chrono::seconds(2), [&] { return emcy_at.has_value(); })) {
          throw std::runtime_error("no EMCY event for the injected fault");
        }
        to_emcy->push_back(Ms(*emcy_at - t0).count());
      }
      axis_->faultReset();
      if (!master_->waitUntil([&] { return axis_->status() != Cia402Axis::Status::kRunning; },
                              std::chrono::seconds(2)) ||
          axis_->status() != Cia402Axis::Status::kSucceeded) {
        throw std::runtime_error("fault reset failed: " + axis_->error());
      }
    }
    master_->setEventCallback({});
  }

 private:
  const CanConfig& config_;
  const AxisConfig& a_;
  const Clock& clock_;
  VirtualBus vbus_;
  std::shared_ptr<Bus> mep_, dep_, sniff_;
  std::unique_ptr<Master> master_;
  std::unique_ptr<Cia402Axis> axis_;
  std::unique_ptr<SimDrive> drive_;
  std::atomic<bool> stop_{false};
  std::thread drive_thread_;
};

struct Row {
  const char* key;
  const char* label;
  Stats s;
};

/// The rows over the limits (--max-p99-ms: SDO, SYNC -> TPDO1, fault -> EMCY; the SYNC period within 10 %).
std::string overTheLimits(const Options& o, const std::vector<Row>& rows) {
  std::string over;
  if (o.max_p99_ms <= 0) return over;
  for (const Row* r : {&rows[0], &rows[2], &rows[4]}) {
    if (r->s.p99 > o.max_p99_ms) over += std::string(" ") + r->label + " p99 " + std::to_string(r->s.p99) + " ms;";
  }
  if (std::fabs(rows[1].s.p50 - o.sync_ms) > 0.1 * o.sync_ms) {
    over += " SYNC period median " + std::to_string(rows[1].s.p50) + " ms, configured " + std::to_string(o.sync_ms) +
            " ms;";
  }
  return over;
}

void report(const Options& o, const CanConfig& config, const std::vector<Row>& rows) {
  const std::string over = overTheLimits(o, rows);
  if (o.csv) {
    std::printf("metric,value,unit\n");
    for (const Row& r : rows) {
      std::printf("%s_p50,%.4f,ms\n%s_p99,%.4f,ms\n%s_max,%.4f,ms\n%s_samples,%zu,count\n", r.key, r.s.p50, r.key,
                  r.s.p99, r.key, r.s.max, r.key, r.s.n);
    }
    if (!over.empty()) throw std::runtime_error("over the limits:" + over);
    return;
  }
  const AxisConfig& a = config.axes[0];
  std::printf(
      "can_bench: %s, master + simulated drive (node %d) in threads, SYNC %d ms, real clock; "
      "SDO timeout %u ms, heartbeat consumer %u ms\n",
      o.interface.empty() ? "virtual bus" : ("SocketCAN " + o.interface).c_str(), a.node_id, o.sync_ms,
      config.sdo_timeout_ms, a.heartbeatTimeoutMs());
  std::printf("%-40s %7s %10s %10s %10s\n", "", "n", "p50 ms", "p99 ms", "max ms");
  for (const Row& r : rows) std::printf("%-40s %7zu %10.3f %10.3f %10.3f\n", r.label, r.s.n, r.s.p50, r.s.p99, r.s.max);
  if (!over.empty())
    throw std::runtime_error("over the limits (--max-p99-ms " + std::to_string(o.max_p99_ms) + "):" + over);
  std::printf("CAN_BENCH OK\n");
  std::fflush(stdout);
}

void run(Options& o) {
  const CanConfig config = benchConfig(o);
  Bench bench(config, o.interface);
  bench.bringUp();
  const std::vector<double> sdo = bench.sdoRoundTrips(o.samples);
  std::vector<double> period, latency, heartbeat, to_emcy, to_state;
  bench.syncTiming(o.samples, &period, &latency, &heartbeat);
  bench.faultTimes(o.faults, &to_emcy, &to_state);
  bench.stop();
  const std::vector<Row> rows{
      {"sdo_round_trip", "SDO expedited upload round trip", stats(sdo)},
      {"sync_period", "SYNC period", stats(period)},
      {"sync_to_tpdo1", "SYNC -> TPDO1 on the bus", stats(latency)},
      {"heartbeat_period", "master heartbeat period", stats(heartbeat)},
      {"fault_to_emcy_event", "injected fault -> master EMCY event", stats(to_emcy)},
      {"fault_to_axis_fault", "injected fault -> axis state 'fault'", stats(to_state)},
  };
  report(o, config, rows);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return runTool(
      "can_bench",
      [&] {
        OptionTable t = optionTable(o);
        return parseArguments(argc, argv, t, kUsage);
      },
      [&] {
        try {
          run(o);
        } catch (const std::exception& e) {
          if (!o.csv) {
            std::printf("CAN_BENCH FAIL: %s\n", e.what());
            std::fflush(stdout);
          }
          throw;
        }
      });
}
