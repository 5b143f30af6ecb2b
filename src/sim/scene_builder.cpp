#include "massage_cell/sim/scene_builder.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

namespace massage_cell::sim {

namespace {

// The massage table (scene_builder.h): its top at z = 0, longer than the body.

Material sheetMaterial(std::uint32_t seed) {
  Material m;
  m.pattern = Material::Pattern::kCloth;
  m.albedo = {0.62f, 0.66f, 0.70f};
  m.contrast = 0.06f;
  m.feature_size = 0.003f;
  m.specular = 0.02f;
  m.shininess = 8.0f;
  m.seed = seed ^ 0x5eedu;
  return m;
}

Material floorMaterial(std::uint32_t seed) {
  Material m;
  m.pattern = Material::Pattern::kTexture;
  m.albedo = {0.30f, 0.27f, 0.25f};
  m.contrast = 0.06f;  // a plain floor, slightly mottled
  m.feature_size = 0.08f;
  m.seed = seed ^ 0xf100u;
  return m;
}

void addTableAndFloor(Scene& scene, std::uint32_t seed) {
  scene.meshes.push_back(makeBox("table", {kTableFootX, -kTableHalfWidth, -kTableThickness},
                                 {kTableHeadX, kTableHalfWidth, 0.0f}, sheetMaterial(seed), kLabelTable));
  const float r = 3.0f;
  scene.meshes.push_back(makeQuad("floor", {-r, -r, kFloorZ}, {r, -r, kFloorZ}, {r, r, kFloorZ}, {-r, r, kFloorZ},
                                  floorMaterial(seed), kLabelFloor));
}

/// Most boxes are printed packaging (labels, text), some plain textured
/// board; colours and print density vary.
Material boxMaterial(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.2f, 0.8f), unit(0.0f, 1.0f);
  Material m;
  if (unit(rng) < 0.7f) {
    m.pattern = Material::Pattern::kPrint;
    m.albedo = {0.6f + 0.5f * u(rng) * 0.6f, 0.6f + 0.5f * u(rng) * 0.6f, 0.6f + 0.5f * u(rng) * 0.6f};
    m.feature_size = 0.01f + 0.01f * unit(rng);
  } else {
    m.pattern = Material::Pattern::kTexture;
    m.albedo = {u(rng), u(rng), u(rng)};
    m.feature_size = 0.012f;
  }
  m.contrast = 0.6f;
  m.specular = 0.05f;
  m.seed = static_cast<std::uint32_t>(rng());
  return m;
}

/// Each face of a box its own part of the material's pattern (a box's faces
/// would otherwise repeat one print, as no real box does).
void offsetFaceTextures(Mesh& box) {
  for (std::size_t v = 0; v < box.uv.size(); ++v) {
    const float face = static_cast<float>(v / 4);
    box.uv[v] += Eigen::Vector2f(0.37f * face, 0.61f * face);
  }
}

}  // namespace

Scene makeBackScene(const BackModel& back, std::uint32_t seed) {
  Scene scene;
  addTableAndFloor(scene, seed);
  scene.meshes.push_back(back.mesh());
  return scene;
}

