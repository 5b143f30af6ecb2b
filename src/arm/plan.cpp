// Press planning and envelope checks (see plan.h).
#include "massage_cell/arm/plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

namespace massage_cell::arm {

namespace {

std::string mm(double metres) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f mm", metres * 1000.0);
  return buf;
}

std::string m3(double metres) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", metres);
  return buf;
}

/// Two unit vectors spanning the plane perpendicular to n.
void tangentBasis(const Eigen::Vector3d& n, Eigen::Vector3d* u, Eigen::Vector3d* v) {
  const Eigen::Vector3d ref = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *u = n.cross(ref).normalized();
  *v = n.cross(*u).normalized();
}

}  // namespace

const char* toString(Technique t) {
  switch (t) {
    case Technique::kPress:
      return "press";
    case Technique::kKnead:
      return "knead";
    case Technique::kStroke:
      return "stroke";
  }
  return "?";
}

HeightGrid::HeightGrid(const std::vector<Eigen::Vector3d>& points, double cell, const Eigen::Vector2d& lo,
                       const Eigen::Vector2d& hi)
    : cell_(cell) {
  const auto inside = [&](const Eigen::Vector3d& p) {
    return p.allFinite() && p.x() >= lo.x() && p.x() <= hi.x() && p.y() >= lo.y() && p.y() <= hi.y();
  };
  double x1 = -INFINITY, y1 = -INFINITY;
  x0_ = INFINITY;
  y0_ = INFINITY;
  for (const Eigen::Vector3d& p : points) {
    if (!inside(p)) continue;
    x0_ = std::min(x0_, p.x());
    y0_ = std::min(y0_, p.y());
    x1 = std::max(x1, p.x());
    y1 = std::max(y1, p.y());
  }
  if (!(cell > 0.0) || !std::isfinite(x0_)) return;
  nx_ = static_cast<int>((x1 - x0_) / cell) + 1;
  ny_ = static_cast<int>((y1 - y0_) / cell) + 1;
  z_.assign(static_cast<std::size_t>(nx_) * ny_, NAN);
  for (const Eigen::Vector3d& p : points) {
    if (!inside(p)) continue;
    float& z = z_[static_cast<std::size_t>(static_cast<int>((p.y() - y0_) / cell)) * nx_ +
                  static_cast<int>((p.x() - x0_) / cell)];
    if (!(z >= p.z())) z = static_cast<float>(p.z());  // NaN or lower: the higher point
  }
}

std::optional<double> HeightGrid::heightAt(double x, double y) const {
  if (z_.empty()) return std::nullopt;
  const int cx = static_cast<int>(std::floor((x - x0_) / cell_)), cy = static_cast<int>(std::floor((y - y0_) / cell_));
  std::optional<double> best;
  for (int j = std::max(0, cy - 1); j <= std::min(ny_ - 1, cy + 1); ++j) {
    for (int i = std::max(0, cx - 1); i <= std::min(nx_ - 1, cx + 1); ++i) {
      const float z = z_[static_cast<std::size_t>(j) * nx_ + i];
      if (std::isfinite(z) && (!best || z > *best)) best = z;
    }
  }
  return best;
}

std::optional<double> BodySurface::heightAt(double x, double y, double radius) const {
  std::optional<double> z;
  double best = radius * radius;
  for (const Eigen::Vector3d& p : points) {
    const double d2 = (p.x() - x) * (p.x() - x) + (p.y() - y) * (p.y() - y);
    if (d2 <= best) {
      best = d2;
      z = p.z();
    }
  }
  return z;
}

