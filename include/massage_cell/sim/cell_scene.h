// The back scene as real massage cells show it: arms lying along the trunk
// or raised beside the head, the neck and the head face-down in a face cradle
// with hair, the buttocks and upper thighs, a towel over them, sheets of
// several colours and weaves. ROS-free.
//
// A default-constructed Dressing gives exactly makeBackScene(back, seed).
// Frame: the world frame `table` of scene.h (x toward the head, y to the
// subject's left, z up, origin on the table top under C7); metres, radians.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/body_parts.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

enum class ArmPose {
  kNone,        ///< no arms (the back model alone)
  kAlongTrunk,  ///< upper arm along the flank, forearm and hand beside the hips, on the table
  kRaised       ///< upper arms cranially from the shoulders, elbows bent, forearms beside the face cradle
};

enum class HairLength {
  kNone,   ///< bald
  kShort,  ///< on the skull only, ending above the occiput's base
  kNape,   ///< down to the posterior hairline (3 cun above C7), covering the neck's upper part
  kLong    ///< down the whole nape to just above C7
};

enum class HairColour { kBlack, kBrown, kBlond, kGrey, kRed };

enum class Weave {
  kFine,     ///< plain fine weave (percale, cotton sheet)
  kTerry,    ///< terry towelling loops
  kWaffle,   ///< waffle weave
  kStripes,  ///< printed stripes across the table (albedo and albedo2, period apart)
  kChecks    ///< printed checks (albedo and albedo2)
};

/// A cloth: colour (linear RGB) and weave.
struct Cloth {
  Eigen::Vector3f albedo{0.82f, 0.82f, 0.80f};
  Weave weave = Weave::kFine;
  Eigen::Vector3f albedo2{0.20f, 0.25f, 0.55f};  ///< stripes' and checks' second colour
  double period = 0.04;                          ///< stripes' and checks' period, metres (0.005 .. 0.5)
};

/// A coloured adhesive dot a therapist sticks on the skin over a landmark
/// (a skin marker): flat colour on the back's skin, centred on the landmark.
struct SkinSticker {
  std::string landmark;  ///< a name of BackModel::landmarks(): "C7", "L4", ...
  Eigen::Vector3f albedo{0.03f, 0.40f, 0.08f};
  double diameter = 0.025;  ///< metres, 0.005 .. 0.06
};

struct Dressing {
  ArmPose arms = ArmPose::kNone;
  /// Along the trunk: abduction of each arm about its shoulder, radians in
  /// 0 .. 0.35 (0 = touching the flank over its length, 0.35 = 20 degrees).
  double arm_abduction_left = 0.0;
  double arm_abduction_right = 0.0;

  /// Neck and head face-down in a face cradle at the table's head end (the
  /// table then ends at the shoulders).
  bool head = false;
  std::optional<Cloth> cradle_cover;     ///< unset: dark vinyl
  HairLength hair = HairLength::kShort;  ///< with the head only
  HairColour hair_colour = HairColour::kBrown;

  /// Buttocks down to the gluteal fold and the upper thighs (kLabelBack).
  bool lower_body = false;

  /// A towel over the buttocks / lower back, draped over the body and hanging
  /// over the flanks to the table. Unset: no towel.
  std::optional<Cloth> towel;
  /// false: the arms lie on the towel (it is tucked between trunk and arms);
  /// true: the towel covers the arms too.
  bool towel_over_arms = false;
  /// World x of the towel's cranial edge on the midline (required with a towel).
  double towel_edge_x = std::numeric_limits<double>::quiet_NaN();
  /// Turn of the edge about z, radians (|tilt| <= 0.3): edge x = towel_edge_x + tan(tilt) * y.
  double towel_edge_tilt = 0.0;

  /// The table's sheet; unset: the default sheet of makeBackScene.
  std::optional<Cloth> sheet;

  /// Skin markers on the back (none by default).
  std::vector<SkinSticker> stickers;
  /// Marks on the back's skin, in world (x, y) (its surface coordinates):
  /// paper tags, a strap or a seam across it, a tattoo's strokes (patches);
  /// moles (spots). None by default.
  std::vector<Patch> skin_patches;
  std::vector<Spot> skin_spots;

  /// Throws std::invalid_argument naming the first bad value (towel edge off
  /// the body, abduction out of range, ...).
  void validate(const BackModel& back) const;
};

/// makeBackScene(back, seed) dressed with `dressing`. Deterministic in seed.
/// Throws std::invalid_argument (Dressing::validate).
Scene makeCellScene(const BackModel& back, std::uint32_t seed, const Dressing& dressing);

/// Where the dressed scene puts the head and its cradle (for tests, framing).
struct HeadLayout {
  double table_end_x = 0.0;   ///< the table's head end when the head lies in the cradle
  double neck_start_x = 0.0;  ///< the neck tube starts inside the back here
  double neck_top_z = 0.0;    ///< top of the neck at the back's neck base
  double hairline_x = 0.0;    ///< posterior hairline (3 cun above C7)
  Eigen::Vector3d head_centre{0.0, 0.0, 0.0};
  Eigen::Vector3d head_axes{0.1, 0.075, 0.095};  ///< semi-axes along x (crown), y, z (occiput up)
  double cradle_top_z = 0.0;                     ///< top of the cradle's pad
};
HeadLayout headLayout(const BackModel& back);

/// Centre-line rings of one arm (side +1: subject's left, -1: right) as
/// makeCellScene builds it; `trunk` is what it lies against.
std::vector<TubeRing> armRings(const BackModel& back, const TrunkSurface& trunk, ArmPose pose, int side,
                               double abduction);

/// Height of the top of a tube (rings as for makeTube, path roughly
/// horizontal) above (x, y); -infinity where the tube is not above it.
double tubeTopAt(const std::vector<TubeRing>& rings, double x, double y);

/// Named cloth colours (linear RGB): white, light_blue, green, grey, beige,
/// peach, pink, dark_blue, black, default_sheet.
const std::vector<std::pair<std::string, Eigen::Vector3f>>& clothColours();
/// Colour by name; throws std::invalid_argument listing the names.
Eigen::Vector3f clothColour(const std::string& name);
/// Sticker colours by name (linear RGB of printed matte vinyl dots): "green", "blue", "orange", "magenta", "yellow".
const std::vector<std::pair<std::string, Eigen::Vector3f>>& stickerColours();
/// Colour by name; throws std::invalid_argument listing the names.
Eigen::Vector3f stickerColour(const std::string& name);
/// "fine", "terry", "waffle"; throws std::invalid_argument.
Weave weaveFromName(const std::string& name);
/// "none", "along", "raised"; throws std::invalid_argument.
ArmPose armPoseFromName(const std::string& name);
/// "none", "short", "nape", "long"; throws std::invalid_argument.
HairLength hairLengthFromName(const std::string& name);
/// "black", "brown", "blond", "grey", "red"; throws std::invalid_argument.
HairColour hairColourFromName(const std::string& name);
/// Typical linear-RGB albedo of a hair colour.
Eigen::Vector3f hairAlbedo(HairColour colour);

/// The surface material of a cloth (sheets, towels, cradle covers).
Material clothMaterial(const Cloth& cloth, std::uint32_t seed);

}  // namespace massage_cell::sim
