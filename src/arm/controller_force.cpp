// The arm controller's press by force (see controller.h and force_press.h): the step's phases, each cycle.
//  1. Z (a stroke: X, Y and Z) to cyclic synchronous position, holding where it stands (the approach point); the
//     force zeroed there.
//  2. Each cycle ForcePress turns the measured force and height into the next height, streamed to Z (a stroke: and
//     where along its path the tool is, streamed to X and Y).
//  3. The streaming axes back to profile position; a press that failed (a limit, no contact, an abort) fails the
//     command, with the tool backed off straight up and then up to the travel height.
#include "massage_cell/arm/controller.h"

#include <cstdio>

namespace massage_cell::arm {

void Controller::startForcePress(const Step& s) {
  press_.reset();
  force_phase_ = ForcePhase::kEnterCyclic;
  if (const ForceReading f = tool_force_->reading(); !f.valid) {
    // Nothing moved yet: the press is refused where it stands (the approach point).
    abortForcePress("no force to press by: " + f.problem);
    force_phase_ = ForcePhase::kLeaveCyclic;
    return;
  }
  for (int i = 0; i < 3; ++i) {
    if (streamingAxes(s) & (1u << i)) axes_[i]->setModeOfOperation(can::Mode::kCyclicSyncPosition);
  }
  log(s.label + (s.force.path.empty() ? ": Z streams its height (cyclic synchronous position)"
                                      : ": X, Y and Z stream the path (cyclic synchronous position)"));
}

unsigned Controller::streamingAxes(const Step& s) { return s.force.path.empty() ? 0b100u : 0b111u; }

bool Controller::streamingModeSet(const Step& s, const std::string& what) {
  for (int i = 0; i < 3; ++i) {
    if (!(streamingAxes(s) & (1u << i))) continue;
    const can::Cia402Axis::Status st = axes_[i]->status();
    if (st == can::Cia402Axis::Status::kRunning) return false;
    if (st == can::Cia402Axis::Status::kFailed) {
      fault("press by force: " + config_.axis(i).name + " could not " + what + ": " + axes_[i]->error());
      return false;
    }
  }
  return true;
}

bool Controller::tickForcePress(const Step& s) {
  switch (force_phase_) {
    case ForcePhase::kEnterCyclic:
      if (!streamingModeSet(s, "stream its position")) return false;
      {
        ForcePressGoal goal = s.force;
        goal.start_z = config_.toolOf(joints()).z();
        press_ = std::make_unique<ForcePress>(config_.force_control, goal);
      }
      force_phase_ = ForcePhase::kPressing;
      if (aborting_) press_->abort(abort_reason_);
      return false;
    case ForcePhase::kPressing: {
      const ForceReading f = tool_force_->reading();
      const double dt = config_.can.sync_period_us / 1e6;
      const double z = config_.toolOf(joints()).z();
      const double tool_z = press_->update(f.valid ? f.force : NAN, z, dt);
      const double joint_z = tool_z - config_.tool_offset.z();
      axes_[2]->setCyclicTarget(config_.axis(2).toCounts(joint_z));
      if (!s.force.path.empty()) {
        const Eigen::Vector2d joint_xy = press_->xy() - config_.tool_offset.head<2>();
        for (int i = 0; i < 2; ++i) axes_[i]->setCyclicTarget(config_.axis(i).toCounts(joint_xy[i]));
      }
      if (!press_->finished()) return false;
      for (int i = 0; i < 3; ++i) {
        if (streamingAxes(s) & (1u << i)) axes_[i]->setModeOfOperation(can::Mode::kProfilePosition);
      }
      force_phase_ = ForcePhase::kLeaveCyclic;
      return false;
    }
    case ForcePhase::kLeaveCyclic:
      if (!streamingModeSet(s, "return to profile position")) return false;
      if (press_ && press_->phase() == ForcePress::Phase::kFailed && !aborting_) {
        log("press by force failed: " + press_->failure());
        aborting_ = true;
        abort_reason_ = press_->failure();
      }
      if (aborting_) {
        // The command fails with the reason; from where it backed off the tool goes up to the travel height.
        queue_.clear();
        Action up{Action::Kind::kStep};
        up.step = retractSteps(config_, s).back();
        up.step.tool.head<2>() = config_.toolOf(joints()).head<2>();
        queue_.push_back(std::move(up));
      }
      return true;
  }
  return false;
}

void Controller::abortForcePress(const std::string& why) {
  if (aborting_) return;
  aborting_ = true;
  abort_reason_ = why;
  queue_.clear();
  if (press_) press_->abort(why);
  log("press by force: backing off: " + why);
}

namespace {

/// N below its region's cap a press to a depth is stopped: the estimate's lag (20 ms filter) and the quick stop let
/// 4-9 N more through at the press's 10 mm/s (test_arm_force_fuzz, presses by depth: +8.7 N over the cap when stopped
/// at it; test_arm_controller: 63.9 N on a 60 N cap).
constexpr double kDepthGuardMargin = 5.0;

}  // namespace

void Controller::guardForce() {
  if (!current_ || current_->kind != Action::Kind::kStep || aborting_) return;
  const Step& s = current_->step;
  if (s.kind == Step::Kind::kForcePress || s.retract || s.force_calibration) return;
  const ForceReading f = tool_force_->reading();
  if (!f.valid) return;
  const Eigen::Vector3d at = config_.toolOf(joints());
  char buf[200];
  std::vector<Step> away;
  if (s.contact) {  // a press to a depth: its region's cap; then back along the press line and up
    if (!(s.force_cap > 0.0) || f.force <= s.force_cap - kDepthGuardMargin) return;
    std::snprintf(buf, sizeof buf,
                  "the force %.1f N came within %.0f N of the region's limit %.1f N while pressing to a depth", f.force,
                  kDepthGuardMargin, s.force_cap);
    away = retractSteps(config_, s);
  } else {  // a move toward the body met it: straight up from where the tool stands
    if (f.force <= config_.force_control.move_guard) return;
    std::snprintf(buf, sizeof buf,
                  "the tool met %.1f N (guard %.1f N) at %s on its way (%s): the body is not where "
                  "vision saw it",
                  f.force, config_.force_control.move_guard, formatPoint(at).c_str(), s.label.c_str());
    Step up;
    up.tool = Eigen::Vector3d(at.x(), at.y(), std::max(at.z(), config_.press.travel_height));
    up.speed = config_.press.retract_speed;
    up.accel = config_.press.acceleration;
    up.retract = true;
    up.label = "force guard: straight up to the travel height";
    away.push_back(up);
  }
  // Quick stop first (the drives' fastest deceleration), then away from the body; the command fails with the reason.
  aborting_ = true;
  abort_reason_ = buf;
  queue_ = {Action{Action::Kind::kQuickStopAll}, Action{Action::Kind::kEnableAll}, Action{Action::Kind::kProfileMode}};
  for (Step& step : away) {
    Action a{Action::Kind::kStep};
    a.step = std::move(step);
    queue_.push_back(std::move(a));
  }
  current_.reset();
  log(std::string("force guard: ") + buf);
}

}  // namespace massage_cell::arm
