// Calibrated multi-view sets with exact planes: the boxes scene and a single
// textured cube, rendered from cameras on an arc (makeMultiView). The true
// planes come from the scene's triangles: a label whose triangles all lie on
// one plane is that plane; a label spread over several planes (the table is a
// box whose six faces all carry kLabelTable) counts only when every pixel it
// has in the views lies on one of them (for the table: only its top is seen).
#include "massage_cell/sim/multiview_set.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
/// Triangles whose planes differ by less than this (normal components, and
/// offset in metres) are on one plane; float vertices are good to ~1e-7.
constexpr double kSamePlane = 1e-5;
/// A pixel's surface point lies on a plane when within this (metres).
constexpr double kOnPlane = 1e-4;
/// Makes the per-view noise seeds of one set differ from another set's.
constexpr std::uint32_t kViewSeedStride = 1000003u;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void validateOptions(const MultiViewOptions& o, const std::string& who) {
  if (o.views < 2) throw std::invalid_argument(who + ": options.views must be >= 2, got " + std::to_string(o.views));
  if (o.width <= 0 || o.height <= 0 || o.width > 16384 || o.height > 16384) {
    throw std::invalid_argument(who + ": options.width/height must be in 1..16384, got " + std::to_string(o.width) +
                                "x" + std::to_string(o.height));
  }
  if (!std::isfinite(o.fx) || !(o.fx > 0.0)) {
    throw std::invalid_argument(who + ": options.fx must be > 0, got " + num(o.fx));
  }
  if (!std::isfinite(o.distance) || !(o.distance > 0.0)) {
    throw std::invalid_argument(who + ": options.distance must be > 0, got " + num(o.distance));
  }
  if (!std::isfinite(o.elevation_deg) || !(o.elevation_deg > 0.0) || o.elevation_deg > 90.0) {
    throw std::invalid_argument(who + ": options.elevation_deg must be in (0, 90], got " + num(o.elevation_deg));
  }
  if (!std::isfinite(o.spread_deg) || o.spread_deg < 0.0) {
    throw std::invalid_argument(who + ": options.spread_deg must be >= 0, got " + num(o.spread_deg));
  }
}

double radians(double degrees) { return degrees * kPi / 180.0; }

// ---------------------------------------------------------------------------
// True planes from the scene's triangles

std::uint8_t triangleLabel(const Mesh& mesh, std::size_t t) {
  return mesh.triangle_labels.empty() ? mesh.label : mesh.triangle_labels[t];
}

/// The planes one label's triangles lie on, accumulated: area-weighted normal
/// and the vertices' sum (the centroid gives the offset).
struct PlaneGroup {
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
  int point_count = 0;
  TruePlane plane() const {
    TruePlane p;
    p.n = normal_sum.normalized();
    p.d = 0.0 - p.n.dot(point_sum / point_count);  // 0.0 - : no -0 for planes through the origin
    return p;
  }
};

struct LabelPlanes {
  std::string name;
  std::vector<PlaneGroup> groups;
};

/// "box_0" + face 5 -> "box 0 +z"; faces in makeBox's order.
std::string faceName(const Mesh& mesh, std::uint8_t label) {
  static const std::array<const char*, 6> kFaces{"-x", "+x", "-y", "+y", "-z", "+z"};
  std::string name = mesh.name;
  std::replace(name.begin(), name.end(), '_', ' ');
  const int face = label - mesh.triangle_labels.front();
  return face >= 0 && face < 6 ? name + " " + kFaces[face] : name + " face " + std::to_string(face);
}

void addTriangle(const Mesh& mesh, std::size_t t, LabelPlanes& planes) {
  Eigen::Vector3d v[3];
  for (int k = 0; k < 3; ++k) v[k] = mesh.vertices[mesh.triangles[t][k]].cast<double>();
  const Eigen::Vector3d cross = (v[1] - v[0]).cross(v[2] - v[0]);  // outward: counter-clockwise seen from outside
  if (!(cross.norm() > 0.0)) return;
  const Eigen::Vector3d n = cross.normalized();
  for (PlaneGroup& g : planes.groups) {
    const TruePlane p = g.plane();
    if ((p.n - n).norm() < kSamePlane && std::abs(p.n.dot(v[0]) + p.d) < kSamePlane) {
      g.normal_sum += cross;
      for (const auto& x : v) g.point_sum += x;
      g.point_count += 3;
      return;
    }
  }
  PlaneGroup g;
  g.normal_sum = cross;
  for (const auto& x : v) g.point_sum += x;
  g.point_count = 3;
  planes.groups.push_back(g);
}

