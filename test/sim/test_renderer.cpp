// Tests of the scene builders, the procedural materials and the Embree renderer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene.h"

namespace {

using massage_cell::sim::albedoAt;
using massage_cell::sim::CameraModel;
using massage_cell::sim::Hit;
using massage_cell::sim::Lighting;
using massage_cell::sim::LightPreset;
using massage_cell::sim::makeBox;
using massage_cell::sim::makeQuad;
using massage_cell::sim::Material;
using massage_cell::sim::Mesh;
using massage_cell::sim::Renderer;
using massage_cell::sim::RenderOptions;
using massage_cell::sim::Scene;
using massage_cell::sim::Spot;
using massage_cell::sim::ViewRender;
namespace sim = massage_cell::sim;

// ---------------------------------------------------------------------------
// Helpers

/// Pinhole camera at `position` looking straight down (optical z = -world z),
/// image up = world +x, image left = world +y (the rig's orientation).
CameraModel downCamera(const Eigen::Vector3d& position, int width, int height, double f) {
  CameraModel c;
  c.width = width;
  c.height = height;
  c.K << f, 0.0, (width - 1) / 2.0, 0.0, f, (height - 1) / 2.0, 0.0, 0.0, 1.0;
  c.D.clear();
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0.0, -1.0, 0.0);
  R.col(1) = Eigen::Vector3d(-1.0, 0.0, 0.0);
  R.col(2) = Eigen::Vector3d(0.0, 0.0, -1.0);
  c.world_from_camera = Eigen::Isometry3d::Identity();
  c.world_from_camera.linear() = R;
  c.world_from_camera.translation() = position;
  return c;
}

/// Our own pinhole projection (independent of CameraModel::project).
Eigen::Vector2d projectPinhole(const CameraModel& c, const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d p = c.world_from_camera.inverse() * p_world;
  return Eigen::Vector2d(c.K(0, 0) * p.x() / p.z() + c.K(0, 2), c.K(1, 1) * p.y() / p.z() + c.K(1, 2));
}

cv::Point pixelOf(const CameraModel& c, const Eigen::Vector3d& p_world) {
  const Eigen::Vector2d px = projectPinhole(c, p_world);
  return cv::Point(static_cast<int>(std::lround(px.x())), static_cast<int>(std::lround(px.y())));
}

Material flat(float grey) {
  Material m;
  m.pattern = Material::Pattern::kFlat;
  m.albedo = Eigen::Vector3f::Constant(grey);
  return m;
}

/// A square quad of half-size `half` at height z, normal +z.
Mesh groundQuad(float half, float z, const Material& m, std::uint8_t label) {
  return makeQuad("ground", Eigen::Vector3f(-half, -half, z), Eigen::Vector3f(half, -half, z),
                  Eigen::Vector3f(half, half, z), Eigen::Vector3f(-half, half, z), m, label);
}

RenderOptions quiet(int supersample = 1) {
  RenderOptions o;
  o.supersample = supersample;
  o.noise_sigma = 0.0f;
  o.exposure = 1.0f;
  return o;
}

Lighting overhead() {
  Lighting l;
  l.direction_to_light = Eigen::Vector3f(0.0f, 0.0f, 1.0f);
  l.intensity = 0.6f;
  l.ambient = 0.3f;
  return l;
}

double grey(const cv::Mat& image, cv::Point p) {
  const cv::Vec3b v = image.at<cv::Vec3b>(p);
  return (v[0] + v[1] + v[2]) / 3.0;
}

double srgb8(double linear) {
  const double c = std::clamp(linear, 0.0, 1.0);
  const double e = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
  return std::round(255.0 * e);
}

bool sameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

// ---------------------------------------------------------------------------
// Scene builders

