// Arm configuration loading and validation (see config.h).
#include "massage_cell/arm/config.h"

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

namespace massage_cell::arm {

namespace {

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/// Field access with messages naming the file and the field path.
class Reader {
 public:
  Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw ArmConfigError(source_ + ": " + path + ": " + what);
  }

  void checkKeys(const YAML::Node& node, const std::string& path, const std::set<std::string>& allowed) const {
    if (!node.IsMap()) fail(path.empty() ? "(top level)" : path, "expected a mapping");
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      if (!allowed.count(key)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(join(path, key), "unknown field (known: " + list + ")");
      }
    }
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

  double number(const YAML::Node& node, const std::string& path, double fallback, bool required = false) const {
    if (!node) {
      if (required) fail(path, "missing");
      return fallback;
    }
    try {
      const double v = node.as<double>();
      if (!std::isfinite(v)) fail(path, "not a finite number");
      return v;
    } catch (const YAML::Exception&) {
      fail(path, "expected a number, got '" + scalarText(node) + "'");
    }
  }

  int integer(const YAML::Node& node, const std::string& path, int fallback) const {
    if (!node) return fallback;
    try {
      return node.as<int>();
    } catch (const YAML::Exception&) {
      fail(path, "expected an integer, got '" + scalarText(node) + "'");
    }
  }

  bool boolean(const YAML::Node& node, const std::string& path, bool fallback) const {
    if (!node) return fallback;
    try {
      return node.as<bool>();  // true/false, yes/no, on/off; anything else throws
    } catch (const YAML::Exception&) {
      fail(path, "expected true or false, got '" + scalarText(node) + "'");
    }
  }

  std::string text(const YAML::Node& node, const std::string& path, const std::string& fallback,
                   bool required = false) const {
    if (!node) {
      if (required) fail(path, "missing");
      return fallback;
    }
    if (!node.IsScalar()) fail(path, "expected a string");
    return node.as<std::string>();
  }

  Eigen::Vector3d vec3(const YAML::Node& node, const std::string& path, const Eigen::Vector3d& fallback,
                       bool required = false) const {
    if (!node) {
      if (required) fail(path, "missing");
      return fallback;
    }
    if (!node.IsSequence() || node.size() != 3) fail(path, "expected a list of 3 numbers [x, y, z]");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = number(node[i], path + "[" + std::to_string(i) + "]", 0.0, true);
    return v;
  }

  static std::string scalarText(const YAML::Node& node) {
    if (node.IsScalar()) return node.Scalar();
    std::ostringstream s;
    s << node;
    return s.str();
  }

 private:
  std::string source_;
};

std::string resolve(const std::string& base_dir, const std::string& path) {
  if (path.empty() || path[0] == '/' || base_dir.empty()) return path;
  return base_dir + "/" + path;
}

std::string dirOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

std::string readFile(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw ArmConfigError(what + " '" + path + "' cannot be read (missing file?)");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

const can::AxisConfig& ArmConfig::axis(int i) const {
  const can::AxisConfig* a = can.findAxis(axis_names.at(static_cast<std::size_t>(i)));
  if (!a) throw ArmConfigError(source + ": axes: CAN axis '" + axis_names.at(i) + "' is not in " + can_config_path);
  return *a;
}

const RegionLimits& ArmConfig::limitsOf(const std::string& region) const {
  const auto it = regions.find(region);
  if (it != regions.end()) return it->second;
  return regions.at(default_region);
}

std::string ArmConfig::regionOf(const std::string& acupoint) const {
  const auto it = acupoint_regions.find(acupoint);
  return it == acupoint_regions.end() ? std::string() : it->second;
}

namespace {

std::map<std::string, std::string> acupointRegions(const std::string& path) {
  const std::string text = readFile(path, "acupoint model");
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ArmConfigError(path + ": not valid YAML: " + e.what());
  }
  const YAML::Node points = root["points"];
  if (!points || !points.IsSequence()) throw ArmConfigError(path + ": points: missing or not a list");
  std::map<std::string, std::string> out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::string where = path + ": points[" + std::to_string(i) + "]";
    if (!points[i].IsMap() || !points[i]["name"] || !points[i]["region"]) {
      throw ArmConfigError(where + ": needs a name and a region");
    }
    out[points[i]["name"].as<std::string>()] = points[i]["region"].as<std::string>();
  }
  return out;
}

ArmConfig armConfig(const std::string& yaml_text, const std::string& source, const std::string& base_dir);

}  // namespace

