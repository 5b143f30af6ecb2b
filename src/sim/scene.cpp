// Scene description of the simulator: procedural materials and mesh builders.
#include "massage_cell/sim/scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

namespace massage_cell::sim {

namespace {

constexpr float kTwoPi = 6.28318530717958647692f;

// ---------------------------------------------------------------------------
// Hash-based lattice value noise: pure functions of (lattice point, seed), so
// deterministic, free of global state and thread-safe.

inline std::uint32_t mix32(std::uint32_t h) {
  // "lowbias32" integer finaliser (good avalanche, cheap).
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return h;
}

inline std::uint32_t hash3(std::uint32_t x, std::uint32_t y, std::uint32_t salt) {
  std::uint32_t h = mix32(salt + 0x9e3779b9u);
  h = mix32(h ^ (x * 0x8da6b343u));
  h = mix32(h ^ (y * 0xd8163841u));
  return h;
}

/// Uniform in [0, 1).
inline float unitFloat(std::uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }

/// Salt of one (seed, pattern, octave, channel) noise field.
inline std::uint32_t salt(std::uint32_t seed, std::uint32_t pattern, std::uint32_t octave, std::uint32_t channel) {
  return mix32(seed * 0x9e3779b1u ^ mix32(pattern * 0x85ebca6bu + octave * 0xc2b2ae35u + channel * 0x27d4eb2fu));
}

/// Quintic fade: C2-continuous interpolation weight.
inline float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }

struct Cell {
  std::uint32_t x0, y0;
  float fx, fy;  ///< fade weights within the cell
};

inline Cell cellOf(const Eigen::Vector2f& uv, float scale) {
  const double px = static_cast<double>(uv.x()) / scale;
  const double py = static_cast<double>(uv.y()) / scale;
  const double flx = std::floor(px);
  const double fly = std::floor(py);
  Cell c;
  // Wrap-around of the lattice index is harmless (the hash just continues).
  c.x0 = static_cast<std::uint32_t>(static_cast<std::int64_t>(flx));
  c.y0 = static_cast<std::uint32_t>(static_cast<std::int64_t>(fly));
  c.fx = fade(static_cast<float>(px - flx));
  c.fy = fade(static_cast<float>(py - fly));
  return c;
}

inline float lerp(float a, float b, float t) { return a + (b - a) * t; }

/// Smooth value noise in [0, 1) with lattice spacing `scale` (metres).
float valueNoise(const Eigen::Vector2f& uv, float scale, std::uint32_t s) {
  const Cell c = cellOf(uv, scale);
  const float v00 = unitFloat(hash3(c.x0, c.y0, s));
  const float v10 = unitFloat(hash3(c.x0 + 1u, c.y0, s));
  const float v01 = unitFloat(hash3(c.x0, c.y0 + 1u, s));
  const float v11 = unitFloat(hash3(c.x0 + 1u, c.y0 + 1u, s));
  return lerp(lerp(v00, v10, c.fx), lerp(v01, v11, c.fx), c.fy);
}

/// Smooth colour value noise: every lattice point has a random colour (half a
/// shared brightness, half per channel), each channel in [0, 1).
Eigen::Vector3f colourNoise(const Eigen::Vector2f& uv, float scale, std::uint32_t s) {
  const Cell c = cellOf(uv, scale);
  auto corner = [s](std::uint32_t x, std::uint32_t y) {
    const std::uint32_t h = hash3(x, y, s);
    const float lum = unitFloat(h);
    const std::uint32_t h1 = mix32(h ^ 0x68e31da4u);
    const std::uint32_t h2 = mix32(h1 ^ 0xb5297a4du);
    const std::uint32_t h3 = mix32(h2 ^ 0x1b56c4e9u);
    return Eigen::Vector3f(0.5f * lum + 0.5f * unitFloat(h1), 0.5f * lum + 0.5f * unitFloat(h2),
                           0.5f * lum + 0.5f * unitFloat(h3));
  };
  const Eigen::Vector3f v00 = corner(c.x0, c.y0);
  const Eigen::Vector3f v10 = corner(c.x0 + 1u, c.y0);
  const Eigen::Vector3f v01 = corner(c.x0, c.y0 + 1u);
  const Eigen::Vector3f v11 = corner(c.x0 + 1u, c.y0 + 1u);
  const Eigen::Vector3f a = v00 + (v10 - v00) * c.fx;
  const Eigen::Vector3f b = v01 + (v11 - v01) * c.fx;
  return a + (b - a) * c.fy;
}

inline float smoothstep(float e0, float e1, float x) {
  const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

inline float positiveScale(float feature_size) {
  return (std::isfinite(feature_size) && feature_size > 1e-6f) ? feature_size : 1e-6f;
}

Eigen::Vector3f clamp01(const Eigen::Vector3f& c) { return c.cwiseMax(0.0f).cwiseMin(1.0f); }

// Pattern ids used to decorrelate the noise fields of different patterns.
enum : std::uint32_t {
  kSaltSkin = 1,
  kSaltCloth = 2,
  kSaltTexture = 3,
  kSaltTerry = 4,
  kSaltWaffle = 5,
  kSaltHair = 6,
  kSaltPrint = 7,
  kSaltPrinted = 8
};

/// How much of a patch's colour covers uv: 1 inside, 0 outside, a 0.5 mm soft edge.
float patchWeight(const Patch& patch, const Eigen::Vector2f& uv) {
  constexpr float kEdge = 0.0005f;
  const Eigen::Vector2f d = uv - patch.centre;
  if (std::abs(d.x()) > patch.half_size.norm() + kEdge || std::abs(d.y()) > patch.half_size.norm() + kEdge) return 0.0f;
  const float c = std::cos(patch.angle), s = std::sin(patch.angle);
  const float a = std::abs(c * d.x() + s * d.y()), b = std::abs(-s * d.x() + c * d.y());
  return (1.0f - smoothstep(patch.half_size.x() - kEdge, patch.half_size.x() + kEdge, a)) *
         (1.0f - smoothstep(patch.half_size.y() - kEdge, patch.half_size.y() + kEdge, b));
}

Eigen::Vector3f skinAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  // Faint mottling: three smooth octaves (2 fs, fs, fs/2), n in [-1, 1].
  constexpr std::array<float, 3> kScales{2.0f, 1.0f, 0.5f};
  constexpr std::array<float, 3> kWeights{0.5f, 0.3f, 0.2f};
  float n = 0.0f;
  for (std::size_t k = 0; k < kScales.size(); ++k) {
    n += kWeights[k] * (2.0f * valueNoise(uv, fs * kScales[k], salt(m.seed, kSaltSkin, k, 0)) - 1.0f);
  }
  Eigen::Vector3f a = m.albedo * (1.0f + m.contrast * n);
  // Spots with a soft edge (a quarter of the radius on either side).
  for (const Spot& spot : m.spots) {
    const float r = std::max(spot.radius, 1e-6f);
    const float d = (uv - spot.centre).norm();
    if (d >= 1.25f * r) continue;
    const float w = 1.0f - smoothstep(0.75f * r, 1.25f * r, d);
    a += (spot.albedo - a) * w;
  }
  for (const Patch& patch : m.patches) a += (patch.albedo - a) * patchWeight(patch, uv);
  return clamp01(a);
}

/// Printed stripes along v or checks: albedo and albedo2 with a soft 1 mm
/// edge (ink bleeding into the cloth), the cloth's fine weave over both.
Eigen::Vector3f printedAlbedo(const Material& m, const Eigen::Vector2f& uv, bool checks) {
  const float period = positiveScale(m.feature_size);
  const float e = std::min(0.25f, 0.001f / period);  // the edge's half width, in periods
  auto band = [&](float t) {  // 0 in the first colour, 1 in the second (centred at 3/4 of the period)
    const float f = t / period - std::floor(t / period);
    float d = std::abs(f - 0.75f);
    d = std::min(d, 1.0f - d);
    return std::clamp((0.25f - d) / (2.0f * e) + 0.5f, 0.0f, 1.0f);
  };
  float w = band(uv.x());
  if (checks) w = std::abs(w - band(uv.y()));
  const Eigen::Vector3f base = m.albedo + (m.albedo2 - m.albedo) * w;
  const float fibre = 2.0f * valueNoise(uv, 0.0015f, salt(m.seed, kSaltPrinted, 0, 0)) - 1.0f;
  return clamp01(base * (1.0f + 0.05f * fibre));
}

Eigen::Vector3f clothAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  // Threads along u and v with period fs; the product gives an over/under weave.
  const float su = std::sin(kTwoPi * uv.x() / fs);
  const float sv = std::sin(kTwoPi * uv.y() / fs);
  const float weave = 0.5f * (su * sv) + 0.25f * (std::abs(su) + std::abs(sv)) - 0.25f;
  const float slub = 2.0f * valueNoise(uv, 4.0f * fs, salt(m.seed, kSaltCloth, 0, 0)) - 1.0f;
  const float fibre = 2.0f * valueNoise(uv, 0.5f * fs, salt(m.seed, kSaltCloth, 1, 0)) - 1.0f;
  const float n = 0.6f * weave + 0.25f * slub + 0.15f * fibre;
  return clamp01(m.albedo * (1.0f + m.contrast * n));
}