TEST(SceneBuilders, BoxHasOutwardCcwFacesFlatNormalsAndFaceLabels) {
  const Eigen::Vector3f lo(-0.1f, -0.2f, 0.0f), hi(0.3f, 0.2f, 0.5f);
  const Mesh box = makeBox("box", lo, hi, flat(0.5f), sim::kLabelBoxFace, sim::kLabelBoxFace);
  ASSERT_EQ(box.triangles.size(), 12u);
  ASSERT_EQ(box.vertices.size(), 24u);
  ASSERT_EQ(box.normals.size(), 24u);
  ASSERT_EQ(box.uv.size(), 24u);
  ASSERT_EQ(box.triangle_labels.size(), 12u);
  const Eigen::Vector3f mid = 0.5f * (lo + hi);
  const Eigen::Vector3f expected_normals[6] = {-Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitX(),
                                               -Eigen::Vector3f::UnitY(), Eigen::Vector3f::UnitY(),
                                               -Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ()};
  for (int t = 0; t < 12; ++t) {
    const Eigen::Vector3i& tri = box.triangles[t];
    const Eigen::Vector3f a = box.vertices[tri[0]], b = box.vertices[tri[1]], c = box.vertices[tri[2]];
    const Eigen::Vector3f n = (b - a).cross(c - a).normalized();
    const int face = t / 2;
    EXPECT_NEAR((n - expected_normals[face]).norm(), 0.0f, 1e-6f) << "triangle " << t;
    EXPECT_GT(n.dot((a + b + c) / 3.0f - mid), 0.0f) << "triangle " << t << " faces inward";
    for (int k = 0; k < 3; ++k) EXPECT_EQ(box.normals[tri[k]], expected_normals[face]) << "triangle " << t;
    EXPECT_EQ(box.triangle_labels[t], sim::kLabelBoxFace + face);
  }
  // uv in metres: the +z face spans 0.4 x 0.4.
  float umax = 0.0f, vmax = 0.0f;
  for (int k = 20; k < 24; ++k) {
    umax = std::max(umax, box.uv[k].x());
    vmax = std::max(vmax, box.uv[k].y());
  }
  EXPECT_NEAR(umax, 0.4f, 1e-6f);
  EXPECT_NEAR(vmax, 0.4f, 1e-6f);

  const Mesh plain = makeBox("plain", lo, hi, flat(0.5f), sim::kLabelTable);
  EXPECT_TRUE(plain.triangle_labels.empty());
  EXPECT_EQ(plain.label, sim::kLabelTable);
  EXPECT_THROW(makeBox("bad", hi, lo, flat(0.5f), 1), std::invalid_argument);
}