// The public loaders: a yaml-cpp error the field readers did not name (a
// list where a name belongs, ...) still names the file and its line.
std::map<std::string, std::string> loadAcupointRegions(const std::string& path) {
  try {
    return acupointRegions(path);
  } catch (const YAML::Exception& e) {
    throw ArmConfigError(path + ": " + e.what());
  }
}

ArmConfig parseArmConfig(const std::string& yaml_text, const std::string& source, const std::string& base_dir) {
  try {
    return armConfig(yaml_text, source, base_dir);
  } catch (const YAML::Exception& e) {
    throw ArmConfigError(source + ": " + e.what());
  }
}

namespace {

void readForce(Reader& r, const YAML::Node& f, ForceConfig* out) {
  r.checkKeys(f, "force",
              {"screw_lead", "screw_efficiency", "mass", "coulomb_friction", "viscous_friction", "friction_stiffness",
               "filter_time_constant", "calibration_travel", "calibration_speeds"});
  ForceConfig& c = *out;
  c.enabled = true;
  c.screw_lead = r.number(f["screw_lead"], "force.screw_lead", 0.0, true);
  c.screw_efficiency = r.number(f["screw_efficiency"], "force.screw_efficiency", c.screw_efficiency);
  c.mass = r.number(f["mass"], "force.mass", c.mass);
  c.coulomb_friction = r.number(f["coulomb_friction"], "force.coulomb_friction", c.coulomb_friction);
  c.viscous_friction = r.number(f["viscous_friction"], "force.viscous_friction", c.viscous_friction);
  c.friction_stiffness = r.number(f["friction_stiffness"], "force.friction_stiffness", c.friction_stiffness);
  c.filter_time_constant = r.number(f["filter_time_constant"], "force.filter_time_constant", c.filter_time_constant);
  c.calibration_travel = r.number(f["calibration_travel"], "force.calibration_travel", c.calibration_travel);
  if (const YAML::Node speeds = f["calibration_speeds"]) {
    if (!speeds.IsSequence()) r.fail("force.calibration_speeds", "expected a list of speeds (m/s)");
    c.calibration_speeds.clear();
    for (std::size_t i = 0; i < speeds.size(); ++i)
      c.calibration_speeds.push_back(r.number(speeds[i], "force.calibration_speeds[" + std::to_string(i) + "]", 0.0));
  }
}

void readForceControl(Reader& r, const YAML::Node& f, ForceControlConfig* out) {
  r.checkKeys(f, "force_control",
              {"contact_force", "seek_speed", "no_contact_band", "early_contact_band", "ramp_rate", "bandwidth",
               "integral", "tissue_exponent", "min_stiffness", "max_stiffness", "max_speed", "max_force_rate",
               "release_speed", "escape_speed", "stroke_speed", "glide_accel", "move_guard"});
  ForceControlConfig& c = *out;
  const std::string p = "force_control.";
  c.contact_force = r.number(f["contact_force"], p + "contact_force", c.contact_force);
  c.seek_speed = r.number(f["seek_speed"], p + "seek_speed", c.seek_speed);
  c.no_contact_band = r.number(f["no_contact_band"], p + "no_contact_band", c.no_contact_band);
  c.early_contact_band = r.number(f["early_contact_band"], p + "early_contact_band", c.early_contact_band);
  c.ramp_rate = r.number(f["ramp_rate"], p + "ramp_rate", c.ramp_rate);
  c.bandwidth = r.number(f["bandwidth"], p + "bandwidth", c.bandwidth);
  c.integral = r.number(f["integral"], p + "integral", c.integral);
  c.tissue_exponent = r.number(f["tissue_exponent"], p + "tissue_exponent", c.tissue_exponent);
  c.min_stiffness = r.number(f["min_stiffness"], p + "min_stiffness", c.min_stiffness);
  c.max_stiffness = r.number(f["max_stiffness"], p + "max_stiffness", c.max_stiffness);
  c.max_speed = r.number(f["max_speed"], p + "max_speed", c.max_speed);
  c.max_force_rate = r.number(f["max_force_rate"], p + "max_force_rate", c.max_force_rate);
  c.release_speed = r.number(f["release_speed"], p + "release_speed", c.release_speed);
  c.escape_speed = r.number(f["escape_speed"], p + "escape_speed", c.escape_speed);
  c.stroke_speed = r.number(f["stroke_speed"], p + "stroke_speed", c.stroke_speed);
  c.glide_accel = r.number(f["glide_accel"], p + "glide_accel", c.glide_accel);
  c.move_guard = r.number(f["move_guard"], p + "move_guard", c.move_guard);
}

ArmConfig armConfig(const std::string& yaml_text, const std::string& source, const std::string& base_dir) {
  Reader r(source);
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ArmConfigError(source + ": not valid YAML: " + e.what());
  }
  r.checkKeys(root, "",
              {"can_config", "axes", "joint_names", "joints", "tool_offset", "workspace", "watchdog_timeout",
               "bringup_timeout", "position_tolerance", "press", "body", "force", "force_control", "regions",
               "default_region", "acupoints", "node"});  // node: the ROS node's settings (read by the node)
  ArmConfig c;
  c.source = source;
  c.can_config_path = resolve(base_dir, r.text(root["can_config"], "can_config", "", true));
  try {
    c.can = can::loadCanConfig(c.can_config_path);
  } catch (const can::ConfigError& e) {
    r.fail("can_config", e.what());
  }
  for (const char* key : {"axes", "joint_names"}) {
    const YAML::Node n = root[key];
    if (!n) {
      if (std::string(key) == "axes") r.fail(key, "missing (the CAN axis names of x, y, z, e.g. [X, Y, Z])");
      continue;
    }
    if (!n.IsSequence() || n.size() != 3) r.fail(key, "expected a list of 3 names (x, y, z)");
    auto& out = std::string(key) == "axes" ? c.axis_names : c.joint_names;
    for (std::size_t i = 0; i < 3; ++i)
      out[i] = r.text(n[i], std::string(key) + "[" + std::to_string(i) + "]", "", true);
  }
  const YAML::Node joints = root["joints"];
  if (!joints) r.fail("joints", "missing");
  r.checkKeys(joints, "joints", {c.axis_names[0], c.axis_names[1], c.axis_names[2]});
  for (int i = 0; i < 3; ++i) {
    const std::string path = "joints." + c.axis_names[i];
    const YAML::Node j = joints[c.axis_names[i]];
    if (!j) r.fail(path, "missing");
    r.checkKeys(j, path, {"min", "max", "max_velocity", "max_acceleration"});
    JointLimits& l = c.joints[i];
    l.min = r.number(j["min"], path + ".min", 0.0, true);
    l.max = r.number(j["max"], path + ".max", 0.0, true);
    l.max_velocity = r.number(j["max_velocity"], path + ".max_velocity", 0.0, true);
    l.max_acceleration = r.number(j["max_acceleration"], path + ".max_acceleration", 0.0, true);
  }
  c.tool_offset = r.vec3(root["tool_offset"], "tool_offset", c.tool_offset);
  const YAML::Node ws = root["workspace"];
  if (!ws) r.fail("workspace", "missing");
  r.checkKeys(ws, "workspace", {"min", "max"});
  c.workspace_min = r.vec3(ws["min"], "workspace.min", {}, true);
  c.workspace_max = r.vec3(ws["max"], "workspace.max", {}, true);
  c.watchdog_timeout = r.number(root["watchdog_timeout"], "watchdog_timeout", c.watchdog_timeout);
  c.bringup_timeout = r.number(root["bringup_timeout"], "bringup_timeout", c.bringup_timeout);
  c.position_tolerance = r.number(root["position_tolerance"], "position_tolerance", c.position_tolerance);

