// Start-up check of a nodelet's dynamic_reconfigure parameters.
#pragma once

#include <algorithm>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>
#include <boost/any.hpp>
#include <boost/thread/recursive_mutex.hpp>

#include "typed_param.h"

namespace massage_cell::nodes {

/// dynamic_reconfigure reads the parameters of `Config` (a generated config
/// class) from the parameter server and ignores one of the wrong type, or
/// clamps a number outside the .cfg's range, without a word. A parameter of
/// the wrong type throws ParamError naming it (the nodelet stops at start-up,
/// as for its other parameters); the clamped ones are returned, one message
/// each in the .cfg's order, for the nodelet to log as an ERROR.
template <class Config>
std::vector<std::string> startParameterProblems(const ros::NodeHandle& pnh) {
  std::vector<std::string> problems;
  const Config min = Config::__getMin__(), max = Config::__getMax__();
  for (const auto& description : Config::__getParamDescriptions__()) {
    XmlRpc::XmlRpcValue v;
    if (!pnh.getParam(description->name, v)) continue;
    const auto type = v.getType();
    if (description->type == "bool") {
      if (type != XmlRpc::XmlRpcValue::TypeBoolean) {
        throw ParamError("parameter ~" + description->name + " must be true or false, got " + xmlRpcTypeName(v));
      }
      continue;
    }
    if (description->type == "str") {
      if (type != XmlRpc::XmlRpcValue::TypeString) {
        throw ParamError("parameter ~" + description->name + " must be a string, got " + xmlRpcTypeName(v));
      }
      continue;
    }
    const bool integer = description->type == "int";
    if (!integer && description->type != "double") continue;
    const bool is_int = type == XmlRpc::XmlRpcValue::TypeInt;
    std::ostringstream problem;
    if (!is_int && (integer || type != XmlRpc::XmlRpcValue::TypeDouble)) {
      throw ParamError("parameter ~" + description->name + " must be " + (integer ? "an integer" : "a number") +
                       ", got " + xmlRpcTypeName(v));
    }
    boost::any lo_any, hi_any;
    description->getValue(min, lo_any);
    description->getValue(max, hi_any);
    const double lo = integer ? boost::any_cast<int>(lo_any) : boost::any_cast<double>(lo_any);
    const double hi = integer ? boost::any_cast<int>(hi_any) : boost::any_cast<double>(hi_any);
    const double value = is_int ? static_cast<int>(v) : static_cast<double>(v);
    if (value < lo || value > hi) {
      problem << "parameter ~" << description->name << " = " << value << " is outside [" << lo << ", " << hi
              << "]: clamped to " << std::min(std::max(value, lo), hi);
      problems.push_back(problem.str());
    }
  }
  return problems;
}

/// Serves `Config` on `pnh`: each start-up problem (startParameterProblems) goes to `log_error` first; `callback`
/// then runs with `mutex` held, at once with the start-up values and on every change.
template <class Config, class Owner>
std::unique_ptr<dynamic_reconfigure::Server<Config>> serveConfig(
    ros::NodeHandle& pnh, boost::recursive_mutex& mutex, Owner* owner, void (Owner::*callback)(Config&, uint32_t),
    const std::function<void(const std::string&)>& log_error) {
  for (const std::string& problem : startParameterProblems<Config>(pnh)) log_error(problem);
  auto server = std::make_unique<dynamic_reconfigure::Server<Config>>(mutex, pnh);
  server->setCallback([owner, callback](Config& config, uint32_t level) { (owner->*callback)(config, level); });
  return server;
}

}  // namespace massage_cell::nodes