TEST(SceneBuilders, QuadAndTransform) {
  Mesh q = makeQuad("q", Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(2, 0, 0), Eigen::Vector3f(2, 1, 0),
                    Eigen::Vector3f(0, 1, 0), flat(0.5f), sim::kLabelPlane);
  ASSERT_EQ(q.triangles.size(), 2u);
  ASSERT_EQ(q.uv.size(), 4u);
  EXPECT_NEAR((q.uv[2] - Eigen::Vector2f(2, 1)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((q.normals[0] - Eigen::Vector3f::UnitZ()).norm(), 0.0f, 1e-6f);
  EXPECT_EQ(q.label, sim::kLabelPlane);
  const Eigen::Matrix3f R = Eigen::AngleAxisf(static_cast<float>(M_PI / 2), Eigen::Vector3f::UnitX()).matrix();
  sim::transform(q, R, Eigen::Vector3f(0, 0, 1));
  EXPECT_NEAR((q.vertices[2] - Eigen::Vector3f(2, 0, 2)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((q.normals[0] - Eigen::Vector3f(0, -1, 0)).norm(), 0.0f, 1e-6f);
  // uv are surface coordinates: unchanged by the transform.
  EXPECT_NEAR((q.uv[2] - Eigen::Vector2f(2, 1)).norm(), 0.0f, 1e-6f);
}

// ---------------------------------------------------------------------------
// Materials

double channelStd(const Material& m, double size, int n, int channel) {
  double s1 = 0.0, s2 = 0.0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2f uv(static_cast<float>(size * i / n), static_cast<float>(size * j / n));
      const double a = albedoAt(m, uv)[channel];
      s1 += a;
      s2 += a * a;
    }
  }
  const double mean = s1 / (n * n);
  return std::sqrt(std::max(0.0, s2 / (n * n) - mean * mean));
}

TEST(Materials, DeterministicAndSeeded) {
  for (auto pattern : {Material::Pattern::kSkin, Material::Pattern::kCloth, Material::Pattern::kTexture}) {
    Material m;
    m.pattern = pattern;
    m.contrast = 0.5f;
    m.seed = 42;
    Material other = m;
    other.seed = 43;
    int differing = 0;
    for (int k = 0; k < 100; ++k) {
      const Eigen::Vector2f uv(0.0137f * k, 0.0071f * k - 0.3f);
      const Eigen::Vector3f a = albedoAt(m, uv);
      EXPECT_EQ(a, albedoAt(m, uv));  // bit-identical
      EXPECT_TRUE((a.array() >= 0.0f).all() && (a.array() <= 1.0f).all());
      if ((a - albedoAt(other, uv)).norm() > 1e-4f) ++differing;
    }
    EXPECT_GT(differing, 50) << "seed has no effect on pattern " << static_cast<int>(pattern);
  }
  Material f;
  f.albedo = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  EXPECT_EQ(albedoAt(f, Eigen::Vector2f(0.3f, -4.0f)), f.albedo);
}

TEST(Materials, SkinIsNearlyUniformTextureIsStrong) {
  Material skin;
  skin.pattern = Material::Pattern::kSkin;
  skin.albedo = Eigen::Vector3f(0.62f, 0.42f, 0.33f);
  skin.contrast = 0.03f;
  skin.seed = 3;
  Material texture;
  texture.pattern = Material::Pattern::kTexture;
  texture.albedo = Eigen::Vector3f(0.5f, 0.5f, 0.5f);
  texture.contrast = 0.6f;
  texture.seed = 3;
  for (int c = 0; c < 3; ++c) {
    const double s = channelStd(skin, 0.2, 200, c);
    EXPECT_LT(s, 0.02) << "channel " << c;
    EXPECT_GT(s, 0.0) << "channel " << c << ": no mottling at all";
    EXPECT_GT(channelStd(texture, 0.2, 200, c), 0.1) << "channel " << c;
  }
  Material cloth;
  cloth.pattern = Material::Pattern::kCloth;
  cloth.contrast = 0.2f;
  cloth.feature_size = 0.002f;
  EXPECT_GT(channelStd(cloth, 0.05, 200, 0), 0.01);
}

TEST(Materials, SkinSpotsHaveSoftEdges) {
  Material skin;
  skin.pattern = Material::Pattern::kSkin;
  skin.albedo = Eigen::Vector3f(0.6f, 0.45f, 0.35f);
  skin.contrast = 0.0f;
  Spot spot;
  spot.centre = Eigen::Vector2f(0.1f, 0.1f);
  spot.radius = 0.004f;
  spot.albedo = Eigen::Vector3f(0.2f, 0.1f, 0.05f);
  skin.spots.push_back(spot);
  EXPECT_NEAR((albedoAt(skin, spot.centre) - spot.albedo).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((albedoAt(skin, Eigen::Vector2f(0.2f, 0.1f)) - skin.albedo).norm(), 0.0f, 1e-6f);
  // At the nominal radius: half-way between the skin and the spot.
  const Eigen::Vector3f edge = albedoAt(skin, spot.centre + Eigen::Vector2f(spot.radius, 0.0f));
  EXPECT_GT(edge.x(), spot.albedo.x() + 0.1f);
  EXPECT_LT(edge.x(), skin.albedo.x() - 0.1f);
}

// ---------------------------------------------------------------------------
// Ground truth and intersect()

TEST(Renderer, QuadDepthPointsAndLabelsAtPixelCentres) {
  Scene scene;
  scene.meshes.push_back(groundQuad(5.0f, 0.0f, flat(0.5f), sim::kLabelPlane));
  const Renderer renderer(scene);
  const double distance = 1.25;
  const CameraModel first = downCamera(Eigen::Vector3d(0.2, -0.1, distance), 80, 60, 60.0);
  const CameraModel second = downCamera(Eigen::Vector3d(0.2, -0.1, distance), 80, 60, 45.0);
  CameraModel turned = first;  // turned by 180 degrees about the vertical
  turned.world_from_camera.linear() =
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix() * first.world_from_camera.linear();
  // Alternating cameras of the same size: nothing of one may leak into the other.
  struct Case {
    int n;
    CameraModel cam;
    double sign;  ///< -1: the turned camera
  };
  for (const Case& c : {Case{1, first, 1.0}, Case{2, first, 1.0}, Case{2, second, 1.0}, Case{2, turned, -1.0},
                        Case{3, first, 1.0}, Case{3, second, 1.0}, Case{1, turned, -1.0}}) {
    const int n = c.n;
    const CameraModel& cam = c.cam;
    const ViewRender v = renderer.render(cam, overhead(), quiet(n));
    ASSERT_EQ(v.image.type(), CV_8UC3);
    ASSERT_EQ(v.depth.type(), CV_32F);
    ASSERT_EQ(v.points.type(), CV_32FC3);
    ASSERT_EQ(v.labels.type(), CV_8U);
    ASSERT_EQ(v.image.size(), cv::Size(80, 60));
    for (int y = 0; y < cam.height; ++y) {
      for (int x = 0; x < cam.width; ++x) {
        ASSERT_NEAR(v.depth.at<float>(y, x), distance, 1e-5) << "supersample " << n << " at " << x << "," << y;
        const cv::Vec3f p = v.points.at<cv::Vec3f>(y, x);
        // Pixel (x, y) sees world (cx - (y - cy) Z / f, cy - (x - cx) Z / f, 0).
        const double ex = 0.2 - c.sign * (y - cam.K(1, 2)) * distance / cam.K(1, 1);
        const double ey = -0.1 - c.sign * (x - cam.K(0, 2)) * distance / cam.K(0, 0);
        ASSERT_NEAR(p[0], ex, 1e-5);
        ASSERT_NEAR(p[1], ey, 1e-5);
        ASSERT_NEAR(p[2], 0.0, 1e-5);
        ASSERT_EQ(v.labels.at<std::uint8_t>(y, x), sim::kLabelPlane);
      }
    }
  }
}

TEST(Renderer, IntersectReturnsDistanceNormalLabelAndMesh) {
  Scene scene;
  scene.meshes.push_back(groundQuad(1.0f, 0.0f, flat(0.5f), sim::kLabelTable));
  scene.meshes.push_back(makeBox("box", Eigen::Vector3f(2.0f, -0.5f, 0.0f), Eigen::Vector3f(3.0f, 0.5f, 1.0f),
                                 flat(0.5f), sim::kLabelBoxFace, sim::kLabelBoxFace));
  const Renderer renderer(scene);
  Hit hit;
  ASSERT_TRUE(renderer.intersect(Eigen::Vector3d(0.1, 0.2, 2.0), Eigen::Vector3d(0.0, 0.0, -3.0), &hit));
  EXPECT_NEAR(hit.distance, 2.0, 1e-6);
  EXPECT_NEAR((hit.point - Eigen::Vector3d(0.1, 0.2, 0.0)).norm(), 0.0, 1e-6);
  EXPECT_NEAR((hit.normal - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-6);
  EXPECT_EQ(hit.label, sim::kLabelTable);
  EXPECT_EQ(hit.mesh, 0);
  // From below: the normal faces the ray's origin.
  ASSERT_TRUE(renderer.intersect(Eigen::Vector3d(0.1, 0.2, -0.5), Eigen::Vector3d(0.0, 0.0, 1.0), &hit));
  EXPECT_NEAR(hit.distance, 0.5, 1e-6);
  EXPECT_NEAR((hit.normal - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-6);
  // A slanted ray onto the box's +x face.
  const Eigen::Vector3d dir = Eigen::Vector3d(-1.0, 0.0, -0.25).normalized();
  ASSERT_TRUE(renderer.intersect(Eigen::Vector3d(4.0, 0.1, 0.75), dir, &hit));
  EXPECT_NEAR(hit.distance, 1.0 / dir.x() * -1.0, 1e-6);
  EXPECT_NEAR(hit.point.x(), 3.0, 1e-6);
  EXPECT_NEAR((hit.normal - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-6);
  EXPECT_EQ(hit.label, sim::kLabelBoxFace + 1);
  EXPECT_EQ(hit.mesh, 1);
  // Misses.
  EXPECT_FALSE(renderer.intersect(Eigen::Vector3d(0.0, 0.0, 2.0), Eigen::Vector3d(0.0, 0.0, 1.0), &hit));
  EXPECT_FALSE(renderer.intersect(Eigen::Vector3d(0.0, 5.0, 2.0), Eigen::Vector3d(0.0, 0.0, -1.0), &hit));
  EXPECT_THROW(renderer.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), &hit), std::invalid_argument);
}

TEST(Renderer, MissesGiveBackgroundNanDepthAndLabelZero) {
  Scene scene;
  scene.background = Eigen::Vector3f(0.06f, 0.2f, 0.5f);
  scene.meshes.push_back(groundQuad(0.1f, 0.0f, flat(0.9f), sim::kLabelPlane));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 1.0), 64, 48, 50.0);
  const ViewRender v = renderer.render(cam, overhead(), quiet(2));
  const cv::Point corner(0, 0);
  const cv::Vec3b bg = v.image.at<cv::Vec3b>(corner);
  EXPECT_EQ(bg[2], srgb8(0.06));  // BGR
  EXPECT_EQ(bg[1], srgb8(0.2));
  EXPECT_EQ(bg[0], srgb8(0.5));
  EXPECT_TRUE(std::isnan(v.depth.at<float>(corner)));
  const cv::Vec3f p = v.points.at<cv::Vec3f>(corner);
  EXPECT_TRUE(std::isnan(p[0]) && std::isnan(p[1]) && std::isnan(p[2]));
  EXPECT_EQ(v.labels.at<std::uint8_t>(corner), sim::kLabelBackground);
  // The quad in the middle is hit.
  EXPECT_EQ(v.labels.at<std::uint8_t>(24, 32), sim::kLabelPlane);
  EXPECT_NEAR(v.depth.at<float>(24, 32), 1.0, 1e-5);

  // An empty scene: everything is background.
  const Renderer empty{Scene{}};
  const ViewRender e = empty.render(cam, overhead(), quiet(1));
  EXPECT_EQ(cv::countNonZero(e.labels), 0);
  EXPECT_EQ(cv::countNonZero(e.depth == e.depth), 0);  // all NaN
  const Scene defaults;
  EXPECT_EQ(e.image.at<cv::Vec3b>(10, 10)[2], srgb8(defaults.background.x()));
}

// ---------------------------------------------------------------------------
// Shading

TEST(Renderer, BoxFaceLabelsAndShadow) {
  Scene scene;
  scene.meshes.push_back(groundQuad(2.0f, 0.0f, flat(0.6f), sim::kLabelTable));
  scene.meshes.push_back(makeBox("box", Eigen::Vector3f(-0.1f, -0.1f, 0.0f), Eigen::Vector3f(0.1f, 0.1f, 0.2f),
                                 flat(0.6f), sim::kLabelBoxFace, sim::kLabelBoxFace));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(-0.8, 0.0, 2.0), 320, 320, 200.0);
  Lighting light;
  light.direction_to_light = Eigen::Vector3f(-1.0f, 0.0f, 1.0f).normalized();  // shadow toward +x
  light.intensity = 0.8f;
  light.ambient = 0.2f;
  RenderOptions options = quiet(2);
  options.shadows = true;
  const ViewRender lit = renderer.render(cam, light, options);
  options.shadows = false;
  const ViewRender unshadowed = renderer.render(cam, light, options);

  const cv::Point top = pixelOf(cam, Eigen::Vector3d(0.0, 0.0, 0.2));
  const cv::Point minus_x = pixelOf(cam, Eigen::Vector3d(-0.1, 0.0, 0.1));
  const cv::Point table = pixelOf(cam, Eigen::Vector3d(-0.5, 0.5, 0.0));
  const cv::Point in_shadow = pixelOf(cam, Eigen::Vector3d(0.22, 0.0, 0.0));
  const cv::Point in_light = pixelOf(cam, Eigen::Vector3d(0.22, 0.4, 0.0));
  EXPECT_EQ(lit.labels.at<std::uint8_t>(top), sim::kLabelBoxFace + 5);
  EXPECT_EQ(lit.labels.at<std::uint8_t>(minus_x), sim::kLabelBoxFace + 0);
  EXPECT_EQ(lit.labels.at<std::uint8_t>(table), sim::kLabelTable);
  EXPECT_EQ(lit.labels.at<std::uint8_t>(in_shadow), sim::kLabelTable);
  EXPECT_EQ(lit.labels.at<std::uint8_t>(in_light), sim::kLabelTable);
  EXPECT_NEAR(lit.depth.at<float>(top), 1.8, 1e-5);

  EXPECT_LT(grey(lit.image, in_shadow) + 40.0, grey(lit.image, in_light));
  EXPECT_EQ(grey(unshadowed.image, in_shadow), grey(unshadowed.image, in_light));
  EXPECT_EQ(grey(lit.image, in_light), grey(unshadowed.image, in_light));  // no shadow acne
  // Shadows only ever darken.
  cv::Mat darker = lit.image > unshadowed.image;
  EXPECT_EQ(cv::countNonZero(darker.reshape(1)), 0);
  // The shadowed and lit table values match the shading model.
  const float ambient_only = 0.2f * 0.6f;
  const float full = 0.6f * (0.2f + 0.8f * std::sqrt(0.5f));
  EXPECT_NEAR(grey(lit.image, in_shadow), srgb8(ambient_only), 1.0);
  EXPECT_NEAR(grey(lit.image, in_light), srgb8(full), 1.0);
}

TEST(Renderer, SurfacesFacingTheLightAreBrighter) {
  // Two roofs: one tilted toward world +y (image left), one toward -y.
  Scene scene;
  Mesh a = groundQuad(0.2f, 0.0f, flat(0.5f), sim::kLabelPlane);
  Mesh b = a;
  const Eigen::Matrix3f tilt_left = Eigen::AngleAxisf(-0.5f, Eigen::Vector3f::UnitX()).matrix();  // normal -> +y
  const Eigen::Matrix3f tilt_right = Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitX()).matrix();
  sim::transform(a, tilt_left, Eigen::Vector3f(0.0f, 0.3f, 0.0f));
  sim::transform(b, tilt_right, Eigen::Vector3f(0.0f, -0.3f, 0.0f));
  ASSERT_GT(a.normals[0].y(), 0.3f);
  ASSERT_LT(b.normals[0].y(), -0.3f);
  scene.meshes.push_back(a);
  scene.meshes.push_back(b);
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 2.0), 160, 120, 120.0);
  const cv::Point pa = pixelOf(cam, Eigen::Vector3d(0.0, 0.3, 0.0));
  const cv::Point pb = pixelOf(cam, Eigen::Vector3d(0.0, -0.3, 0.0));
  ASSERT_LT(pa.x, pb.x);  // +y is the image's left
  const ViewRender left = renderer.render(cam, Lighting::preset(LightPreset::kTopLeft), quiet(1));
  const ViewRender right = renderer.render(cam, Lighting::preset(LightPreset::kTopRight), quiet(1));
  const ViewRender centre = renderer.render(cam, Lighting::preset(LightPreset::kTopCentre), quiet(1));
  EXPECT_GT(grey(left.image, pa), grey(left.image, pb) + 10.0);
  EXPECT_LT(grey(right.image, pa) + 10.0, grey(right.image, pb));
  EXPECT_NEAR(grey(centre.image, pa), grey(centre.image, pb), 1.0);  // symmetric
  EXPECT_GT(grey(left.image, pa), grey(right.image, pa));

  const Lighting presets[3] = {Lighting::preset(LightPreset::kTopLeft), Lighting::preset(LightPreset::kTopCentre),
                               Lighting::preset(LightPreset::kTopRight)};
  for (const Lighting& l : presets) {
    EXPECT_NEAR(l.direction_to_light.norm(), 1.0f, 1e-6f);
    EXPECT_GT(l.direction_to_light.x(), 0.0f);  // toward the head end
    EXPECT_FLOAT_EQ(l.intensity, 0.85f);
    EXPECT_FLOAT_EQ(l.ambient, 0.30f);
  }
  EXPECT_GT(presets[0].direction_to_light.y(), 0.0f);
  EXPECT_FLOAT_EQ(presets[1].direction_to_light.y(), 0.0f);
  EXPECT_LT(presets[2].direction_to_light.y(), 0.0f);

  // Exposure scales the linear radiance.
  RenderOptions bright = quiet(1);
  bright.exposure = 1.5f;
  const ViewRender brighter = renderer.render(cam, Lighting::preset(LightPreset::kTopCentre), bright);
  EXPECT_GT(grey(brighter.image, pa), grey(centre.image, pa) + 10.0);
}

