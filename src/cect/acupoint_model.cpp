// The acupoint model's file (acupoint_model.h): config/acupoints.yaml read into an AcupointModel
// (loadAcupointModel: every error names the file, and the key where there is one), its checks
// (AcupointModel::validate) and look-ups (names, find). The model's stages: silhouette.cpp, landmarks.cpp,
// landmarks_3d.cpp and placement.cpp.
#include "massage_cell/cect/acupoint_model.h"

#include "acupoint_model_detail.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace massage_cell::cect {

namespace {

const std::vector<std::string>& standardLevels() {
  static const std::vector<std::string> levels = {"C7", "T1",  "T2",  "T3",  "T4", "T5", "T6", "T7", "T8",
                                                  "T9", "T10", "T11", "T12", "L1", "L2", "L3", "L4", "L5"};
  return levels;
}

int levelIndex(const std::string& level) {
  const auto& levels = standardLevels();
  const auto it = std::find(levels.begin(), levels.end(), level);
  return it == levels.end() ? -1 : static_cast<int>(it - levels.begin());
}

const std::set<std::string>& regions() {
  static const std::set<std::string> r = {"upper_back", "lower_back", "midline", "shoulder"};
  return r;
}

// --- YAML helpers: errors name the key.

template <typename T>
T get(const YAML::Node& node, const std::string& key, const std::string& where) {
  const YAML::Node v = node[key];
  if (!v) throw std::runtime_error(where + ": missing key '" + key + "'");
  try {
    return v.as<T>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(where + ": key '" + key + "' has the wrong type");
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// AcupointModel

std::vector<std::string> AcupointModel::names() const {
  std::vector<std::string> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(p.name);
  return out;
}

const AcupointSpec* AcupointModel::find(const std::string& name) const {
  for (const auto& p : points) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

void AcupointModel::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("acupoint model: " + what); };
  if (level_fraction.empty()) fail("level_fraction is empty");
  for (const auto& [level, f] : level_fraction) {
    if (levelIndex(level) < 0) {
      fail("unknown vertebral level '" + level + "' in level_fraction (expected C7, T1..T12, L1..L5)");
    }
    if (!std::isfinite(f)) fail("level_fraction of " + level + " is not finite");
  }
  const auto c7 = level_fraction.find("C7"), l4 = level_fraction.find("L4");
  if (c7 == level_fraction.end() || c7->second != 0.0) fail("level_fraction must list C7 = 0");
  if (l4 == level_fraction.end() || l4->second != 1.0) fail("level_fraction must list L4 = 1");
  // Increasing in the spine's order.
  std::string prev;
  double prev_f = -std::numeric_limits<double>::infinity();
  for (const auto& level : standardLevels()) {
    const auto it = level_fraction.find(level);
    if (it == level_fraction.end()) continue;
    if (!(it->second > prev_f)) {
      fail("level_fraction must increase from C7 to L5: " + level + " = " + num(it->second) + " is not below " + prev +
           " = " + num(prev_f));
    }
    prev = level;
    prev_f = it->second;
  }
  if (!(cun_per_shoulder_width > 0.0 && cun_per_shoulder_width < 0.5)) {
    fail("cun_per_shoulder_width = " + num(cun_per_shoulder_width) + " is not in (0, 0.5)");
  }
  if (!(c7_below_top >= 0.0 && c7_below_top < 0.5)) fail("c7_below_top = " + num(c7_below_top) + " is not in [0, 0.5)");
  if (!(std::abs(waist_rim_offset) < 0.2))
    fail("waist_rim_offset = " + num(waist_rim_offset) + " is not in (-0.2, 0.2)");
  if (!(shoulder_below_c7 >= 0.0 && shoulder_below_c7 < 0.5))
    fail("shoulder_below_c7 = " + num(shoulder_below_c7) + " is not in [0, 0.5)");
  if (!(length_per_shoulder_width > 0.3 && length_per_shoulder_width < 3.0))
    fail("length_per_shoulder_width = " + num(length_per_shoulder_width) + " is not in (0.3, 3)");
  for (const double v :
       {layout_sigma.c7_measured, layout_sigma.c7_inferred, layout_sigma.l4_measured, layout_sigma.l4_inferred,
        layout_sigma.c7_given, layout_sigma.l4_given, layout_sigma.level_given, layout_sigma.across})
    if (!(v >= 0.0 && v < 1.0)) fail("layout_sigma: " + num(v) + " is not in [0, 1)");
  const Plausibility& pl = plausibility;
  if (!(pl.min_length_m > 0.0 && pl.min_length_m < pl.max_length_m))
    fail("plausibility: min_length_m " + num(pl.min_length_m) + " must be > 0 and < max_length_m " +
         num(pl.max_length_m));
  if (!(pl.min_shoulder_width_m > 0.0 && pl.min_shoulder_width_m < pl.max_shoulder_width_m))
    fail("plausibility: min_shoulder_width_m " + num(pl.min_shoulder_width_m) +
         " must be > 0 and < max_shoulder_width_m " + num(pl.max_shoulder_width_m));
  if (!(pl.proportion_tolerance > 0.0 && pl.proportion_tolerance < 1.0))
    fail("plausibility: proportion_tolerance " + num(pl.proportion_tolerance) + " is not in (0, 1)");
  if (!(pl.given_level_tolerance > 0.0 && pl.given_level_tolerance < 0.5))
    fail("plausibility: given_level_tolerance " + num(pl.given_level_tolerance) + " is not in (0, 0.5)");
  if (!(pl.given_level_limit >= pl.given_level_tolerance && pl.given_level_limit < 0.5))
    fail("plausibility: given_level_limit " + num(pl.given_level_limit) + " is not in [given_level_tolerance, 0.5)");
  if (!(pl.max_given_off_midline_cun > 0.0 && pl.max_given_off_midline_cun <= 6.0))
    fail("plausibility: max_given_off_midline_cun " + num(pl.max_given_off_midline_cun) + " is not in (0, 6]");
  if (!(pl.given_disagreement_sigmas > 0.0))
    fail("plausibility: given_disagreement_sigmas " + num(pl.given_disagreement_sigmas) + " must be > 0");
  if (!(pl.min_shoulder_below_c7 < pl.max_shoulder_below_c7))
    fail("plausibility: min_shoulder_below_c7 must be < max_shoulder_below_c7");
  if (!(waist_fraction > 0.0 && waist_fraction < 1.5)) {
    fail("waist_fraction = " + num(waist_fraction) + " is not in (0, 1.5)");
  }
  if (points.empty()) fail("no points");
  std::set<std::string> seen;
  for (const auto& p : points) {
    if (p.name.empty()) fail("a point has an empty name");
    if (!seen.insert(p.name).second) fail("duplicate point name '" + p.name + "'");
    if (!level_fraction.count(p.level)) {
      fail("point '" + p.name + "': unknown level '" + p.level + "' (not in level_fraction)");
    }
    if (!(std::abs(p.lateral_cun) <= 10.0)) {
      fail("point '" + p.name + "': lateral_cun = " + num(p.lateral_cun) + " is not in -10 .. 10");
    }
    if (!regions().count(p.region)) {
      fail("point '" + p.name + "': unknown region '" + p.region +
           "' (expected upper_back, lower_back, midline or shoulder)");
    }
  }
}

namespace {

AcupointModel acupointModel(const std::string& path) {
  const std::string where = "acupoint model '" + path + "'";
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(where + ": cannot open the file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(where + ": not valid YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error(where + ": expected a mapping at the top level");
  AcupointModel m;
  m.head_up = root["head_up"] ? get<bool>(root, "head_up", where) : true;
  m.cun_per_shoulder_width = get<double>(root, "cun_per_shoulder_width", where);
  m.c7_below_top = get<double>(root, "c7_below_top", where);
  m.waist_fraction = get<double>(root, "waist_fraction", where);
  if (root["waist_rim_offset"]) m.waist_rim_offset = get<double>(root, "waist_rim_offset", where);
  if (root["shoulder_below_c7"]) m.shoulder_below_c7 = get<double>(root, "shoulder_below_c7", where);
  if (root["length_per_shoulder_width"])
    m.length_per_shoulder_width = get<double>(root, "length_per_shoulder_width", where);
  if (const YAML::Node ls = root["layout_sigma"]) {
    if (!ls.IsMap()) throw std::runtime_error(where + ": 'layout_sigma' must be a mapping");
    const std::string at = where + ", layout_sigma";
    AcupointModel::LayoutSigma& l = m.layout_sigma;
    for (const auto& kv : ls) {
      const std::string key = kv.first.as<std::string>();
      double* field = key == "c7_measured"   ? &l.c7_measured
                      : key == "c7_inferred" ? &l.c7_inferred
                      : key == "l4_measured" ? &l.l4_measured
                      : key == "l4_inferred" ? &l.l4_inferred
                      : key == "c7_given"    ? &l.c7_given
                      : key == "l4_given"    ? &l.l4_given
                      : key == "level_given" ? &l.level_given
                      : key == "across"      ? &l.across
                                             : nullptr;
      if (!field)
        throw std::runtime_error(
            at + ": unknown key '" + key +
            "' (c7_measured, c7_inferred, l4_measured, l4_inferred, c7_given, l4_given, level_given, "
            "across)");
      *field = get<double>(ls, key, at);
    }
  }
  if (const YAML::Node pl = root["plausibility"]) {
    if (!pl.IsMap()) throw std::runtime_error(where + ": 'plausibility' must be a mapping");
    const std::string at = where + ", plausibility";
    AcupointModel::Plausibility& b = m.plausibility;
    const std::map<std::string, double*> fields{{"min_length_m", &b.min_length_m},
                                                {"max_length_m", &b.max_length_m},
                                                {"min_shoulder_width_m", &b.min_shoulder_width_m},
                                                {"max_shoulder_width_m", &b.max_shoulder_width_m},
                                                {"proportion_tolerance", &b.proportion_tolerance},
                                                {"min_shoulder_below_c7", &b.min_shoulder_below_c7},
                                                {"max_shoulder_below_c7", &b.max_shoulder_below_c7},
                                                {"given_level_tolerance", &b.given_level_tolerance},
                                                {"given_level_limit", &b.given_level_limit},
                                                {"max_given_off_midline_cun", &b.max_given_off_midline_cun},
                                                {"given_disagreement_sigmas", &b.given_disagreement_sigmas}};
    for (const auto& kv : pl) {
      const std::string key = kv.first.as<std::string>();
      const auto field = fields.find(key);
      if (field == fields.end()) {
        std::string known;
        for (const auto& [name, ptr] : fields) known += (known.empty() ? "" : ", ") + name;
        throw std::runtime_error(at + ": unknown key '" + key + "' (" + known + ")");
      }
      *field->second = get<double>(pl, key, at);
    }
  }
  const YAML::Node levels = root["level_fraction"];
  if (!levels || !levels.IsMap()) throw std::runtime_error(where + ": missing mapping 'level_fraction'");
  for (const auto& kv : levels) {
    const std::string level = kv.first.as<std::string>();
    if (m.level_fraction.count(level)) throw std::runtime_error(where + ": level '" + level + "' listed twice");
    try {
      m.level_fraction[level] = kv.second.as<double>();
    } catch (const YAML::Exception&) {
      throw std::runtime_error(where + ": level_fraction of '" + level + "' is not a number");
    }
  }
  const YAML::Node points = root["points"];
  if (!points || !points.IsSequence()) throw std::runtime_error(where + ": missing sequence 'points'");
  for (std::size_t i = 0; i < points.size(); ++i) {
    const YAML::Node p = points[i];
    const std::string at = where + ", points[" + std::to_string(i) + "]";
    if (!p.IsMap()) throw std::runtime_error(at + ": expected a mapping");
    AcupointSpec s;
    s.name = get<std::string>(p, "name", at);
    s.level = get<std::string>(p, "level", at);
    s.lateral_cun = get<double>(p, "lateral_cun", at);
    s.region = get<std::string>(p, "region", at);
    m.points.push_back(s);
  }
  try {
    m.validate();
  } catch (const std::invalid_argument& e) {
    std::string what = e.what();
    const std::string prefix = "acupoint model: ";
    if (what.rfind(prefix, 0) == 0) what = what.substr(prefix.size());
    throw std::runtime_error(where + ": " + what);
  }
  return m;
}

}  // namespace

// A yaml-cpp error the field readers did not name still names the file and its line.
AcupointModel loadAcupointModel(const std::string& path) {
  try {
    return acupointModel(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("acupoint model '" + path + "': " + e.what());
  }
}

}  // namespace massage_cell::cect