std::string checkBodyClearance(const ArmConfig& c, const BodySurface& body, const Eigen::Vector3d& from,
                               const Eigen::Vector3d& to, double max_depth) {
  const double length = (to - from).norm();
  const int n = std::max(1, static_cast<int>(std::ceil(length / 0.005)));  // samples every 5 mm
  const double floor_unknown = std::min(c.body.safe_height, from.z());
  for (int k = 0; k < n; ++k) {
    const int i = k == 0 ? n : k;  // the target first: its depth is what a refusal should name
    const Eigen::Vector3d p = from + (to - from) * (static_cast<double>(i) / n);
    const std::string what = i == n ? "the target " + formatPoint(p) : "the path at " + formatPoint(p);
    const auto skin = body.heightAt(p.x(), p.y(), c.body.radius);
    const auto seen = body.dense.heightAt(p.x(), p.y());
    if (skin && p.z() < *skin - max_depth - 1e-9) {
      char buf[96];
      std::snprintf(buf, sizeof buf, " is %.1f mm below the body's surface (limit %.1f mm)", 1e3 * (*skin - p.z()),
                    1e3 * max_depth);
      return what + buf;
    }
    if (seen && p.z() < *seen - max_depth - c.body.surface_tolerance - 1e-9) {
      char buf[128];
      std::snprintf(buf, sizeof buf, " is %.1f mm below the surface stereo sees (limit %.1f mm: %.1f + its error %.1f)",
                    1e3 * (*seen - p.z()), 1e3 * (max_depth + c.body.surface_tolerance), 1e3 * max_depth,
                    1e3 * c.body.surface_tolerance);
      return what + buf;
    }
    if (!skin && !seen && p.z() < floor_unknown - 1e-9) {
      char buf[128];
      std::snprintf(buf, sizeof buf, " is below the safe height %.3f m, and no body surface is known there",
                    c.body.safe_height);
      return what + buf;
    }
  }
  return "";
}

double maxLineSpeed(const ArmConfig& c) {
  double sum = 0.0;
  for (const JointLimits& j : c.joints) sum += j.max_velocity * j.max_velocity;
  return std::sqrt(sum);
}

double distanceFromPath(const Eigen::Vector2d& p, const std::vector<Eigen::Vector3d>& path) {
  if (path.size() == 1) return (p - path[0].head<2>()).norm();
  double best = INFINITY;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d a = path[i - 1].head<2>(), b = path[i].head<2>();
    const double len2 = (b - a).squaredNorm();
    const double f = len2 > 0.0 ? std::clamp((p - a).dot(b - a) / len2, 0.0, 1.0) : 0.0;
    best = std::min(best, (p - (a + f * (b - a))).norm());
  }
  return best;
}

std::string formatPoint(const Eigen::Vector3d& p) {
  return "(" + m3(p.x()) + ", " + m3(p.y()) + ", " + m3(p.z()) + ") m";
}

std::string checkTool(const ArmConfig& c, const Eigen::Vector3d& tool) {
  if (!tool.allFinite()) return "the position is not finite";
  for (int k = 0; k < 3; ++k) {
    const char axis = "xyz"[k];
    if (tool[k] < c.workspace_min[k]) {
      return formatPoint(tool) + " is outside the workspace envelope: " + axis + " below " + m3(c.workspace_min[k]) +
             " m";
    }
    if (tool[k] > c.workspace_max[k]) {
      return formatPoint(tool) + " is outside the workspace envelope: " + axis + " above " + m3(c.workspace_max[k]) +
             " m";
    }
  }
  const Eigen::Vector3d q = c.jointsOf(tool);
  for (int k = 0; k < 3; ++k) {
    if (q[k] < c.joints[k].min || q[k] > c.joints[k].max) {
      return formatPoint(tool) + " needs joint " + c.axis_names[k] + " at " + m3(q[k]) + " m, outside its limits [" +
             m3(c.joints[k].min) + ", " + m3(c.joints[k].max) + "] m";
    }
  }
  return "";
}

std::vector<Step> retractSteps(const ArmConfig& c, const Step& from) {
  std::vector<Step> out;
  Step back;
  back.tool = from.retreat;
  back.speed = c.press.retract_speed;
  back.accel = c.press.acceleration;
  back.label = "retract";
  back.retract = true;
  back.contact = true;
  back.target = from.target;
  back.retreat = from.retreat;
  out.push_back(back);
  Step up = back;
  up.tool.z() = std::max(from.retreat.z(), c.press.travel_height);
  up.speed = 0.0;
  up.accel = 0.0;
  up.contact = false;
  up.label = "retract: up to the travel height";
  out.push_back(up);
  return out;
}