TEST(Renderer, SpecularHighlight) {
  Scene scene;
  Material shiny = flat(0.3f);
  shiny.specular = 0.5f;
  shiny.shininess = 50.0f;
  scene.meshes.push_back(groundQuad(2.0f, 0.0f, shiny, sim::kLabelPlane));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 1.0), 101, 101, 50.0);
  const ViewRender v = renderer.render(cam, overhead(), quiet(1));
  // Light and viewer overhead: the highlight is at the image centre.
  EXPECT_GT(grey(v.image, cv::Point(50, 50)), grey(v.image, cv::Point(5, 5)) + 30.0);
}

// ---------------------------------------------------------------------------
// Sensor noise and supersampling

TEST(Renderer, NoiseIsSeededAndHasTheRequestedSigma) {
  Scene scene;
  scene.meshes.push_back(groundQuad(5.0f, 0.0f, flat(0.25f), sim::kLabelPlane));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 1.0), 200, 150, 150.0);
  const Lighting light = overhead();
  const ViewRender clean1 = renderer.render(cam, light, quiet(1));
  const ViewRender clean2 = renderer.render(cam, light, quiet(1));
  EXPECT_TRUE(sameImage(clean1.image, clean2.image));

  RenderOptions noisy = quiet(1);
  noisy.noise_sigma = 3.0f;
  noisy.noise_seed = 11;
  const ViewRender a = renderer.render(cam, light, noisy);
  const ViewRender b = renderer.render(cam, light, noisy);
  noisy.noise_seed = 12;
  const ViewRender c = renderer.render(cam, light, noisy);
  EXPECT_TRUE(sameImage(a.image, b.image));
  EXPECT_FALSE(sameImage(a.image, c.image));
  EXPECT_FALSE(sameImage(a.image, clean1.image));

  cv::Mat diff;
  cv::subtract(a.image, clean1.image, diff, cv::noArray(), CV_32FC3);
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff.reshape(1), mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.1);
  EXPECT_NEAR(stddev[0], 3.0, 0.2);
  // Ground truth is not affected by the noise.
  EXPECT_EQ(cv::norm(a.depth, clean1.depth, cv::NORM_INF), 0.0);
}

