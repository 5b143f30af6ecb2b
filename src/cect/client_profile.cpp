// A client's profile (client_profile.h): its YAML file and its corrections on the acupoint model.
#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/locate.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

namespace massage_cell::cect {

namespace {

constexpr const char* kFormat = "massage_cell/client_profile 1";
// C7 -> L4 of adults lying prone: 0.28 .. 0.58 m (config/acupoints.yaml's
// plausibility); a profile's value outside a wider band is a typing error.
constexpr double kMinLength = 0.2, kMaxLength = 0.8;
// A correction is a nudge of the layout, not another point: at most a tenth
// of C7 -> L4 (~4.5 cm, a vertebra and a bit) along, 1 cun across.
constexpr double kMaxAlong = 0.1, kMaxAcrossCun = 1.0;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/// Why a profile's values are out of bounds ("" when they are not).
std::string problemOf(const ClientProfile& p) {
  if (!std::isnan(p.c7_to_l4_m) && !(p.c7_to_l4_m >= kMinLength && p.c7_to_l4_m <= kMaxLength))
    return "c7_to_l4_m = " + num(p.c7_to_l4_m) + " is not in " + num(kMinLength) + " .. " + num(kMaxLength) + " m";
  if (!(p.length_tolerance_m > 0.0 && p.length_tolerance_m <= 0.1))
    return "length_tolerance_m = " + num(p.length_tolerance_m) + " is not in (0, 0.1] m";
  for (const auto& [name, c] : p.corrections) {
    if (!(std::abs(c.along) <= kMaxAlong))
      return "corrections." + name + ".along = " + num(c.along) + " is beyond +-" + num(kMaxAlong) + " of C7 -> L4";
    if (!(std::abs(c.across_cun) <= kMaxAcrossCun))
      return "corrections." + name + ".across_cun = " + num(c.across_cun) + " is beyond +-" + num(kMaxAcrossCun) +
             " cun";
  }
  return "";
}

double number(const YAML::Node& node, const std::string& field) {
  try {
    return node.as<double>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(field + " is not a number");
  }
}

ClientProfile parse(const YAML::Node& root) {
  if (!root.IsMap()) throw std::runtime_error("not a YAML map");
  if (!root["format"] || root["format"].as<std::string>() != kFormat)
    throw std::runtime_error(std::string("no 'format: ") + kFormat +
                             "' line (not a client profile, or another version)");
  ClientProfile p;
  if (root["client"]) p.client = root["client"].as<std::string>();
  if (root["c7_to_l4_m"]) p.c7_to_l4_m = number(root["c7_to_l4_m"], "c7_to_l4_m");
  if (root["length_tolerance_m"]) p.length_tolerance_m = number(root["length_tolerance_m"], "length_tolerance_m");
  if (const YAML::Node cs = root["corrections"]) {
    if (!cs.IsMap()) throw std::runtime_error("corrections is not a map of acupoint names");
    for (const auto& kv : cs) {
      const std::string name = kv.first.as<std::string>();
      if (!kv.second.IsMap()) throw std::runtime_error("corrections." + name + " is not a map {along, across_cun}");
      AcupointCorrection c;
      if (kv.second["along"]) c.along = number(kv.second["along"], "corrections." + name + ".along");
      if (kv.second["across_cun"])
        c.across_cun = number(kv.second["across_cun"], "corrections." + name + ".across_cun");
      p.corrections[name] = c;
    }
  }
  if (const std::string problem = problemOf(p); !problem.empty()) throw std::runtime_error(problem);
  return p;
}

}  // namespace

ClientProfile loadClientProfile(const std::string& path) {
  try {
    return parse(YAML::LoadFile(path));
  } catch (const YAML::BadFile&) {
    throw std::runtime_error("client profile '" + path + "': cannot read the file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("client profile '" + path + "': " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("client profile '" + path + "': " + e.what());
  }
}

void saveClientProfile(const ClientProfile& p, const std::string& path) {
  if (const std::string problem = problemOf(p); !problem.empty())
    throw std::invalid_argument("saveClientProfile: " + problem);
  YAML::Emitter out;
  out << YAML::BeginMap << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "client" << YAML::Value << YAML::DoubleQuoted << p.client;
  if (!std::isnan(p.c7_to_l4_m)) out << YAML::Key << "c7_to_l4_m" << YAML::Value << p.c7_to_l4_m;
  out << YAML::Key << "length_tolerance_m" << YAML::Value << p.length_tolerance_m;
  if (!p.corrections.empty()) {
    out << YAML::Key << "corrections" << YAML::Value << YAML::BeginMap;
    for (const auto& [name, c] : p.corrections) {
      out << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "along" << YAML::Value
          << c.along << YAML::Key << "across_cun" << YAML::Value << c.across_cun << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  std::ofstream f(path);
  f << out.c_str() << "\n";
  if (!f) throw std::runtime_error("client profile '" + path + "': cannot write the file");
}

AcupointModel withCorrections(const AcupointModel& model, const ClientProfile& profile) {
  AcupointModel m = model;
  for (const auto& [name, c] : profile.corrections) {
    bool found = false;
    for (AcupointSpec& spec : m.points) {
      if (spec.name != name) continue;
      spec.level_offset += c.along;
      spec.lateral_cun += c.across_cun;
      found = true;
    }
    if (!found)
      throw std::invalid_argument("client profile '" + profile.client + "': a correction for '" + name +
                                  "', which the acupoint model does not have");
  }
  return m;
}

ClientProfile measuredProfile(const ClientProfile& base, const LocatedAcupoints& located, const std::string& client) {
  const BackLandmarks& l = located.landmarks;
  if (!(l.c7_given && l.l4_given))
    throw std::runtime_error(
        "C7 and L4 must both be given (a click, ~set_landmark, --landmark, skin markers) to measure the client's C7 -> "
        "L4");
  if (!(located.valid && located.check.trusted && std::isfinite(located.check.length_m)))
    throw std::runtime_error("no trusted C7 -> L4 on this pair: " + located.reason);
  ClientProfile p = base;
  if (!client.empty()) p.client = client;
  p.c7_to_l4_m = located.check.length_m;
  return p;
}

}  // namespace massage_cell::cect
