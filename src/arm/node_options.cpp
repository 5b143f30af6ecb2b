#include "massage_cell/arm/node_options.h"

#include <cmath>
#include <sstream>
#include <type_traits>

#include <yaml-cpp/yaml.h>

namespace massage_cell::arm {

namespace {

void require(bool ok, const std::string& name, const std::string& what, double value) {
  if (ok) return;
  std::ostringstream s;
  s << name << " must be " << what << ", got " << value;
  throw ArmConfigError(s.str());
}

}  // namespace

NodeOptions loadNodeOptions(const std::string& path) {
  NodeOptions o;
  try {
    const YAML::Node node = YAML::LoadFile(path)["node"];
    if (!node) return o;
    visitOptions(o, [&node](const char* key, auto& value) {
      if (node[key]) value = node[key].as<std::decay_t<decltype(value)>>();
    });
  } catch (const YAML::Exception& e) {
    throw ArmConfigError(path + ": node: " + e.what());
  }
  return o;
}

void validate(const NodeOptions& o) {
  require(o.publish_rate > 0.0, "publish_rate", "> 0", o.publish_rate);
  require(o.max_target_age > 0.0, "max_target_age", "> 0", o.max_target_age);
  require(o.tf_timeout >= 0.0, "tf_timeout", ">= 0", o.tf_timeout);
  require(o.command_timeout > 0.0, "command_timeout", "> 0", o.command_timeout);
  require(o.surface_max_age > 0.0, "surface_max_age", "> 0", o.surface_max_age);
  if (o.can_interface.empty()) throw ArmConfigError("can_interface must be 'sim' or an interface name (can0)");
  require(o.realtime.priority >= 0 && o.realtime.priority <= 99, "realtime_priority", "0 (normal scheduling) .. 99",
          o.realtime.priority);
}

}  // namespace massage_cell::arm
