// arm_bench: the arm controller against simulated drives on the in-process
// virtual bus (the arm node's can_interface "sim"), real clock, master and
// drives in their own threads: the controller cycle's jitter at the SYNC
// rate while the arm keeps moving, the e-stop -> quick-stop frame latency,
// and the final position error of moves.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <random>
#include <thread>

#include "cli.h"
#include "massage_cell/arm/sim_cell.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using namespace massage_cell::tools;
using Clock = std::chrono::steady_clock;
using Ms = std::chrono::duration<double, std::milli>;

const char* const kUsage =
    R"(Usage: arm_bench [--duration S] [--estops N] [--moves N] [--config FILE] [--seed N] [--rt-priority P] [--lock-memory] [--csv]

Runs the arm controller on simulated CiA 402 drives (in-process virtual bus,
real clock; master and drives in their own threads, as the arm node's
can_interface "sim"), homes it (drives configured to home in place), then:
  cycle jitter     |interval - SYNC period| between controller cycles over
                   --duration seconds while the arm moves between random
                   points of the workspace (p50 / p99 / max)
  e-stop latency   setEstop(true) -> the quick-stop RPDO1 on the bus, over N
                   e-stops during moves (max); also -> every drive stopping
  move error       distance between the goal and where the simulated drives
                   stand after N moves of up to 0.15 m per axis (max)
  --duration S  default 60          --estops N  default 20
  --moves N     default 20          --seed N    default 1
  --config FILE default the package's config/arm.yaml
  --rt-priority P  run the master and drive threads under SCHED_FIFO priority P
                (1..99; 0 = normal scheduling, the default), as the arm node's
                realtime_priority does (same library code); a refusal (no
                privilege) is reported and the bench runs with normal scheduling
  --lock-memory mlockall(MCL_CURRENT | MCL_FUTURE) first, as the node's lock_memory
  --csv         print metric,value,unit rows instead of the table
Targets: cycle jitter p99 <= 2 ms, e-stop -> quick-stop frame <= 10 ms, move error <= 0.1 mm.
)";

