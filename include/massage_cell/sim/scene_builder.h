// Scenes of the massage cell for the simulator: the prone subject on the
// massage table, stacked boxes (planar reconstruction), and the thesis's
// efficiency sets (Fig. 2.9 / 2.10). ROS-free.
#pragma once

#include <cstdint>
#include <vector>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

/// The massage table of the back scenes: top at z = 0 over x in
/// [kTableFootX, kTableHeadX], |y| <= kTableHalfWidth; the floor below.
constexpr float kTableHeadX = 0.45f;
constexpr float kTableFootX = -1.45f;
constexpr float kTableHalfWidth = 0.36f;
constexpr float kTableThickness = 0.10f;
constexpr float kFloorZ = -0.75f;

/// The massage table (top at z = 0) under a cloth sheet, on a floor, with
/// the subject's back mesh on it. meshes: table, floor, back.
Scene makeBackScene(const BackModel& back, std::uint32_t seed);

/// `count` textured boxes stacked on the table (no subject): each face has
/// its own label kLabelBoxFace + i and its own texture.
Scene makeBoxesScene(std::uint32_t seed, int count = 3);

/// One left view and right views R1..Rn of growing disparity range: R_k is
/// rendered with the baseline that makes the scene's disparities span
/// `levels[k]` integer levels (8, 16, ..., 64) from `min_disparity`.
struct EfficiencySet {
  Scene scene;
  CameraModel left;
  std::vector<CameraModel> rights;
  std::vector<double> baselines;     ///< metres, per right view
  std::vector<int> levels;           ///< disparity levels spanned, per right view
  double z_near = 0.0, z_far = 0.0;  ///< depth range of the scene in the left view (metres)
};

/// gradient = false: fronto-parallel layers (a multi-layer scene);
/// gradient = true: one slanted plane whose depth changes across the image.
/// Throws std::invalid_argument for a bad size or fx.
EfficiencySet makeEfficiencySet(bool gradient, int width, int height, double fx, std::uint32_t seed, int views = 8);

}  // namespace massage_cell::sim
