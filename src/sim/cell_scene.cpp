// The dressed back scene (cell_scene.h): assembles makeBackScene's table,
// floor and back with the lower body, head, neck, hair, face cradle, arms,
// towel and sheet; names and materials of cloths and hair.
#include "massage_cell/sim/cell_scene.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cell_scene_parts.h"
#include "massage_cell/sim/scene_builder.h"

namespace massage_cell::sim {

namespace {

constexpr std::size_t kTableMesh = 0;  // makeBackScene's meshes: table, floor, back
constexpr std::size_t kBackMesh = 2;
constexpr double kMaxAbduction = 0.35;
constexpr float kArmBoardInner = 0.16f;  // arm boards beside the face cradle, |y| from here ...
constexpr float kArmBoardOuter = 0.46f;  // ... to here (wider than the table: the elbows rest on them)
constexpr float kArmBoardEnd = 0.62f;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

template <typename T>
T fromName(const std::string& what, const std::string& name, const std::vector<std::pair<std::string, T>>& table) {
  std::string names;
  for (const auto& [n, v] : table) {
    if (n == name) return v;
    names += (names.empty() ? "" : ", ") + n;
  }
  throw std::invalid_argument("unknown " + what + " '" + name + "' (expected " + names + ")");
}

bool inUnitRange(const Eigen::Vector3f& albedo) {
  return albedo.allFinite() && albedo.minCoeff() >= 0.0f && albedo.maxCoeff() <= 1.0f;
}

void checkCloth(const char* what, const std::optional<Cloth>& cloth) {
  if (cloth && !(inUnitRange(cloth->albedo) && inUnitRange(cloth->albedo2))) {
    throw std::invalid_argument(std::string("Dressing: ") + what + " albedo must lie in [0, 1]");
  }
  if (cloth && !(cloth->period >= 0.005 && cloth->period <= 0.5)) {
    throw std::invalid_argument(std::string("Dressing: ") + what + " pattern period " + num(cloth->period) +
                                " m is not in 0.005 .. 0.5 m");
  }
}

void checkSkinMarks(const std::vector<Patch>& patches, const std::vector<Spot>& spots) {
  for (const Patch& p : patches) {
    if (!(p.centre.allFinite() && std::isfinite(p.angle) && p.half_size.minCoeff() > 0.0f &&
          p.half_size.maxCoeff() <= 1.0f && inUnitRange(p.albedo))) {
      throw std::invalid_argument("Dressing: a skin patch at (" + num(p.centre.x()) + ", " + num(p.centre.y()) +
                                  ") needs a finite centre and angle, half sides in (0, 1] m and an albedo in [0, 1]");
    }
  }
  for (const Spot& s : spots) {
    if (!(s.centre.allFinite() && s.radius > 0.0f && s.radius <= 0.05f && inUnitRange(s.albedo))) {
      throw std::invalid_argument("Dressing: a skin spot at (" + num(s.centre.x()) + ", " + num(s.centre.y()) +
                                  ") needs a finite centre, a radius in (0, 0.05] m and an albedo in [0, 1]");
    }
  }
}

void checkStickers(const std::vector<SkinSticker>& stickers, const BackModel& back) {
  const auto landmarks = back.landmarks();
  for (const SkinSticker& s : stickers) {
    if (!landmarks.count(s.landmark)) {
      throw std::invalid_argument("Dressing: a sticker on '" + s.landmark + "', which is not a landmark of the back");
    }
    if (!(s.diameter >= 0.005 && s.diameter <= 0.06)) {
      throw std::invalid_argument("Dressing: the sticker on " + s.landmark + " has diameter " + num(s.diameter) +
                                  " m, not in 0.005 .. 0.06 m");
    }
    if (!(s.albedo.allFinite() && s.albedo.minCoeff() >= 0.0f && s.albedo.maxCoeff() <= 1.0f)) {
      throw std::invalid_argument("Dressing: the sticker on " + s.landmark + " has an albedo outside [0, 1]");
    }
  }
}

/// The stickers as spots of the back's skin (its uv is the world's x, y), centred on their landmarks.
void addStickers(const std::vector<SkinSticker>& stickers, const BackModel& back, Material* back_skin) {
  const auto landmarks = back.landmarks();
  for (const SkinSticker& s : stickers) {
    const Eigen::Vector3d& at = landmarks.at(s.landmark);
    Spot spot;
    spot.centre = at.head<2>().cast<float>();
    spot.radius = static_cast<float>(0.5 * s.diameter);
    spot.albedo = s.albedo;
    back_skin->spots.push_back(spot);
  }
}

void shortenTable(Scene& scene, double head_x) {
  Mesh& table = scene.meshes[kTableMesh];
  table = makeBox("table", {kTableFootX, -kTableHalfWidth, -kTableThickness},
                  {static_cast<float>(head_x), kTableHalfWidth, 0.0f}, table.material, kLabelTable);
}

void addArmBoards(Scene& scene, double from_x) {
  const Material sheet = scene.meshes[kTableMesh].material;
  for (int side : {-1, 1}) {
    const float y0 = side > 0 ? kArmBoardInner : -kArmBoardOuter;
    const float y1 = side > 0 ? kArmBoardOuter : -kArmBoardInner;
    scene.meshes.push_back(makeBox(side > 0 ? "arm_board_left" : "arm_board_right",
                                   {static_cast<float>(from_x) - 0.01f, y0, -kTableThickness}, {kArmBoardEnd, y1, 0.0f},
                                   sheet, kLabelTable));
  }
}

void addHead(Scene& scene, const BackModel& back, const Dressing& d, std::uint32_t seed, const Material& skin) {
  const HeadLayout layout = headLayout(back);
  shortenTable(scene, layout.table_end_x);
  scene.meshes.push_back(neckMesh(back, layout, skin));
  scene.meshes.push_back(headMesh(layout, skin));
  for (Mesh& m : hairMeshes(back, layout, d.hair, d.hair_colour, seed)) scene.meshes.push_back(std::move(m));
  for (Mesh& m : cradleMeshes(layout, d.cradle_cover, seed)) scene.meshes.push_back(std::move(m));
  if (d.arms == ArmPose::kRaised) addArmBoards(scene, layout.table_end_x);
}

std::vector<std::vector<TubeRing>> addArms(Scene& scene, const BackModel& back, const TrunkSurface& trunk,
                                           const Dressing& d, const Material& skin) {
  std::vector<std::vector<TubeRing>> arms;
  if (d.arms == ArmPose::kNone) return arms;
  TubeOptions o;
  o.segments = 40;
  for (int side : {1, -1}) {
    const double abduction = side > 0 ? d.arm_abduction_left : d.arm_abduction_right;
    arms.push_back(armRings(back, trunk, d.arms, side, abduction));
    scene.meshes.push_back(makeTube(side > 0 ? "arm_left" : "arm_right", arms.back(), o, skin, kLabelArm));
  }
  return arms;
}

}  // namespace

void Dressing::validate(const BackModel& back) const {
  for (const auto& [name, a] : {std::pair<const char*, double>{"arm_abduction_left", arm_abduction_left},
                                {"arm_abduction_right", arm_abduction_right}}) {
    if (!(a >= 0.0 && a <= kMaxAbduction)) {
      throw std::invalid_argument(std::string("Dressing: ") + name + " = " + num(a) + " is not in 0 .. " +
                                  num(kMaxAbduction) + " rad");
    }
  }
  checkCloth("cradle_cover", cradle_cover);
  checkCloth("towel", towel);
  checkCloth("sheet", sheet);
  checkStickers(stickers, back);
  checkSkinMarks(skin_patches, skin_spots);
  if (!towel) return;
  const double lowest = (lower_body ? LowerBody(back).xEnd() : back.extent()[0]) + 0.1;
  const double highest = back.levelX("T1");
  if (!(towel_edge_x >= lowest && towel_edge_x <= highest)) {
    throw std::invalid_argument("Dressing: towel_edge_x = " + num(towel_edge_x) + " is off the body (expected " +
                                num(lowest) + " .. " + num(highest) + " m)");
  }
  if (!(std::abs(towel_edge_tilt) <= 0.3)) {
    throw std::invalid_argument("Dressing: towel_edge_tilt = " + num(towel_edge_tilt) + " is not in -0.3 .. 0.3 rad");
  }
}

Scene makeCellScene(const BackModel& back, std::uint32_t seed, const Dressing& d) {
  d.validate(back);
  Scene scene = makeBackScene(back, seed);
  if (d.sheet) scene.meshes[kTableMesh].material = clothMaterial(*d.sheet, seed ^ 0x5eedu);
  const Material skin = plainSkin(scene.meshes[kBackMesh].material);
  Material& back_skin = scene.meshes[kBackMesh].material;
  back_skin.spots.insert(back_skin.spots.end(), d.skin_spots.begin(), d.skin_spots.end());
  back_skin.patches = d.skin_patches;
  addStickers(d.stickers, back, &back_skin);
  std::optional<LowerBody> lower;
  if (d.lower_body) {
    lower.emplace(back);
    scene.meshes.push_back(lower->mesh(skin));
  }
  const TrunkSurface trunk(back, lower ? &*lower : nullptr);
  if (d.head) addHead(scene, back, d, seed, skin);
  const auto arms = addArms(scene, back, trunk, d, skin);
  if (d.towel) {
    scene.meshes.push_back(
        towelMesh(trunk, arms, d.towel_over_arms, d.towel_edge_x, d.towel_edge_tilt, *d.towel, seed));
  }
  return scene;
}

Material plainSkin(const Material& back_skin) {
  Material m = back_skin;
  m.spots.clear();
  m.patches.clear();
  return m;
}

Material clothMaterial(const Cloth& cloth, std::uint32_t seed) {
  Material m;
  m.albedo = cloth.albedo;
  m.specular = 0.02f;
  m.shininess = 8.0f;
  m.seed = seed;
  switch (cloth.weave) {
    case Weave::kFine:
      m.pattern = Material::Pattern::kCloth;
      m.feature_size = 0.003f;
      m.contrast = 0.08f;
      break;
    case Weave::kTerry:
      m.pattern = Material::Pattern::kTerry;
      m.feature_size = 0.0025f;
      m.contrast = 0.35f;
      break;
    case Weave::kWaffle:
      m.pattern = Material::Pattern::kWaffle;
      m.feature_size = 0.0065f;
      m.contrast = 0.2f;
      break;
    case Weave::kStripes:
    case Weave::kChecks:
      m.pattern = cloth.weave == Weave::kStripes ? Material::Pattern::kStripes : Material::Pattern::kChecks;
      m.albedo2 = cloth.albedo2;
      m.feature_size = static_cast<float>(cloth.period);
      break;
  }
  return m;
}

const std::vector<std::pair<std::string, Eigen::Vector3f>>& stickerColours() {
  // Saturated matte vinyl: far from skin's hue (10..40 degrees) at every skin tone.
  static const std::vector<std::pair<std::string, Eigen::Vector3f>> colours = {{"green", {0.03f, 0.40f, 0.08f}},
                                                                               {"blue", {0.02f, 0.12f, 0.55f}},
                                                                               {"orange", {0.80f, 0.20f, 0.01f}},
                                                                               {"magenta", {0.55f, 0.03f, 0.35f}},
                                                                               {"yellow", {0.75f, 0.65f, 0.02f}}};
  return colours;
}

Eigen::Vector3f stickerColour(const std::string& name) { return fromName("sticker colour", name, stickerColours()); }

const std::vector<std::pair<std::string, Eigen::Vector3f>>& clothColours() {
  static const std::vector<std::pair<std::string, Eigen::Vector3f>> colours = {
      {"white", {0.82f, 0.82f, 0.80f}},        {"light_blue", {0.42f, 0.60f, 0.78f}}, {"green", {0.22f, 0.46f, 0.28f}},
      {"grey", {0.38f, 0.38f, 0.39f}},         {"beige", {0.70f, 0.57f, 0.42f}},      {"peach", {0.84f, 0.55f, 0.43f}},
      {"pink", {0.86f, 0.50f, 0.56f}},         {"dark_blue", {0.05f, 0.09f, 0.24f}},  {"black", {0.03f, 0.03f, 0.035f}},
      {"default_sheet", {0.62f, 0.66f, 0.70f}}};
  return colours;
}

Eigen::Vector3f clothColour(const std::string& name) { return fromName("cloth colour", name, clothColours()); }

Weave weaveFromName(const std::string& name) {
  return fromName<Weave>("weave", name,
                         {{"fine", Weave::kFine},
                          {"terry", Weave::kTerry},
                          {"waffle", Weave::kWaffle},
                          {"stripes", Weave::kStripes},
                          {"checks", Weave::kChecks}});
}

ArmPose armPoseFromName(const std::string& name) {
  return fromName<ArmPose>("arm pose", name,
                           {{"none", ArmPose::kNone}, {"along", ArmPose::kAlongTrunk}, {"raised", ArmPose::kRaised}});
}

HairLength hairLengthFromName(const std::string& name) {
  return fromName<HairLength>("hair length", name,
                              {{"none", HairLength::kNone},
                               {"short", HairLength::kShort},
                               {"nape", HairLength::kNape},
                               {"long", HairLength::kLong}});
}

HairColour hairColourFromName(const std::string& name) {
  return fromName<HairColour>("hair colour", name,
                              {{"black", HairColour::kBlack},
                               {"brown", HairColour::kBrown},
                               {"blond", HairColour::kBlond},
                               {"grey", HairColour::kGrey},
                               {"red", HairColour::kRed}});
}

Eigen::Vector3f hairAlbedo(HairColour colour) {
  switch (colour) {
    case HairColour::kBlack:
      return {0.018f, 0.015f, 0.013f};
    case HairColour::kBrown:
      return {0.09f, 0.05f, 0.028f};
    case HairColour::kBlond:
      return {0.52f, 0.40f, 0.22f};
    case HairColour::kGrey:
      return {0.40f, 0.39f, 0.38f};
    case HairColour::kRed:
      return {0.33f, 0.10f, 0.04f};
  }
  return {0.09f, 0.05f, 0.028f};
}

}  // namespace massage_cell::sim
