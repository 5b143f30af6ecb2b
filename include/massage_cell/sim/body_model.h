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
  double shoulder_width = 0.44;  ///< across the shoulders (acromion to acromion)
  double waist_width = 0.31;     ///< narrowest, around L2
  double hip_width = 0.36;       ///< at the iliac crests / upper buttocks
  double torso_length = 0.50;    ///< C7 to the iliac-crest line (L4), along x
  double neck_width = 0.12;
  double back_height = 0.21;             ///< height of the back's top above the table at mid-back
  double lateral_rounding = 1.0;         ///< how round the flanks are (0.6 flat .. 1.6 round)
  double thoracic_curvature = 0.025;     ///< rise of the upper back (kyphosis) above a flat line
  double lumbar_curvature = 0.02;        ///< dip of the lower back (lordosis)
  double spine_depth = 0.006;            ///< depth of the spine groove between the paraspinal muscles
  double paraspinal_width = 0.035;       ///< half-width of the paraspinal muscle ridge
  double scapula_prominence = 0.006;     ///< how much the scapulae stand out
  double scapula_medial_offset = 0.075;  ///< midline to the medial scapular border (= 3 cun)
  double shoulder_slope = 0.25;          ///< radians: drop of the shoulders toward the arms
  double buttock_height = 0.05;          ///< rise of the upper buttocks above the lower back
  double spinous_prominence = 0.0;       ///< height of the spinous processes' bumps in the spine groove (lean builds)
  Eigen::Vector3f skin_albedo{0.78f, 0.57f, 0.47f};  ///< linear RGB
  int moles = 4;                                     ///< number of small dark spots on the skin
  std::uint32_t skin_seed = 1;

  /// The mean subject.
  static BodyParameters mean();
  /// Subject `index` in 1..28 (distinct bodies and skin tones drawn around the
  /// mean from `seed`); 0 is the mean subject. Throws std::invalid_argument otherwise.
  static BodyParameters subject(int index, std::uint32_t seed = 2024);
  /// Subject `index` >= 1 of a wide population drawn from `seed`: male (odd
  /// index) and female (even) builds, BMI spread over 18..38, statures over
  /// the adult range, and the six Fitzpatrick skin types in turn (every 12
  /// consecutive indices hold each type for both sexes); 0 is the mean
  /// subject. Throws std::invalid_argument for a negative index.
  static BodyParameters varied(int index, std::uint32_t seed = 2024);
  /// Throws std::invalid_argument naming the first implausible value.
  void validate() const;
};

/// A subject described the way a clinic would: sex, body-mass index,
/// stature and Fitzpatrick skin type.
struct Build {
  bool female = false;
  double bmi = 24.0;      ///< kg/m^2, 16..42
  double stature = 1.75;  ///< metres, 1.40..2.05
  int skin_type = 2;      ///< Fitzpatrick I..VI as 1..6
  int moles = 4;
  std::uint32_t skin_seed = 1;
  /// Throws std::invalid_argument naming the first value out of range.
  void validate() const;
};

/// Body parameters of a build: widths, depth, roundness and the visibility
/// of scapulae, spine groove and spinous processes follow BMI and sex
/// (lean: bony landmarks stand out; obese: round flanks, hardly any waist,
/// faint landmarks), lengths follow the stature. Throws std::invalid_argument.
BodyParameters bodyFromBuild(const Build& build);

/// Typical linear-RGB albedo of Fitzpatrick skin type 1..6 (I very light ..
/// VI very dark); luminance strictly decreasing. Throws std::invalid_argument.
Eigen::Vector3f fitzpatrickAlbedo(int skin_type);

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
  /// The part of extent() at full height: without the end caps that lower the
  /// surface to the table at the buttocks and at the neck base.
  Eigen::Vector2d fullHeightExtent() const;
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
