// The simulated stereo rig the rendering tools (cect_eval, render_scene) set
// up from their camera options.
#pragma once

#include "massage_cell/sim/camera_model.h"

namespace massage_cell::tools {

/// A rig of `width` x `height` pixels, focal length `fx` (px) and `baseline` (m), its cameras `camera_height` (m)
/// above the table; rectified unless `raw`. The rest is sim::RigParameters' defaults.
inline sim::RigParameters cameraRig(int width, int height, double fx, double baseline, double camera_height, bool raw) {
  sim::RigParameters rig;
  rig.width = width;
  rig.height = height;
  rig.fx = fx;
  rig.baseline = baseline;
  rig.centre.z() = camera_height;
  rig.rectified = !raw;
  return rig;
}

}  // namespace massage_cell::tools