Scene makeBoxesScene(std::uint32_t seed, int count) {
  if (count < 1 || count > 40) throw std::invalid_argument("boxes scene: count must be in 1..40");
  Scene scene;
  addTableAndFloor(scene, seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  // A stack: each box smaller than the one below, turned a little about z.
  float base_z = 0.0f;
  float size_x = 0.34f, size_y = 0.26f;
  for (int i = 0; i < count; ++i) {
    const float h = 0.06f + 0.08f * unit(rng);
    const float sx = size_x * (0.9f + 0.1f * unit(rng));
    const float sy = size_y * (0.9f + 0.1f * unit(rng));
    Mesh box = makeBox("box_" + std::to_string(i), {-sx / 2, -sy / 2, 0.0f}, {sx / 2, sy / 2, h}, boxMaterial(rng),
                       kLabelBoxFace, static_cast<std::uint8_t>(kLabelBoxFace + 6 * i));
    offsetFaceTextures(box);
    const float yaw = (unit(rng) - 0.5f) * 0.6f;
    const Eigen::Vector3f offset(-0.27f + (unit(rng) - 0.5f) * 0.06f, (unit(rng) - 0.5f) * 0.06f, base_z);
    transform(box, Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix(), offset);
    scene.meshes.push_back(std::move(box));
    base_z += h;
    size_x *= 0.72f;
    size_y *= 0.72f;
  }
  return scene;
}

EfficiencySet makeEfficiencySet(bool gradient, int width, int height, double fx, std::uint32_t seed, int views) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384) {
    throw std::invalid_argument("efficiency set: image size must be in 1..16384");
  }
  if (!(fx > 0.0) || !std::isfinite(fx)) throw std::invalid_argument("efficiency set: fx must be > 0");
  if (views < 1 || views > 64) throw std::invalid_argument("efficiency set: views must be in 1..64");

  EfficiencySet set;
  constexpr double kHeight = 1.0;  // camera 1 m above the base plane
  set.z_far = kHeight;
  set.z_near = 0.5 * kHeight;
  // The left camera looks straight down from (0, 0, kHeight), image up = +x world.
  CameraModel& left = set.left;
  left.width = width;
  left.height = height;
  left.K << fx, 0, (width - 1) / 2.0, 0, fx, (height - 1) / 2.0, 0, 0, 1;
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();
  R.col(1) = -Eigen::Vector3d::UnitX();
  R.col(2) = -Eigen::Vector3d::UnitZ();
  left.world_from_camera.linear() = R;
  left.world_from_camera.translation() = Eigen::Vector3d(0, 0, kHeight);

  std::mt19937 rng(seed);
  // Half extents of the view on the base plane, with margin for the right views.
  const float hx = static_cast<float>(kHeight * (height / 2.0) / fx) * 1.3f;
  const float hy = static_cast<float>(kHeight * (width / 2.0) / fx) * 1.3f + 0.2f;
  if (!gradient) {
    // Base plane plus three fronto-parallel layers up to z_near.
    set.scene.meshes.push_back(makeQuad("layer_0", {-hx, -hy - 0.4f, 0.0f}, {hx, -hy - 0.4f, 0.0f}, {hx, hy, 0.0f},
                                        {-hx, hy, 0.0f}, boxMaterial(rng), kLabelPlane));
    const float tops[3] = {0.2f, 0.35f, static_cast<float>(kHeight - set.z_near)};
    const float sizes[3] = {0.75f, 0.5f, 0.3f};
    for (int i = 0; i < 3; ++i) {
      const float sx = hx * sizes[i], sy = hy * sizes[i] * 0.6f;
      const float cx = (i - 1) * 0.25f * hx, cy = (1 - i) * 0.2f * hy;
      set.scene.meshes.push_back(makeQuad("layer_" + std::to_string(i + 1), {cx - sx, cy - sy, tops[i]},
                                          {cx + sx, cy - sy, tops[i]}, {cx + sx, cy + sy, tops[i]},
                                          {cx - sx, cy + sy, tops[i]}, boxMaterial(rng),
                                          static_cast<std::uint8_t>(kLabelPlane)));
    }
  } else {
    // One plane rising from z = 0 at the image bottom (-x) to z = kHeight - z_near at the top (+x).
    const float rise = static_cast<float>(kHeight - set.z_near);
    const float x0 = -static_cast<float>(kHeight * (height / 2.0) / fx);
    const float x1 = static_cast<float>(set.z_near * (height / 2.0) / fx);
    const float slope = rise / (x1 - x0);
    const float xa = x0 - 0.5f, xb = x1 + 0.5f;
    set.scene.meshes.push_back(makeQuad("gradient", {xa, -hy - 0.4f, slope * (xa - x0)},
                                        {xb, -hy - 0.4f, slope * (xb - x0)}, {xb, hy, slope * (xb - x0)},
                                        {xa, hy, slope * (xa - x0)}, boxMaterial(rng), kLabelPlane));
    set.z_near = kHeight - slope * (x1 - x0);
  }
  const double span = 1.0 / set.z_near - 1.0 / set.z_far;
  for (int k = 1; k <= views; ++k) {
    const int levels = 8 * k;
    const double baseline = levels / (fx * span);
    CameraModel right = left;
    right.world_from_camera.translation() += baseline * R.col(0);
    set.rights.push_back(right);
    set.baselines.push_back(baseline);
    set.levels.push_back(levels);
  }
  return set;
}

}  // namespace massage_cell::sim