namespace {

/// The request's own limits (targets, hold, repeats, speed, depth) and the tool's current position; the hold and
/// speed to use (a request's negative hold / zero speed: the configuration's).
std::string checkRequest(const ArmConfig& c, const Eigen::Vector3d& from, const PressRequest& req, double* hold,
                         double* speed) {
  const PressConfig& pc = c.press;
  if (req.targets.empty()) return "no target given";
  if (req.targets.size() > static_cast<std::size_t>(pc.max_targets)) {
    return std::to_string(req.targets.size()) + " targets: at most " + std::to_string(pc.max_targets) +
           " in one request (press.max_targets)";
  }
  *hold = req.hold < 0.0 ? pc.hold : req.hold;
  if (!std::isfinite(*hold) || *hold > pc.max_hold) {
    return "hold " + m3(*hold) + " s is beyond the limit " + m3(pc.max_hold) + " s";
  }
  if (req.repeats < 1 || req.repeats > pc.max_repeats) {
    return "repeats must be 1.." + std::to_string(pc.max_repeats) + ", got " + std::to_string(req.repeats);
  }
  const bool stroke = req.technique == Technique::kStroke;
  *speed = req.speed != 0.0 ? req.speed : stroke ? c.force_control.stroke_speed : pc.speed;
  if (!(*speed > 0.0) || *speed > pc.max_speed) {
    return "speed " + m3(*speed) + " m/s must be in (0, " + m3(pc.max_speed) + "] m/s";
  }
  if (!std::isfinite(req.depth) || req.depth < 0.0) return "depth must be >= 0 m (0: the region's default)";
  if (!std::isfinite(req.force) || req.force < 0.0) return "force must be >= 0 N (0: the region's default)";
  const bool by_force = req.mode.value_or(pc.mode) == PressConfig::Mode::kForce;
  if (by_force && !c.force.enabled) return "a press by force needs the tool's force (config force:)";
  if (by_force && req.depth > 0.0) return "a depth is for presses to a depth (mode depth), not by force";
  if (!by_force && req.force > 0.0) return "a force is for presses by force (mode force), not to a depth";
  if (stroke && !by_force) return "a stroke glides at a force: mode force, not depth";
  if (stroke && req.targets.size() < 2) return "a stroke needs a path of at least two points (frames or points)";
  if (stroke && req.hold >= 0.0) return "a stroke holds its force while it glides: give no hold";
  if (std::string bad = checkTool(c, from); !bad.empty()) return "the tool's current position " + bad;
  return "";
}

/// Where one target is pressed: approach point on its normal, the press end point at the region's depth, the travel
/// height above them, and (kneading) the circle around the pressed point; every point within the arm's reach.
struct PressGeometry {
  std::string who;  ///< the target's name, or "target N"
  Eigen::Vector3d approach, bottom;
  double travel_z = 0.0;
  std::vector<Eigen::Vector3d> circle;            ///< kneading: the circle's points, closed
  int circles = 0;                                ///< ... and how many times it is run
  std::optional<ForcePressGoal> force;            ///< a press by force (bottom: the seek's lowest point)
  Eigen::Vector3d end = Eigen::Vector3d::Zero();  ///< a stroke: the approach point over its last point
  double force_cap = 0.0;  ///< N, a press to a depth: its region's force cap (0: none configured)
};

/// The target's region (the configuration's default when it names none), or why it is not known.
std::string regionOf(const ArmConfig& c, const PressTarget& t, const std::string& who, std::string* region) {
  *region = t.region.empty() ? c.default_region : t.region;
  if (c.regions.count(*region)) return "";
  std::string known;
  for (const auto& kv : c.regions) known += (known.empty() ? "" : ", ") + kv.first;
  return who + ": unknown region '" + *region + "' (known: " + known + ")";
}

/// Segments of a circle kneaded by force: the tool glides round it without stopping, so its direction turns by
/// 10 deg at each corner (at the default 25 mm/s a 4 mm circle asks ~0.16 m/s^2 of X and Y, within their 0.5).
constexpr int kForceKneadSegments = 36;

/// Kneading by force: from the pressed point out to a circle of knead_radius across the skin (horizontal: the
/// press is vertical), round it once per knead_period for the hold, back to the point; every point within reach.
std::string kneadPath(const ArmConfig& c, const Eigen::Vector3d& centre, double hold, ForcePressGoal* goal) {
  const PressConfig& pc = c.press;
  const int circles = std::max(1, static_cast<int>(std::lround(hold / pc.knead_period)));
  goal->path = {centre};
  for (int k = 0; k < circles * kForceKneadSegments; ++k) {
    const double a = 2.0 * M_PI * k / kForceKneadSegments;
    goal->path.push_back(centre + pc.knead_radius * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0));
  }
  goal->path.push_back(goal->path[1]);  // the last circle closed
  goal->path.push_back(centre);
  goal->glide_speed = std::min(pc.max_speed, 2.0 * M_PI * pc.knead_radius / pc.knead_period);
  for (int k = 1; k <= kForceKneadSegments; ++k) {
    if (std::string bad = checkTool(c, goal->path[k]); !bad.empty()) return "the knead point " + bad;
  }
  return "";
}

