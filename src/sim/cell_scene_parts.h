// Builders of the dressed scene's parts, shared by the cell scene's sources
// (private to src/sim; the public API is cell_scene.h).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "massage_cell/sim/cell_scene.h"

namespace massage_cell::sim {

/// Skin of the back's mesh without its moles, for the other skin parts.
Material plainSkin(const Material& back_skin);

Mesh neckMesh(const BackModel& back, const HeadLayout& layout, const Material& skin);
Mesh headMesh(const HeadLayout& layout, const Material& skin);
std::vector<Mesh> hairMeshes(const BackModel& back, const HeadLayout& layout, HairLength length, HairColour colour,
                             std::uint32_t seed);
/// The padded ring, its plate and struts (kLabelCradle).
std::vector<Mesh> cradleMeshes(const HeadLayout& layout, const std::optional<Cloth>& cover, std::uint32_t seed);

/// A towel whose cranial edge lies at x = edge_x + tan(tilt) y, draped over
/// `trunk`, hanging over the flanks and the table's sides; tucked under the
/// arms, or draped over them too when `over_arms`.
Mesh towelMesh(const TrunkSurface& trunk, const std::vector<std::vector<TubeRing>>& arms, bool over_arms, double edge_x,
               double tilt, const Cloth& cloth, std::uint32_t seed);

}  // namespace massage_cell::sim