  if (const YAML::Node p = root["press"]) {
    r.checkKeys(p, "press",
                {"approach_height", "approach_clearance", "approach_speed", "travel_height", "speed", "max_speed",
                 "acceleration", "retract_speed", "hold", "max_hold", "max_repeats", "max_targets", "estop_release",
                 "max_normal_tilt_deg", "knead_radius", "knead_period", "knead_segments", "mode", "contact_area"});
    PressConfig& pc = c.press;
    pc.approach_height = r.number(p["approach_height"], "press.approach_height", pc.approach_height);
    pc.approach_clearance = r.number(p["approach_clearance"], "press.approach_clearance", pc.approach_clearance);
    pc.approach_speed = r.number(p["approach_speed"], "press.approach_speed", pc.approach_speed);
    pc.travel_height = r.number(p["travel_height"], "press.travel_height", pc.travel_height);
    pc.speed = r.number(p["speed"], "press.speed", pc.speed);
    pc.max_speed = r.number(p["max_speed"], "press.max_speed", pc.max_speed);
    pc.acceleration = r.number(p["acceleration"], "press.acceleration", pc.acceleration);
    pc.retract_speed = r.number(p["retract_speed"], "press.retract_speed", pc.retract_speed);
    pc.hold = r.number(p["hold"], "press.hold", pc.hold);
    pc.max_hold = r.number(p["max_hold"], "press.max_hold", pc.max_hold);
    pc.max_repeats = r.integer(p["max_repeats"], "press.max_repeats", pc.max_repeats);
    pc.max_targets = r.integer(p["max_targets"], "press.max_targets", pc.max_targets);
    pc.estop_release = r.boolean(p["estop_release"], "press.estop_release", pc.estop_release);
    pc.max_normal_tilt =
        r.number(p["max_normal_tilt_deg"], "press.max_normal_tilt_deg", pc.max_normal_tilt * 180.0 / M_PI) * M_PI /
        180.0;
    pc.knead_radius = r.number(p["knead_radius"], "press.knead_radius", pc.knead_radius);
    pc.knead_period = r.number(p["knead_period"], "press.knead_period", pc.knead_period);
    pc.knead_segments = r.integer(p["knead_segments"], "press.knead_segments", pc.knead_segments);
    const std::string mode = r.text(p["mode"], "press.mode", "depth");
    if (mode != "depth" && mode != "force") r.fail("press.mode", "'" + mode + "' is neither depth nor force");
    pc.mode = mode == "force" ? PressConfig::Mode::kForce : PressConfig::Mode::kDepth;
    pc.contact_area = r.number(p["contact_area"], "press.contact_area", pc.contact_area);
  }
  if (const YAML::Node b = root["body"]) {
    r.checkKeys(b, "body", {"safe_height", "radius", "surface_cell", "surface_tolerance"});
    c.body.safe_height = r.number(b["safe_height"], "body.safe_height", c.body.safe_height);
    c.body.radius = r.number(b["radius"], "body.radius", c.body.radius);
    c.body.surface_cell = r.number(b["surface_cell"], "body.surface_cell", c.body.surface_cell);
    c.body.surface_tolerance = r.number(b["surface_tolerance"], "body.surface_tolerance", c.body.surface_tolerance);
  }
  if (const YAML::Node f = root["force"]) readForce(r, f, &c.force);
  if (const YAML::Node f = root["force_control"]) readForceControl(r, f, &c.force_control);
  const YAML::Node regions = root["regions"];
  if (!regions || !regions.IsMap() || regions.size() == 0)
    r.fail("regions", "missing or empty (region: {max_depth, default_depth})");
  for (const auto& kv : regions) {
    const std::string name = kv.first.as<std::string>();
    const std::string path = "regions." + name;
    r.checkKeys(kv.second, path,
                {"max_depth", "default_depth", "default_force", "max_force", "max_pressure", "max_indentation"});
    RegionLimits l;
    l.max_depth = r.number(kv.second["max_depth"], path + ".max_depth", 0.0, true);
    l.default_depth = r.number(kv.second["default_depth"], path + ".default_depth", 0.0, true);
    // Force mode's limits: required with press.mode force (validate()), else optional.
    l.default_force = r.number(kv.second["default_force"], path + ".default_force", 0.0);
    l.max_force = r.number(kv.second["max_force"], path + ".max_force", 0.0);
    l.max_pressure = r.number(kv.second["max_pressure"], path + ".max_pressure", 0.0);
    l.max_indentation = r.number(kv.second["max_indentation"], path + ".max_indentation", 0.0);
    c.regions[name] = l;
  }
  c.default_region = r.text(root["default_region"], "default_region", c.default_region);
  const std::string acupoints = r.text(root["acupoints"], "acupoints", "");
  if (!acupoints.empty()) {
    c.acupoints_path = resolve(base_dir, acupoints);
    try {
      c.acupoint_regions = loadAcupointRegions(c.acupoints_path);
    } catch (const ArmConfigError& e) {
      r.fail("acupoints", e.what());
    }
  }
  validate(c);
  return c;
}

}  // namespace

