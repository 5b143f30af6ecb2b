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
/// Cycles in a row the force must rise faster than max_force_rate to be a hit: a hit keeps rising, one late sample
/// on a loaded machine is a single step (arm.test's stroke read 1178 N/s once, qemu_can_force 1881 N/s, both on soft
/// tissue); the second cycle costs 10 ms against bone.
constexpr int kRateCycles = 2;
/// The seek's first cycles, in the air (1.25 mm at 5 mm/s, 28 mm above where vision put the skin): after
/// kAirSettleCycles (the estimate's filters settled after the start: its acceleration low-pass is 50 ms), the mean of
/// kAirCycles is the press's zero. Taken sliding, where the friction is known (coulomb, in the seek's direction): the
/// estimate's own zero, taken standing at the approach point, carries the static friction's unknown state and one
/// filtered sample's noise (test_arm_force_fuzz read 3-9 N in the air after standing 0.1-0.25 s; the 30 N hold of
/// test_arm_controller: 1.57 N RMS with the estimate's zero, 2.04 with the zero taken standing, 1.49 taken sliding).
constexpr int kAirSettleCycles = 15;
constexpr int kAirCycles = 10;
/// Sliding against the zero taken standing, the air reads what the static friction's state was: up to 3.2 N in
/// test_arm_force_fuzz's 150 requests. More than this many contact forces is not the air.
constexpr double kAirLimit = 2.0;
/// m of arc length over which a stroke's skin heights are smoothed (a local linear fit): vision puts each point's
/// height within 3-5 mm, and between points 4 cm apart that is a slope error of up to 0.2 fed forward at the glide
/// speed; over +-8 cm (3-4 points) the fit halves it, while a back's curvature bends the fit by ~1 mm
/// (test_force_press, +-3 mm on points 4 cm apart: the stroke's force error 1.1-1.2 N RMS between straight legs,
/// 0.8-1.0 N smoothed over 8 cm; 5-16 cm all give 0.7-1.1 N).
constexpr double kSkinSmoothing = 0.08;

}  // namespace

