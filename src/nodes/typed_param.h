// Typed private parameters: ros::NodeHandle::param() silently keeps the
// default when a parameter is set with another type (`approximate_sync: maybe`,
// `_publish_rate:=fast`); typedParam() refuses it with a message naming the
// parameter, and the node stops at start-up (nodelets: FATAL + exit 1).
#pragma once

#include <stdexcept>
#include <string>
#include <type_traits>

#include <ros/ros.h>

namespace massage_cell::nodes {

class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline std::string xmlRpcTypeName(XmlRpc::XmlRpcValue v) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return "a boolean";
    case XmlRpc::XmlRpcValue::TypeInt:
      return "an integer (" + std::to_string(static_cast<int>(v)) + ")";
    case XmlRpc::XmlRpcValue::TypeDouble:
      return "a number";
    case XmlRpc::XmlRpcValue::TypeString:
      return "a string ('" + static_cast<std::string>(v) + "')";
    case XmlRpc::XmlRpcValue::TypeArray:
      return "a list";
    case XmlRpc::XmlRpcValue::TypeStruct:
      return "a dictionary";
    default:
      return "an unknown type";
  }
}

/// The private parameter `name` of type T (bool, int, double, std::string),
/// or `fallback` when it is not set. Throws ParamError when it is set with
/// another type (an integer is a number; a number is not an integer; a string
/// is taken for a string parameter, an integer too: `device: 0`).
template <typename T>
T typedParam(const ros::NodeHandle& pnh, const std::string& name, const T& fallback) {
  XmlRpc::XmlRpcValue value;
  if (!pnh.getParam(name, value)) return fallback;
  const auto type = value.getType();
  const std::string where = "parameter ~" + name + " ";
  if constexpr (std::is_same_v<T, bool>) {
    if (type == XmlRpc::XmlRpcValue::TypeBoolean) return static_cast<bool>(value);
    throw ParamError(where + "must be true or false, got " + xmlRpcTypeName(value));
  } else if constexpr (std::is_same_v<T, int>) {
    if (type == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(value);
    throw ParamError(where + "must be an integer, got " + xmlRpcTypeName(value));
  } else if constexpr (std::is_same_v<T, double>) {
    if (type == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(value);
    if (type == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(value);
    throw ParamError(where + "must be a number, got " + xmlRpcTypeName(value));
  } else {
    static_assert(std::is_same_v<T, std::string>, "typedParam: bool, int, double or std::string");
    if (type == XmlRpc::XmlRpcValue::TypeString) return static_cast<std::string>(value);
    if (type == XmlRpc::XmlRpcValue::TypeInt) return std::to_string(static_cast<int>(value));
    throw ParamError(where + "must be a string, got " + xmlRpcTypeName(value));
  }
}

/// A nodelet's onInit(): runs `init`; a ParamError is logged FATAL under the
/// nodelet's `name` and rethrown, so that the node exits 1 (runNodelet) or the
/// nodelet manager reports the failed load.
template <class Init>
void initOrStop(const std::string& name, Init&& init) {
  try {
    init();
  } catch (const ParamError& e) {
    ROS_FATAL_STREAM("[" << name << "] " << e.what());
    throw;
  }
}

/// typedParam() into `*value`, keeping it as the fallback.
template <typename T>
void readParam(const ros::NodeHandle& pnh, const std::string& name, T* value) {
  *value = typedParam<T>(pnh, name, *value);
}

}  // namespace massage_cell::nodes
