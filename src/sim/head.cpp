// The neck, the head face-down in a face cradle, and the hair (cell_scene.h).
//
// The neck is an elliptic tube that starts inside the back (its top 1 mm
// below the back's skin) and comes out where the back's end cap at the neck
// base drops to the table, so back and neck join without a gap; it runs
// cranially, sinking a little, into the head: an ellipsoid whose occiput is
// about as high as the neck's base and whose face hangs in the opening of a
// U-shaped padded ring (open toward the chin), resting on it with forehead
// and cheeks. The ring sits on a plate held by two struts from the table's
// head end. Hair is a shell a few mm outside the scalp (and, for longer
// hair, a half tube over the nape), with strands along the meridians from
// the crown.
#include <cmath>
#include <random>
#include <vector>

#include "cell_scene_parts.h"
#include "massage_cell/sim/cell_scene.h"
#include "shape_math.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRingStep = 0.004;

/// Head frame for makeEllipsoid: first axis +x (crown), second -z (the seam
/// of the texture under the face), third +y.
Eigen::Matrix3d headRotation() {
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d::UnitX();
  r.col(1) = -Eigen::Vector3d::UnitZ();
  r.col(2) = Eigen::Vector3d::UnitY();
  return r;
}

double neckEndX(const HeadLayout& h) { return h.head_centre.x() - 0.3 * h.head_axes.x(); }

std::vector<TubeRing> neckRings(const BackModel& back, const HeadLayout& h, double from_x, double inflate) {
  const double half_width = 0.5 * back.body().neck_width + 0.004;
  const double half_depth = 0.46 * back.body().neck_width;
  const double x_full = back.fullHeightExtent()[1];
  const double x_end = neckEndX(h);
  const double z0 = h.neck_top_z - half_depth;
  const double drop = z0 - (h.head_centre.z() + 0.01);
  std::vector<TubeRing> rings;
  const int n = std::max(2, static_cast<int>(std::ceil((x_end - from_x) / kRingStep)));
  for (int i = 0; i <= n; ++i) {
    const double x = from_x + (x_end - from_x) * i / n;
    const double base = 1.0 + 0.3 * (1.0 - smooth5(x_full - 0.02, h.hairline_x, x));  // trapezius at the base
    rings.push_back({Eigen::Vector3d(x, 0.0, z0 - drop * smooth5(x_full, x_end, x)), half_width * base + inflate,
                     half_depth + inflate});
  }
  return rings;
}

Material hairMaterial(HairColour colour, std::uint32_t seed) {
  std::mt19937 rng(seed ^ 0x6a1du);
  const float jitter = 0.85f + 0.3f * static_cast<float>(rng()) / 4294967296.0f;
  Material m;
  m.pattern = Material::Pattern::kHair;
  m.albedo = (hairAlbedo(colour) * jitter).cwiseMin(0.95f);
  m.contrast = colour == HairColour::kGrey ? 0.9f : colour == HairColour::kBlond ? 0.45f : 0.55f;
  m.feature_size = 0.0007f;
  m.specular = 0.2f;
  m.shininess = 35.0f;
  m.seed = static_cast<std::uint32_t>(rng());
  return m;
}

Material vinylMaterial(const Eigen::Vector3f& albedo, std::uint32_t seed) {
  Material m;
  m.pattern = Material::Pattern::kCloth;
  m.albedo = albedo;
  m.contrast = 0.05f;
  m.feature_size = 0.0015f;
  m.specular = 0.25f;
  m.shininess = 25.0f;
  m.seed = seed;
  return m;
}

/// The U of the cradle's pad in the table plane, open toward the chin.
std::vector<Eigen::Vector2d> cradlePath(const HeadLayout& h, double offset) {
  const double xh = h.head_centre.x(), A = h.head_axes.x();
  const double x0 = xh - 0.45 * A, x1 = xh + 0.7 * A - offset;
  std::vector<Eigen::Vector2d> path;
  for (double x = x0; x < x1; x += kRingStep) path.emplace_back(x, -offset);
  const int arc = static_cast<int>(std::ceil(kPi * offset / kRingStep));
  for (int i = 0; i <= arc; ++i) {
    const double a = -0.5 * kPi + kPi * i / arc;
    path.emplace_back(x1 + offset * std::cos(a), offset * std::sin(a));
  }
  for (double x = x1 - kRingStep; x > x0 - 1e-9; x -= kRingStep) path.emplace_back(x, offset);
  return path;
}

}  // namespace