struct Options {
  double duration = 60.0;
  int estops = 20;
  int moves = 20;
  std::string config;  // default: the package's config/arm.yaml
  std::uint32_t seed = 1;
  int rt_priority = 0;
  bool lock_memory = false;
  bool csv = false;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

/// Waits (real time) until pred holds; throws with `what` on timeout.
template <typename Pred>
void waitFor(Pred pred, double seconds, const std::string& what) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  while (!pred()) {
    if (Clock::now() > deadline) throw std::runtime_error("timed out waiting for " + what);
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

/// Runs a command to its end; throws with the controller's message on refusal or failure.
void run(arm::Controller& c, const arm::Accepted& a, const std::string& what, double seconds = 60.0) {
  if (!a) throw std::runtime_error(what + " refused: " + a.error);
  waitFor([&] { return c.result(a.id).done; }, seconds, what);
  const arm::CommandResult r = c.result(a.id);
  if (!r.success) throw std::runtime_error(what + " failed: " + r.message);
}

/// A random point of the workspace envelope within `reach` of `from` on every axis.
Eigen::Vector3d randomPoint(const arm::ArmConfig& c, std::mt19937& rng, const Eigen::Vector3d& from, double reach) {
  Eigen::Vector3d p;
  for (int k = 0; k < 3; ++k) {
    std::uniform_real_distribution<double> d(std::max(c.workspace_min[k], from[k] - reach),
                                             std::min(c.workspace_max[k], from[k] + reach));
    p[k] = d(rng);
  }
  return p;
}

/// The arm node's controller on simulated drives (the node's code path: can_interface sim, realtime_priority,
/// lock_memory), homed in place, with the node's keep-alive timer, a sniffer on the bus and its cycles recorded.
class ArmBench {
 public:
  explicit ArmBench(const arm::ArmConfig& config) : config_(config), cell_(config_), c_(cell_.controller()) {
    period_ms_ = config_.can.sync_period_us / 1000.0;
    sniffer_ = cell_.bus().open("arm_bench sniffer");
    sniffer_->setFilters({{0x200, 0x780}});  // RPDO1 of every node
    c_.setCycleObserver([this](can::TimePoint now) {
      if (!recording_) return;
      std::lock_guard<std::mutex> lock(cycle_mutex_);
      cycles_.push_back(now);
    });
    keep_alive_ = std::thread([this] {  // the node's keep-alive timer (20 Hz)
      while (!done_) {
        c_.keepAlive();
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    });
  }
  ~ArmBench() {
    done_ = true;
    if (keep_alive_.joinable()) keep_alive_.join();
  }

  /// Starts the controller's threads (with the options' real-time settings), brings the drives up and homes.
  void start(const Options& o) {
    realtime_ = cell_.start({o.rt_priority, o.lock_memory});
    if (!realtime_.error.empty()) std::fprintf(stderr, "arm_bench: warning: %s\n", realtime_.error.c_str());
    waitFor([&] { return c_.mode() != arm::Mode::kStarting; }, 10.0, "the bring-up");
    if (c_.mode() == arm::Mode::kFault) throw std::runtime_error("bring-up failed: " + c_.status().faults.front());
    run(c_, c_.home(), "homing");
  }

  double periodMs() const { return period_ms_; }
  const can::RealtimeStatus& realtime() const { return realtime_; }
  void stop() { cell_.stop(); }

  /// |cycle interval - SYNC period| of the controller's cycles while it moves to random points for `seconds`, ms.
  std::vector<double> cycleJitter(double seconds, std::mt19937& rng) {
    {
      std::lock_guard<std::mutex> lock(cycle_mutex_);
      cycles_.reserve(static_cast<std::size_t>(seconds * 1000.0 / period_ms_) + 1000);
    }
    recording_ = true;
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < end) {
      const arm::Accepted a = c_.moveTo(randomPoint(config_, rng, c_.status().tool, 1.0));
      if (!a) throw std::runtime_error("move refused: " + a.error);
      while (!c_.result(a.id).done && Clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      if (!c_.result(a.id).done) {
        // The stop ends this move (which then fails with the stop's reason).
        const arm::Accepted s = c_.stop("bench time is up");
        waitFor([&] { return c_.result(s.id).done && c_.mode() == arm::Mode::kIdle; }, 10.0, "the stop");
      } else if (!c_.result(a.id).success) {
        throw std::runtime_error("move failed: " + c_.result(a.id).message);
      }
    }
    recording_ = false;
    std::vector<double> jitter;
    std::lock_guard<std::mutex> lock(cycle_mutex_);
    for (std::size_t i = 1; i < cycles_.size(); ++i)
      jitter.push_back(std::abs(Ms(cycles_[i] - cycles_[i - 1]).count() - period_ms_));
    if (jitter.size() < 10)
      throw std::runtime_error("too few controller cycles recorded (" + std::to_string(jitter.size()) + ")");
    return jitter;
  }

  /// E-stops pressed during moves: to the quick-stop RPDO1 on the bus and to every drive stopping, ms.
  void estops(int count, std::mt19937& rng, std::vector<double>* frame_ms, std::vector<double>* drive_ms) {
    std::uniform_int_distribution<int> delay(150, 600);
    for (int k = 0; k < count; ++k) {
      const arm::Accepted a = c_.moveTo(randomPoint(config_, rng, c_.status().tool, 0.1));
      if (!a) throw std::runtime_error("move refused: " + a.error);
      std::this_thread::sleep_for(std::chrono::milliseconds(delay(rng)));
      while (sniffer_->receive(can::Duration::zero())) {
      }
      const auto pressed = Clock::now();
      c_.setEstop(true);
      double frame = NAN;
      while (std::isnan(frame)) {
        const auto f = sniffer_->receive(std::chrono::milliseconds(50));
        if (!f) throw std::runtime_error("no quick-stop RPDO1 within 50 ms of the e-stop");
        const std::uint16_t cw = static_cast<std::uint16_t>(f->frame.data[0] | f->frame.data[1] << 8);
        if (cw == can::cw::kQuickStop) frame = Ms(f->stamp - pressed).count();
      }
      frame_ms->push_back(frame);
      waitFor(
          [&] {
            for (int i = 0; i < 3; ++i)
              if (cell_.drive(i).state() == can::Cia402State::kOperationEnabled) return false;
            return true;
          },
          1.0, "the drives to leave operation enabled");
      drive_ms->push_back(Ms(Clock::now() - pressed).count());
      waitFor([&] { return c_.result(a.id).done; }, 1.0, "the move to end");
      c_.setEstop(false);
      run(c_, c_.resetFault(), "reset after the e-stop", 10.0);
    }
  }

  /// Final position error of moves to random points, on the simulated drives, mm.
  std::vector<double> moveErrors(int count, std::mt19937& rng) {
    std::vector<double> error_mm;
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector3d goal = randomPoint(config_, rng, c_.status().tool, 0.15);
      run(c_, c_.moveTo(goal), "move " + std::to_string(k + 1));
      Eigen::Vector3d q;
      for (int i = 0; i < 3; ++i) q[i] = config_.axis(i).toMetres(cell_.drive(i).position());
      error_mm.push_back((config_.toolOf(q) - goal).norm() * 1000.0);
    }
    return error_mm;
  }

 private:
  const arm::ArmConfig config_;
  arm::SimCell cell_;
  arm::Controller& c_;
  double period_ms_ = 0.0;
  std::shared_ptr<can::Bus> sniffer_;
  std::mutex cycle_mutex_;
  std::vector<Clock::time_point> cycles_;
  std::atomic<bool> recording_{false}, done_{false};
  std::thread keep_alive_;
  can::RealtimeStatus realtime_;
};

struct Row {
  const char* name;
  double value;
  const char* unit;
  const char* label;
};

void bench(const Options& o) {
  arm::ArmConfig config = arm::loadArmConfig(o.config.empty() ? packageFile("config/arm.yaml") : o.config);
  // Home in place (method 37): the bench measures the controller, not homing runs.
  for (can::AxisConfig& a : config.can.axes) a.homing_method = 37;
  ArmBench b(config);
  b.start(o);
  std::mt19937 rng(o.seed);
  const std::vector<double> jitter = b.cycleJitter(o.duration, rng);
  std::vector<double> frame_ms, drive_ms;
  b.estops(o.estops, rng, &frame_ms, &drive_ms);
  const std::vector<double> error_mm = b.moveErrors(o.moves, rng);
  b.stop();
  const can::RealtimeStatus& realtime = b.realtime();
  const std::vector<Row> rows = {
      {"cycle_jitter_p50_ms", percentile(jitter, 0.5), "ms", "cycle jitter p50"},
      {"cycle_jitter_p99_ms", percentile(jitter, 0.99), "ms", "cycle jitter p99 (target <= 2)"},
      {"cycle_jitter_max_ms", percentile(jitter, 1.0), "ms", "cycle jitter max"},
      {"cycles", static_cast<double>(jitter.size() + 1), "count", "cycles measured"},
      {"realtime_priority", static_cast<double>(realtime.priority), "",
       "SCHED_FIFO priority of the threads (0: normal)"},
      {"estop_latency_ms", percentile(frame_ms, 1.0), "ms", "e-stop -> quick-stop RPDO1, max (target <= 10)"},
      {"estop_latency_p50_ms", percentile(frame_ms, 0.5), "ms", "e-stop -> quick-stop RPDO1, p50"},
      {"estop_to_drives_stopping_ms", percentile(drive_ms, 1.0), "ms",
       "e-stop -> every drive out of operation enabled, max"},
      {"move_error_mm", percentile(error_mm, 1.0), "mm", "move end error, max (target <= 0.1)"},
  };
  if (o.csv) {
    std::printf("metric,value,unit\n");
    for (const Row& r : rows) std::printf("%s,%.4f,%s\n", r.name, r.value, r.unit);
    return;
  }
  std::printf(
      "arm_bench: %.0f s at %.0f Hz SYNC, %d e-stops, %d moves (simulated drives, virtual bus, real clock; %s)\n",
      o.duration, 1000.0 / b.periodMs(), o.estops, o.moves,
      realtime.error.empty() ? realtime.describe().c_str() : "real-time refused: see the warning");
  for (const Row& r : rows) std::printf("  %-52s %10.4f %s\n", r.label, r.value, r.unit);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return runTool(
      "arm_bench",
      [&] {
        OptionTable t;
        t.values["--duration"] = [&](const std::string& opt, const std::string& v) {
          o.duration = parseDouble(opt, v);
          require(o.duration > 0.0, "--duration must be > 0");
        };
        t.values["--estops"] = [&](const std::string& opt, const std::string& v) {
          o.estops = parseInt(opt, v);
          require(o.estops >= 1, "--estops must be >= 1");
        };
        t.values["--moves"] = [&](const std::string& opt, const std::string& v) {
          o.moves = parseInt(opt, v);
          require(o.moves >= 1, "--moves must be >= 1");
        };
        t.values["--config"] = [&](const std::string&, const std::string& v) { o.config = v; };
        t.values["--seed"] = [&](const std::string& opt, const std::string& v) { o.seed = parseSeed(opt, v); };
        t.values["--rt-priority"] = [&](const std::string& opt, const std::string& v) {
          o.rt_priority = parseInt(opt, v);
          require(o.rt_priority >= 0 && o.rt_priority <= 99, "--rt-priority must be 0..99");
        };
        t.flags["--lock-memory"] = [&] { o.lock_memory = true; };
        t.flags["--csv"] = [&] { o.csv = true; };
        return parseArguments(argc, argv, t, kUsage);
      },
      [&] { bench(o); });
}