TEST(Renderer, SupersamplingAntiAliasesASlantedEdge) {
  Scene scene;
  scene.background = Eigen::Vector3f::Zero();
  // A half-plane with a slanted edge through the image.
  scene.meshes.push_back(makeQuad("slant", Eigen::Vector3f(-1.0f, -0.13f, 0.0f), Eigen::Vector3f(1.0f, 0.21f, 0.0f),
                                  Eigen::Vector3f(1.0f, 2.0f, 0.0f), Eigen::Vector3f(-1.0f, 2.0f, 0.0f), flat(0.8f),
                                  sim::kLabelPlane));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 1.0), 120, 90, 100.0);
  const ViewRender aliased = renderer.render(cam, overhead(), quiet(1));
  const ViewRender smooth = renderer.render(cam, overhead(), quiet(4));
  std::set<int> values1, values4;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      values1.insert(aliased.image.at<cv::Vec3b>(y, x)[1]);
      values4.insert(smooth.image.at<cv::Vec3b>(y, x)[1]);
    }
  }
  EXPECT_EQ(values1.size(), 2u);
  EXPECT_GE(values4.size(), 8u);
  const int lo = *values1.begin(), hi = *values1.rbegin();
  int intermediate = 0;
  for (int v : values4) intermediate += (v > lo && v < hi) ? 1 : 0;
  EXPECT_GE(intermediate, 6);
  // Away from the edge the supersampled image equals the aliased one.
  EXPECT_EQ(smooth.image.at<cv::Vec3b>(0, 0), aliased.image.at<cv::Vec3b>(0, 0));
  EXPECT_EQ(smooth.image.at<cv::Vec3b>(89, 119), aliased.image.at<cv::Vec3b>(89, 119));
  // Ground truth stays at the pixel centres: identical labels either way.
  EXPECT_EQ(cv::countNonZero(aliased.labels != smooth.labels), 0);
}