Eigen::Vector3f textureAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  // Five octaves from 4 fs down to fs / 4, each with its own random colours.
  constexpr std::array<float, 5> kScales{4.0f, 2.0f, 1.0f, 0.5f, 0.25f};
  constexpr std::array<float, 5> kWeights{0.30f, 0.25f, 0.20f, 0.15f, 0.10f};
  // Scales the sum of centred octaves to a standard deviation of about 0.5.
  constexpr float kGain = 3.6f;
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  for (std::size_t k = 0; k < kScales.size(); ++k) {
    n += kWeights[k] *
         (2.0f * colourNoise(uv, fs * kScales[k], salt(m.seed, kSaltTexture, k, 0)) - Eigen::Vector3f::Ones());
  }
  n = (kGain * n).cwiseMax(-1.0f).cwiseMin(1.0f);
  return clamp01(m.albedo.cwiseProduct(Eigen::Vector3f::Ones() + m.contrast * n));
}

/// Terry towelling: one loop per lattice cell of pitch fs, jittered, each a
/// soft bright blob of its own brightness; the gaps between loops are darker.
Eigen::Vector3f terryAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  const Cell c = cellOf(uv, fs);
  const Eigen::Vector2f local(static_cast<float>(uv.x() / fs - std::floor(uv.x() / fs)),
                              static_cast<float>(uv.y() / fs - std::floor(uv.y() / fs)));
  float loop = 0.0f;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const std::uint32_t h = hash3(c.x0 + static_cast<std::uint32_t>(dx), c.y0 + static_cast<std::uint32_t>(dy),
                                    salt(m.seed, kSaltTerry, 0, 0));
      const Eigen::Vector2f centre(dx + 0.2f + 0.6f * unitFloat(h), dy + 0.2f + 0.6f * unitFloat(mix32(h)));
      const float d2 = (local - centre).squaredNorm() / (0.38f * 0.38f);
      loop = std::max(loop, (0.6f + 0.4f * unitFloat(mix32(h ^ 0x51ed27u))) * std::exp(-d2));
    }
  }
  const float fluff = 2.0f * valueNoise(uv, 6.0f * fs, salt(m.seed, kSaltTerry, 1, 0)) - 1.0f;
  const float n = 0.7f * (2.0f * loop - 1.0f) + 0.3f * fluff;
  return clamp01(m.albedo * (1.0f + m.contrast * n));
}

