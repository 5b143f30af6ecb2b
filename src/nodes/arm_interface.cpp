#include "arm_interface.h"

#include <algorithm>
#include <cmath>

#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>

#include "tf_lookup.h"

namespace massage_cell::nodes {

namespace {

Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }
Eigen::Vector3d toEigen(const geometry_msgs::Vector3& v) { return {v.x, v.y, v.z}; }

}  // namespace

massage_cell::ArmState armStateMsg(const arm::ArmStatus& s, const std::string& base_frame, const ros::Time& stamp) {
  massage_cell::ArmState st;
  st.header.stamp = stamp;
  st.header.frame_id = base_frame;
  st.mode = arm::toString(s.mode);
  st.homed = s.homed;
  st.estop_active = s.estop_input;
  st.estop_latched = s.estop_latched;
  for (const arm::AxisStatus& a : s.axes) {
    st.axis_names.push_back(a.name);
    st.position.push_back(a.position);
    st.axis_state.push_back(can::toString(a.state));
    st.node_state.push_back(can::toString(a.node));
    st.axis_homed.push_back(a.homed);
  }
  st.tool.x = s.tool.x();
  st.tool.y = s.tool.y();
  st.tool.z = s.tool.z();
  st.faults = s.faults;
  st.activity = s.activity;
  st.last_error = s.last_error;
  st.bus_state = can::toString(s.bus);
  st.force_valid = s.force.valid;
  st.force = s.force.valid ? s.force.force : 0.0;
  st.force_source = s.force.valid ? s.force.source : s.force.source + ": " + s.force.problem;
  st.press_phase = s.press_phase;
  st.force_target = s.force_target;
  st.force_limit = s.force_limit;
  return st;
}

geometry_msgs::WrenchStamped wrenchMsg(const arm::ArmStatus& s, const std::string& tool_frame, const ros::Time& stamp) {
  // The force the body puts on the tool, in the tool frame (axes parallel to the arm base: the gantry does not turn).
  geometry_msgs::WrenchStamped w;
  w.header.stamp = stamp;
  w.header.frame_id = tool_frame;
  w.wrench.force.z = s.force.force;
  return w;
}

sensor_msgs::JointState jointStateMsg(const arm::ArmStatus& s, const arm::ArmConfig& config, const ros::Time& stamp) {
  sensor_msgs::JointState js;
  js.header.stamp = stamp;
  for (int i = 0; i < 3; ++i) {
    js.name.push_back(config.joint_names[i]);
    js.position.push_back(s.axes[i].position);
  }
  return js;
}

void reportArm(const arm::ArmStatus& s, const arm::NodeOptions& options, const can::RealtimeStatus& realtime,
               diagnostic_updater::DiagnosticStatusWrapper* out) {
  using diagnostic_msgs::DiagnosticStatus;
  using Level = arm::Health::Level;
  const arm::Health health = arm::health(s);
  out->summary(health.level == Level::kError  ? DiagnosticStatus::ERROR
               : health.level == Level::kWarn ? DiagnosticStatus::WARN
                                              : DiagnosticStatus::OK,
               health.text);
  out->add("mode", arm::toString(s.mode));
  out->add("homed", s.homed);
  out->add("e-stop input", s.estop_input);
  out->add("e-stop latched", s.estop_latched);
  out->add("CAN interface", options.can_interface);
  out->add("real-time scheduling", realtime.describe());
  out->add("bus state", can::toString(s.bus));
  for (const auto& a : s.axes) out->add("axis " + a.name, arm::describeAxis(a));
  out->add("tool (" + options.base_frame + ")", arm::formatPoint(s.tool));
  out->add("activity", s.activity);
  out->add("tool force", s.force.valid ? arm::formatForce(s.force) : s.force.source + ": " + s.force.problem);
  out->add("last error", s.last_error);
  out->add("controller cycles", s.cycles);
}

bool ArmTargets::lookup(const std::string& frame, const ros::Time& stamp, geometry_msgs::TransformStamped* out,
                        std::string* error) const {
  return lookupFresh(tf_, options_.base_frame, frame, stamp, options_.tf_timeout, options_.max_target_age, out, error);
}

arm::BodySurface ArmTargets::body() const {
  arm::BodySurface body;
  body.points = framePositions(tf_, options_.base_frame, options_.acupoint_prefix, options_.max_target_age);
  std::lock_guard<std::mutex> lock(surface_mutex_);
  if (!surface_stamp_.isZero() && (ros::Time::now() - surface_stamp_).toSec() <= options_.surface_max_age)
    body.dense = surface_;
  return body;
}

