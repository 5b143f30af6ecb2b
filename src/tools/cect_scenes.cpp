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

/// Paper tags (with a line of ink) on some acupoints, as on a teaching phantom.
void addPaperTags(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  const float paper = static_cast<float>(d.uniform(0.70, 0.90));
  const Eigen::Vector3f colour = d.pick(std::vector<Eigen::Vector3f>{
      {paper, paper, paper}, {paper, paper, 0.8f * paper}, {paper, 0.9f * paper, 0.6f * paper}});
  const double share = d.uniform(0.15, 0.5);
  for (const auto& [name, at] : back.acupoints()) {
    if (!d.chance(share)) continue;
    sim::Patch tag;
    tag.centre = at.head<2>().cast<float>();
    tag.half_size = {static_cast<float>(d.uniform(0.006, 0.010)), static_cast<float>(d.uniform(0.010, 0.020))};
    tag.angle = static_cast<float>(d.uniform(-0.3, 0.3));
    tag.albedo = colour;
    s->skin_patches.push_back(tag);
    sim::Patch ink = tag;
    ink.half_size = {0.0012f, 0.7f * tag.half_size.y()};
    ink.albedo = {0.05f, 0.05f, 0.07f};
    s->skin_patches.push_back(ink);
  }
}

/// A band across the whole back: a bra strap, a swimsuit's string, a phantom's seam.
void addBand(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  sim::Patch band;
  band.centre = {static_cast<float>(d.uniform(back.levelX("L3"), back.levelX("T2"))), 0.0f};
  const bool seam = d.chance(0.3);
  band.half_size = {static_cast<float>(0.5 * (seam ? d.uniform(0.002, 0.006) : d.uniform(0.008, 0.030))), 0.5f};
  band.angle = static_cast<float>(d.uniform(-0.12, 0.12));
  band.albedo = seam ? Eigen::Vector3f(0.5f * back.body().skin_albedo)
                     : d.pick(std::vector<Eigen::Vector3f>{{0.02f, 0.02f, 0.02f},
                                                           {0.85f, 0.85f, 0.83f},
                                                           {0.55f, 0.05f, 0.08f},
                                                           {0.05f, 0.07f, 0.25f},
                                                           {0.60f, 0.45f, 0.35f}});
  s->skin_patches.push_back(band);
}

/// A tattoo: dark (or coloured) strokes in a patch of the back.
void addTattoo(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  const Eigen::Vector2f centre(static_cast<float>(d.uniform(back.levelX("L3"), back.levelX("T1"))),
                               static_cast<float>(d.uniform(-0.12, 0.12)));
  const double radius = d.uniform(0.03, 0.08);
  const Eigen::Vector3f ink = d.pick(std::vector<Eigen::Vector3f>{
      {0.04f, 0.05f, 0.09f}, {0.04f, 0.05f, 0.09f}, {0.45f, 0.05f, 0.05f}, {0.05f, 0.25f, 0.10f}});
  const int strokes = static_cast<int>(d.uniform(6, 20));
  for (int i = 0; i < strokes; ++i) {
    sim::Patch p;
    p.centre = centre + Eigen::Vector2f(static_cast<float>(d.uniform(-radius, radius)),
                                        static_cast<float>(d.uniform(-radius, radius)));
    p.half_size = {static_cast<float>(d.uniform(0.008, 0.025)), static_cast<float>(d.uniform(0.001, 0.003))};
    p.angle = static_cast<float>(d.uniform(-3.14159, 3.14159));
    p.albedo = ink;
    s->skin_patches.push_back(p);
  }
}

void addMoles(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  const int moles = static_cast<int>(d.uniform(5, 30));
  for (int i = 0; i < moles; ++i) {
    sim::Spot m;
    m.centre = {static_cast<float>(d.uniform(back.levelX("L4"), back.levelX("C7"))),
                static_cast<float>(d.uniform(-0.18, 0.18))};
    m.radius = static_cast<float>(d.uniform(0.001, 0.003));
    m.albedo = static_cast<float>(d.uniform(0.4, 1.0)) * Eigen::Vector3f(0.25f, 0.15f, 0.10f);
    s->skin_spots.push_back(m);
  }
}

/// A printed sheet: stripes or checks of two of the cloths' colours.
void printedSheet(Draw& d, sim::Dressing* s) {
  const auto& colours = sim::clothColours();
  sim::Cloth c{d.pick(colours).second, d.chance(0.5) ? sim::Weave::kStripes : sim::Weave::kChecks};
  c.albedo2 = d.pick(colours).second;
  c.period = d.uniform(0.01, 0.12);
  s->sheet = c;
}

void skinMarks(Draw& d, const sim::BackModel& back, sim::Dressing* s) {
  if (d.chance(0.5)) addPaperTags(d, back, s);
  if (d.chance(0.6)) addBand(d, back, s);
  if (d.chance(0.4)) addTattoo(d, back, s);
  addMoles(d, back, s);
  if (d.chance(0.5)) printedSheet(d, s);
}

/// A phone's or a cheap camera's image: white balance, lens, exposure, file.
sim::PhotoArtefacts photoArtefacts(Draw& d, int width) {
  sim::PhotoArtefacts a;
  for (int c = 0; c < 3; ++c) a.colour_gains[c] = d.uniform(0.85, 1.15);
  a.vignetting = d.uniform(0.0, 0.5);
  if (d.chance(0.5)) {
    a.motion_blur_px = d.uniform(1.0, 6.0) * width / 640.0;
    a.motion_blur_angle = d.uniform(0.0, 3.14159);
  }
  a.jpeg_quality = static_cast<int>(d.uniform(40, 90));
  return a;
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
  if (!s.dressing.skin_patches.empty()) o << ", " << s.dressing.skin_patches.size() << " skin patches";
  if (s.photo.any()) o << ", photo: " << s.photo.describe();
  return o.str();
}

}  // namespace

const std::vector<std::string>& realConditions() {
  static const std::vector<std::string> c{"arms_touching", "arms_apart", "arms_raised", "neck_cut",
                                          "hips_cut",      "towel",      "dark_skin",   "toe_in",
                                          "mixed",         "skin_marks", "photo"};
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
  } else if (condition == "skin_marks") {
    armsAlong(d, &s.dressing, 0.1);
    skinMarks(d, back, &s.dressing);
  } else if (condition == "photo") {
    armsAlong(d, &s.dressing, 0.1);
    s.photo = photoArtefacts(d, base.width);
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
