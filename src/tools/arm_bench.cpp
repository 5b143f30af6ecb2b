// arm_bench: the arm controller against simulated drives on the in-process
// virtual bus (the arm node's can_interface "sim"), real clock, master and
// drives in their own threads: the controller cycle's jitter at the SYNC
// rate while the arm keeps moving, the e-stop -> quick-stop frame latency,
// and the final position error of moves; with --force, the error of the
// tool's force estimate (the Z drive's torque) against the force a simulated
// body pushes the tool with, during presses to a depth, and how presses by
// force hold their force (the true force against the target) (issue 45).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

#include "cli.h"
#include "massage_cell/arm/sim_body.h"
#include "massage_cell/arm/sim_cell.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using namespace massage_cell::tools;
using Clock = std::chrono::steady_clock;
using Ms = std::chrono::duration<double, std::milli>;

const char* const kUsage =
    R"(Usage: arm_bench [--duration S] [--estops N] [--moves N] [--config FILE] [--seed N] [--rt-priority P] [--lock-memory] [--csv]
       arm_bench --force [--forces N,N,...] [--hold S] [--breathing-mm MM] [--stiffness-scale K] [--config FILE] [--rt-priority P] [--lock-memory] [--csv]

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

--force: instead, the error of the tool's force estimate (from the Z drive's
torque, ArmStatus::force) against the force a simulated body pushes the tool
with (SimCell::bodyForce), on the simulated drives: a flat back, skin at
z = 0.15 m, the default tissue (sim_body.h) breathing. The drives home as the
config says (not in place: the drives' physical frame is then the arm's, which
the body needs). Prints the baseline identified by the calibration moves at the
end of homing against the drive's true mechanics (can_axes.yaml sim.mechanics,
as the estimate sees them through the nominal screw efficiency), then for each
target force two presses at the same point, sampled every controller cycle:
  to a depth  region lower_back, depth = the tissue's indentation at that force
              (skipped beyond the region's max_depth): the estimate at the
              approach point before contact (the no-contact error), its error
              during the descent from contact, and while holding: the true mean
              force and the estimate's error (mean, RMS, max)
  by force    mode force, the force itself (force_press.h): while holding, the
              true force's mean and its error against the target (RMS, max
              |e|); the overshoot (peak true force from contact to the end of
              the hold over the target); the tool's indentation into the skin
              when the press found contact (switched from seeking to ramping);
              the estimate's error RMS. A press by force refused or stopped by
              a limit (the region's force cap: lower_back's is 60 N) is
              reported as failed, with the controller's message.
Targets (issue 45, by force, 10-60 N, breathing): hold error <= 0.5 N RMS,
overshoot <= 10 %, contact within 2 mm of indentation.
  --forces N,...      target forces, N (default 10,20,40,60)
  --hold S            s at depth (default 3)
  --breathing-mm MM   the back's breathing, mm peak to peak over 4 s (default 3; 0: still)
  --stiffness-scale K the tissue's stiffness x K (default 1; subjects differ by +-50 %: 0.5 .. 1.5)
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
  // --force
  bool force = false;
  std::vector<double> forces{10.0, 20.0, 40.0, 60.0};  ///< N
  double hold = 3.0;                                   ///< s
  double breathing_mm = 3.0;                           ///< peak to peak
  double stiffness_scale = 1.0;
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
  std::string name;
  double value;
  std::string unit;
  std::string label;
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
    for (const Row& r : rows) std::printf("%s,%.4f,%s\n", r.name.c_str(), r.value, r.unit.c_str());
    return;
  }
  std::printf(
      "arm_bench: %.0f s at %.0f Hz SYNC, %d e-stops, %d moves (simulated drives, virtual bus, real clock; %s)\n",
      o.duration, 1000.0 / b.periodMs(), o.estops, o.moves,
      realtime.error.empty() ? realtime.describe().c_str() : "real-time refused: see the warning");
  for (const Row& r : rows) std::printf("  %-52s %10.4f %s\n", r.label.c_str(), r.value, r.unit.c_str());
}

// --- --force: the force estimate's error during presses on a simulated body ---------------------------------------

std::string format(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* f, ...) {
  char buf[512];
  va_list args;
  va_start(args, f);
  std::vsnprintf(buf, sizeof buf, f, args);
  va_end(args);
  return buf;
}