/// Planes of the table and the box faces, by label.
std::map<std::uint8_t, LabelPlanes> scenePlanes(const Scene& scene) {
  std::map<std::uint8_t, LabelPlanes> planes;
  for (const Mesh& mesh : scene.meshes) {
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const std::uint8_t label = triangleLabel(mesh, t);
      if (label != kLabelTable && label < kLabelBoxFace) continue;
      LabelPlanes& lp = planes[label];
      if (lp.name.empty()) lp.name = mesh.triangle_labels.empty() ? labelName(label) : faceName(mesh, label);
      addTriangle(mesh, t, lp);
    }
  }
  return planes;
}

/// World points of the views' pixels, by label.
std::array<std::vector<Eigen::Vector3d>, 256> pointsByLabel(const std::vector<ViewRender>& renders) {
  std::array<std::vector<Eigen::Vector3d>, 256> points;
  for (const ViewRender& r : renders) {
    for (int y = 0; y < r.labels.rows; ++y) {
      const auto* lab = r.labels.ptr<std::uint8_t>(y);
      const auto* pts = r.points.ptr<cv::Vec3f>(y);
      for (int x = 0; x < r.labels.cols; ++x) {
        if (lab[x] != kLabelBackground) points[lab[x]].emplace_back(pts[x][0], pts[x][1], pts[x][2]);
      }
    }
  }
  return points;
}

/// The first of the planes that holds all the points (within kOnPlane); -1
/// when there are no points or no plane holds them all.
int planeOfAll(const std::vector<TruePlane>& planes, const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) return -1;
  std::vector<bool> holds(planes.size(), true);
  for (const Eigen::Vector3d& X : points) {
    for (std::size_t g = 0; g < planes.size(); ++g) {
      if (holds[g] && !(std::abs(planes[g].n.dot(X) + planes[g].d) < kOnPlane)) holds[g] = false;
    }
  }
  const auto first = std::find(holds.begin(), holds.end(), true);
  return first == holds.end() ? -1 : static_cast<int>(first - holds.begin());
}

std::vector<TruePlane> truePlanes(const Scene& scene, const std::vector<ViewRender>& renders) {
  const std::array<std::vector<Eigen::Vector3d>, 256> points = pointsByLabel(renders);
  std::vector<TruePlane> planes;
  for (const auto& [label, lp] : scenePlanes(scene)) {
    std::vector<TruePlane> candidates;
    for (const PlaneGroup& g : lp.groups) candidates.push_back(g.plane());
    const int g = planeOfAll(candidates, points[label]);
    if (g < 0) continue;
    TruePlane p = candidates[static_cast<std::size_t>(g)];
    p.name = lp.name;
    p.label = label;
    planes.push_back(p);
  }
  return planes;
}

// ---------------------------------------------------------------------------
// Rendering

double medianPlaneDepth(const ViewRender& view, const std::vector<TruePlane>& planes) {
  std::array<bool, 256> is_plane{};
  for (const TruePlane& p : planes) is_plane[p.label] = true;
  std::vector<float> depths;
  for (int y = 0; y < view.labels.rows; ++y) {
    for (int x = 0; x < view.labels.cols; ++x) {
      if (is_plane[view.labels.at<std::uint8_t>(y, x)]) depths.push_back(view.depth.at<float>(y, x));
    }
  }
  if (depths.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto mid = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
  std::nth_element(depths.begin(), mid, depths.end());
  return *mid;
}

/// Renders every camera, fills the set's images, labels, depth, P and planes.
void renderSet(MultiViewSet& set, const Lighting& lighting, const MultiViewOptions& options) {
  const Renderer renderer(set.scene);
  std::vector<ViewRender> renders;
  for (std::size_t i = 0; i < set.cameras.size(); ++i) {
    RenderOptions ro;
    ro.supersample = options.supersample;
    ro.noise_sigma = options.noise_sigma;
    ro.noise_seed = options.seed * kViewSeedStride + static_cast<std::uint32_t>(i);
    renders.push_back(renderer.render(set.cameras[i], lighting, ro));
    set.P.push_back(set.cameras[i].projectionMatrix());
    set.images.push_back(renders.back().image);
    set.labels.push_back(renders.back().labels);
    set.depth.push_back(renders.back().depth);
  }
  set.planes = truePlanes(set.scene, renders);
  set.scene_depth = medianPlaneDepth(renders.front(), set.planes);
}

/// Centre of the bounding box of the box faces' vertices.
Eigen::Vector3d boxesCentre(const Scene& scene) {
  Eigen::AlignedBox3d box;
  for (const Mesh& mesh : scene.meshes) {
    if (mesh.triangle_labels.empty()) continue;
    for (const Eigen::Vector3f& v : mesh.vertices) box.extend(v.cast<double>());
  }
  return box.center();
}

// ---------------------------------------------------------------------------
// The cube

/// A strong colour texture at about 1/25 of the edge, so that corners and
/// correlation windows find structure on every face.
Material cubeMaterial(double edge, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.3f, 0.8f);
  Material m;
  m.pattern = Material::Pattern::kTexture;
  m.albedo = {u(rng), u(rng), u(rng)};
  m.contrast = 0.6f;
  m.feature_size = static_cast<float>(edge / 25.0);
  m.specular = 0.05f;
  m.seed = static_cast<std::uint32_t>(rng());
  return m;
}