/// Why `force` may not be pressed in `region` (above its cap, or not above the contact force); empty when it may.
std::string forceRefusal(const ArmConfig& c, const std::string& who, const std::string& region, const RegionLimits& lim,
                         double force) {
  const double cap = lim.forceCap(c.press.contact_area);
  char buf[320];
  if (force > cap + 1e-9) {
    std::snprintf(buf, sizeof buf,
                  "%s: force %.1f N is above the %s limit %.1f N (max_force %.1f N; max_pressure %.1f N/cm^2 x %.1f "
                  "cm^2 = %.1f N)",
                  who.c_str(), force, region.c_str(), cap, lim.max_force, lim.max_pressure, c.press.contact_area,
                  lim.max_pressure * c.press.contact_area);
    return buf;
  }
  if (!(force > c.force_control.contact_force)) {
    std::snprintf(buf, sizeof buf, "%s: force %.1f N is not above the contact force %.1f N", who.c_str(), force,
                  c.force_control.contact_force);
    return buf;
  }
  return "";
}

/// A press by force: vertical (the Z drive senses the force), from the approach point above the point down to the
/// skin and up to no_contact_band below it at most; the force and its cap from the region.
std::string forceGeometry(const ArmConfig& c, const PressRequest& req, const PressTarget& t, const std::string& region,
                          const RegionLimits& lim, double hold, PressGeometry* g) {
  const std::string& who = g->who;
  const double cap = lim.forceCap(c.press.contact_area);
  const double force = req.force > 0.0 ? req.force : lim.default_force;
  if (std::string bad = forceRefusal(c, who, region, lim, force); !bad.empty()) return bad;
  g->approach = t.point + c.press.approach_height * Eigen::Vector3d::UnitZ();
  g->bottom = t.point - c.force_control.no_contact_band * Eigen::Vector3d::UnitZ();
  g->travel_z = std::max(c.press.travel_height, g->approach.z());
  const Eigen::Vector3d over(g->approach.x(), g->approach.y(), g->travel_z);
  for (const auto& [what, p] : {std::pair<const char*, Eigen::Vector3d>{"travel point", over},
                                {"approach point", g->approach},
                                {"lowest point of the seek", g->bottom}}) {
    if (std::string bad = checkTool(c, p); !bad.empty()) return who + ": the " + what + " " + bad;
  }
  ForcePressGoal goal;
  goal.start_z = g->approach.z();
  goal.expected_skin_z = t.point.z();
  goal.force = force;
  goal.max_force = cap;
  goal.max_indentation = lim.max_indentation;
  goal.hold = hold;
  if (req.technique == Technique::kKnead && c.press.knead_radius > 0.0) {
    if (std::string bad = kneadPath(c, t.point, hold, &goal); !bad.empty()) return who + ": " + bad;
  }
  g->force = goal;
  return "";
}

/// Closer than this across the skin, two points of a stroke are one (a repeated frame, a typo).
constexpr double kMinStrokeLeg = 0.005;