ArmConfig loadArmConfig(const std::string& path) {
  return parseArmConfig(readFile(path, "arm configuration"), path, dirOf(path));
}

namespace {

/// The force section against the drives: the Z axis must report its torque.
template <typename Fail>
void validateForce(const ArmConfig& c, const Fail& fail) {
  const ForceConfig& f = c.force;
  const can::AxisConfig& z = c.axis(2);
  if (!z.torque_pdo || !(z.rated_torque > 0.0)) {
    fail("force", "needs the Z axis '" + z.name + "' to report its torque (torque_pdo: true and rated_torque in " +
                      c.can_config_path + ")");
  }
  if (!(f.screw_lead > 0.0)) fail("force.screw_lead", "must be > 0 m");
  if (!(f.screw_efficiency > 0.0) || f.screw_efficiency > 1.0) fail("force.screw_efficiency", "must be in (0, 1]");
  if (!(f.mass >= 0.0) || !(f.coulomb_friction >= 0.0) || !(f.viscous_friction >= 0.0))
    fail("force", "mass, coulomb_friction and viscous_friction must be >= 0");
  if (!(f.friction_stiffness > 0.0)) fail("force.friction_stiffness", "must be > 0");
  if (!(f.filter_time_constant >= 0.0)) fail("force.filter_time_constant", "must be >= 0 s");
  if (!(f.calibration_travel > 0.0) || c.workspace_max.z() - f.calibration_travel < c.body.safe_height)
    fail("force.calibration_travel", "must be > 0 and keep the tool above body.safe_height below the top");
  if (f.calibration_speeds.size() < 2) fail("force.calibration_speeds", "needs two speeds or more");
  for (double v : f.calibration_speeds)
    if (!(v > 0.0) || v > c.joints[2].max_velocity)
      fail("force.calibration_speeds", "each must be > 0 and <= the Z joint's max_velocity");
}

/// Force mode: the loop's settings, and every region's force limits when presses are by force.
template <typename Fail>
void validateForceControl(const ArmConfig& c, const Fail& fail) {
  const ForceControlConfig& f = c.force_control;
  const bool positive = f.contact_force > 0.0 && f.seek_speed > 0.0 && f.no_contact_band > 0.0 &&
                        f.early_contact_band > 0.0 && f.ramp_rate > 0.0 && f.bandwidth > 0.0 && f.integral >= 0.0 &&
                        f.tissue_exponent >= 1.0 && f.min_stiffness > 0.0 && f.max_stiffness >= f.min_stiffness &&
                        f.max_speed > 0.0 && f.max_force_rate > 0.0 && f.release_speed > 0.0 && f.escape_speed > 0.0 &&
                        f.stroke_speed > 0.0 && f.glide_accel > 0.0 && f.move_guard > f.contact_force;
  if (!positive)
    fail("force_control",
         "every setting must be > 0 (integral >= 0, tissue_exponent >= 1, max_stiffness >= min, move_guard > "
         "contact_force)");
  if (f.seek_speed > c.press.max_speed) fail("force_control.seek_speed", "must be <= press.max_speed");
  if (f.early_contact_band >= c.press.approach_height)
    fail("force_control.early_contact_band", "must be < press.approach_height (the seek starts there)");
  if (f.stroke_speed > c.press.max_speed) fail("force_control.stroke_speed", "must be <= press.max_speed");
  if (f.escape_speed > c.joints[2].max_velocity)
    fail("force_control.escape_speed", "must be <= the Z joint's max_velocity");
  if (!(c.press.contact_area > 0.0)) fail("press.contact_area", "must be > 0 cm^2");
  if (c.press.mode == PressConfig::Mode::kForce && !c.force.enabled)
    fail("press.mode", "force needs the force: section (the Z drive's torque)");
  if (!c.force.enabled) return;  // presses by force cannot be asked for: the regions' force limits are not used
  for (const auto& [name, l] : c.regions) {
    const std::string path = "regions." + name;
    if (!(l.max_force > 0.0) || !(l.max_pressure > 0.0) || !(l.max_indentation > 0.0))
      fail(path, "presses by force (force: is configured) need max_force, max_pressure and max_indentation > 0");
    if (!(l.default_force > f.contact_force) || l.default_force > l.forceCap(c.press.contact_area))
      fail(path + ".default_force", "must be above force_control.contact_force and within max_force and " +
                                        std::string("max_pressure x press.contact_area"));
  }
}

}  // namespace