// ---------------------------------------------------------------------------
// Validation

Mesh triangleMesh(const std::string& name) {
  Mesh m;
  m.name = name;
  m.vertices = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 1, 0)};
  m.triangles = {Eigen::Vector3i(0, 1, 2)};
  return m;
}

void expectInvalidMesh(const Mesh& mesh) {
  Scene scene;
  scene.meshes.push_back(triangleMesh("fine"));
  scene.meshes.push_back(mesh);
  try {
    const Renderer renderer(scene);
    ADD_FAILURE() << "mesh '" << mesh.name << "' was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(mesh.name), std::string::npos) << e.what();
  }
}

TEST(Renderer, RejectsMalformedMeshes) {
  Scene ok;
  ok.meshes.push_back(triangleMesh("ok"));
  EXPECT_NO_THROW(Renderer renderer(ok));
  Mesh m = triangleMesh("index_out_of_range");
  m.triangles.emplace_back(0, 1, 3);
  expectInvalidMesh(m);
  m = triangleMesh("negative_index");
  m.triangles[0] = Eigen::Vector3i(-1, 1, 2);
  expectInvalidMesh(m);
  m = triangleMesh("nan_vertex");
  m.vertices[1].y() = std::numeric_limits<float>::quiet_NaN();
  expectInvalidMesh(m);
  m = triangleMesh("inf_vertex");
  m.vertices[2].z() = std::numeric_limits<float>::infinity();
  expectInvalidMesh(m);
  m = triangleMesh("normals_size");
  m.normals = {Eigen::Vector3f::UnitZ()};
  expectInvalidMesh(m);
  m = triangleMesh("uv_size");
  m.uv = {Eigen::Vector2f::Zero(), Eigen::Vector2f::Zero()};
  expectInvalidMesh(m);
  m = triangleMesh("labels_size");
  m.triangle_labels = {1, 2};
  expectInvalidMesh(m);
}