std::string ArmTargets::setSurface(const sensor_msgs::PointCloud2& cloud) {
  if (cloud.header.frame_id.empty()) return "the cloud has no frame_id";
  const auto has_float = [&](const char* name) {
    return std::any_of(cloud.fields.begin(), cloud.fields.end(), [&](const sensor_msgs::PointField& f) {
      return f.name == name && f.datatype == sensor_msgs::PointField::FLOAT32;
    });
  };
  if (!has_float("x") || !has_float("y") || !has_float("z")) return "the cloud has no float32 x, y and z fields";
  geometry_msgs::TransformStamped t;
  try {
    t = tf_.lookupTransform(options_.base_frame, cloud.header.frame_id, ros::Time(0));
  } catch (const tf2::TransformException& e) {
    return "the frame '" + cloud.header.frame_id + "' is not connected to " + options_.base_frame + ": " + e.what();
  }
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(cloud.width) * cloud.height);
  for (sensor_msgs::PointCloud2ConstIterator<float> it(cloud, "x"); it != it.end(); ++it) {
    geometry_msgs::Point p, q;
    p.x = it[0];
    p.y = it[1];
    p.z = it[2];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    tf2::doTransform(p, q, t);
    points.push_back(toEigen(q));
  }
  // Where the tool can go, and a radius around it (a point farther out never bounds a motion).
  const Eigen::Vector2d margin = Eigen::Vector2d::Constant(config_.body.radius);
  arm::HeightGrid grid(points, config_.body.surface_cell, config_.workspace_min.head<2>() - margin,
                       config_.workspace_max.head<2>() + margin);
  std::lock_guard<std::mutex> lock(surface_mutex_);
  surface_ = std::move(grid);
  surface_stamp_ = cloud.header.stamp.isZero() ? ros::Time::now() : cloud.header.stamp;
  return "";
}

std::string ArmTargets::moveGoal(const geometry_msgs::PointStamped& target, const Eigen::Vector3d& tool,
                                 Eigen::Vector3d* goal) const {
  if (target.header.frame_id.empty()) return "move_to refused: the target has no frame_id";
  geometry_msgs::TransformStamped t;
  std::string error;
  if (!lookup(target.header.frame_id, target.header.stamp, &t, &error)) {
    return "move_to refused: the target frame " + error;
  }
  geometry_msgs::Point p;
  tf2::doTransform(target.point, p, t);
  *goal = toEigen(p);
  if (!arm::checkTool(config_, *goal).empty()) return "";  // outside the envelope: the controller says so
  const std::string why =
      arm::checkBodyClearance(config_, body(), tool, *goal, config_.limitsOf(config_.default_region).max_depth);
  return why.empty() ? "" : "move refused: " + why;
}

std::string ArmTargets::whyNoFrame(const std::string& frame) const {
  const std::string& prefix = options_.acupoint_prefix;
  if (frame.rfind(prefix, 0) == 0) {
    const std::string name = frame.substr(prefix.size());
    if (!config_.regionOf(name).empty())
      return "; " + name +
             " is an acupoint of the model but CECT publishes no valid fix for it now (see its "
             "acupoints message's reason)";
    return "; '" + name + "' is not an acupoint of the model (" + config_.acupoints_path + ")";
  }
  if (!config_.regionOf(frame).empty())
    return "; acupoint frames are named '" + prefix + "<name>': did you mean '" + prefix + frame + "'?";
  return "";
}

std::string ArmTargets::sensorForce(const geometry_msgs::WrenchStamped& wrench, double* force_z) const {
  const geometry_msgs::Vector3& f = wrench.wrench.force;
  if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z)) return "the force is not finite";
  if (wrench.header.frame_id.empty()) return "the wrench has no frame_id";
  geometry_msgs::TransformStamped t;
  try {  // the sensor is fixed to the tool, whose orientation does not change: the latest transform
    t = tf_.lookupTransform(options_.base_frame, wrench.header.frame_id, ros::Time(0));
  } catch (const tf2::TransformException& e) {
    return "the frame '" + wrench.header.frame_id + "' is not connected to " + options_.base_frame + ": " + e.what();
  }
  geometry_msgs::Vector3 in_base;
  tf2::doTransform(f, in_base, t);
  *force_z = in_base.z;
  return "";
}

