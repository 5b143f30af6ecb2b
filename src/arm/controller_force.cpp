// The arm controller's press by force (see controller.h and force_press.h): the step's phases, each cycle.
//  1. Z to cyclic synchronous position, holding where it stands (the approach point); the force zeroed there.
//  2. Each cycle ForcePress turns the measured force and height into the next height, streamed to Z.
//  3. Z back to profile position; a press that failed (a limit, no contact, an abort) fails the command, with
//     the tool backed off to its approach point and then up to the travel height.
#include "massage_cell/arm/controller.h"

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
  axes_[2]->setModeOfOperation(can::Mode::kCyclicSyncPosition);
  log(s.label + ": Z streams its height (cyclic synchronous position)");
}

bool Controller::tickForcePress(const Step& s) {
  const can::Cia402Axis::Status st = axes_[2]->status();
  switch (force_phase_) {
    case ForcePhase::kEnterCyclic:
      if (st == can::Cia402Axis::Status::kRunning) return false;
      if (st == can::Cia402Axis::Status::kFailed) {
        fault("press by force: Z could not stream its height: " + axes_[2]->error());
        return false;
      }
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
      if (!press_->finished()) return false;
      axes_[2]->setModeOfOperation(can::Mode::kProfilePosition);
      force_phase_ = ForcePhase::kLeaveCyclic;
      return false;
    }
    case ForcePhase::kLeaveCyclic:
      if (st == can::Cia402Axis::Status::kRunning) return false;
      if (st == can::Cia402Axis::Status::kFailed) {
        fault("press by force: Z could not return to profile position: " + axes_[2]->error());
        return false;
      }
      if (press_ && press_->phase() == ForcePress::Phase::kFailed && !aborting_) {
        log("press by force failed: " + press_->failure());
        aborting_ = true;
        abort_reason_ = press_->failure();
      }
      if (aborting_) {
        // The command fails with the reason; from the approach point the tool goes up to the travel height.
        queue_.clear();
        Action up{Action::Kind::kStep};
        up.step = retractSteps(config_, s).back();
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

}  // namespace massage_cell::arm
