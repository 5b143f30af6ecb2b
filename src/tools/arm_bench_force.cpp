// arm_bench --force: the tool's force estimate against the force a simulated body pushes it with, presses by
// force, strokes and the over-force stop, on the simulated drives (arm_bench.cpp's usage text says what each
// section measures).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <random>
#include <thread>

#include "arm_bench.h"
#include "cli.h"
#include "massage_cell/arm/sim_body.h"
#include "package_paths.h"

namespace massage_cell::tools {

namespace {

/// Where a controller cycle was in the press (its activity). A press to a depth approaches, descends and holds; a
/// press by force approaches, seeks the skin, ramps the force up, holds it (a stroke: glides) and releases, then
/// backs off.
enum class Phase { kOther, kApproach, kDescend, kHold, kSeek, kRamp, kGlide, kRelease, kBackOff };

struct ForceSample {
  Phase phase = Phase::kOther;
  std::uint64_t cycle = 0;   ///< the controller's cycle count
  Eigen::Vector2d xy{0, 0};  ///< m, the tool across the skin
  double tool_z = 0.0;       ///< m
  double estimate = 0.0;     ///< N, ArmStatus::force
  double pressed = 0.0;      ///< N, what the press acts on: the estimate less the press's zero (ArmStatus::force_zero)
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
/// approaches or presses, or when the arm is left in fault. `each` (if any) sees every sample as it is taken.
PressRun samplePress(ArmBench& b, const arm::SimBody& body, const arm::PressRequest& request, const std::string& what,
                     const std::function<void(const ForceSample&)>& each = {}) {
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
      f.cycle = s.cycles;
      f.xy = s.tool.head<2>();
      f.truth = b.cell().bodyForce();
      f.indentation = body.indentation(s.tool, b.cell().bodyTime());
      f.tool_z = s.tool.z();
      f.estimate = s.force.force;
      f.pressed = s.force.force - s.force_zero;
      const std::string& act = s.activity;
      if (has(act, ": approach")) f.phase = Phase::kApproach;
      if (has(act, ": descend")) f.phase = Phase::kDescend;
      if (has(act, ": hold")) f.phase = Phase::kHold;  // also a press by force's "holding 30 N"
      if (has(act, ": seeking the skin")) f.phase = Phase::kSeek;
      if (has(act, ": ramping")) f.phase = Phase::kRamp;
      if (has(act, ": releasing")) f.phase = Phase::kRelease;
      if (s.press_phase == "glide") f.phase = Phase::kGlide;
      if (s.press_phase == "back off") f.phase = Phase::kBackOff;
      if (f.phase != Phase::kOther && f.phase != Phase::kBackOff && !s.force.valid)
        throw std::runtime_error(what + ": the force estimate is not valid (" + s.force.problem + ")");
      run.samples.push_back(f);
      if (each) each(f);
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

/// What the force bench presses: the configuration, the tissue and breathing asked for, a flat back with its skin at
/// 15 cm (workspace z >= 0.08, body.safe_height above) under `point`, pressed in `region`.
struct ForceWorld {
  arm::ArmConfig config;
  arm::Tissue tissue;
  arm::Breathing breathing;
  double skin = 0.15;
  Eigen::Vector3d point{0.15, 0.10, 0.15};
  std::string region = "lower_back";
  /// The target forces' depths beyond the region's max_depth, checked before anything moves: why each is skipped
  /// (empty: pressed).
  std::vector<std::string> skipped;
  double cap() const { return config.regions.at(region).forceCap(config.press.contact_area); }
};

ForceWorld forceWorld(const Options& o) {
  ForceWorld w;
  // The config's homing (switches): only then is the drives' physical frame, where the body lies, the arm's.
  w.config = arm::loadArmConfig(o.config.empty() ? packageFile("config/arm.yaml") : o.config);
  const arm::ArmConfig& config = w.config;
  if (!config.force.enabled)
    throw std::runtime_error(config.source + " has no force: section: the arm estimates no force");
  if (!(config.axis(2).sim.mechanics.screw_lead > 0.0))
    throw std::runtime_error("the Z axis has no sim.mechanics (screw_lead 0): its simulated drive reports no torque");
  for (const char* region : {"lower_back", "upper_back"})
    if (!config.regions.count(region)) throw std::runtime_error(config.source + " has no region " + region);
  const double max_depth = config.regions.at(w.region).max_depth;
  w.tissue.stiffness *= o.stiffness_scale;
  w.breathing.amplitude = o.breathing_mm / 1000.0;
  w.skipped.resize(o.forces.size());
  for (std::size_t k = 0; k < o.forces.size(); ++k) {
    const double depth = w.tissue.indentationAt(o.forces[k]);
    if (depth > max_depth)
      w.skipped[k] = format("%g N needs %.1f mm of this tissue, beyond %s's max_depth %.1f mm: skipped", o.forces[k],
                            depth * 1000.0, w.region.c_str(), max_depth * 1000.0);
  }
  if (std::all_of(w.skipped.begin(), w.skipped.end(), [](const std::string& why) { return !why.empty(); }))
    throw std::runtime_error(format("no target force fits within %s's max_depth %.1f mm with this tissue (%s)",
                                    w.region.c_str(), max_depth * 1000.0, w.skipped.front().c_str()));
  for (const std::string& why : w.skipped)
    if (!why.empty()) std::fprintf(stderr, "arm_bench: %s\n", why.c_str());
  return w;
}

/// The baseline the calibration moves identified at homing against the Z drive's true mechanics.
Section baselineSection(const arm::ArmConfig& config, const arm::ForceReading& calibrated) {
  const can::SimDriveSettings::Mechanics& truth = config.axis(2).sim.mechanics;
  // What the estimate sees of the true mechanics: F = 2 pi eta_nominal T / lead_nominal of T = lead F / (2 pi eta).
  const double seen =
      config.force.screw_efficiency * truth.screw_lead / (truth.screw_efficiency * config.force.screw_lead);
  return {format("baseline identified at homing vs the true Z mechanics (x %.4f: efficiency %.2f nominal, %.2f true)",
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
           {"force_after_homing_N", calibrated.force, "N", "estimate after homing (no contact)"}}};
}

/// The estimate's error over every press to a depth.
struct DepthTotals {
  std::vector<ForceSample> holds;
  double worst_descent = 0.0, worst_no_contact = 0.0;
  int pressed = 0;
  int guarded = 0;  ///< stopped by the force guard near the region's cap
};

/// A press to the depth at which the tissue holds `target`: the estimate's error before, during and at the depth.
Section depthPress(ArmBench& b, const ForceWorld& w, const arm::SimBody& body, double target, double hold,
                   DepthTotals* totals) {
  const std::string key = "force_" + format("%g", target) + "N_";
  const double depth = w.tissue.indentationAt(target);
  const double max_depth = w.config.regions.at(w.region).max_depth;
  arm::PressRequest request = onePress(format("%g N", target), w.region, w.point, hold);
  request.mode = arm::PressConfig::Mode::kDepth;
  request.depth = depth;
  const std::string what = format("the press to a depth for %g N", target);
  const PressRun run = samplePress(b, body, request, what);
  // The breathing pushes a tool held at a depth by +-10-15 N: near the cap the force guard stops it (a result).
  const bool guarded = !run.success && run.message.find("of the region's limit") != std::string::npos;
  if (!run.success && !guarded)
    throw std::runtime_error(what + (run.refused ? " refused: " : " failed: ") + run.message);
  const std::vector<ForceSample>& samples = run.samples;
  ++totals->pressed;
  totals->guarded += guarded ? 1 : 0;
  const ErrorStats held = errorStats(samples, [](const ForceSample& f) { return f.phase == Phase::kHold; });
  const ErrorStats descent =
      errorStats(samples, [](const ForceSample& f) { return f.phase == Phase::kDescend && f.truth > 0.0; });
  // At the approach point, still in the air (before the press re-zeroes the estimate): the no-contact error.
  const double approach_z = w.skin + w.config.press.approach_height;
  const ErrorStats air = errorStats(samples, [&](const ForceSample& f) {
    return f.phase == Phase::kApproach && std::abs(f.tool_z - approach_z) < 5e-4;
  });
  if (held.n == 0 && !guarded) throw std::runtime_error(what + ": no cycle sampled while holding");
  for (const ForceSample& f : samples)
    if (f.phase == Phase::kHold) totals->holds.push_back(f);
  if (descent.n > 0) totals->worst_descent = std::max(totals->worst_descent, descent.max);
  if (air.n > 0) totals->worst_no_contact = std::max(totals->worst_no_contact, std::abs(air.mean));
  return {
      format("%g N to a depth: %.2f mm (%s max_depth %.1f mm), hold %g s, %d cycles held: the estimate's error", target,
             depth * 1000.0, w.region.c_str(), max_depth * 1000.0, hold, held.n) +
          (guarded ? " (STOPPED: " + run.message + ")" : std::string()),
      {{key + "depth_mm", depth * 1000.0, "mm", "depth (the tissue's indentation at the force)"},
       {key + "no_contact_N", air.mean, "N", format("estimate at the approach point, no contact (%d cycles)", air.n)},
       {key + "descent_error_rms_N", descent.rms, "N",
        format("descent from contact: error RMS (%d cycles)", descent.n)},
       {key + "descent_error_max_N", descent.max, "N", "descent from contact: error max |e|"},
       {key + "true_mean_N", held.truth_mean, "N", "holding: true force, mean"},
       {key + "estimate_mean_N", held.estimate_mean, "N", "holding: estimate, mean"},
       {key + "error_mean_N", held.mean, "N", "holding: error (estimate - true), mean"},
       {key + "error_rms_N", held.rms, "N", "holding: error RMS"},
       {key + "error_max_N", held.max, "N", "holding: error max |e|"}}};
}

/// The worst of the presses by force.
struct ByForceTotals {
  double rms = NAN, max = NAN, overshoot = NAN, contact = NAN, estimate = NAN;
  int ended = 0, failed = 0;
};

/// A press by force to `target` at the same point: how the true force held it.
Section byForcePress(ArmBench& b, const ForceWorld& w, const arm::SimBody& body, double target, double hold,
                     ByForceTotals* totals) {
  arm::PressRequest request = onePress(format("%g N", target), w.region, w.point, hold);
  request.mode = arm::PressConfig::Mode::kForce;
  request.force = target;
  const std::string what = format("the press by force to %g N", target);
  const PressRun run = samplePress(b, body, request, what);
  if (!run.success && !limitStopped(run))
    throw std::runtime_error(what + (run.refused ? " refused: " : " failed: ") + run.message);
  const ByForceStats bf = byForceStats(run.samples, target);
  if (run.success && bf.held == 0) throw std::runtime_error(what + ": no cycle sampled while holding");
  ++(run.success ? totals->ended : totals->failed);
  totals->rms = maxOf(totals->rms, bf.error_rms);
  totals->max = maxOf(totals->max, bf.error_max);
  totals->overshoot = maxOf(totals->overshoot, bf.overshoot_pct);
  totals->contact = maxOf(totals->contact, bf.contact_mm);
  totals->estimate = maxOf(totals->estimate, bf.estimate_rms);
  const std::string bk = "force_" + format("%g", target) + "N_byforce_";
  const std::string how =
      run.success ? "ended" : format("FAILED (%s: %s)", run.refused ? "refused" : "stopped", run.message.c_str());
  return {format("%g N by force (%s cap %.1f N), hold %g s, %d cycles held: %s", target, w.region.c_str(), w.cap(),
                 hold, bf.held, how.c_str()),
          {{bk + "failed", run.success ? 0.0 : 1.0, "", "failed (1: refused or stopped by a limit)"},
           {bk + "true_mean_N", bf.truth_mean, "N", "holding: true force, mean"},
           {bk + "error_rms_N", bf.error_rms, "N", "holding: true - target, RMS (target <= 0.5 N RMS)"},
           {bk + "error_max_N", bf.error_max, "N", "holding: true - target, max |e|"},
           {bk + "peak_N", bf.peak, "N", "true force peak, contact to the end of the hold"},
           {bk + "overshoot_pct", bf.overshoot_pct, "%", "overshoot (peak - target) / target (target <= 10 %)"},
           {bk + "contact_mm", bf.contact_mm, "mm", "indentation at contact detection (target <= 2 mm)"},
           {bk + "contact_true_N", bf.contact_force, "N", "true force at contact detection"},
           {bk + "estimate_error_rms_N", bf.estimate_rms, "N", "holding: estimate - true, RMS"}}};
}

/// Distance across the skin from `p` to the polyline through the request's targets, m.
double distanceToPath(const Eigen::Vector2d& p, const std::vector<arm::PressTarget>& path) {
  double best = INFINITY;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d a = path[i - 1].point.head<2>(), c = path[i].point.head<2>();
    const double f = std::clamp((p - a).dot(c - a) / (c - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + f * (c - a))).norm());
  }
  return best;
}

/// The most of a region's cap a stroke is asked for: breathing pushes +-5-10 N on a tool riding the skin.
constexpr double kStrokeShare = 0.75;

/// Strokes of 0.16 m along x over a back rising 2 cm along them (its tissue and breathing as asked), the path's
/// points where a vision error of up to +-3 mm (seeded) put them, at each target force up to 3/4 of the upper back's
/// cap.
Section strokeSection(ArmBench& b, const ForceWorld& w, const Options& o) {
  constexpr double kSlope = 0.125, kLength = 0.16;
  const double x0 = w.point.x(), y0 = w.point.y();
  const auto skin = [&w, x0](double x) { return w.skin + kSlope * (x - x0); };
  const auto body = std::make_shared<const arm::SimBody>([skin](double x, double) { return skin(x); },
                                                         [t = w.tissue](double, double) { return t; }, w.breathing);
  b.cell().setBody(body);
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> vision(-0.003, 0.003);
  const double cap = w.config.regions.at("upper_back").forceCap(w.config.press.contact_area);
  Section section{format("strokes of %.2f m along a back rising %.0f mm (upper_back, cap %.1f N: forces up to 3/4 "
                         "of it), points +-3 mm, at %.0f mm/s: the true force while gliding, the tool across the skin",
                         kLength, 1000.0 * kSlope * kLength, cap, 1000.0 * w.config.force_control.stroke_speed),
                  {}};
  for (double target : o.forces) {
    if (target > kStrokeShare * cap) continue;  // no margin for the breathing under it: the cap would stop it
    arm::PressRequest request;
    request.technique = arm::Technique::kStroke;
    request.mode = arm::PressConfig::Mode::kForce;
    request.force = target;
    for (int i = 0; i <= 4; ++i) {
      const double x = x0 + kLength * i / 4.0;
      request.targets.push_back({format("point %d", i + 1), "upper_back",
                                 Eigen::Vector3d(x, y0 + 0.005 * (i % 2), skin(x) + vision(rng)),
                                 Eigen::Vector3d::UnitZ()});
    }
    const std::string what = format("the stroke at %g N", target);
    const PressRun run = samplePress(b, *body, request, what);
    if (!run.success) throw std::runtime_error(what + (run.refused ? " refused: " : " failed: ") + run.message);
    int n = 0, within_1n = 0, within_10pct = 0;
    double sum2 = 0.0, worst = 0.0, path = 0.0;
    for (const ForceSample& f : run.samples) {
      if (f.phase != Phase::kGlide) continue;
      const double e = f.truth - target;
      ++n;
      sum2 += e * e;
      worst = std::max(worst, std::abs(e));
      within_1n += std::abs(e) <= 1.0;
      within_10pct += std::abs(e) <= 0.1 * target;
      path = std::max(path, distanceToPath(f.xy, request.targets));
    }
    if (n == 0) throw std::runtime_error(what + ": no cycle sampled while gliding");
    const std::string key = "stroke_" + format("%g", target) + "N_";
    section.rows.push_back({key + "error_rms_N", std::sqrt(sum2 / n), "N",
                            format("%g N: true - target while gliding, RMS (%d cycles)", target, n)});
    section.rows.push_back({key + "error_max_N", worst, "N", format("%g N: ... max |e| (target <= 1 N)", target)});
    section.rows.push_back(
        {key + "within_1N_pct", 100.0 * within_1n / n, "%", format("%g N: time within 1 N", target)});
    section.rows.push_back(
        {key + "within_10pct_pct", 100.0 * within_10pct / n, "%", format("%g N: time within 10 %%", target)});
    section.rows.push_back({key + "path_error_max_mm", 1000.0 * path, "mm",
                            format("%g N: the tool's distance from the path, max (target <= 3 mm)", target)});
  }
  return section;
}

/// A press by force holding 3/4 of the region's cap when the client pushes up (the back rises 10 mm at 40 mm/s, faster
/// than the loop may move the tool): the cap stops it. How many cycles from the estimate passing the cap, and from
/// the true force passing it, to the press backing off; how far the true force went past the cap.
Section overForceSection(ArmBench& b, const ForceWorld& w) {
  auto lift = std::make_shared<std::atomic<double>>(0.0);
  const auto body =
      std::make_shared<const arm::SimBody>([lift, skin = w.skin](double, double) { return skin + lift->load(); },
                                           [t = w.tissue](double, double) { return t; }, w.breathing);
  b.cell().setBody(body);
  const double cap = w.cap(), target = 0.75 * cap, period_ms = b.periodMs();
  arm::PressRequest request = onePress("over-force", w.region, w.point, 4.0);
  request.mode = arm::PressConfig::Mode::kForce;
  request.force = target;
  std::optional<Clock::time_point> lifting;
  const PressRun run = samplePress(b, *body, request, "the over-force press", [&](const ForceSample& f) {
    if (f.phase == Phase::kHold && !lifting) lifting = Clock::now() + std::chrono::seconds(1);
    if (lifting && Clock::now() > *lifting)
      lift->store(std::min(0.010, 0.040 * std::chrono::duration<double>(Clock::now() - *lifting).count()));
  });
  lift->store(0.0);
  // Stopped by the cap, or by the force's rate first (a late cycle on a loaded machine makes a steeper rise): both
  // are the over-force stop.
  const bool by_cap = !run.success && run.message.find("passed the press's limit") != std::string::npos;
  const bool by_rate = !run.success && run.message.find("the force rose at") != std::string::npos;
  if (!by_cap && !by_rate)
    throw std::runtime_error("the over-force press was not stopped by its cap or its force rate: " +
                             (run.success ? std::string("it ended") : run.message));
  std::optional<std::uint64_t> estimate_over, truth_over, backing_off, before_backing_off;
  double peak = 0.0;
  for (const ForceSample& f : run.samples) {
    if (!truth_over && f.truth > cap) truth_over = f.cycle;
    if (!estimate_over && f.pressed > cap) estimate_over = f.cycle;
    if (!backing_off && f.phase == Phase::kBackOff) backing_off = f.cycle;
    if (!backing_off) before_backing_off = f.cycle;
    peak = std::max(peak, f.truth);
  }
  const auto cycles = [&](const std::optional<std::uint64_t>& from) {
    return from && backing_off ? static_cast<double>(*backing_off) - static_cast<double>(*from) : NAN;
  };
  // The status is polled, not pushed: on a loaded machine the poll may miss the cycles just before the back-off. When
  // the estimate was not seen past the cap before the back-off and cycles were missed there, it passed it unseen: the
  // latency is unknown (NaN, the missed cycles said), never a negative number.
  const double missed =
      before_backing_off && backing_off ? static_cast<double>(*backing_off - *before_backing_off) - 1 : NAN;
  const bool estimate_unseen = (!estimate_over || (backing_off && *estimate_over > *backing_off)) && missed > 0;
  const double estimate_to_backoff = by_rate ? 0.0 : estimate_unseen ? NAN : cycles(estimate_over) * period_ms;
  return {
      format("over-force: holding %.0f N (%s cap %.1f N), the back pushes up 10 mm at 40 mm/s: %s", target,
             w.region.c_str(), cap, run.message.c_str()),
      {{"overforce_by_rate", by_rate ? 1.0 : 0.0, "", "stopped by the force rate before the cap (1)"},
       {"overforce_estimate_to_backoff_ms", estimate_to_backoff, "ms",
        "the estimate past the cap (or the rate) -> backing off (target <= 10 ms; NaN: passed in unpolled cycles)"},
       {"overforce_unpolled_cycles", missed, "count", "controller cycles the status poll missed before the back-off"},
       {"overforce_truth_to_backoff_ms", cycles(truth_over) * period_ms, "ms",
        "the true force past the cap -> backing off (the estimate's lag included)"},
       {"overforce_peak_N", peak, "N", "true force peak"},
       {"overforce_peak_over_cap_N", peak - cap, "N", "true force peak past the cap"}}};
}

void printSections(const std::vector<Section>& sections, const ForceWorld& w, const Options& o, ArmBench& b) {
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
      w.skin, w.point.x(), w.point.y(), w.tissue.exponent, w.tissue.stiffness, w.tissue.exponent, o.stiffness_scale,
      w.tissue.damping, o.breathing_mm, w.breathing.period, 1000.0 / b.periodMs(),
      realtime.error.empty() ? realtime.describe().c_str() : "real-time refused: see the warning");
  for (const Section& s : sections) {
    std::printf("  %s\n", s.title.c_str());
    for (const Row& r : s.rows) std::printf("    %-60s %10.4f %s\n", r.label.c_str(), r.value, r.unit.c_str());
  }
}

}  // namespace

