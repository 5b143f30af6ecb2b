// A client's profile (client_profile.h): its YAML file and its corrections on the acupoint model.
#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/locate.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <limits>
#include <set>
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

const char* const kKeys[] = {"format", "client", "c7_to_l4_m", "length_tolerance_m", "corrections"};
const char* const kCorrectionKeys[] = {"along", "across_cun"};

template <std::size_t N>
std::string listOf(const char* const (&keys)[N]) {
  std::string s;
  for (const char* k : keys) s += (s.empty() ? "" : ", ") + std::string(k);
  return s;
}

template <std::size_t N>
bool known(const char* const (&keys)[N], const std::string& key) {
  return std::find(std::begin(keys), std::end(keys), key) != std::end(keys);
}

/// What kind of YAML node `node` is, for the messages.
std::string kindOf(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Scalar:
      return "'" + node.Scalar() + "'";
    default:
      return "empty";
  }
}

/// The name a map's key gives (a scalar); `where` names the map in the message.
std::string keyName(const YAML::Node& key, const std::string& where) {
  if (!key.IsScalar()) throw std::runtime_error(where + " has a key that is not a name (" + kindOf(key) + ")");
  return key.Scalar();
}

/// A finite number; `field` names it in the message.
double number(const YAML::Node& node, const std::string& field) {
  double v = std::numeric_limits<double>::quiet_NaN();
  try {
    if (node.IsScalar()) v = node.as<double>();
  } catch (const YAML::Exception&) {
  }
  if (!std::isfinite(v)) throw std::runtime_error(field + " is not a number (got " + kindOf(node) + ")");
  return v;
}

AcupointCorrection correction(const std::string& name, const YAML::Node& node) {
  const std::string field = "corrections." + name;
  if (!node.IsMap()) throw std::runtime_error(field + " is not a map {along, across_cun} (got " + kindOf(node) + ")");
  AcupointCorrection c;
  std::set<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = keyName(kv.first, field);
    if (!known(kCorrectionKeys, key))
      throw std::runtime_error("unknown key '" + field + "." + key + "' (known: " + listOf(kCorrectionKeys) + ")");
    if (!seen.insert(key).second) throw std::runtime_error(field + "." + key + " given twice");
    (key == "along" ? c.along : c.across_cun) = number(kv.second, field + "." + key);
  }
  return c;
}

ClientProfile parse(const YAML::Node& root) {
  if (!root.IsMap())
    throw std::runtime_error("not a YAML map of the keys " + listOf(kKeys) + " (got " + kindOf(root) + ")");
  // The format first: another kind of file (an acupoint model, a camera_info) is said to be one, not a list of
  // unknown keys.
  const YAML::Node format = root["format"];
  if (!format)
    throw std::runtime_error(std::string("missing key 'format' (format: ") + kFormat + "): not a client profile");
  if (!format.IsScalar() || format.Scalar() != kFormat)
    throw std::runtime_error("format is " + kindOf(format) + ", not '" + kFormat +
                             "' (not a client profile, or another version)");
  ClientProfile p;
  std::set<std::string> seen;
  for (const auto& kv : root) {
    const std::string key = keyName(kv.first, "the file");
    if (!known(kKeys, key)) throw std::runtime_error("unknown key '" + key + "' (known: " + listOf(kKeys) + ")");
    if (!seen.insert(key).second) throw std::runtime_error(key + " given twice");
    const YAML::Node& value = kv.second;
    if (key == "client") {
      if (!value.IsScalar())
        throw std::runtime_error("client is not a name (got " + kindOf(value) + "; quote it: client: \"...\")");
      p.client = value.Scalar();
    } else if (key == "c7_to_l4_m") {
      p.c7_to_l4_m = number(value, key);
    } else if (key == "length_tolerance_m") {
      p.length_tolerance_m = number(value, key);
    } else if (key == "corrections") {
      if (!value.IsMap())
        throw std::runtime_error("corrections is not a map of acupoint names (got " + kindOf(value) + ")");
      for (const auto& c : value) {
        const std::string name = keyName(c.first, "corrections");
        if (p.corrections.count(name)) throw std::runtime_error("corrections." + name + " given twice");
        p.corrections[name] = correction(name, c.second);
      }
    }
  }
  if (!seen.count("client"))
    throw std::runtime_error("missing key 'client' (the client's id; client: \"\" when there is none)");
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

std::string describeClientProfile(const ClientProfile& p) {
  std::ostringstream s;
  s << "'" << p.client << "', C7 -> L4 ";
  if (std::isnan(p.c7_to_l4_m))
    s << "not measured";
  else
    s << std::fixed << std::setprecision(3) << p.c7_to_l4_m << " m";
  s << ", " << p.corrections.size() << (p.corrections.size() == 1 ? " correction" : " corrections");
  return s.str();
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
  if (!(l.c7.given() && l.l4.given()))
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
