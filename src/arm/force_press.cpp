// A press by force (see force_press.h).
#include "massage_cell/arm/force_press.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace massage_cell::arm {

namespace {

std::string fmt(const char* format, double a, double b = 0.0, double c = 0.0) {
  char buf[200];
  std::snprintf(buf, sizeof buf, format, a, b, c);
  return buf;
}

/// A measured height within this of where the back-off aims counts as there.
constexpr double kArrived = 0.0005;
/// How deep the contact force itself has pressed the tissue when contact is seen (~3 N on 4 N/mm tissue).
constexpr double kContactIndentation = 0.0005;
/// Cycles in a row the force must stay above contact_force to be a contact.
constexpr int kContactCycles = 3;

}  // namespace

const char* toString(ForcePress::Phase phase) {
  switch (phase) {
    case ForcePress::Phase::kSeek:
      return "seek";
    case ForcePress::Phase::kRamp:
      return "ramp";
    case ForcePress::Phase::kHold:
      return "hold";
    case ForcePress::Phase::kRelease:
      return "release";
    case ForcePress::Phase::kBackOff:
      return "back off";
    case ForcePress::Phase::kDone:
      return "done";
    case ForcePress::Phase::kFailed:
      return "failed";
  }
  return "?";
}

ForcePress::ForcePress(const ForceControlConfig& config, const ForcePressGoal& goal)
    : c_(config), g_(goal), z_cmd_(goal.start_z), contact_z_(NAN), last_force_(NAN) {}

void ForcePress::fail(const std::string& why) {
  if (failure_.empty()) failure_ = why;
  phase_ = Phase::kBackOff;
  set_point_ = 0.0;
}

void ForcePress::abort(const std::string& why) {
  if (!finished()) fail(why);
}

std::string ForcePress::checkLimits(double force, double z, double dt) {
  const double rate = std::isfinite(last_force_) && dt > 0.0 ? (force - last_force_) / dt : 0.0;
  if (force > g_.max_force)
    return fmt("the force %.1f N passed the press's limit %.1f N (the region's force and pressure limits)", force,
               g_.max_force);
  if (rate > c_.max_force_rate)
    return fmt("the force rose at %.0f N/s (limit %.0f N/s): the tool hit something, not soft tissue", rate,
               c_.max_force_rate);
  if (std::isfinite(contact_z_) && contact_z_ - z > g_.max_indentation)
    return fmt("the tool sank %.1f mm past the contact point (limit %.1f mm)", 1000.0 * (contact_z_ - z),
               1000.0 * g_.max_indentation);
  if (phase_ == Phase::kSeek && z < g_.expected_skin_z - c_.no_contact_band)
    return fmt("no contact %.1f mm below where vision put the skin (band %.1f mm): the body is not where it was seen",
               1000.0 * (g_.expected_skin_z - z), 1000.0 * c_.no_contact_band);
  return {};
}

double ForcePress::localStiffness(double force, double z) const {
  // The power law's slope n F / x, x from the contact point (plus the contact force's own indentation, ~0.5 mm).
  const double x = std::max(0.0, contact_z_ - z) + kContactIndentation;
  return std::clamp(c_.tissue_exponent * std::max(force, c_.contact_force) / x, c_.min_stiffness, c_.max_stiffness);
}

double ForcePress::admittance(double force, double z, double feed_forward, double dt) {
  // Too little force: down (z falls); too much: up. The integral follows the breathing's slow push without a lag.
  const double k = localStiffness(force, z);
  const double error = set_point_ - force;
  const double integral_limit = c_.integral > 0.0 ? c_.max_speed * k / c_.integral : 0.0;
  integral_ = std::clamp(integral_ + error * dt, -integral_limit, integral_limit);
  const double v =
      std::clamp((feed_forward + c_.bandwidth * error + c_.integral * integral_) / k, -c_.max_speed, c_.max_speed);
  return z_cmd_ - v * dt;
}

double ForcePress::update(double force, double z, double dt) {
  if (finished()) return z_cmd_;
  if (phase_ != Phase::kBackOff) {
    if (!std::isfinite(force)) {
      fail("the force is not known (the estimate is not valid)");
    } else if (std::string why = checkLimits(force, z, dt); !why.empty()) {
      fail(why);
    }
  }
  last_force_ = force;
  switch (phase_) {
    case Phase::kSeek:
      // Contact: the force above contact_force for kContactCycles cycles in a row (one noisy sample in the air is
      // not the skin; at 5 mm/s the wait costs 0.1 mm of indentation).
      above_ = force > c_.contact_force ? above_ + 1 : 0;
      if (above_ >= kContactCycles) {
        contact_z_ = z;
        set_point_ = force;
        integral_ = 0.0;
        phase_ = Phase::kRamp;
      } else {
        z_cmd_ -= c_.seek_speed * dt;
      }
      break;
    case Phase::kRamp: {
      const double before = set_point_;
      set_point_ = std::min(g_.force, set_point_ + c_.ramp_rate * dt);
      z_cmd_ = admittance(force, z, (set_point_ - before) / dt, dt);
      if (set_point_ >= g_.force) phase_ = Phase::kHold;
      break;
    }
    case Phase::kHold:
      held_ += dt;
      z_cmd_ = admittance(force, z, 0.0, dt);
      if (held_ >= g_.hold) phase_ = Phase::kRelease;
      break;
    case Phase::kRelease: {
      const double before = set_point_;
      set_point_ = std::max(0.0, set_point_ - c_.ramp_rate * dt);
      z_cmd_ = admittance(force, z, (set_point_ - before) / dt, dt);
      if (set_point_ <= 0.0) phase_ = Phase::kBackOff;
      break;
    }
    case Phase::kBackOff:
      z_cmd_ = std::min(g_.start_z, std::max(z_cmd_, z) + c_.release_speed * dt);
      if (z_cmd_ >= g_.start_z && std::abs(z - g_.start_z) <= kArrived)
        phase_ = failure_.empty() ? Phase::kDone : Phase::kFailed;
      break;
    case Phase::kDone:
    case Phase::kFailed:
      break;
  }
  return z_cmd_;
}

std::string ForcePress::describe() const {
  switch (phase_) {
    case Phase::kSeek:
      return "seeking the skin";
    case Phase::kRamp:
      return fmt("ramping to %.0f N", g_.force);
    case Phase::kHold:
      return fmt("holding %.0f N", g_.force);
    case Phase::kRelease:
      return "releasing";
    case Phase::kBackOff:
      return failure_.empty() ? "backing off" : "backing off: " + failure_;
    case Phase::kDone:
      return "done";
    case Phase::kFailed:
      return "failed: " + failure_;
  }
  return "?";
}

}  // namespace massage_cell::arm
