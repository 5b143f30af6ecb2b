// arm_bench: the arm controller against simulated drives on the in-process
// virtual bus (the arm node's can_interface "sim"), real clock, master and
// drives in their own threads: the controller cycle's jitter at the SYNC
// rate while the arm keeps moving, the e-stop -> quick-stop frame latency,
// and the final position error of moves; with --force, the error of the
// tool's force estimate (the Z drive's torque) against the force a simulated
// body pushes the tool with, during presses to a depth, and how presses by
// force hold their force (the true force against the target) (issue 45).
#include <cmath>
#include <cstdio>
#include <random>

#include "arm_bench.h"
#include "cli.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using namespace massage_cell::tools;

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
  strokes     each target force up to 3/4 of upper_back's cap (40 N): a
              stroke of 0.16 m along a back rising 2 cm, through 5 points
              placed within +-3 mm (--seed): while gliding, the true force's
              error (RMS,
              max |e|, time within 1 N and within 10 %) and the tool's
              farthest distance from the path across the skin
  over-force  a press holding 3/4 of lower_back's cap when the back pushes
              up 10 mm at 40 mm/s: the cycles from the estimate (and from the
              true force) passing the cap to the press backing off, and how far
              the true force went past the cap
  and the controller cycle's jitter p99 over the whole run (the force loop
  running).
Targets (issue 45, by force, 10-60 N, breathing): hold error <= 0.5 N RMS,
overshoot <= 10 %, contact within 2 mm of indentation; a stroke within 1 N of
its force and 3 mm of its path; an over-force backing off within one cycle
(10 ms); cycle jitter p99 <= 2 ms.
  --forces N,...      target forces, N (default 10,20,40,60)
  --hold S            s at depth (default 3)
  --breathing-mm MM   the back's breathing, mm peak to peak over 4 s (default 3; 0: still)
  --stiffness-scale K the tissue's stiffness x K (default 1; subjects differ by +-50 %: 0.5 .. 1.5)
)";

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
