#include "cect_scenes.h"

#include <algorithm>
#include <cstdint>
#include <random>
#include <sstream>
#include <stdexcept>

namespace massage_cell::tools {
namespace {

struct Draw {
  std::mt19937 rng;
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  bool chance(double p) { return uniform(0.0, 1.0) < p; }
  template <typename T>
  const T& pick(const std::vector<T>& v) {
    return v[std::uniform_int_distribution<std::size_t>(0, v.size() - 1)(rng)];
  }
};

std::uint32_t conditionSeed(const std::string& condition) {
  std::uint32_t h = 2166136261u;
  for (const char c : condition) h = (h ^ static_cast<std::uint8_t>(c)) * 16777619u;
  return h;
}

/// The image's top and bottom edges on the body (world x at the back's height).
struct Framing {
  double top = 0.0, bottom = 0.0;
};

/// A cell's usual view: the neck and part of the head above, the view ending
/// between just below L4 and mid-buttocks.
Framing usualFraming(Draw& d, const sim::BackModel& back) {
  const double l4 = back.levelX("L4");
  return {d.uniform(0.06, 0.16), d.uniform(l4 - 0.22, l4 - 0.06)};
}

void dressCell(Draw& d, sim::Dressing* s) {
  s->head = true;
  s->lower_body = true;
  s->hair = d.pick(std::vector<sim::HairLength>{sim::HairLength::kShort, sim::HairLength::kNape, sim::HairLength::kLong,
                                                sim::HairLength::kNone});
  s->hair_colour =
      d.pick(std::vector<sim::HairColour>{sim::HairColour::kBlack, sim::HairColour::kBrown, sim::HairColour::kBlond,
                                          sim::HairColour::kGrey, sim::HairColour::kRed});
  const auto& colours = sim::clothColours();
  s->sheet = sim::Cloth{d.pick(colours).second, d.chance(0.7) ? sim::Weave::kFine : sim::Weave::kWaffle};
}

void armsAlong(Draw& d, sim::Dressing* s, double max_abduction) {
  s->arms = sim::ArmPose::kAlongTrunk;
  s->arm_abduction_left = d.uniform(0.0, max_abduction);
  s->arm_abduction_right = d.uniform(0.0, max_abduction);
}

void addTowel(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  const auto& colours = sim::clothColours();
  s->towel = sim::Cloth{d.pick(colours).second,
                        d.pick(std::vector<sim::Weave>{sim::Weave::kTerry, sim::Weave::kWaffle, sim::Weave::kFine})};
  const double l4 = back.levelX("L4"), l5 = back.levelX("L5");
  s->towel_edge_x = d.uniform(l4 - 0.10, l5);
  s->towel_edge_tilt = d.uniform(-0.15, 0.15);
}

void rawToeIn(Draw& d, sim::RigParameters* rig) {
  rig->rectified = false;
  rig->toe_in = d.uniform(0.017, 0.07);  // 1-4 degrees
  rig->baseline = d.uniform(0.06, 0.12);
}

std::string describe(const Scenario& s, const std::string& condition, const Framing& f) {
  std::ostringstream o;
  o.precision(2);
  o << condition << ": arms "
    << (s.dressing.arms == sim::ArmPose::kNone     ? "none"
        : s.dressing.arms == sim::ArmPose::kRaised ? "raised"
                                                   : "along")
    << (s.dressing.towel ? ", towel" : "") << ", view x " << f.top << " .. " << f.bottom << " m"
    << (s.rig.rectified ? "" : ", raw toe-in rig") << ", B " << s.rig.baseline << " m";
  return o.str();
}

}  // namespace

const std::vector<std::string>& realConditions() {
  static const std::vector<std::string> c{"arms_touching", "arms_apart", "arms_raised", "neck_cut", "hips_cut",
                                          "towel",         "dark_skin",  "toe_in",      "mixed"};
  return c;
}

Scenario realScenario(const std::string& condition, int subject, const sim::RigParameters& base) {
  if (std::find(realConditions().begin(), realConditions().end(), condition) == realConditions().end())
    throw std::invalid_argument("unknown realistic condition '" + condition + "'");
  Draw d{std::mt19937(conditionSeed(condition) ^ (2654435761u * static_cast<std::uint32_t>(subject)))};
  Scenario s;
  s.body = sim::BodyParameters::varied(subject);
  s.rig = base;
  const sim::BackModel back(s.body);
  dressCell(d, &s.dressing);
  Framing f = usualFraming(d, back);
  const double l2 = back.levelX("L2"), l4 = back.levelX("L4");
  if (condition == "arms_touching") {
    armsAlong(d, &s.dressing, 0.0);
  } else if (condition == "arms_apart") {
    s.dressing.arms = sim::ArmPose::kAlongTrunk;
    s.dressing.arm_abduction_left = d.uniform(0.08, 0.35);
    s.dressing.arm_abduction_right = d.uniform(0.08, 0.35);
  } else if (condition == "arms_raised") {
    s.dressing.arms = sim::ArmPose::kRaised;
  } else if (condition == "neck_cut") {
    armsAlong(d, &s.dressing, 0.1);
    f.top = d.uniform(0.01, 0.05);
  } else if (condition == "hips_cut") {
    armsAlong(d, &s.dressing, 0.1);
    f.bottom = d.uniform(l4 - 0.22, l2);
  } else if (condition == "towel") {
    armsAlong(d, &s.dressing, 0.1);
    addTowel(d, back, &s.dressing);
  } else if (condition == "dark_skin") {
    armsAlong(d, &s.dressing, 0.1);
    s.body.skin_albedo = sim::fitzpatrickAlbedo(5 + subject % 2);
  } else if (condition == "toe_in") {
    armsAlong(d, &s.dressing, 0.1);
    rawToeIn(d, &s.rig);
  } else {  // mixed
    const double pose = d.uniform(0.0, 1.0);
    if (pose < 0.7)
      armsAlong(d, &s.dressing, 0.35);
    else if (pose < 0.9)
      s.dressing.arms = sim::ArmPose::kRaised;
    if (d.chance(0.5)) addTowel(d, back, &s.dressing);
    f = {d.uniform(0.01, 0.16), d.uniform(l4 - 0.22, l2)};
    if (d.chance(0.5))
      rawToeIn(d, &s.rig);
    else
      s.rig.baseline = d.uniform(0.06, 0.12);
    s.light = d.pick(std::vector<sim::LightPreset>{sim::LightPreset::kTopLeft, sim::LightPreset::kTopCentre,
                                                   sim::LightPreset::kTopRight});
  }
  s.rig = sim::frameRig(s.rig, f.top, f.bottom, 0.17);
  s.summary = describe(s, condition, f);
  return s;
}

}  // namespace massage_cell::tools