std::string ArmTargets::pointsInBase(const massage_cell::AcupointArray& acupoints,
                                     std::vector<Eigen::Vector3d>* out) const {
  if (acupoints.header.frame_id.empty()) return "the acupoints have no frame_id";
  geometry_msgs::TransformStamped t;
  try {
    t = tf_.lookupTransform(options_.base_frame, acupoints.header.frame_id, ros::Time(0));
  } catch (const tf2::TransformException& e) {
    return "the frame '" + acupoints.header.frame_id + "' is not connected to " + options_.base_frame + ": " + e.what();
  }
  out->clear();
  for (const massage_cell::Acupoint& a : acupoints.acupoints) {
    if (!a.valid) continue;
    geometry_msgs::Point p;
    tf2::doTransform(a.position, p, t);
    out->push_back(toEigen(p));
  }
  return "";
}

template <class Request>
std::string ArmTargets::pressRequest(const Request& req, arm::PressRequest* press,
                                     std::vector<FrameTarget>* frames) const {
  arm::MassageFields fields;
  fields.targets = req.frames.size() + req.points.size();
  fields.regions = req.regions.size();
  fields.normals = req.normals.size();
  fields.technique = req.technique;
  fields.mode = req.mode;
  fields.force = req.force;
  fields.depth = req.depth;
  fields.hold = req.hold;
  fields.speed = req.speed;
  fields.repeats = req.repeats;
  if (std::string why = arm::pressSettings(config_, fields, press); !why.empty()) return why;
  const arm::BodySurface skin = body();
  for (std::size_t i = 0; i < fields.targets; ++i) {
    arm::PressTarget target;
    if (std::string why = pressTarget(req, i, skin, &target); !why.empty()) return why;
    if (i < req.frames.size()) frames->emplace_back(static_cast<int>(i), req.frames[i]);
    press->targets.push_back(target);
  }
  return "";
}

template <class Request>
std::string ArmTargets::pressTarget(const Request& req, std::size_t i, const arm::BodySurface& body,
                                    arm::PressTarget* target) const {
  geometry_msgs::TransformStamped t;
  std::string error;
  if (i < req.frames.size()) {  // an acupoint's (or any) tf frame
    const std::string& frame = req.frames[i];
    if (!lookup(frame, ros::Time(0), &t, &error))
      return "target " + std::to_string(i + 1) + ": the frame " + error + whyNoFrame(frame);
    const std::string& prefix = options_.acupoint_prefix;
    target->name = frame.rfind(prefix, 0) == 0 ? frame.substr(prefix.size()) : frame;
    target->point = {t.transform.translation.x, t.transform.translation.y, t.transform.translation.z};
    target->region = config_.regionOf(target->name);
  } else {  // a point in any frame
    const geometry_msgs::PointStamped& ps = req.points[i - req.frames.size()];
    target->name = "point " + std::to_string(i - req.frames.size() + 1);
    if (ps.header.frame_id.empty()) return target->name + " has no frame_id";
    if (!lookup(ps.header.frame_id, ps.header.stamp, &t, &error)) return target->name + ": the frame " + error;
    geometry_msgs::Point p;
    tf2::doTransform(ps.point, p, t);
    target->point = toEigen(p);
  }
  if (!req.regions.empty() && !req.regions[i].empty()) target->region = req.regions[i];
  // A surface point under the skin the arm knows would press deeper than the region allows.
  const double limit = config_.limitsOf(target->region.empty() ? config_.default_region : target->region).max_depth;
  if (std::string why = arm::checkBodyClearance(config_, body, target->point, target->point, limit); !why.empty()) {
    return target->name + ": " + why;
  }
  if (!req.normals.empty()) {
    const geometry_msgs::Vector3Stamped& ns = req.normals[i];
    if (!lookup(ns.header.frame_id.empty() ? options_.base_frame : ns.header.frame_id, ros::Time(0), &t, &error)) {
      return target->name + ": the normal's frame " + error;
    }
    geometry_msgs::Vector3 v;
    tf2::doTransform(ns.vector, v, t);
    target->normal = toEigen(v);
  }
  return "";
}

// The service's request and the action's goal: the same fields, one conversion.
template std::string ArmTargets::pressRequest(const massage_cell::Massage::Request&, arm::PressRequest*,
                                              std::vector<FrameTarget>*) const;
template std::string ArmTargets::pressRequest(const massage_cell::MassageGoal&, arm::PressRequest*,
                                              std::vector<FrameTarget>*) const;

}  // namespace massage_cell::nodes
