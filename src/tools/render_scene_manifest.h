// render_scene's manifest.yaml: the run's settings, the subject, its
// dressing, the cameras and the files written.
#pragma once

#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "render_scene_files.h"
#include "render_scene_options.h"

namespace massage_cell::tools::render_scene {

/// Opens the manifest's map: the preset, the world frame and the rendering settings.
void beginManifest(YAML::Emitter& m, const Options& o);

/// A camera's size, intrinsics, distortion, pose and projection, under `name`.
void emitCamera(YAML::Emitter& out, const std::string& name, const sim::CameraModel& c);

/// A stereo pair: rectified, baseline, and both cameras.
void emitStereoCameras(YAML::Emitter& m, const sim::StereoPairModel& pair);

/// The back preset's subject, light, camera shift and breathing amplitude.
void emitBody(YAML::Emitter& m, const Options& o, const sim::BodyParameters& b);

/// The back preset's dressing, toe-in and framing.
void emitDressing(YAML::Emitter& m, const Options& o, const sim::Dressing& d);

/// Closes the manifest with the files written and writes it to `dir`/manifest.yaml.
void endManifest(YAML::Emitter& m, const std::vector<std::string>& files, const fs::path& dir);

}  // namespace massage_cell::tools::render_scene