const char* toString(ForcePress::Phase phase) {
  switch (phase) {
    case ForcePress::Phase::kSeek:
      return "seek";
    case ForcePress::Phase::kRamp:
      return "ramp";
    case ForcePress::Phase::kHold:
      return "hold";
    case ForcePress::Phase::kGlide:
      return "glide";
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
    : c_(config), g_(goal), z_cmd_(goal.start_z), contact_z_(NAN), last_force_(NAN), xy_(NAN, NAN) {
  if (g_.path.empty()) return;
  xy_ = g_.path.front().head<2>();
  if (g_.path.size() < 2) {
    g_.path.clear();  // a press in place where it is, backing off at once
    fail("a stroke's path needs at least two points");
    return;
  }
  arc_.push_back(0.0);
  for (std::size_t i = 1; i < g_.path.size(); ++i)
    arc_.push_back(arc_.back() + (g_.path[i] - g_.path[i - 1]).head<2>().norm());
}

double ForcePress::progress() const { return arc_.empty() || arc_.back() <= 0.0 ? 0.0 : s_ / arc_.back(); }

double ForcePress::expectedSkin() const {
  if (arc_.empty()) return g_.expected_skin_z;
  // A local linear fit (tricube weights) of the path's heights against arc length, around where the tool is.
  double sw = 0.0, sa = 0.0, sz = 0.0, saa = 0.0, saz = 0.0;
  for (std::size_t i = 0; i < arc_.size(); ++i) {
    const double d = std::abs(arc_[i] - s_) / kSkinSmoothing;
    if (d >= 1.0) continue;
    const double w = std::pow(1.0 - d * d * d, 3.0);
    const double a = arc_[i] - s_;
    sw += w;
    sa += w * a;
    sz += w * g_.path[i].z();
    saa += w * a * a;
    saz += w * a * g_.path[i].z();
  }
  const double det = sw * saa - sa * sa;
  if (sw > 0.0 && det > 1e-12 * sw * sw) return (saa * sz - sa * saz) / det;
  // Too few points around (legs longer than the smoothing): straight between the two points either side.
  const std::size_t i = leg();
  const double span = arc_[i] - arc_[i - 1];
  const double f = span > 0.0 ? std::clamp((s_ - arc_[i - 1]) / span, 0.0, 1.0) : 1.0;
  return g_.path[i - 1].z() + f * (g_.path[i].z() - g_.path[i - 1].z());
}

double ForcePress::indentation(double z) const {
  // The skin found at contact, carried along the path as vision shaped it.
  if (!std::isfinite(contact_z_)) return 0.0;
  return contact_z_ + (expectedSkin() - g_.expected_skin_z) - z;
}

std::size_t ForcePress::leg() const {
  return std::clamp<std::size_t>(std::upper_bound(arc_.begin(), arc_.end(), s_) - arc_.begin(), 1, arc_.size() - 1);
}

double ForcePress::maxIndentation() const {
  // Each region's own guard (thin tissue over the lungs, thick lumbar muscles): a stroke from the upper to the lower
  // back at one force sinks deeper where the tissue is softer.
  if (g_.path_max_indentation.size() != g_.path.size() || g_.path.size() < 2) return g_.max_indentation;
  const std::size_t i = leg();
  return std::min(g_.path_max_indentation[i - 1], g_.path_max_indentation[i]);
}

double ForcePress::backOffZ() const { return g_.start_z + (expectedSkin() - g_.expected_skin_z); }

double ForcePress::glide(double dt) {
  const double length = arc_.back();
  const double remaining = length - s_;
  // Accelerate to the glide speed, brake to stop at the end (never slower than one cycle's acceleration: it ends).
  speed_ = std::max(c_.glide_accel * dt, std::min({g_.glide_speed, speed_ + c_.glide_accel * dt,
                                                   std::sqrt(2.0 * c_.glide_accel * std::max(0.0, remaining))}));
  const double before = expectedSkin();
  s_ = std::min(length, s_ + speed_ * dt);
  const std::size_t i = leg();
  const double span = arc_[i] - arc_[i - 1];
  const double f = span > 0.0 ? std::clamp((s_ - arc_[i - 1]) / span, 0.0, 1.0) : 1.0;
  xy_ = g_.path[i - 1].head<2>() + f * (g_.path[i] - g_.path[i - 1]).head<2>();
  return expectedSkin() - before;
}

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
  rising_ = rate > c_.max_force_rate ? rising_ + 1 : 0;
  if (rising_ >= kRateCycles)
    return fmt("the force rose at %.0f N/s (limit %.0f N/s): the tool hit something, not soft tissue", rate,
               c_.max_force_rate);
  if (const double limit = maxIndentation(); indentation(z) > limit)
    return fmt(arc_.empty() ? "the tool sank %.1f mm past the contact point (limit %.1f mm)"
                            : "the tool sank %.1f mm past the skin along the stroke (limit %.1f mm)",
               1000.0 * indentation(z), 1000.0 * limit);
  if (phase_ == Phase::kSeek && z < expectedSkin() - c_.no_contact_band)
    return fmt("no contact %.1f mm below where vision put the skin (band %.1f mm): the body is not where it was seen",
               1000.0 * (expectedSkin() - z), 1000.0 * c_.no_contact_band);
  return {};
}

double ForcePress::localStiffness(double force, double z) const {
  // The power law's slope n F / x, x from the contact point (plus the contact force's own indentation, ~0.5 mm).
  const double x = std::max(0.0, indentation(z)) + kContactIndentation;
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

double ForcePress::zero() const { return air_cycles_ >= kAirSettleCycles + kAirCycles ? air_ : 0.0; }

bool ForcePress::measureAir(double force) {
  ++air_cycles_;
  if (!std::isfinite(force)) {
    fail("the force is not known (the estimate is not valid)");
  } else if (force > g_.max_force) {
    fail(fmt("the force %.1f N leaving the approach point passed the press's limit %.1f N: something presses the tool",
             force, g_.max_force));
  } else if (air_cycles_ > kAirSettleCycles) {
    air_ += force / kAirCycles;
    if (air_cycles_ == kAirSettleCycles + kAirCycles && std::abs(air_) > kAirLimit * c_.contact_force)
      fail(
          fmt("the force reads %.1f N leaving the approach point, in the air (more than %.1f N): something touches "
              "the tool, or the force is off",
              air_, kAirLimit * c_.contact_force));
  }
  return phase_ == Phase::kSeek && air_cycles_ < kAirSettleCycles + kAirCycles;
}

double ForcePress::update(double force, double z, double dt) {
  if (finished()) return z_cmd_;
  const int in_air = kAirSettleCycles + kAirCycles;
  if (phase_ == Phase::kSeek && air_cycles_ < in_air && measureAir(force)) {
    z_cmd_ -= c_.seek_speed * dt;
    return z_cmd_;
  }
  force -= air_;
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
      if (above_ >= kContactCycles && z > expectedSkin() + c_.early_contact_band) {
        fail(
            fmt("contact (%.1f N) %.1f mm above where vision put the skin (band %.1f mm): not the skin where it was "
                "seen",
                force, 1000.0 * (z - expectedSkin()), 1000.0 * c_.early_contact_band));
      } else if (above_ >= kContactCycles) {
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
      if (set_point_ >= g_.force) phase_ = arc_.empty() ? Phase::kHold : Phase::kGlide;
      break;
    }
    case Phase::kGlide: {
      // Along the path at the force: the skin's expected rise or fall moves the tool with it, the force corrects.
      const double skin_change = glide(dt);
      z_cmd_ = admittance(force, z, 0.0, dt) + skin_change;
      if (s_ >= arc_.back()) phase_ = Phase::kRelease;
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
    case Phase::kBackOff: {
      // Up only, to the approach height over the skin where the tool is (a stroke's end may lie above its start).
      const double to = backOffZ();
      const double from = std::max(z_cmd_, z);
      const double speed = failure_.empty() ? c_.release_speed : c_.escape_speed;
      z_cmd_ = from >= to ? from : std::min(to, from + speed * dt);
      if (z_cmd_ >= to && z >= to - kArrived) phase_ = failure_.empty() ? Phase::kDone : Phase::kFailed;
      break;
    }
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
    case Phase::kGlide:
      return fmt("gliding at %.0f N, %.0f %% of the path", g_.force, 100.0 * progress());
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