/// Waffle weave: square pockets of pitch fs between raised, lighter ridges,
/// with a fine thread texture on top.
Eigen::Vector3f waffleAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  auto border = [](double t) {
    const float f = static_cast<float>(t - std::floor(t));
    return 1.0f - smoothstep(0.08f, 0.22f, std::min(f, 1.0f - f));
  };
  const float ridge = std::max(border(uv.x() / fs), border(uv.y() / fs));
  const float thread = std::sin(kTwoPi * 6.0f * uv.x() / fs) * std::sin(kTwoPi * 6.0f * uv.y() / fs);
  const float slub = 2.0f * valueNoise(uv, 3.0f * fs, salt(m.seed, kSaltWaffle, 0, 0)) - 1.0f;
  const float n = 0.65f * (2.0f * ridge - 1.0f) + 0.15f * thread + 0.2f * slub;
  return clamp01(m.albedo * (1.0f + m.contrast * n));
}

/// Hair: noise stretched along u (the strands' direction) at the strand width
/// fs and half of it, plus coarser clumps; the contrast sets how much strands differ.
Eigen::Vector3f hairAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  const Eigen::Vector2f along40(uv.x() / 40.0f, uv.y()), along12(uv.x() / 12.0f, uv.y());
  const float strand = 2.0f * valueNoise(along40, fs, salt(m.seed, kSaltHair, 0, 0)) - 1.0f;
  const float fine = 2.0f * valueNoise(along40, 0.5f * fs, salt(m.seed, kSaltHair, 1, 0)) - 1.0f;
  const float clump = 2.0f * valueNoise(along12, 8.0f * fs, salt(m.seed, kSaltHair, 2, 0)) - 1.0f;
  const float n = 0.45f * strand + 0.3f * fine + 0.25f * clump;
  return clamp01(m.albedo * (1.0f + m.contrast * n));
}

