// The massage session's routine and fix (see session.h).
#include "massage_cell/arm/session.h"

#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

namespace massage_cell::arm {

namespace {

void require(bool ok, const std::string& field, const std::string& want) {
  if (!ok) throw std::invalid_argument("session: " + field + ": " + want);
}

}  // namespace

void SessionConfig::validate() const {
  require(!acupoints.empty(), "acupoints", "expected a non-empty list of acupoint names");
  std::set<std::string> seen;
  for (const std::string& a : acupoints) {
    require(!a.empty(), "acupoints", "an empty name");
    require(seen.insert(a).second, "acupoints", "'" + a + "' is listed twice");
  }
  require(technique == "press" || technique == "knead", "technique",
          "expected press or knead, got '" + technique + "'");
  require(std::isfinite(depth) && depth >= 0.0 && depth <= 0.03, "depth", "expected 0 .. 0.03 m");
  require(mode == "depth" || mode == "force", "mode", "expected force or depth, got '" + mode + "'");
  require(std::isfinite(force) && force >= 0.0 && force <= 100.0, "force", "expected 0 .. 100 N (0: the region's)");
  require(std::isfinite(hold) && hold >= 0.0 && hold <= 60.0, "hold", "expected 0 .. 60 s");
  require(repeats >= 1 && repeats <= 20, "repeats", "expected 1 .. 20");
  for (std::size_t i = 0; i < strokes.size(); ++i) {
    const std::string field = "strokes[" + std::to_string(i) + "]";
    require(strokes[i].size() >= 2, field, "expected a path of two acupoints or more");
    std::set<std::string> on_path;
    for (const std::string& a : strokes[i]) {
      require(!a.empty(), field, "an empty name");
      require(on_path.insert(a).second, field, "'" + a + "' is on the path twice");
    }
  }
  require(strokes.empty() || mode == "force", "strokes", "a stroke glides at a force: needs mode force");
  require(std::isfinite(stroke_force) && stroke_force >= 0.0 && stroke_force <= 100.0, "stroke_force",
          "expected 0 .. 100 N (0: the regions' default)");
  require(std::isfinite(fix_window) && fix_window > 0.0, "fix_window", "expected > 0 s");
  require(fix_samples >= 1, "fix_samples", "expected >= 1");
  require(std::isfinite(fix_tolerance) && fix_tolerance > 0.0, "fix_tolerance", "expected > 0 m");
  require(std::isfinite(fix_timeout) && fix_timeout > 0.0, "fix_timeout", "expected > 0 s");
}

SessionConfig SessionConfig::load(const std::string& path) {
  SessionConfig c;
  try {
    const YAML::Node root = YAML::LoadFile(path);
    static const std::set<std::string> known = {
        "acupoints", "technique",    "mode",         "force",      "depth",       "hold",          "repeats",
        "strokes",   "stroke_force", "frame_prefix", "fix_window", "fix_samples", "fix_tolerance", "fix_timeout"};
    for (const auto& kv : root) {
      const std::string key = kv.first.as<std::string>();
      if (!known.count(key)) throw std::invalid_argument("session: unknown field '" + key + "'");
    }
    if (root["acupoints"]) c.acupoints = root["acupoints"].as<std::vector<std::string>>();
    if (root["technique"]) c.technique = root["technique"].as<std::string>();
    if (root["mode"]) c.mode = root["mode"].as<std::string>();
    if (root["force"]) c.force = root["force"].as<double>();
    if (root["depth"]) c.depth = root["depth"].as<double>();
    if (root["hold"]) c.hold = root["hold"].as<double>();
    if (root["repeats"]) c.repeats = root["repeats"].as<int>();
    if (root["strokes"]) c.strokes = root["strokes"].as<std::vector<std::vector<std::string>>>();
    if (root["stroke_force"]) c.stroke_force = root["stroke_force"].as<double>();
    if (root["frame_prefix"]) c.frame_prefix = root["frame_prefix"].as<std::string>();
    if (root["fix_window"]) c.fix_window = root["fix_window"].as<double>();
    if (root["fix_samples"]) c.fix_samples = root["fix_samples"].as<int>();
    if (root["fix_tolerance"]) c.fix_tolerance = root["fix_tolerance"].as<double>();
    if (root["fix_timeout"]) c.fix_timeout = root["fix_timeout"].as<double>();
    c.validate();
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  return c;
}

std::vector<std::string> SessionConfig::allAcupoints() const {
  std::vector<std::string> all = acupoints;
  std::set<std::string> seen(all.begin(), all.end());
  for (const auto& path : strokes)
    for (const std::string& a : path)
      if (seen.insert(a).second) all.push_back(a);
  return all;
}

StableFix::StableFix(double window_s, int samples, double tolerance_m)
    : window_(window_s), tolerance_(tolerance_m), samples_(samples) {}

void StableFix::add(const std::string& name, double t, const Eigen::Vector3d& position, bool valid) {
  auto& h = history_[name];
  if (!valid || !position.allFinite()) {
    h.clear();
    return;
  }
  h.push_back({t, position});
  while (!h.empty() && h.front().t < t - window_) h.erase(h.begin());
}

std::vector<StableFix::Sample> StableFix::recent(const std::string& name, double now) const {
  std::vector<Sample> out;
  const auto it = history_.find(name);
  if (it == history_.end()) return out;
  for (const Sample& s : it->second) {
    if (s.t >= now - window_ && s.t <= now) out.push_back(s);
  }
  return out;
}

Eigen::Vector3d StableFix::mean(const std::string& name, double now) const {
  const std::vector<Sample> r = recent(name, now);
  if (r.empty()) return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (const Sample& s : r) m += s.p;
  return m / static_cast<double>(r.size());
}

bool StableFix::stable(const std::string& name, double now) const {
  const std::vector<Sample> r = recent(name, now);
  if (static_cast<int>(r.size()) < samples_) return false;
  const Eigen::Vector3d m = mean(name, now);
  for (const Sample& s : r) {
    if ((s.p - m).norm() > tolerance_) return false;
  }
  return true;
}

std::vector<std::string> StableFix::unstable(const std::vector<std::string>& names, double now) const {
  std::vector<std::string> out;
  for (const std::string& n : names) {
    if (!stable(n, now)) out.push_back(n);
  }
  return out;
}

}  // namespace massage_cell::arm