/// A stroke: one press by force that glides through every target in order, vertical like every press by force. Its
/// limits are the most conservative of the regions it crosses (the lowest force cap, the shallowest indentation
/// guard, the lowest default force); no leg rises or falls steeper than press.max_normal_tilt; every point of the
/// path (down to the seek's and the indentation guard's lowest), its approach points and the travel points over its
/// ends lie within the arm's reach.
/// Why the leg of a stroke from `a` to `b` (named `from`, `to`) cannot be glided: its points (nearly) one, or the
/// skin between them steeper than press.max_normal_tilt; empty when it can.
std::string strokeLeg(const ArmConfig& c, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const std::string& from,
                      const std::string& to) {
  const Eigen::Vector3d d = b - a;
  const double leg = d.head<2>().norm();
  char buf[200];
  if (leg < kMinStrokeLeg) {
    std::snprintf(buf, sizeof buf, "stroke: %s and %s are %.1f mm apart across the skin (at least %.1f mm)",
                  from.c_str(), to.c_str(), 1e3 * leg, 1e3 * kMinStrokeLeg);
    return buf;
  }
  if (const double slope = std::atan2(std::abs(d.z()), leg); slope > c.press.max_normal_tilt + 1e-9) {
    std::snprintf(buf, sizeof buf, "stroke: the skin from %s to %s %s %.1f deg (limit %.1f deg)", from.c_str(),
                  to.c_str(), d.z() > 0 ? "rises" : "falls", slope * 180.0 / M_PI,
                  c.press.max_normal_tilt * 180.0 / M_PI);
    return buf;
  }
  return "";
}

/// Why a stroke's point `t` (named `who`) cannot be glided over: not finite, an unknown region, its approach point or
/// its lowest point (the seek's band or the region's indentation guard below it) out of reach; empty when it can.
/// Its region in `region`.
std::string strokePoint(const ArmConfig& c, const PressTarget& t, const std::string& who, std::string* region) {
  if (!t.point.allFinite()) return who + ": the point is not finite";
  if (std::string bad = regionOf(c, t, who, region); !bad.empty()) return bad;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::string bad = checkTool(c, t.point + c.press.approach_height * up); !bad.empty())
    return who + ": the approach point " + bad;
  const double lowest = std::max(c.force_control.no_contact_band, c.regions.at(*region).max_indentation);
  if (std::string bad = checkTool(c, t.point - lowest * up); !bad.empty()) return who + ": the lowest point " + bad;
  return "";
}

std::string strokeGeometry(const ArmConfig& c, const PressRequest& req, double speed, PressGeometry* g) {
  const auto name = [&](int i) {
    const PressTarget& t = req.targets[i];
    return t.name.empty() ? "point " + std::to_string(i + 1) : t.name;
  };
  const int n = static_cast<int>(req.targets.size());
  g->who = name(0) + " -> " + name(n - 1);
  // 1. Every point and leg, and the most conservative limits of the regions it crosses (its force is one for the
  //    whole stroke; the indentation guard is each region's where the tool is).
  std::string cap_region;
  const RegionLimits* cap_limits = nullptr;
  double indentation = INFINITY, default_force = INFINITY, highest = -INFINITY;
  ForcePressGoal goal;
  for (int i = 0; i < n; ++i) {
    const PressTarget& t = req.targets[i];
    std::string region;
    if (std::string bad = strokePoint(c, t, "stroke point " + name(i), &region); !bad.empty()) return bad;
    if (i > 0) {
      if (std::string bad = strokeLeg(c, req.targets[i - 1].point, t.point, name(i - 1), name(i)); !bad.empty())
        return bad;
    }
    const RegionLimits& lim = c.regions.at(region);
    if (!cap_limits || lim.forceCap(c.press.contact_area) < cap_limits->forceCap(c.press.contact_area)) {
      cap_limits = &lim;
      cap_region = region;
    }
    indentation = std::min(indentation, lim.max_indentation);
    default_force = std::min(default_force, lim.default_force);
    highest = std::max(highest, t.point.z());
    goal.path.push_back(t.point);
    goal.path_max_indentation.push_back(lim.max_indentation);
  }
  // 2. Its force within those limits.
  const double force = req.force > 0.0 ? req.force : default_force;
  if (std::string bad = forceRefusal(c, "stroke " + g->who, cap_region, *cap_limits, force); !bad.empty()) return bad;
  // 3. Over its ends: the approach points and the travel height above the highest point.
  g->approach = goal.path.front() + c.press.approach_height * Eigen::Vector3d::UnitZ();
  g->bottom = goal.path.front() - c.force_control.no_contact_band * Eigen::Vector3d::UnitZ();
  g->travel_z = std::max(c.press.travel_height, highest + c.press.approach_height);
  g->end = goal.path.back() + c.press.approach_height * Eigen::Vector3d::UnitZ();
  for (const Eigen::Vector3d& end : {g->approach, g->end}) {
    if (std::string bad = checkTool(c, Eigen::Vector3d(end.x(), end.y(), g->travel_z)); !bad.empty())
      return "stroke " + g->who + ": the travel point " + bad;
  }
  goal.start_z = g->approach.z();
  goal.expected_skin_z = goal.path.front().z();
  goal.force = force;
  goal.max_force = cap_limits->forceCap(c.press.contact_area);
  goal.max_indentation = indentation;
  goal.glide_speed = speed;
  g->force = goal;
  return "";
}