void checkFinite(const Eigen::Vector3f& v, const std::string& what) {
  if (!v.allFinite()) throw std::invalid_argument(what + " must be finite");
}

/// Printed packaging: a pale board with ink marks on a lattice of pitch fs,
/// rows of small glyph-like blocks (text) and, every few rows, larger solid
/// panels, so the surface has corners and straight edges as labels do.
Eigen::Vector3f printAlbedo(const Material& m, const Eigen::Vector2f& uv) {
  const float fs = positiveScale(m.feature_size);
  const Cell c = cellOf(uv, fs);
  const float lx = static_cast<float>(uv.x() / fs - std::floor(uv.x() / fs));
  const float ly = static_cast<float>(uv.y() / fs - std::floor(uv.y() / fs));
  const std::uint32_t row = hash3(0u, c.y0, salt(m.seed, kSaltPrint, 0, 0));
  const std::uint32_t h = hash3(c.x0, c.y0, salt(m.seed, kSaltPrint, 1, 0));
  Eigen::Vector3f board = m.albedo;
  const bool text_row = unitFloat(row) < 0.75f;
  const bool panel = unitFloat(mix32(row)) < 0.1f;
  bool ink = false;
  if (panel) {
    ink = true;  // a solid band across the face
  } else if (text_row && unitFloat(h) < 0.8f) {
    const float x0 = 0.1f + 0.3f * unitFloat(mix32(h)), x1 = 0.6f + 0.3f * unitFloat(mix32(h ^ 0x9e37u));
    const float y0 = 0.15f + 0.2f * unitFloat(mix32(h ^ 0x7f4au)), y1 = 0.65f + 0.25f * unitFloat(mix32(h ^ 0x3c6eu));
    ink = lx > x0 && lx < x1 && ly > y0 && ly < y1;
  }
  if (!ink) return clamp01(board.cwiseProduct(Eigen::Vector3f::Constant(1.0f + 0.05f * (unitFloat(h) - 0.5f))));
  // Ink: dark or one of the label's colours, the same along a row.
  const std::uint32_t colour = mix32(row ^ (panel ? 0x1234u : 0u));
  const Eigen::Vector3f tint(unitFloat(colour), unitFloat(mix32(colour)), unitFloat(mix32(colour ^ 0x55u)));
  const float darkness = unitFloat(mix32(colour ^ 0xabcu)) < 0.5f ? 0.15f : 0.55f;
  return clamp01(board.cwiseProduct(darkness * Eigen::Vector3f::Ones() + m.contrast * 0.5f * tint));
}

}  // namespace

Eigen::Vector3f albedoAt(const Material& material, const Eigen::Vector2f& uv) {
  switch (material.pattern) {
    case Material::Pattern::kFlat:
      return material.albedo;
    case Material::Pattern::kSkin:
      return skinAlbedo(material, uv);
    case Material::Pattern::kCloth:
      return clothAlbedo(material, uv);
    case Material::Pattern::kTexture:
      return textureAlbedo(material, uv);
    case Material::Pattern::kTerry:
      return terryAlbedo(material, uv);
    case Material::Pattern::kWaffle:
      return waffleAlbedo(material, uv);
    case Material::Pattern::kHair:
      return hairAlbedo(material, uv);
    case Material::Pattern::kPrint:
      return printAlbedo(material, uv);
    case Material::Pattern::kStripes:
      return printedAlbedo(material, uv, false);
    case Material::Pattern::kChecks:
      return printedAlbedo(material, uv, true);
  }
  return material.albedo;
}

