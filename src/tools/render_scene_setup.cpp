#include "render_scene_setup.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <vector>

#include "cli.h"
#include "sim_rig.h"

namespace massage_cell::tools::render_scene {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

/// A world x from "0.05" (metres) or a vertebral level with an optional offset ("L4-0.18").
double anatomicalX(const std::string& option, const std::string& text, const sim::BackModel& back) {
  std::size_t split = 0;
  while (split < text.size() && (std::isalnum(static_cast<unsigned char>(text[split])) != 0)) ++split;
  if (split == 0 || std::isdigit(static_cast<unsigned char>(text[0])) != 0) return parseDouble(option, text);
  const std::string level = text.substr(0, split);
  const auto& levels = sim::vertebralLevels();
  require(std::find(levels.begin(), levels.end(), level) != levels.end(),
          option + ": unknown vertebral level '" + level + "' in '" + text + "' (C7, T1..T12, L1..L5)");
  return back.levelX(level) + (split < text.size() ? parseDouble(option, text.substr(split)) : 0.0);
}

sim::Cloth cloth(const std::string& colour, const std::string& weave) {
  return {sim::clothColour(colour), sim::weaveFromName(weave)};
}

/// --sticker LANDMARK=COLOUR (the landmark is checked with the dressing).
sim::SkinSticker sticker(const std::string& value, double diameter) {
  const std::size_t eq = value.find('=');
  require(eq != std::string::npos && eq > 0 && eq + 1 < value.size(),
          "--sticker expects LANDMARK=COLOUR (e.g. C7=green), got '" + value + "'");
  sim::SkinSticker s;
  s.landmark = value.substr(0, eq);
  try {
    s.albedo = sim::stickerColour(value.substr(eq + 1));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--sticker: ") + e.what());
  }
  s.diameter = diameter;
  return s;
}

}  // namespace

sim::LightPreset lightPreset(const std::string& name) {
  if (name == "top_left") return sim::LightPreset::kTopLeft;
  if (name == "top_right") return sim::LightPreset::kTopRight;
  return sim::LightPreset::kTopCentre;
}

sim::StereoPairModel makePair(const Options& o, const sim::BackModel* back) {
  sim::RigParameters rig = cameraRig(o.width, o.height, o.fx, o.baseline, o.camera_height, o.raw);
  rig.shift = o.shift;
  rig.toe_in = o.toe_in * kDegree;
  try {
    if (back && !o.frame_top.empty()) {
      rig = sim::frameRig(rig, anatomicalX("--frame-top", o.frame_top, *back),
                          anatomicalX("--frame-bottom", o.frame_bottom, *back), back->body().back_height);
    }
    return sim::makeStereoPair(rig);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

sim::BodyParameters bodyParameters(const Options& o) {
  sim::BodyParameters body;
  try {
    if (o.varied > 0) {
      body = sim::BodyParameters::varied(o.varied, o.body_seed);
    } else if (!o.build.empty()) {
      sim::Build b;
      b.female = o.build == "female";
      b.bmi = o.bmi;
      b.stature = o.stature;
      b.skin_type = o.skin_type > 0 ? o.skin_type : 2;
      body = sim::bodyFromBuild(b);
    } else {
      body = sim::BodyParameters::subject(o.subject, o.body_seed);
    }
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (o.skin_type > 0) body.skin_albedo = sim::fitzpatrickAlbedo(o.skin_type);
  return body;
}

sim::Dressing dressing(const Options& o, const sim::BackModel& back) {
  sim::Dressing d;
  d.arms = sim::armPoseFromName(o.arms);
  d.arm_abduction_left = o.arm_angle * kDegree;
  d.arm_abduction_right = (o.arm_angle_right >= 0.0 ? o.arm_angle_right : o.arm_angle) * kDegree;
  d.head = o.head;
  d.hair = sim::hairLengthFromName(o.hair);
  d.hair_colour = sim::hairColourFromName(o.hair_colour);
  if (!o.cradle_cover.empty()) d.cradle_cover = cloth(o.cradle_cover, "fine");
  d.lower_body = o.lower_body || !o.towel.empty();
  if (!o.towel.empty()) {
    d.towel = cloth(o.towel, o.towel_weave);
    d.towel_edge_x = anatomicalX("--towel-edge", o.towel_edge, back);
    d.towel_edge_tilt = o.towel_tilt * kDegree;
  }
  if (!o.sheet.empty()) d.sheet = cloth(o.sheet, o.sheet_weave);
  for (const std::string& s : o.stickers) d.stickers.push_back(sticker(s, o.sticker_size));
  try {
    d.validate(back);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return d;
}

void checkBackSetup(const Options& o) {
  const sim::BackModel back(bodyParameters(o));
  (void)dressing(o, back);
  (void)makePair(o, &back);
}

bool dressed(const Options& o) {
  return o.arms != "none" || o.head || o.lower_body || !o.towel.empty() || !o.sheet.empty() || !o.frame_top.empty();
}

sim::RenderOptions renderOptions(const Options& o, std::uint32_t frame) {
  sim::RenderOptions r;
  r.supersample = o.supersample;
  r.noise_sigma = static_cast<float>(o.noise);
  r.exposure = static_cast<float>(o.exposure);
  r.noise_seed = o.seed * 7919u + frame;
  return r;
}

}  // namespace massage_cell::tools::render_scene
