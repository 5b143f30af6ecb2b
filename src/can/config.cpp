// YAML configuration of the CAN motion stack (see config.h); yaml-cpp does
// the parsing, this file the field checks and messages.
#include "massage_cell/can/config.h"

#include "massage_cell/can/canopen.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <type_traits>

namespace massage_cell::can {

std::int32_t AxisConfig::toCounts(double metres) const {
  const double c = std::round(metres * counts_per_metre);
  if (c > std::numeric_limits<std::int32_t>::max()) return std::numeric_limits<std::int32_t>::max();
  if (c < std::numeric_limits<std::int32_t>::min()) return std::numeric_limits<std::int32_t>::min();
  return static_cast<std::int32_t>(c);
}

const AxisConfig* CanConfig::findNode(std::uint8_t node) const {
  for (const AxisConfig& a : axes) {
    if (a.node_id == node) return &a;
  }
  return nullptr;
}

const AxisConfig* CanConfig::findAxis(const std::string& name) const {
  for (const AxisConfig& a : axes) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

namespace {

// Reads typed fields of one YAML map, naming "<source>: <path>.<field>" in errors
// and rejecting fields it was not asked about (typos).
class Fields {
 public:
  Fields(const YAML::Node& node, std::string path, std::string source)
      : node_(node), path_(std::move(path)), source_(std::move(source)) {
    if (!node_.IsMap()) fail(path_, "expected a map");
  }

  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw ConfigError(source_ + ": " + where + ": " + what);
  }
  std::string where(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

  bool has(const std::string& key) {
    used_.insert(key);
    return node_[key].IsDefined() && !node_[key].IsNull();
  }
  YAML::Node get(const std::string& key) {
    used_.insert(key);
    return node_[key];
  }

  template <typename T>
  void read(const std::string& key, T& out, bool required, double lo, double hi) {
    if (!has(key)) {
      if (required) fail(where(key), "missing field (required)");
      return;
    }
    const YAML::Node v = node_[key];
    if (!v.IsScalar()) fail(where(key), "expected a scalar");
    const std::string text = v.Scalar();
    double d = 0.0;
    try {
      std::size_t pos = 0;
      d = std::stod(text, &pos);
      if (pos != text.size()) throw std::invalid_argument(text);
    } catch (const std::exception&) {
      fail(where(key), "expected a number, got '" + text + "'");
    }
    if (!std::isfinite(d)) fail(where(key), "expected a finite number, got '" + text + "'");
    if constexpr (std::is_integral_v<T>) {
      if (d != std::floor(d)) fail(where(key), "expected an integer, got '" + text + "'");
    }
    if (d < lo || d > hi) {
      std::ostringstream s;
      s << text << " is outside " << lo << ".." << hi;
      fail(where(key), s.str());
    }
    out = static_cast<T>(d);
  }

  void readString(const std::string& key, std::string& out, bool required) {
    if (!has(key)) {
      if (required) fail(where(key), "missing field (required)");
      return;
    }
    const YAML::Node v = node_[key];
    if (!v.IsScalar() || v.Scalar().empty()) fail(where(key), "expected a non-empty string");
    out = v.Scalar();
  }

  void readBool(const std::string& key, bool& out) {
    if (!has(key)) return;
    const YAML::Node v = node_[key];
    try {
      out = v.as<bool>();
    } catch (const YAML::Exception&) {
      fail(where(key), "expected true or false, got '" + (v.IsScalar() ? v.Scalar() : std::string("?")) + "'");
    }
  }

  /// Throws for a field nobody read.
  void rejectUnknown() const {
    for (const auto& kv : node_) {
      const std::string key = kv.first.as<std::string>();
      if (!used_.count(key)) fail(where(key), "unknown field");
    }
  }

 private:
  YAML::Node node_;
  std::string path_, source_;
  std::set<std::string> used_;
};

constexpr double kBig = 1e12;

AxisConfig parseAxis(const YAML::Node& node, const std::string& path, const std::string& source) {
  AxisConfig a;
  Fields f(node, path, source);
  f.readString("name", a.name, true);
  int node_id = 0;
  f.read("node_id", node_id, true, 1, 127);
  a.node_id = static_cast<std::uint8_t>(node_id);
  f.read("counts_per_metre", a.counts_per_metre, true, 1e-9, kBig);
  f.read("heartbeat_ms", a.heartbeat_ms, false, 1, 65535);
  f.read("heartbeat_timeout_ms", a.heartbeat_timeout_ms, false, 0, 600000);
  f.readBool("velocity_pdo", a.velocity_pdo);
  f.readBool("torque_pdo", a.torque_pdo);
  f.read("rated_torque", a.rated_torque, a.torque_pdo, 1e-6, kBig);
  f.read("profile_velocity", a.profile_velocity, false, 1e-9, kBig);
  f.read("profile_acceleration", a.profile_acceleration, false, 1e-9, kBig);
  f.read("profile_deceleration", a.profile_deceleration, false, 1e-9, kBig);
  f.read("quick_stop_deceleration", a.quick_stop_deceleration, false, 1e-9, kBig);
  f.read("quick_stop_option", a.quick_stop_option, false, 0, 8);
  f.read("min_position", a.min_position, false, -kBig, kBig);
  f.read("max_position", a.max_position, false, -kBig, kBig);
  f.read("following_error_window", a.following_error_window, false, 1e-12, kBig);
  f.read("enable_timeout_ms", a.enable_timeout_ms, false, 1, 600000);
  f.read("move_timeout_ms", a.move_timeout_ms, false, 1, 3600000);
  f.read("master_heartbeat_timeout_ms", a.master_heartbeat_timeout_ms, false, 0, 65535);
  f.read("abort_connection_option", a.abort_connection_option, false, 0, 3);
  if (f.has("homing")) {
    Fields h(f.get("homing"), f.where("homing"), source);
    h.read("method", a.homing_method, false, -128, 127);
    h.read("offset", a.home_offset, false, -kBig, kBig);
    h.read("speed", a.homing_speed, false, 1e-9, kBig);
    h.read("timeout_ms", a.homing_timeout_ms, false, 1, 3600000);
    h.read("retries", a.homing_retries, false, 0, 100);
    h.rejectUnknown();
  }
  if (f.has("sim")) {
    Fields s(f.get("sim"), f.where("sim"), source);
    s.readString("device_name", a.sim.device_name, false);
    s.read("start_position", a.sim.start_position, false, -kBig, kBig);
    s.read("home_switch", a.sim.home_switch, false, -kBig, kBig);
    s.read("max_velocity", a.sim.max_velocity, false, 1e-9, kBig);
    s.read("device_type", a.sim.device_type, false, 0, 4294967295.0);
    if (s.has("mechanics")) {
      Fields m(s.get("mechanics"), s.where("mechanics"), source);
      SimDriveSettings::Mechanics& k = a.sim.mechanics;
      m.read("screw_lead", k.screw_lead, true, 1e-6, 1.0);
      m.read("screw_efficiency", k.screw_efficiency, false, 0.05, 1.0);
      m.read("moving_mass", k.moving_mass, false, 0.0, 1000.0);
      m.read("gravity", k.gravity, false, -100.0, 100.0);
      m.read("coulomb_friction", k.coulomb_friction, false, 0.0, 1e4);
      m.read("viscous_friction", k.viscous_friction, false, 0.0, 1e6);
      m.read("friction_stiffness", k.friction_stiffness, false, 1.0, 1e12);
      m.read("torque_noise", k.torque_noise, false, 0.0, 1000.0);
      m.read("seed", k.seed, false, 0, 4294967295.0);
      m.rejectUnknown();
      if (a.rated_torque <= 0.0) s.fail(s.where("mechanics"), "needs the axis' rated_torque (0x6076)");
    }
    s.rejectUnknown();
  }
  f.rejectUnknown();
  return a;
}

}  // namespace

void validate(const CanConfig& c, const std::string& source) {
  auto fail = [&](const std::string& where, const std::string& what) {
    throw ConfigError(source + ": " + where + ": " + what);
  };
  if (c.axes.empty()) fail("axes", "no axes configured");
  if (c.sync_period_us < 1000) fail("bus.sync_period_ms", "must be at least 1 ms");
  if (!validNodeId(c.master_node_id)) {
    fail("bus.master_node_id", std::to_string(c.master_node_id) + " is outside 1..127");
  }
  std::map<int, std::string> ids;
  std::set<std::string> names;
  for (std::size_t i = 0; i < c.axes.size(); ++i) {
    const AxisConfig& a = c.axes[i];
    const std::string p = "axes[" + std::to_string(i) + "]";
    if (a.name.empty()) fail(p + ".name", "missing field (required)");
    if (!validNodeId(a.node_id)) fail(p + ".node_id", std::to_string(a.node_id) + " is outside 1..127");
    if (auto it = ids.find(a.node_id); it != ids.end()) {
      fail(p + ".node_id",
           "duplicate node id " + std::to_string(a.node_id) + " (axis '" + it->second + "' already uses it)");
    }
    ids[a.node_id] = a.name;
    if (!names.insert(a.name).second) fail(p + ".name", "duplicate axis name '" + a.name + "'");
    if (!(a.counts_per_metre > 0)) fail(p + ".counts_per_metre", "must be > 0");
    if (a.min_position >= a.max_position) fail(p + ".max_position", "must be greater than min_position");
    if (a.heartbeatTimeoutMs() <= a.heartbeat_ms) fail(p + ".heartbeat_timeout_ms", "must be longer than heartbeat_ms");
    if (a.node_id == c.master_node_id) {
      fail(p + ".node_id", "node id " + std::to_string(a.node_id) +
                               " is the master's own (bus.master_node_id); "
                               "give the master or the axis another id");
    }
    if (a.master_heartbeat_timeout_ms > 0) {
      if (c.master_heartbeat_ms == 0) {
        fail(p + ".master_heartbeat_timeout_ms",
             "the drive would monitor the master's heartbeat, but "
             "bus.master_heartbeat_ms is 0 (the master sends none)");
      }
      if (a.master_heartbeat_timeout_ms <= c.master_heartbeat_ms) {
        fail(p + ".master_heartbeat_timeout_ms", std::to_string(a.master_heartbeat_timeout_ms) +
                                                     " ms must be longer than bus.master_heartbeat_ms (" +
                                                     std::to_string(c.master_heartbeat_ms) + " ms)");
      }
    }
    if (a.abort_connection_option < 0 || a.abort_connection_option > 3) {
      fail(p + ".abort_connection_option", std::to_string(a.abort_connection_option) + " is outside 0..3");
    }
    const double max_counts = static_cast<double>(std::numeric_limits<std::int32_t>::max());
    if (std::abs(a.min_position) * a.counts_per_metre > max_counts ||
        std::abs(a.max_position) * a.counts_per_metre > max_counts) {
      fail(p + ".counts_per_metre", "position limits do not fit in 32-bit counts at this scale");
    }
  }
}

namespace {

CanConfig canConfig(const std::string& text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(source + ": YAML syntax error: " + e.what());
  }
  if (!root.IsMap()) throw ConfigError(source + ": expected a map with 'bus' and 'axes'");
  CanConfig c;
  Fields top(root, "", source);
  if (top.has("bus")) {
    Fields b(top.get("bus"), "bus", source);
    double sync_ms = c.sync_period_us / 1000.0;
    b.read("sync_period_ms", sync_ms, false, 1, 10000);
    c.sync_period_us = static_cast<std::uint32_t>(std::lround(sync_ms * 1000.0));
    b.read("sdo_timeout_ms", c.sdo_timeout_ms, false, 1, 600000);
    b.read("boot_timeout_ms", c.boot_timeout_ms, false, 1, 600000);
    b.read("master_node_id", c.master_node_id, false, 1, 127);
    b.read("master_heartbeat_ms", c.master_heartbeat_ms, false, 0, 65535);
    b.rejectUnknown();
  }
  if (!top.has("axes")) top.fail("axes", "missing field (required)");
  const YAML::Node axes = top.get("axes");
  if (!axes.IsSequence()) top.fail("axes", "expected a list of axes");
  for (std::size_t i = 0; i < axes.size(); ++i) {
    c.axes.push_back(parseAxis(axes[i], "axes[" + std::to_string(i) + "]", source));
  }
  top.rejectUnknown();
  validate(c, source);
  return c;
}

}  // namespace

// A yaml-cpp error the field readers did not name still names the file and its line.
CanConfig parseCanConfig(const std::string& text, const std::string& source) {
  try {
    return canConfig(text, source);
  } catch (const YAML::Exception& e) {
    throw ConfigError(source + ": " + e.what());
  }
}

CanConfig loadCanConfig(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot read the file");
  std::stringstream s;
  s << in.rdbuf();
  return parseCanConfig(s.str(), path);
}

}  // namespace massage_cell::can
