// arm_bench's parts shared by its two benches (arm_bench.cpp: cycle jitter, e-stop latency, move error;
// arm_bench_force.cpp: --force): the options, the arm on simulated drives, the printed rows.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "cli.h"
#include "massage_cell/arm/sim_cell.h"

namespace massage_cell::tools {

namespace arm = massage_cell::arm;
namespace can = massage_cell::can;
using Clock = std::chrono::steady_clock;
using Ms = std::chrono::duration<double, std::milli>;

struct Options {
  double duration = 60.0;
  int estops = 20;
  int moves = 20;
  std::string config;  // default: the package's config/arm.yaml
  std::uint32_t seed = 1;
  int rt_priority = 0;
  bool lock_memory = false;
  bool csv = false;
  // --force
  bool force = false;
  std::vector<double> forces{10.0, 20.0, 40.0, 60.0};  ///< N
  double hold = 3.0;                                   ///< s
  double breathing_mm = 3.0;                           ///< peak to peak
  double stiffness_scale = 1.0;
};

inline double percentile(std::vector<double> v, double p) {
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
inline void run(arm::Controller& c, const arm::Accepted& a, const std::string& what, double seconds = 60.0) {
  if (!a) throw std::runtime_error(what + " refused: " + a.error);
  waitFor([&] { return c.result(a.id).done; }, seconds, what);
  const arm::CommandResult r = c.result(a.id);
  if (!r.success) throw std::runtime_error(what + " failed: " + r.message);
}

/// A random point of the workspace envelope within `reach` of `from` on every axis.
inline Eigen::Vector3d randomPoint(const arm::ArmConfig& c, std::mt19937& rng, const Eigen::Vector3d& from,
                                   double reach) {
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
  arm::SimCell& cell() { return cell_; }
  arm::Controller& controller() { return c_; }
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
    return recordedJitter();
  }

  /// Records the controller's cycles from now on (recordedJitter() returns them).
  void recordCycles() { recording_ = true; }
  /// Stops recording: |cycle interval - SYNC period| of the cycles recorded, ms.
  std::vector<double> recordedJitter() {
    recording_ = false;
    std::vector<double> jitter;
    std::lock_guard<std::mutex> lock(cycle_mutex_);
    for (std::size_t i = 1; i < cycles_.size(); ++i)
      jitter.push_back(std::abs(Ms(cycles_[i] - cycles_[i - 1]).count() - period_ms_));
    cycles_.clear();
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
  std::string name;
  double value;
  std::string unit;
  std::string label;
};

struct Section {
  std::string title;
  std::vector<Row> rows;
};

/// The --force bench (arm_bench_force.cpp).
void forceBench(const Options& o);

}  // namespace massage_cell::tools