TEST(Renderer, RejectsInvalidOptions) {
  Scene scene;
  scene.meshes.push_back(groundQuad(1.0f, 0.0f, flat(0.5f), sim::kLabelPlane));
  const Renderer renderer(scene);
  const CameraModel cam = downCamera(Eigen::Vector3d(0.0, 0.0, 1.0), 16, 12, 10.0);
  const Lighting light = overhead();
  auto expectThrow = [&](RenderOptions o, const char* what) {
    EXPECT_THROW(renderer.render(cam, light, o), std::invalid_argument) << what;
  };
  RenderOptions o = quiet(1);
  o.supersample = 0;
  expectThrow(o, "supersample 0");
  o.supersample = 9;
  expectThrow(o, "supersample 9");
  o = quiet(1);
  o.noise_sigma = -1.0f;
  expectThrow(o, "negative sigma");
  o.noise_sigma = std::numeric_limits<float>::quiet_NaN();
  expectThrow(o, "NaN sigma");
  o = quiet(1);
  o.exposure = 0.0f;
  expectThrow(o, "zero exposure");
  o.exposure = -2.0f;
  expectThrow(o, "negative exposure");
  o = quiet(8);
  EXPECT_NO_THROW(renderer.render(cam, light, o));
  Lighting dark = light;
  dark.direction_to_light.setZero();
  EXPECT_THROW(renderer.render(cam, dark, quiet(1)), std::invalid_argument);
  CameraModel empty = cam;
  empty.width = 0;
  EXPECT_THROW(renderer.render(empty, light, quiet(1)), std::invalid_argument);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