void forceBench(const Options& o) {
  const auto began = Clock::now();
  const ForceWorld w = forceWorld(o);
  ArmBench b(w.config);
  const auto body = std::make_shared<const arm::SimBody>(arm::SimBody::flat(w.skin, w.tissue, w.breathing));
  b.cell().setBody(body);
  b.start(o);
  // The estimate takes its zero under the identified baseline over a few cycles after homing.
  const auto settle = Clock::now() + std::chrono::seconds(1);
  while (!b.controller().status().force.valid && Clock::now() < settle)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // read 20 cycles after the zero, not at it
  const arm::ForceReading calibrated = b.controller().status().force;
  if (!calibrated.valid) throw std::runtime_error("no force estimate after homing: " + calibrated.problem);

  std::vector<Section> sections{baselineSection(w.config, calibrated)};
  b.recordCycles();  // the cycle's jitter with the force loop running
  DepthTotals depth;
  ByForceTotals by_force;
  for (std::size_t k = 0; k < o.forces.size(); ++k) {
    const double target = o.forces[k];
    if (w.skipped[k].empty()) {
      sections.push_back(depthPress(b, w, *body, target, o.hold, &depth));
    } else {
      const std::string key = "force_" + format("%g", target) + "N_";
      sections.push_back({format("to a depth: %s", w.skipped[k].c_str()),
                          {{key + "depth_mm", w.tissue.indentationAt(target) * 1000.0, "mm", "depth needed"},
                           {key + "skipped", 1.0, "", "skipped (1)"}}});
    }
    sections.push_back(byForcePress(b, w, *body, target, o.hold, &by_force));
  }
  sections.push_back(strokeSection(b, w, o));
  sections.push_back(overForceSection(b, w));
  const std::vector<double> jitter = b.recordedJitter();
  b.stop();
  const ErrorStats overall = errorStats(depth.holds, [](const ForceSample&) { return true; });
  sections.push_back({"all presses to a depth: the estimate's error",
                      {{"force_error_rms_N", overall.rms, "N", "holding: error RMS"},
                       {"force_error_max_N", overall.max, "N", "holding: error max |e|"},
                       {"force_descent_error_max_N", depth.worst_descent, "N", "descent from contact: error max |e|"},
                       {"force_no_contact_max_N", depth.worst_no_contact, "N", "no contact: |estimate| max"},
                       {"force_presses", static_cast<double>(depth.pressed), "count", "presses"},
                       {"force_presses_guarded", static_cast<double>(depth.guarded), "count",
                        "of them stopped by the force guard 5 N before the cap (breathing under a held depth)"}}});
  sections.push_back(
      {"all presses by force: the true force",
       {{"force_byforce_error_rms_max_N", by_force.rms, "N", "hold error RMS, worst target (target <= 0.5 N RMS)"},
        {"force_byforce_error_max_N", by_force.max, "N", "hold error max |e|"},
        {"force_byforce_overshoot_max_pct", by_force.overshoot, "%", "overshoot max (target <= 10 %)"},
        {"force_byforce_contact_mm_max", by_force.contact, "mm", "contact indentation max (target <= 2 mm)"},
        {"force_byforce_estimate_error_rms_max_N", by_force.estimate, "N",
         "holding: estimate - true RMS, worst target"},
        {"force_byforce_presses", static_cast<double>(by_force.ended), "count", "presses ended"},
        {"force_byforce_failed", static_cast<double>(by_force.failed), "count", "presses failed (a limit)"}}});
  sections.push_back({"run",
                      {{"force_cycle_jitter_p99_ms", percentile(jitter, 0.99), "ms",
                        "cycle jitter p99, the force loop running (target <= 2)"},
                       {"runtime_s", std::chrono::duration<double>(Clock::now() - began).count(), "s",
                        "bench runtime (homing included)"}}});
  printSections(sections, w, o, b);
}

}  // namespace massage_cell::tools