std::string pressGeometry(const ArmConfig& c, const PressRequest& req, int i, double hold, PressGeometry* g) {
  const PressConfig& pc = c.press;
  const PressTarget& t = req.targets[i];
  g->who = t.name.empty() ? "target " + std::to_string(i + 1) : t.name;
  const std::string& who = g->who;
  if (!t.point.allFinite()) return who + ": the point is not finite";
  if (!t.normal.allFinite() || !(t.normal.norm() > 1e-9)) return who + ": the surface normal is zero or not finite";
  const Eigen::Vector3d n = t.normal.normalized();
  const double tilt = std::acos(std::clamp(n.z(), -1.0, 1.0));
  if (tilt > pc.max_normal_tilt + 1e-9) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s: the surface normal is %.1f deg from vertical (limit %.1f deg)", who.c_str(),
                  tilt * 180.0 / M_PI, pc.max_normal_tilt * 180.0 / M_PI);
    return buf;
  }
  std::string region;
  if (std::string bad = regionOf(c, t, who, &region); !bad.empty()) return bad;
  const RegionLimits& lim = c.regions.at(region);
  if (req.mode.value_or(pc.mode) == PressConfig::Mode::kForce) return forceGeometry(c, req, t, region, lim, hold, g);
  g->force_cap = lim.forceCap(pc.contact_area);
  const double depth = req.depth > 0.0 ? req.depth : lim.default_depth;
  if (depth > lim.max_depth + 1e-12) {
    return who + ": depth " + mm(depth) + " is deeper than the " + region + " limit " + mm(lim.max_depth);
  }
  g->approach = t.point + pc.approach_height * n;
  g->bottom = t.point - depth * n;
  g->travel_z = std::max(pc.travel_height, g->approach.z());
  struct Named {
    const char* what;
    Eigen::Vector3d p;
  };
  std::vector<Named> visit = {{"travel point", Eigen::Vector3d(g->approach.x(), g->approach.y(), g->travel_z)},
                              {"approach point", g->approach},
                              {"press end point", g->bottom}};
  // Kneading: circles of knead_radius around the pressed point, in the tangent plane.
  if (req.technique == Technique::kKnead && pc.knead_radius > 0.0) {
    Eigen::Vector3d u, v;
    tangentBasis(n, &u, &v);
    for (int k = 0; k <= pc.knead_segments; ++k) {
      const double a = 2.0 * M_PI * k / pc.knead_segments;
      g->circle.push_back(g->bottom + pc.knead_radius * (std::cos(a) * u + std::sin(a) * v));
    }
    g->circles = std::max(1, static_cast<int>(std::lround(hold / pc.knead_period)));
    for (const auto& p : g->circle) visit.push_back({"knead point", p});
  }
  for (const Named& v : visit) {
    if (std::string bad = checkTool(c, v.p); !bad.empty()) return who + ": the " + v.what + " " + bad;
  }
  return "";
}

/// Appends the steps of a routine, following the tool from `at`.
class StepWriter {
 public:
  StepWriter(const PressConfig& pc, const Eigen::Vector3d& from) : pc_(pc), at_(from) {}

  void move(const Eigen::Vector3d& goal, double v, const std::string& label, bool contact, bool retract, int target,
            const Eigen::Vector3d& retreat) {
    Step s;
    s.kind = Step::Kind::kMove;
    s.tool = goal;
    s.speed = v;
    s.accel = v > 0.0 ? pc_.acceleration : 0.0;
    s.label = label;
    s.contact = contact;
    s.retract = retract;
    s.target = target;
    s.retreat = retreat;
    s.force_cap = contact ? cap_ : 0.0;
    steps_.push_back(s);
    at_ = goal;
  }

