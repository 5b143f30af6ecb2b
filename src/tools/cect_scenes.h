// The scenes cect_eval measures on: the thesis's experiments (ideal,
// lighting, shift: the armless torso of the original simulator) and the
// realistic cell (arms, head in a face cradle, towels, framings that cut the
// neck or the hips, every skin type, raw toe-in rigs), each drawn per
// subject from a fixed seed.
#pragma once

#include <string>
#include <vector>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/photo_artefacts.h"
#include "massage_cell/sim/renderer.h"

namespace massage_cell::tools {

/// One rendered pair's set-up.
struct Scenario {
  sim::BodyParameters body;
  sim::Dressing dressing;
  sim::RigParameters rig;
  sim::LightPreset light = sim::LightPreset::kTopCentre;
  double yaw_deg = 0.0;  ///< the subject turned on the table
  /// What the camera or the photo does to both rendered views (none by default).
  sim::PhotoArtefacts photo;
  std::string summary;  ///< one line: what this pair shows
};

/// The realistic conditions, in order: arms_touching, arms_apart,
/// arms_raised, neck_cut, hips_cut, towel, dark_skin, toe_in, mixed,
/// skin_marks (paper tags on acupoints, a strap or a seam across the back,
/// tattoos, moles; printed sheets), photo (colour casts, vignetting, motion
/// blur, JPEG).
const std::vector<std::string>& realConditions();

/// Subject `subject` (>= 1; BodyParameters::varied) of realistic condition
/// `condition` on `base` (size, fx, baseline as given; its framing and
/// lenses are the condition's). Throws std::invalid_argument for an unknown
/// condition.
Scenario realScenario(const std::string& condition, int subject, const sim::RigParameters& base);

}  // namespace massage_cell::tools