/// makeBox gives every face uv from (0, 0): shifting each face's uv by a few
/// edges makes each face show a texture patch of its own (no repeated pattern
/// for the matcher to confuse).
void separateFaceTextures(Mesh& cube, double edge) {
  for (std::size_t k = 0; k < cube.uv.size(); ++k) {
    const int face = static_cast<int>(k / 4);  // makeBox: four vertices per face
    cube.uv[k].x() += static_cast<float>(3.0 * edge * face);
  }
}

/// Cameras of makeMultiView turned about the vertical through `target` so
/// that they look from the +x +y quadrant: each sees the +x, +y and +z faces.
std::vector<CameraModel> cubeCameras(const Eigen::Vector3d& target, const MultiViewOptions& o) {
  std::vector<CameraModel> cameras = makeMultiView(o.views, target, o.distance, radians(o.elevation_deg),
                                                   radians(o.spread_deg), o.width, o.height, o.fx);
  // makeMultiView's middle camera looks along +x (it stands on the -x side); a
  // turn by -135 degrees puts it on the diagonal between +x and +y.
  const Eigen::AngleAxisd yaw(-0.75 * kPi, Eigen::Vector3d::UnitZ());
  const Eigen::Isometry3d turn = Eigen::Translation3d(target) * yaw * Eigen::Translation3d(-target);
  for (CameraModel& c : cameras) c.world_from_camera = turn * c.world_from_camera;
  return cameras;
}

}  // namespace

MultiViewSet renderBoxesViews(int count, const MultiViewOptions& options) {
  validateOptions(options, "renderBoxesViews");
  MultiViewSet set;
  set.scene = makeBoxesScene(options.seed, count);
  set.cameras = makeMultiView(options.views, boxesCentre(set.scene), options.distance, radians(options.elevation_deg),
                              radians(options.spread_deg), options.width, options.height, options.fx);
  renderSet(set, Lighting(), options);
  return set;
}

MultiViewSet renderCubeViews(double edge, const MultiViewOptions& options) {
  validateOptions(options, "renderCubeViews");
  if (!std::isfinite(edge) || !(edge > 0.0)) {
    throw std::invalid_argument("renderCubeViews: edge must be > 0, got " + num(edge));
  }
  if (options.spread_deg >= 90.0 || options.elevation_deg >= 90.0) {
    throw std::invalid_argument(
        "renderCubeViews: options.spread_deg and elevation_deg must be below 90 (every view "
        "must see two sides), got " +
        num(options.spread_deg) + " and " + num(options.elevation_deg));
  }
  MultiViewSet set;
  const float e = static_cast<float>(edge);
  Mesh cube = makeBox("cube", {-e / 2, -e / 2, 0.0f}, {e / 2, e / 2, e}, cubeMaterial(edge, options.seed),
                      kLabelBoxFace, kLabelBoxFace);
  separateFaceTextures(cube, edge);
  set.scene.meshes.push_back(std::move(cube));
  set.scene.background = Eigen::Vector3f::Zero();
  set.cameras = cubeCameras(Eigen::Vector3d(0.0, 0.0, edge / 2.0), options);
  // Light from the cameras' side, so that all three visible faces are lit differently.
  Lighting lighting;
  lighting.direction_to_light = Eigen::Vector3f(0.6f, 0.35f, 0.75f).normalized();
  renderSet(set, lighting, options);
  return set;
}

}  // namespace massage_cell::sim