  void hold(const Eigen::Vector3d& at, double duration, const std::string& label, int target,
            const Eigen::Vector3d& retreat) {
    Step h;
    h.kind = Step::Kind::kHold;
    h.tool = at;
    h.duration = duration;
    h.label = label;
    h.contact = true;
    h.target = target;
    h.retreat = retreat;
    h.force_cap = cap_;
    steps_.push_back(h);
  }

  /// Target i: up from where the tool is, over, down to the approach point; each repeat descends, holds (or kneads)
  /// and retracts; then up to the travel height.
  void press(const PressGeometry& g, const PressRequest& req, int i, double hold_s, double speed) {
    const int n_targets = static_cast<int>(req.targets.size());
    const std::string prefix = "press " + std::to_string(i + 1) + "/" + std::to_string(n_targets) + " " + g.who + ": ";
    const Eigen::Vector3d over(g.approach.x(), g.approach.y(), g.travel_z);
    cap_ = g.force_cap;
    if (at_.z() < g.travel_z - 1e-9)
      move(Eigen::Vector3d(at_.x(), at_.y(), g.travel_z), 0.0, prefix + "up to the travel height", false, false, i,
           g.approach);
    move(over, 0.0, prefix + "travel", false, false, i, g.approach);
    approach(g.approach, g.travel_z, prefix, i);
    for (int r = 0; r < req.repeats; ++r) {
      const std::string rep =
          req.repeats > 1 ? " (" + std::to_string(r + 1) + "/" + std::to_string(req.repeats) + ")" : "";
      if (g.force) {
        char what[32];
        std::snprintf(what, sizeof what, "%s %.0f N", g.force->path.empty() ? "press" : "knead", g.force->force);
        forcePress(g, prefix + what + rep, i);
        continue;
      }
      move(g.bottom, speed, prefix + "descend" + rep, true, false, i, g.approach);
      if (req.technique == Technique::kKnead && !g.circle.empty()) {
        knead(g, prefix + "knead" + rep, i, speed);
      } else {
        hold(g.bottom, hold_s, prefix + "hold" + rep, i, g.approach);
      }
      move(g.approach, pc_.retract_speed, prefix + "retract" + rep, true, true, i, g.approach);
      steps_.back().press_done = true;
    }
    move(over, 0.0, prefix + "up to the travel height", false, true, i, g.approach);
  }

  /// A stroke: up, over its first point, down to the approach point; each repeat a press by force gliding to the
  /// last point, backing off over it, up to the travel height (and, to repeat, back over the first point).
  void stroke(const PressGeometry& g, const PressRequest& req) {
    const std::string prefix = "stroke " + g.who + ": ";
    const Eigen::Vector3d over(g.approach.x(), g.approach.y(), g.travel_z), over_end(g.end.x(), g.end.y(), g.travel_z);
    for (int r = 0; r < req.repeats; ++r) {
      const std::string rep =
          req.repeats > 1 ? " (" + std::to_string(r + 1) + "/" + std::to_string(req.repeats) + ")" : "";
      if (at_.z() < g.travel_z - 1e-9)
        move(Eigen::Vector3d(at_.x(), at_.y(), g.travel_z), 0.0, prefix + "up to the travel height", false, false, 0,
             g.approach);
      move(over, 0.0, prefix + "travel" + rep, false, false, 0, g.approach);
      approach(g.approach, g.travel_z, prefix, 0, rep);
      char what[48];
      std::snprintf(what, sizeof what, "glide at %.0f N", g.force->force);
      forcePress(g, prefix + what + rep, 0);
      at_ = g.end;
      move(over_end, 0.0, prefix + "up to the travel height" + rep, false, true, 0, g.end);
    }
  }

  std::vector<Step>& steps() { return steps_; }

 private:
  /// From over the approach point at the travel height down to it: fast, then its last approach_clearance slowly.
  void approach(const Eigen::Vector3d& to, double travel_z, const std::string& prefix, int i,
                const std::string& rep = "") {
    const double slow_from = to.z() + pc_.approach_clearance;
    if (pc_.approach_clearance > 0.0 && slow_from < travel_z - 1e-9)
      move(Eigen::Vector3d(to.x(), to.y(), slow_from), 0.0, prefix + "down" + rep, false, false, i, to);
    move(to, pc_.approach_clearance > 0.0 ? pc_.approach_speed : 0.0, prefix + "approach" + rep, false, false, i, to);
  }