HeadLayout headLayout(const BackModel& back) {
  const BodyParameters& b = back.body();
  const double size = std::sqrt(b.torso_length / 0.5);
  HeadLayout h;
  const double x_full = back.fullHeightExtent()[1];
  h.table_end_x = back.extent()[1] + 0.01;
  h.neck_start_x = x_full - 0.025;
  h.neck_top_z = back.height(x_full - 0.001, 0.0) - 0.001;
  h.hairline_x = 3.0 * back.cun();
  h.head_axes = Eigen::Vector3d(0.105, 0.077, 0.095) * size;
  h.head_centre = Eigen::Vector3d(h.hairline_x + 0.8 * h.head_axes.x(), 0.0, h.neck_top_z - h.head_axes.z());
  h.cradle_top_z = h.head_centre.z() - 0.62 * h.head_axes.z();
  return h;
}

Mesh neckMesh(const BackModel& back, const HeadLayout& h, const Material& skin) {
  TubeOptions o;
  o.segments = 48;
  o.cap_start = false;
  o.cap_end = false;
  return makeTube("neck", neckRings(back, h, h.neck_start_x, 0.0), o, skin, kLabelNeck);
}

Mesh headMesh(const HeadLayout& h, const Material& skin) {
  const Eigen::Vector3d axes(h.head_axes.x(), h.head_axes.z(), h.head_axes.y());
  return makeEllipsoid("head", h.head_centre, headRotation(), axes, 48, 64, skin, kLabelHead);
}

std::vector<Mesh> hairMeshes(const BackModel& back, const HeadLayout& h, HairLength length, HairColour colour,
                             std::uint32_t seed) {
  if (length == HairLength::kNone) return {};
  const double thick = length == HairLength::kShort ? 0.006 : 0.009;
  const Eigen::Vector3d axes(h.head_axes.x() + thick, h.head_axes.z() + thick, h.head_axes.y() + thick);
  const Eigen::Vector3d c = h.head_centre;
  const double lowest = length == HairLength::kLong ? -0.45 : -0.3;  // of the head's half height, below the centre
  const double x_min = length == HairLength::kShort ? h.hairline_x + 0.025 : -1.0;
  const Material m = hairMaterial(colour, seed);
  std::vector<Mesh> out;
  out.push_back(makeEllipsoid("hair", c, headRotation(), axes, 48, 64, m, kLabelHair, [&](const Eigen::Vector3d& p) {
    return (p.z() - c.z()) > lowest * h.head_axes.z() && p.x() >= x_min;
  }));
  if (length == HairLength::kShort) return out;
  const double from = length == HairLength::kNape ? h.hairline_x - 0.005 : back.fullHeightExtent()[1] - 0.004;
  TubeOptions o;
  o.segments = 40;
  o.cap_start = false;
  o.cap_end = false;
  const double spread = length == HairLength::kLong ? 0.5 : 0.15;
  o.angle_from = -spread;
  o.angle_to = kPi + spread;
  out.push_back(makeTube("hair_nape", neckRings(back, h, from, thick), o, m, kLabelHair));
  return out;
}

std::vector<Mesh> cradleMeshes(const HeadLayout& h, const std::optional<Cloth>& cover, std::uint32_t seed) {
  const double pad_a = 0.034, pad_b = 0.021;
  const double offset = 0.75 * h.head_axes.y() + pad_a;
  const Material pad = cover ? clothMaterial(*cover, seed ^ 0xc0feu) : vinylMaterial({0.035f, 0.035f, 0.04f}, seed);
  std::vector<TubeRing> rings;
  for (const Eigen::Vector2d& p : cradlePath(h, offset)) {
    rings.push_back({Eigen::Vector3d(p.x(), p.y(), h.cradle_top_z - pad_b), pad_a, pad_b});
  }
  TubeOptions o;
  o.segments = 32;
  std::vector<Mesh> out{makeTube("cradle_pad", rings, o, pad, kLabelCradle)};
  // Plate under the face and two struts into the table's head end.
  const Material frame = vinylMaterial({0.06f, 0.06f, 0.065f}, seed ^ 0xf7a3u);
  const double xh = h.head_centre.x(), A = h.head_axes.x();
  const float top = static_cast<float>(h.head_centre.z() - h.head_axes.z() - 0.035), bottom = top - 0.015f;
  const float half = static_cast<float>(offset + pad_a + 0.01);
  out.push_back(makeBox("cradle_plate", {static_cast<float>(xh - 0.5 * A), -half, bottom},
                        {static_cast<float>(xh + 0.75 * A + 0.02), half, top}, frame, kLabelCradle));
  for (int side : {-1, 1}) {
    const float y0 = side > 0 ? 0.07f : -0.095f;
    out.push_back(makeBox(side > 0 ? "cradle_strut_left" : "cradle_strut_right",
                          {static_cast<float>(h.table_end_x - 0.05), y0, bottom},
                          {static_cast<float>(xh - 0.5 * A + 0.01), y0 + 0.025f, top}, frame, kLabelCradle));
  }
  return out;
}

}  // namespace massage_cell::sim
