// Scene description of the simulator: triangle meshes with a material and a
// region label each. ROS-free (Eigen + OpenCV only).
//
// World frame `table` (REP 103, metres): origin on the table top, on the
// body's midline at the level of C7; x toward the subject's head (cranial),
// y toward the subject's left, z up. The subject lies prone along x.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace massage_cell::sim {

/// Region labels written to `*_labels.png` (one byte per pixel).
enum Label : std::uint8_t {
  kLabelBackground = 0,  ///< nothing hit, or the room behind the table
  kLabelBack = 1,        ///< the subject's skin
  kLabelTable = 2,       ///< massage table and its sheet
  kLabelFloor = 3,       ///< floor under the table
  kLabelArm = 4,         ///< the subject's arms and hands (cell_scene.h)
  kLabelNeck = 5,        ///< the skin of the neck
  kLabelHead = 6,        ///< the skin of the head and face
  kLabelHair = 7,        ///< hair on the head (and the nape)
  kLabelTowel = 8,       ///< towels and drapes over the body
  kLabelPlane = 9,       ///< calibration / efficiency planes
  kLabelBoxFace = 10,    ///< box faces: kLabelBoxFace + face index (10..249 for the 40 boxes a scene may hold)
  kLabelCradle = 250     ///< the face cradle: its padded ring and support
};

/// Short lower-case name of a label ("back", "towel", "box face", ...).
const char* labelName(std::uint8_t label);

/// A small round spot on the skin (a mole or a freckle), in surface (u, v) metres.
struct Spot {
  Eigen::Vector2f centre{0.0f, 0.0f};
  float radius = 0.002f;
  Eigen::Vector3f albedo{0.25f, 0.15f, 0.10f};
};

/// A rectangle on the skin (a paper tag, a strap or a seam across the back, a
/// tattoo's stroke), in surface (u, v) metres, with a soft edge of 0.5 mm.
struct Patch {
  Eigen::Vector2f centre{0.0f, 0.0f};
  Eigen::Vector2f half_size{0.01f, 0.005f};  ///< half its sides along its own axes
  float angle = 0.0f;                        ///< its first axis from u, radians
  Eigen::Vector3f albedo{0.85f, 0.85f, 0.82f};
};

/// Surface appearance. Colours are linear RGB in [0, 1].
struct Material {
  enum class Pattern {
    kFlat,     ///< uniform albedo
    kSkin,     ///< smooth albedo with faint low-contrast mottling and optional spots
    kCloth,    ///< fine weave-like texture (sheets)
    kTexture,  ///< strong multi-scale colour texture (boxes, efficiency scenes)
    kTerry,    ///< terry towelling: a dense field of small loops (feature_size = loop pitch)
    kWaffle,   ///< waffle weave: raised ridges around square cells (feature_size = cell pitch)
    kHair,     ///< hair: fine strands along u (feature_size = strand width), clumps and sheen in the albedo
    kPrint,    ///< printed packaging: ink glyph rows and panels on a pale board (feature_size = glyph pitch)
    kStripes,  ///< printed stripes along v, albedo and albedo2 (feature_size = period)
    kChecks    ///< printed checks, albedo and albedo2 (feature_size = period)
  };
  Pattern pattern = Pattern::kFlat;
  Eigen::Vector3f albedo{0.5f, 0.5f, 0.5f};
  Eigen::Vector3f albedo2{0.2f, 0.2f, 0.5f};  ///< the second colour of stripes and checks
  float specular = 0.0f;                      ///< Blinn-Phong specular weight (0 = matte)
  float shininess = 20.0f;                    ///< Blinn-Phong exponent
  float feature_size = 0.01f;                 ///< metres: scale of the pattern
  float contrast = 0.0f;                      ///< pattern amplitude, 0 = uniform, ~0.03 for skin, ~0.6 for textures
  std::uint32_t seed = 0;
  std::vector<Spot> spots;     ///< skin only
  std::vector<Patch> patches;  ///< skin only
};

/// Albedo of `material` at surface coordinates `uv` (metres). Deterministic.
Eigen::Vector3f albedoAt(const Material& material, const Eigen::Vector2f& uv);

struct Mesh {
  std::string name;
  std::vector<Eigen::Vector3f> vertices;   ///< world frame, metres
  std::vector<Eigen::Vector3i> triangles;  ///< vertex indices, counter-clockwise seen from outside
  std::vector<Eigen::Vector3f> normals;    ///< per vertex, unit, outward; empty: the triangle's own normal
  std::vector<Eigen::Vector2f> uv;         ///< per vertex surface coordinates (metres); empty: world (x, y)
  Material material;
  std::uint8_t label = kLabelBackground;
  /// Per-triangle labels (e.g. one per box face); empty: `label` for all.
  std::vector<std::uint8_t> triangle_labels;
};

struct Scene {
  std::vector<Mesh> meshes;
  Eigen::Vector3f background{0.06f, 0.06f, 0.07f};  ///< linear RGB of rays that hit nothing
};

/// An axis-aligned box [lo, hi] with outward normals; uv per face in metres.
/// Face labels, when `face_label_base` > 0: base + 0..5 (-x, +x, -y, +y, -z, +z).
Mesh makeBox(const std::string& name, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Material& material,
             std::uint8_t label, std::uint8_t face_label_base = 0);

/// A planar quad with corners c0..c3 (counter-clockwise seen from the side its
/// normal points to), uv = metres along c0->c1 and c0->c3.
Mesh makeQuad(const std::string& name, const Eigen::Vector3f& c0, const Eigen::Vector3f& c1, const Eigen::Vector3f& c2,
              const Eigen::Vector3f& c3, const Material& material, std::uint8_t label);

/// Applies a rigid transform to a mesh's vertices and normals.
void transform(Mesh& mesh, const Eigen::Matrix3f& rotation, const Eigen::Vector3f& translation);

}  // namespace massage_cell::sim