  void forcePress(const PressGeometry& g, const std::string& label, int i) {
    Step s;
    s.kind = Step::Kind::kForcePress;
    s.tool = g.approach;
    s.label = label;
    s.contact = true;
    s.target = i;
    s.retreat = g.approach;
    s.force = *g.force;
    s.press_done = true;
    steps_.push_back(s);
  }

  void knead(const PressGeometry& g, const std::string& label, int i, double speed) {
    const double seg_len = (g.circle[1] - g.circle[0]).norm();
    const double knead_speed = std::min(pc_.max_speed, seg_len * pc_.knead_segments / pc_.knead_period);
    move(g.circle[0], speed, label, true, false, i, g.approach);
    for (int k = 0; k < g.circles; ++k) {
      for (std::size_t s = 1; s < g.circle.size(); ++s)
        move(g.circle[s], knead_speed, label, true, false, i, g.approach);
    }
    move(g.bottom, speed, label, true, false, i, g.approach);
  }

  const PressConfig& pc_;
  Eigen::Vector3d at_;
  double cap_ = 0.0;  ///< the force cap of the target being written (its contact steps')
  std::vector<Step> steps_;
};

}  // namespace

std::string planMassage(const ArmConfig& c, const Eigen::Vector3d& from, const PressRequest& req,
                        std::vector<Step>* steps) {
  steps->clear();
  double hold = 0.0, speed = 0.0;
  if (std::string bad = checkRequest(c, from, req, &hold, &speed); !bad.empty()) return bad;
  StepWriter writer(c.press, from);
  if (req.technique == Technique::kStroke) {
    PressGeometry g;
    if (std::string bad = strokeGeometry(c, req, speed, &g); !bad.empty()) return bad;
    writer.stroke(g, req);
    *steps = std::move(writer.steps());
    return "";
  }
  for (int i = 0; i < static_cast<int>(req.targets.size()); ++i) {
    PressGeometry g;
    if (std::string bad = pressGeometry(c, req, i, hold, &g); !bad.empty()) return bad;
    writer.press(g, req, i, hold, speed);
  }
  *steps = std::move(writer.steps());
  return "";
}

std::string pressSettings(const ArmConfig& config, const MassageFields& f, PressRequest* out) {
  const std::string n = std::to_string(f.targets);
  if (f.targets == 0) return "no target (frames or points) given";
  if (f.targets > static_cast<std::size_t>(config.press.max_targets)) {
    return n + " targets: at most " + std::to_string(config.press.max_targets) + " in one request (press.max_targets)";
  }
  if (!std::isfinite(f.hold)) return "hold must be a finite number of seconds (0: the default; < 0: none)";
  if (f.regions != 0 && f.regions != f.targets) {
    return "regions has " + std::to_string(f.regions) + " entries for " + n + " targets";
  }
  if (f.normals != 0 && f.normals != f.targets) {
    return "normals has " + std::to_string(f.normals) + " entries for " + n + " targets";
  }
  if (f.technique.empty() || f.technique == "press") {
    out->technique = Technique::kPress;
  } else if (f.technique == "knead") {
    out->technique = Technique::kKnead;
  } else if (f.technique == "stroke") {
    out->technique = Technique::kStroke;
  } else {
    return "unknown technique '" + f.technique + "' (press, knead or stroke)";
  }
  if (f.mode == "force") {
    out->mode = PressConfig::Mode::kForce;
  } else if (f.mode == "depth") {
    out->mode = PressConfig::Mode::kDepth;
  } else if (!f.mode.empty()) {
    return "unknown mode '" + f.mode + "' (force or depth; empty: the configuration's)";
  }
  out->force = f.force;
  out->depth = f.depth;
  out->hold = f.hold == 0.0 ? -1.0 : std::max(0.0, f.hold);
  out->speed = f.speed;
  out->repeats = f.repeats == 0 ? 1 : f.repeats;
  return "";
}

}  // namespace massage_cell::arm
