// render_scene's options turned into the simulator's set-up: the light, the
// rig, the subject, its dressing and the render options (bad values end as
// usage errors).
#pragma once

#include <cstdint>
#include <string>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/renderer.h"
#include "render_scene_options.h"

namespace massage_cell::tools::render_scene {

/// --light: top_left | top_centre | top_right (checked by parseOptions).
sim::LightPreset lightPreset(const std::string& name);

/// The stereo rig; framed on the back when --frame-top / --frame-bottom are given (`back` needed then).
sim::StereoPairModel makePair(const Options& o, const sim::BackModel* back = nullptr);

/// The subject: --subject, --varied or --build, with --skin-type over its skin colour.
sim::BodyParameters bodyParameters(const Options& o);

/// The back preset's dressing, validated on `back`.
sim::Dressing dressing(const Options& o, const sim::BackModel& back);

/// Builds the subject, its dressing and the rig once so that bad values end
/// as usage errors (parseOptions).
void checkBackSetup(const Options& o);

/// true when the options dress the back or frame the cameras on it.
bool dressed(const Options& o);

/// Supersampling, noise and exposure; the noise seeded per `frame`.
sim::RenderOptions renderOptions(const Options& o, std::uint32_t frame);

}  // namespace massage_cell::tools::render_scene