Mesh makeBox(const std::string& name, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Material& material,
             std::uint8_t label, std::uint8_t face_label_base) {
  checkFinite(lo, "makeBox(" + name + "): lo");
  checkFinite(hi, "makeBox(" + name + "): hi");
  if (!(lo.array() < hi.array()).all()) {
    throw std::invalid_argument("makeBox(" + name + "): lo must be below hi on every axis");
  }
  if (face_label_base > 0 && face_label_base > 255 - 5) {
    throw std::invalid_argument("makeBox(" + name + "): face_label_base + 5 exceeds 255");
  }
  Mesh mesh;
  mesh.name = name;
  mesh.material = material;
  mesh.label = label;
  mesh.vertices.reserve(24);
  mesh.normals.reserve(24);
  mesh.uv.reserve(24);
  mesh.triangles.reserve(12);
  // Faces -x, +x, -y, +y, -z, +z. For axis a with sign s the in-face axes
  // (b, c) are chosen so that e_b x e_c = s e_a (counter-clockwise outside).
  for (int face = 0; face < 6; ++face) {
    const int a = face / 2;
    const bool positive = (face % 2) == 1;
    const int b = positive ? (a + 1) % 3 : (a + 2) % 3;
    const int c = positive ? (a + 2) % 3 : (a + 1) % 3;
    Eigen::Vector3f normal = Eigen::Vector3f::Zero();
    normal[a] = positive ? 1.0f : -1.0f;
    const int first = static_cast<int>(mesh.vertices.size());
    const std::array<std::array<bool, 2>, 4> corners{{{false, false}, {true, false}, {true, true}, {false, true}}};
    for (const auto& corner : corners) {
      Eigen::Vector3f p;
      p[a] = positive ? hi[a] : lo[a];
      p[b] = corner[0] ? hi[b] : lo[b];
      p[c] = corner[1] ? hi[c] : lo[c];
      mesh.vertices.push_back(p);
      mesh.normals.push_back(normal);
      mesh.uv.emplace_back(p[b] - lo[b], p[c] - lo[c]);
    }
    mesh.triangles.emplace_back(first, first + 1, first + 2);
    mesh.triangles.emplace_back(first, first + 2, first + 3);
    if (face_label_base > 0) {
      const auto face_label = static_cast<std::uint8_t>(face_label_base + face);
      mesh.triangle_labels.push_back(face_label);
      mesh.triangle_labels.push_back(face_label);
    }
  }
  return mesh;
}

Mesh makeQuad(const std::string& name, const Eigen::Vector3f& c0, const Eigen::Vector3f& c1, const Eigen::Vector3f& c2,
              const Eigen::Vector3f& c3, const Material& material, std::uint8_t label) {
  checkFinite(c0, "makeQuad(" + name + "): c0");
  checkFinite(c1, "makeQuad(" + name + "): c1");
  checkFinite(c2, "makeQuad(" + name + "): c2");
  checkFinite(c3, "makeQuad(" + name + "): c3");
  const Eigen::Vector3f e1 = c1 - c0;
  const Eigen::Vector3f e3 = c3 - c0;
  // Newell-style normal of the quad: robust for slightly non-planar corners.
  const Eigen::Vector3f cross = (c2 - c0).cross(c3 - c1);
  if (!(e1.norm() > 0.0f) || !(e3.norm() > 0.0f) || !(cross.norm() > 0.0f)) {
    throw std::invalid_argument("makeQuad(" + name + "): degenerate quad");
  }
  const Eigen::Vector3f u_axis = e1.normalized();
  const Eigen::Vector3f v_axis = e3.normalized();
  const Eigen::Vector3f normal = cross.normalized();
  Mesh mesh;
  mesh.name = name;
  mesh.material = material;
  mesh.label = label;
  for (const Eigen::Vector3f& c : {c0, c1, c2, c3}) {
    mesh.vertices.push_back(c);
    mesh.normals.push_back(normal);
    mesh.uv.emplace_back((c - c0).dot(u_axis), (c - c0).dot(v_axis));
  }
  mesh.triangles.emplace_back(0, 1, 2);
  mesh.triangles.emplace_back(0, 2, 3);
  return mesh;
}

const char* labelName(std::uint8_t label) {
  switch (label) {
    case kLabelBackground:
      return "background";
    case kLabelBack:
      return "back";
    case kLabelTable:
      return "table";
    case kLabelFloor:
      return "floor";
    case kLabelArm:
      return "arm";
    case kLabelNeck:
      return "neck";
    case kLabelHead:
      return "head";
    case kLabelHair:
      return "hair";
    case kLabelTowel:
      return "towel";
    case kLabelPlane:
      return "plane";
    case kLabelCradle:
      return "face cradle";
    default:
      return label >= kLabelBoxFace ? "box face" : "unknown";
  }
}

void transform(Mesh& mesh, const Eigen::Matrix3f& rotation, const Eigen::Vector3f& translation) {
  for (Eigen::Vector3f& v : mesh.vertices) v = rotation * v + translation;
  for (Eigen::Vector3f& n : mesh.normals) {
    const Eigen::Vector3f r = rotation * n;
    const float len = r.norm();
    n = len > 0.0f ? Eigen::Vector3f(r / len) : r;
  }
}

}  // namespace massage_cell::sim