/// Where a controller cycle was in the press (its activity). A press to a depth approaches, descends and holds; a
/// press by force approaches, seeks the skin, ramps the force up, holds it and releases (then backs off: kOther).
enum class Phase { kOther, kApproach, kDescend, kHold, kSeek, kRamp, kRelease };

struct ForceSample {
  Phase phase = Phase::kOther;
  double tool_z = 0.0;       ///< m
  double estimate = 0.0;     ///< N, ArmStatus::force
  double truth = 0.0;        ///< N, SimCell::bodyForce
  double indentation = NAN;  ///< m, the tool tip into the skin (SimBody::indentation at SimCell::bodyTime)
  double error() const { return estimate - truth; }
};

/// A press sampled: its samples and how it ended.
struct PressRun {
  std::vector<ForceSample> samples;
  bool refused = false;  ///< the controller refused the request (nothing moved)
  bool success = false;
  std::string message;  ///< the refusal or the failure
};

/// Runs a massage request to its end, sampling the force estimate, the body's true force and the tool's
/// indentation into it once per controller cycle (status polled at 1 kHz, a sample when its cycle count moved on).
/// A refusal or a failure is returned (PressRun); throws on a timeout, when the estimate is not valid while the press
/// approaches or presses, or when the arm is left in fault.
PressRun samplePress(ArmBench& b, const arm::SimBody& body, const arm::PressRequest& request, const std::string& what) {
  arm::Controller& c = b.controller();
  PressRun run;
  const arm::Accepted a = c.massage(request);
  if (!a) {
    run.refused = true;
    run.message = a.error;
    return run;
  }
  std::uint64_t last_cycle = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(120);
  const auto has = [](const std::string& s, const char* what) { return s.find(what) != std::string::npos; };
  while (!c.result(a.id).done) {
    if (Clock::now() > deadline) throw std::runtime_error("timed out waiting for " + what);
    const arm::ArmStatus s = c.status();
    if (s.cycles != last_cycle) {
      last_cycle = s.cycles;
      ForceSample f;
      f.truth = b.cell().bodyForce();
      f.indentation = body.indentation(s.tool, b.cell().bodyTime());
      f.tool_z = s.tool.z();
      f.estimate = s.force.force;
      const std::string& act = s.activity;
      if (has(act, ": approach")) f.phase = Phase::kApproach;
      if (has(act, ": descend")) f.phase = Phase::kDescend;
      if (has(act, ": hold")) f.phase = Phase::kHold;  // also a press by force's "holding 30 N"
      if (has(act, ": seeking the skin")) f.phase = Phase::kSeek;
      if (has(act, ": ramping")) f.phase = Phase::kRamp;
      if (has(act, ": releasing")) f.phase = Phase::kRelease;
      if (f.phase != Phase::kOther && !s.force.valid)
        throw std::runtime_error(what + ": the force estimate is not valid (" + s.force.problem + ")");
      run.samples.push_back(f);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const arm::CommandResult r = c.result(a.id);
  run.success = r.success;
  run.message = r.message;
  if (!r.success) {
    if (c.mode() == arm::Mode::kFault)
      throw std::runtime_error(what + " failed and left the arm in fault: " + r.message);
  }
  return run;
}

/// Whether a press by force was refused or stopped by the region's force cap (plan.cpp's forceGeometry, force_press.h's
/// limits): a result (a 60 N press on lower_back, capped at 60 N, may overshoot it), not a bench error.
bool limitStopped(const PressRun& run) {
  for (const char* limit : {"is above the", "passed the press's limit"})
    if (run.message.find(limit) != std::string::npos) return true;
  return false;
}

/// How a press by force held its target, from the true force.
struct ByForceStats {
  int held = 0;                ///< cycles holding
  double truth_mean = NAN;     ///< N, while holding
  double error_rms = NAN;      ///< N, true - target while holding
  double error_max = NAN;      ///< N, |true - target| max while holding
  double peak = NAN;           ///< N, the true force's peak from contact to the end of the hold
  double overshoot_pct = NAN;  ///< (peak - target) / target, %
  double contact_mm = NAN;     ///< the indentation when the press switched from seeking to ramping, mm
  double contact_force = NAN;  ///< N, the true force then
  double estimate_rms = NAN;   ///< N, estimate - true while holding
};

ByForceStats byForceStats(const std::vector<ForceSample>& samples, double target) {
  ByForceStats s;
  double sum = 0.0, sum2 = 0.0, worst = 0.0, est2 = 0.0, peak = -INFINITY;
  bool pressing = false;  // from contact (the first ramping cycle) to the end of the hold
  for (const ForceSample& f : samples) {
    if (f.phase == Phase::kRamp && !pressing && std::isnan(s.contact_mm)) {
      pressing = true;
      s.contact_mm = f.indentation * 1000.0;
      s.contact_force = f.truth;
    }
    if (pressing && f.phase != Phase::kRamp && f.phase != Phase::kHold) pressing = false;  // released or stopped
    if (pressing) peak = std::max(peak, f.truth);
    if (f.phase != Phase::kHold) continue;
    ++s.held;
    const double e = f.truth - target;
    sum += f.truth;
    sum2 += e * e;
    worst = std::max(worst, std::abs(e));
    est2 += f.error() * f.error();
  }
  if (std::isfinite(peak)) {
    s.peak = peak;
    s.overshoot_pct = (peak - target) / target * 100.0;
  }
  if (s.held == 0) return s;
  s.truth_mean = sum / s.held;
  s.error_rms = std::sqrt(sum2 / s.held);
  s.error_max = worst;
  s.estimate_rms = std::sqrt(est2 / s.held);
  return s;
}

/// The larger of a and b, NaN ignored (NaN when both are).
double maxOf(double a, double b) { return std::isnan(a) ? b : std::isnan(b) ? a : std::max(a, b); }

/// Of the samples `pick` selects: how many, the true and the estimated mean force, the error's mean, RMS and max |e|.
struct ErrorStats {
  int n = 0;
  double truth_mean = NAN, estimate_mean = NAN, mean = NAN, rms = NAN, max = NAN;
};

template <typename Pick>
ErrorStats errorStats(const std::vector<ForceSample>& samples, Pick pick) {
  ErrorStats e;
  double truth = 0.0, estimate = 0.0, sum = 0.0, sum2 = 0.0, worst = 0.0;
  for (const ForceSample& f : samples) {
    if (!pick(f)) continue;
    ++e.n;
    truth += f.truth;
    estimate += f.estimate;
    sum += f.error();
    sum2 += f.error() * f.error();
    worst = std::max(worst, std::abs(f.error()));
  }
  if (e.n == 0) return e;
  e.truth_mean = truth / e.n;
  e.estimate_mean = estimate / e.n;
  e.mean = sum / e.n;
  e.rms = std::sqrt(sum2 / e.n);
  e.max = worst;
  return e;
}

/// One vertical press of `hold` s at `point` (region `region`); the caller sets its mode and depth or force.
arm::PressRequest onePress(const std::string& name, const std::string& region, const Eigen::Vector3d& point,
                           double hold) {
  arm::PressRequest request;
  request.targets.push_back({name, region, point, Eigen::Vector3d::UnitZ()});
  request.hold = hold;
  return request;
}

struct Section {
  std::string title;
  std::vector<Row> rows;
};

void forceBench(const Options& o) {
  const auto began = Clock::now();
  // The config's homing (switches): only then is the drives' physical frame, where the body lies, the arm's.
  const arm::ArmConfig config = arm::loadArmConfig(o.config.empty() ? packageFile("config/arm.yaml") : o.config);
  if (!config.force.enabled)
    throw std::runtime_error(config.source + " has no force: section: the arm estimates no force");
  const can::SimDriveSettings::Mechanics& truth = config.axis(2).sim.mechanics;
  if (!(truth.screw_lead > 0.0))
    throw std::runtime_error("the Z axis has no sim.mechanics (screw_lead 0): its simulated drive reports no torque");
  const std::string region = "lower_back";
  if (!config.regions.count(region)) throw std::runtime_error(config.source + " has no region " + region);
  const double max_depth = config.regions.at(region).max_depth;

  // A flat back, skin at 15 cm (workspace z >= 0.08, body.safe_height above), under a point of the workspace.
  const double skin = 0.15;
  const Eigen::Vector3d point(0.15, 0.10, skin);
  arm::Tissue tissue;
  tissue.stiffness *= o.stiffness_scale;
  arm::Breathing breathing;
  breathing.amplitude = o.breathing_mm / 1000.0;
  // The target forces' depths, checked against the region's limit before anything moves.
  std::vector<std::string> skipped(o.forces.size());
  for (std::size_t k = 0; k < o.forces.size(); ++k) {
    const double depth = tissue.indentationAt(o.forces[k]);
    if (depth > max_depth)
      skipped[k] = format("%g N needs %.1f mm of this tissue, beyond %s's max_depth %.1f mm: skipped", o.forces[k],
                          depth * 1000.0, region.c_str(), max_depth * 1000.0);
  }
  if (std::all_of(skipped.begin(), skipped.end(), [](const std::string& w) { return !w.empty(); }))
    throw std::runtime_error(format("no target force fits within %s's max_depth %.1f mm with this tissue (%s)",
                                    region.c_str(), max_depth * 1000.0, skipped.front().c_str()));
  for (const std::string& why : skipped)
    if (!why.empty()) std::fprintf(stderr, "arm_bench: %s\n", why.c_str());

  ArmBench b(config);
  const auto body = std::make_shared<const arm::SimBody>(arm::SimBody::flat(skin, tissue, breathing));
  b.cell().setBody(body);
  b.start(o);
  // The estimate takes its zero under the identified baseline over a few cycles after homing.
  const auto settle = Clock::now() + std::chrono::seconds(1);
  while (!b.controller().status().force.valid && Clock::now() < settle)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // read 20 cycles after the zero, not at it
  const arm::ForceReading calibrated = b.controller().status().force;
  if (!calibrated.valid) throw std::runtime_error("no force estimate after homing: " + calibrated.problem);
  // What the estimate sees of the true mechanics: F = 2 pi eta_nominal T / lead_nominal of T = lead F / (2 pi eta).
  const double seen =
      config.force.screw_efficiency * truth.screw_lead / (truth.screw_efficiency * config.force.screw_lead);

  std::vector<Section> sections;
  sections.push_back(
      {format("baseline identified at homing vs the true Z mechanics (x %.4f: efficiency %.2f nominal, %.2f true)",
              seen, config.force.screw_efficiency, truth.screw_efficiency),
       {{"force_mass_kg", calibrated.baseline.mass, "kg", "moving mass, identified"},
        {"force_true_mass_kg", truth.moving_mass * seen, "kg",
         format("moving mass, true (%.2f kg x)", truth.moving_mass)},
        {"force_coulomb_N", calibrated.baseline.coulomb, "N", "coulomb friction, identified"},
        {"force_true_coulomb_N", truth.coulomb_friction * seen, "N",
         format("coulomb friction, true (%.1f N x)", truth.coulomb_friction)},
        {"force_viscous_Ns_per_m", calibrated.baseline.viscous, "N s/m", "viscous friction, identified"},
        {"force_true_viscous_Ns_per_m", truth.viscous_friction * seen, "N s/m",
         format("viscous friction, true (%.0f N s/m x)", truth.viscous_friction)},
        {"force_after_homing_N", calibrated.force, "N", "estimate after homing (no contact)"}}});

  const double approach_z = skin + config.press.approach_height;
  const double cap = config.regions.at(region).forceCap(config.press.contact_area);
  std::vector<ForceSample> all_holds;
  double worst_descent = 0.0, worst_no_contact = 0.0;
  int pressed = 0;
  // Presses by force: the worst target's hold error RMS, the largest overshoot and contact indentation.
  double bf_rms = NAN, bf_max = NAN, bf_overshoot = NAN, bf_contact = NAN, bf_estimate = NAN;
  int bf_ended = 0, bf_failed = 0;
  for (std::size_t k = 0; k < o.forces.size(); ++k) {
    const double target = o.forces[k];
    const std::string key = "force_" + format("%g", target) + "N_";
    const double depth = tissue.indentationAt(target);
    if (!skipped[k].empty()) {
      sections.push_back(
          {format("to a depth: %s", skipped[k].c_str()),
           {{key + "depth_mm", depth * 1000.0, "mm", "depth needed"}, {key + "skipped", 1.0, "", "skipped (1)"}}});
    } else {
      arm::PressRequest request = onePress(format("%g N", target), region, point, o.hold);
      request.mode = arm::PressConfig::Mode::kDepth;
      request.depth = depth;
      const std::string what = format("the press to a depth for %g N", target);
      const PressRun run = samplePress(b, *body, request, what);
      if (!run.success) throw std::runtime_error(what + (run.refused ? " refused: " : " failed: ") + run.message);
      const std::vector<ForceSample>& samples = run.samples;
      ++pressed;
      const ErrorStats hold = errorStats(samples, [](const ForceSample& f) { return f.phase == Phase::kHold; });
      const ErrorStats descent =
          errorStats(samples, [](const ForceSample& f) { return f.phase == Phase::kDescend && f.truth > 0.0; });
      // At the approach point, still in the air (before the press re-zeroes the estimate): the no-contact error.
      const ErrorStats air = errorStats(samples, [&](const ForceSample& f) {
        return f.phase == Phase::kApproach && std::abs(f.tool_z - approach_z) < 5e-4;
      });
      if (hold.n == 0) throw std::runtime_error(what + ": no cycle sampled while holding");
      for (const ForceSample& f : samples)
        if (f.phase == Phase::kHold) all_holds.push_back(f);
      if (descent.n > 0) worst_descent = std::max(worst_descent, descent.max);
      if (air.n > 0) worst_no_contact = std::max(worst_no_contact, std::abs(air.mean));
      sections.push_back(
          {format("%g N to a depth: %.2f mm (%s max_depth %.1f mm), hold %g s, %d cycles held: the estimate's error",
                  target, depth * 1000.0, region.c_str(), max_depth * 1000.0, o.hold, hold.n),
           {{key + "depth_mm", depth * 1000.0, "mm", "depth (the tissue's indentation at the force)"},
            {key + "no_contact_N", air.mean, "N",
             format("estimate at the approach point, no contact (%d cycles)", air.n)},
            {key + "descent_error_rms_N", descent.rms, "N",
             format("descent from contact: error RMS (%d cycles)", descent.n)},
            {key + "descent_error_max_N", descent.max, "N", "descent from contact: error max |e|"},
            {key + "true_mean_N", hold.truth_mean, "N", "holding: true force, mean"},
            {key + "estimate_mean_N", hold.estimate_mean, "N", "holding: estimate, mean"},
            {key + "error_mean_N", hold.mean, "N", "holding: error (estimate - true), mean"},
            {key + "error_rms_N", hold.rms, "N", "holding: error RMS"},
            {key + "error_max_N", hold.max, "N", "holding: error max |e|"}}});
    }

    // The same target by force, at the same point.
    arm::PressRequest request = onePress(format("%g N", target), region, point, o.hold);
    request.mode = arm::PressConfig::Mode::kForce;
    request.force = target;
    const std::string what = format("the press by force to %g N", target);
    const PressRun run = samplePress(b, *body, request, what);
    if (!run.success && !limitStopped(run))
      throw std::runtime_error(what + (run.refused ? " refused: " : " failed: ") + run.message);
    const ByForceStats bf = byForceStats(run.samples, target);
    if (run.success && bf.held == 0) throw std::runtime_error(what + ": no cycle sampled while holding");
    const std::string bk = key + "byforce_";
    if (run.success)
      ++bf_ended;
    else
      ++bf_failed;
    bf_rms = maxOf(bf_rms, bf.error_rms);
    bf_max = maxOf(bf_max, bf.error_max);
    bf_overshoot = maxOf(bf_overshoot, bf.overshoot_pct);
    bf_contact = maxOf(bf_contact, bf.contact_mm);
    bf_estimate = maxOf(bf_estimate, bf.estimate_rms);
    const std::string how =
        run.success ? "ended" : format("FAILED (%s: %s)", run.refused ? "refused" : "stopped", run.message.c_str());
    sections.push_back(
        {format("%g N by force (%s cap %.1f N), hold %g s, %d cycles held: %s", target, region.c_str(), cap, o.hold,
                bf.held, how.c_str()),
         {{bk + "failed", run.success ? 0.0 : 1.0, "", "failed (1: refused or stopped by a limit)"},
          {bk + "true_mean_N", bf.truth_mean, "N", "holding: true force, mean"},
          {bk + "error_rms_N", bf.error_rms, "N", "holding: true - target, RMS (target <= 0.5 N RMS)"},
          {bk + "error_max_N", bf.error_max, "N", "holding: true - target, max |e|"},
          {bk + "peak_N", bf.peak, "N", "true force peak, contact to the end of the hold"},
          {bk + "overshoot_pct", bf.overshoot_pct, "%", "overshoot (peak - target) / target (target <= 10 %)"},
          {bk + "contact_mm", bf.contact_mm, "mm", "indentation at contact detection (target <= 2 mm)"},
          {bk + "contact_true_N", bf.contact_force, "N", "true force at contact detection"},
          {bk + "estimate_error_rms_N", bf.estimate_rms, "N", "holding: estimate - true, RMS"}}});
  }
  b.stop();
  const ErrorStats overall = errorStats(all_holds, [](const ForceSample&) { return true; });
  const double runtime = std::chrono::duration<double>(Clock::now() - began).count();
  sections.push_back({"all presses to a depth: the estimate's error",
                      {{"force_error_rms_N", overall.rms, "N", "holding: error RMS"},
                       {"force_error_max_N", overall.max, "N", "holding: error max |e|"},
                       {"force_descent_error_max_N", worst_descent, "N", "descent from contact: error max |e|"},
                       {"force_no_contact_max_N", worst_no_contact, "N", "no contact: |estimate| max"},
                       {"force_presses", static_cast<double>(pressed), "count", "presses"}}});
  sections.push_back(
      {"all presses by force: the true force",
       {{"force_byforce_error_rms_max_N", bf_rms, "N", "hold error RMS, worst target (target <= 0.5 N RMS)"},
        {"force_byforce_error_max_N", bf_max, "N", "hold error max |e|"},
        {"force_byforce_overshoot_max_pct", bf_overshoot, "%", "overshoot max (target <= 10 %)"},
        {"force_byforce_contact_mm_max", bf_contact, "mm", "contact indentation max (target <= 2 mm)"},
        {"force_byforce_estimate_error_rms_max_N", bf_estimate, "N", "holding: estimate - true RMS, worst target"},
        {"force_byforce_presses", static_cast<double>(bf_ended), "count", "presses ended"},
        {"force_byforce_failed", static_cast<double>(bf_failed), "count", "presses failed (a limit)"}}});
  sections.push_back({"run", {{"runtime_s", runtime, "s", "bench runtime (homing included)"}}});

  if (o.csv) {
    std::printf("metric,value,unit\n");
    for (const Section& s : sections)
      for (const Row& r : s.rows) std::printf("%s,%.4f,%s\n", r.name.c_str(), r.value, r.unit.c_str());
    return;
  }
  const can::RealtimeStatus& realtime = b.realtime();
  std::printf(
      "arm_bench --force: presses on a simulated back: flat, skin at z %.3f m, pressed at (%.3f, %.3f); tissue "
      "F = k x^%.1f, k %.3g N/m^%.1f (x %.2f), damping %.1f s/m; breathing %.1f mm p-p / %.0f s; %.0f Hz SYNC "
      "(simulated drives, virtual bus, real clock; %s)\n",
      skin, point.x(), point.y(), tissue.exponent, tissue.stiffness, tissue.exponent, o.stiffness_scale, tissue.damping,
      o.breathing_mm, breathing.period, 1000.0 / b.periodMs(),
      realtime.error.empty() ? realtime.describe().c_str() : "real-time refused: see the warning");
  for (const Section& s : sections) {
    std::printf("  %s\n", s.title.c_str());
    for (const Row& r : s.rows) std::printf("    %-60s %10.4f %s\n", r.label.c_str(), r.value, r.unit.c_str());
  }
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
        t.flags["--force"] = [&] { o.force = true; };
        t.values["--forces"] = [&](const std::string& opt, const std::string& v) {
          o.forces.clear();
          for (const std::string& item : splitList(v)) {
            o.forces.push_back(parseDouble(opt, item));
            require(o.forces.back() > 0.0, "--forces must be > 0 N");
          }
          require(!o.forces.empty(), "--forces needs one force or more");
        };
        t.values["--hold"] = [&](const std::string& opt, const std::string& v) {
          o.hold = parseDouble(opt, v);
          require(o.hold > 0.0, "--hold must be > 0");
        };
        t.values["--breathing-mm"] = [&](const std::string& opt, const std::string& v) {
          o.breathing_mm = parseDouble(opt, v);
          require(o.breathing_mm >= 0.0 && o.breathing_mm <= 10.0, "--breathing-mm must be 0..10");
        };
        t.values["--stiffness-scale"] = [&](const std::string& opt, const std::string& v) {
          o.stiffness_scale = parseDouble(opt, v);
          require(o.stiffness_scale > 0.0, "--stiffness-scale must be > 0");
        };
        return parseArguments(argc, argv, t, kUsage);
      },
      [&] { o.force ? forceBench(o) : bench(o); });
}
