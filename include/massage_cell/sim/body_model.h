// A parametric human back lying prone on the massage table, with its
// anatomical ground truth (spine, vertebral levels, scapulae, iliac crests)
// and the acupoints of shared/reference/back_acupoints.md. ROS-free.
//
// Frame: the world frame `table` of scene.h (x cranial, y subject's left,
// z up, origin on the table top at the midline under C7). Lengths in metres.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

struct BodyParameters {
  double shoulder_width = 0.44;      ///< across the shoulders (acromion to acromion)
  double waist_width = 0.31;         ///< narrowest, around L2
  double hip_width = 0.36;           ///< at the iliac crests / upper buttocks
  double torso_length = 0.50;        ///< C7 to the iliac-crest line (L4), along x
  double neck_width = 0.12;
  double back_height = 0.21;         ///< height of the back's top above the table at mid-back
  double lateral_rounding = 1.0;     ///< how round the flanks are (0.6 flat .. 1.6 round)
  double thoracic_curvature = 0.025; ///< rise of the upper back (kyphosis) above a flat line
  double lumbar_curvature = 0.02;    ///< dip of the lower back (lordosis)
  double spine_depth = 0.006;        ///< depth of the spine groove between the paraspinal muscles
  double paraspinal_width = 0.035;   ///< half-width of the paraspinal muscle ridge
  double scapula_prominence = 0.006; ///< how much the scapulae stand out
  double scapula_medial_offset = 0.075; ///< midline to the medial scapular border (= 3 cun)
  double shoulder_slope = 0.25;      ///< radians: drop of the shoulders toward the arms
  double buttock_height = 0.05;      ///< rise of the upper buttocks above the lower back
  Eigen::Vector3f skin_albedo{0.78f, 0.57f, 0.47f};  ///< linear RGB
  int moles = 4;                     ///< number of small dark spots on the skin
  std::uint32_t skin_seed = 1;

  /// The mean subject.
  static BodyParameters mean();
  /// Subject `index` in 1..28 (distinct bodies and skin tones drawn around the
  /// mean from `seed`); 0 is the mean subject. Throws std::invalid_argument otherwise.
  static BodyParameters subject(int index, std::uint32_t seed = 2024);
  /// Throws std::invalid_argument naming the first implausible value.
  void validate() const;
};

/// Vertebral level names in order: "C7", "T1".."T12", "L1".."L5".
const std::vector<std::string>& vertebralLevels();

class BackModel {
 public:
  /// breathing_phase in [0, 1) (one breath), breathing_amplitude in metres
  /// (rise of the upper back at full inhalation; 0 = no breathing).
  explicit BackModel(const BodyParameters& body, double breathing_phase = 0.0, double breathing_amplitude = 0.0);

  const BodyParameters& body() const { return body_; }
  /// Height of the skin above the table at (x, y); NaN outside the body's outline.
  double height(double x, double y) const;
  /// Half-width of the body's outline at x (0 beyond the ends).
  double halfWidth(double x) const;
  /// x extent of the modelled back surface [x_min, x_max] (upper buttocks .. neck base).
  Eigen::Vector2d extent() const;
  /// Triangle mesh of the back surface down to the table, `spacing` metres
  /// between vertices, label kLabelBack, skin material with the body's albedo.
  Mesh mesh(double spacing = 0.004) const;

  /// x of a vertebral level (lower border of its spinous process).
  double levelX(const std::string& level) const;
  /// 3D point on the skin at vertebral level `level` and `lateral_cun` cun
  /// toward the subject's left (+) or right (-) of the midline.
  Eigen::Vector3d surfacePoint(const std::string& level, double lateral_cun) const;
  /// Metres per cun laterally (scapula_medial_offset / 3).
  double cun() const;

  /// Named landmarks on the skin: "C7", "T1".."L5" (on the midline),
  /// "scapula_inferior_angle_L/R", "iliac_crest_L/R", "acromion_L/R".
  std::map<std::string, Eigen::Vector3d> landmarks() const;
  /// Every acupoint of back_acupoints.md: "GV14", "BL23_L", "BL23_R", "EX_B2_T5_L", "GB21_L", ...
  std::map<std::string, Eigen::Vector3d> acupoints() const;
  /// The spine midline on the skin, from C7 to L5, `count` points.
  std::vector<Eigen::Vector3d> midline(int count = 50) const;

 private:
  BodyParameters body_;
  double breathing_phase_;
  double breathing_amplitude_;
};

}  // namespace massage_cell::sim