void validate(const ArmConfig& c) {
  const std::string& s = c.source;
  auto fail = [&](const std::string& path, const std::string& what) {
    throw ArmConfigError(s + ": " + path + ": " + what);
  };
  std::set<std::string> seen;
  for (int i = 0; i < 3; ++i) {
    if (!seen.insert(c.axis_names[i]).second) fail("axes", "axis '" + c.axis_names[i] + "' given twice");
    const can::AxisConfig* a = c.can.findAxis(c.axis_names[i]);
    if (!a)
      fail("axes[" + std::to_string(i) + "]", "CAN axis '" + c.axis_names[i] + "' is not in " + c.can_config_path);
    const JointLimits& l = c.joints[i];
    const std::string path = "joints." + c.axis_names[i];
    if (!(l.min < l.max)) fail(path, "min " + num(l.min) + " m must be below max " + num(l.max) + " m");
    if (l.min < a->min_position) {
      fail(path + ".min", num(l.min) + " m is beyond the drive's software limit " + num(a->min_position) + " m");
    }
    if (l.max > a->max_position) {
      fail(path + ".max", num(l.max) + " m is beyond the drive's software limit " + num(a->max_position) + " m");
    }
    if (!(l.max_velocity > 0.0) || l.max_velocity > a->sim.max_velocity) {
      fail(path + ".max_velocity", "must be in (0, " + num(a->sim.max_velocity) + "] m/s, got " + num(l.max_velocity));
    }
    if (!(l.max_acceleration > 0.0)) fail(path + ".max_acceleration", "must be > 0, got " + num(l.max_acceleration));
  }
  for (int k = 0; k < 3; ++k) {
    const char axis = "xyz"[k];
    if (!(c.workspace_min[k] < c.workspace_max[k]))
      fail("workspace", std::string("min.") + axis + " must be below max." + axis);
    const double lo = c.joints[k].min + c.tool_offset[k], hi = c.joints[k].max + c.tool_offset[k];
    if (c.workspace_min[k] < lo - 1e-12 || c.workspace_max[k] > hi + 1e-12) {
      fail("workspace", std::string("the ") + axis + " range [" + num(c.workspace_min[k]) + ", " +
                            num(c.workspace_max[k]) + "] m is not inside what the joint limits reach with the tool (" +
                            num(lo) + ", " + num(hi) + ") m");
    }
  }
  if (c.watchdog_timeout < 0.0) fail("watchdog_timeout", "must be >= 0 (0: off)");
  if (!(c.bringup_timeout > 0.0)) fail("bringup_timeout", "must be > 0");
  if (!(c.position_tolerance > 0.0)) fail("position_tolerance", "must be > 0");
  const PressConfig& p = c.press;
  if (!(p.approach_height > 0.0)) fail("press.approach_height", "must be > 0");
  if (!(p.approach_clearance >= 0.0)) fail("press.approach_clearance", "must be >= 0 (0: none)");
  if (!(p.approach_speed > 0.0)) fail("press.approach_speed", "must be > 0");
  if (p.travel_height < c.workspace_min.z() || p.travel_height > c.workspace_max.z()) {
    fail("press.travel_height", num(p.travel_height) + " m is outside the workspace's z range");
  }
  if (!(p.speed > 0.0) || !(p.max_speed >= p.speed)) fail("press.speed", "must be > 0 and <= press.max_speed");
  if (!(p.acceleration > 0.0)) fail("press.acceleration", "must be > 0");
  if (!(p.retract_speed > 0.0)) fail("press.retract_speed", "must be > 0");
  if (!(p.hold >= 0.0) || !(p.max_hold >= p.hold)) fail("press.hold", "must be >= 0 and <= press.max_hold");
  if (p.max_repeats < 1) fail("press.max_repeats", "must be >= 1");
  if (p.max_targets < 1) fail("press.max_targets", "must be >= 1");
  if (!(c.body.safe_height >= c.workspace_min.z()) || c.body.safe_height > c.workspace_max.z()) {
    fail("body.safe_height", num(c.body.safe_height) + " m is outside the workspace's z range");
  }
  if (!(c.body.radius > 0.0)) fail("body.radius", "must be > 0");
  if (!(c.body.surface_cell > 0.0)) fail("body.surface_cell", "must be > 0");
  if (!(c.body.surface_tolerance >= 0.0)) fail("body.surface_tolerance", "must be >= 0");
  if (!(p.max_normal_tilt >= 0.0) || p.max_normal_tilt > M_PI / 2)
    fail("press.max_normal_tilt_deg", "must be in [0, 90]");
  if (!(p.knead_radius >= 0.0) || !(p.knead_period > 0.0) || p.knead_segments < 3) {
    fail("press", "knead_radius >= 0, knead_period > 0 and knead_segments >= 3 required");
  }
  for (const auto& [name, l] : c.regions) {
    if (!(l.max_depth > 0.0)) fail("regions." + name + ".max_depth", "must be > 0");
    if (!(l.default_depth > 0.0) || l.default_depth > l.max_depth) {
      fail("regions." + name + ".default_depth", "must be > 0 and <= max_depth " + num(l.max_depth));
    }
  }
  if (c.force.enabled) validateForce(c, fail);
  validateForceControl(c, fail);
  if (!c.regions.count(c.default_region)) fail("default_region", "'" + c.default_region + "' is not one of regions");
  for (const auto& [point, region] : c.acupoint_regions) {
    if (!c.regions.count(region)) {
      fail("acupoints",
           "point " + point + " of " + c.acupoints_path + " has region '" + region + "', which regions does not list");
    }
  }
}

}  // namespace massage_cell::arm
