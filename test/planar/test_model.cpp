// Tests of the piecewise-planar model (model.h): plane fitting and
// construction, angles between planes, the triangle mesh (orientation, area,
// texture coordinates, invalid input), OBJ / PLY files read back, and
// overlays of facets in front of and partly behind a known camera.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "massage_cell/planar/model.h"

namespace planar = massage_cell::planar;

namespace {

// ---------------------------------------------------------------------------
// Helpers

/// Camera at the origin looking along +z (x right, y down), f = 200 px, 320 x 240.
constexpr int kWidth = 320, kHeight = 240;
constexpr double kFocal = 200.0, kCx = 160.0, kCy = 120.0;

planar::Projection camera() {
  Eigen::Matrix3d K;
  K << kFocal, 0, kCx, 0, kFocal, kCy, 0, 0, 1;
  planar::Projection P;
  P << K, Eigen::Vector3d::Zero();
  return P;
}

planar::View greyView(unsigned char value) {
  planar::View view;
  view.name = "grey";
  view.image = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(value));
  view.P = camera();
  return view;
}

/// The unit square on z = 0 with normal +z; its vertices counter-clockwise
/// seen from +z, or clockwise when asked.
planar::Facet unitSquare(bool clockwise = false) {
  planar::Facet facet;
  facet.plane.n = Eigen::Vector3d::UnitZ();
  facet.plane.d = 0.0;
  std::vector<Eigen::Vector3d> square{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  if (clockwise) std::reverse(square.begin(), square.end());
  facet.polygons.push_back(square);
  facet.colour = cv::Vec3b(10, 20, 30);
  return facet;
}

/// A square of side `side` at depth z in front of camera(), facing it.
planar::Facet frontSquare(double side, double z) {
  planar::Facet facet;
  facet.plane.n = -Eigen::Vector3d::UnitZ();
  facet.plane.d = z;
  const double h = side / 2;
  facet.polygons.push_back({{-h, -h, z}, {-h, h, z}, {h, h, z}, {h, -h, z}});
  return facet;
}

Eigen::Vector3d triangleNormal(const planar::TriangleMesh& mesh, const std::array<int, 3>& t) {
  const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>(), b = mesh.vertices[t[1]].cast<double>(),
                        c = mesh.vertices[t[2]].cast<double>();
  return (b - a).cross(c - a);
}

double meshArea(const planar::TriangleMesh& mesh) {
  double sum = 0.0;
  for (const auto& t : mesh.triangles) sum += 0.5 * triangleNormal(mesh, t).norm();
  return sum;
}

/// Expects `f` to throw E with `part` in its message.
template <typename E>
void expectThrowWith(const std::function<void()>& f, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning '" << part << "'";
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

std::vector<std::string> readLines(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

int countPrefix(const std::vector<std::string>& lines, const std::string& prefix) {
  return static_cast<int>(
      std::count_if(lines.begin(), lines.end(), [&](const std::string& l) { return l.rfind(prefix, 0) == 0; }));
}

bool contains(const std::vector<std::string>& lines, const std::string& line) {
  return std::find(lines.begin(), lines.end(), line) != lines.end();
}

/// The numbers after `prefix` on each line starting with it ("vt " -> the texture coordinates).
std::vector<std::vector<double>> numbersAfter(const std::vector<std::string>& lines, const std::string& prefix) {
  std::vector<std::vector<double>> rows;
  for (const auto& line : lines) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::istringstream in(line.substr(prefix.size()));
    rows.emplace_back();
    for (double value; in >> value;) rows.back().push_back(value);
  }
  return rows;
}

/// Per pixel: inside(x, y) says whether the pixel centre is inside the
/// facet's projection. Pixels inside with all neighbours `band` away are
/// expected changed, pixels outside likewise unchanged; the band in between
/// holds the anti-aliased outline. Returns the number of pixels checked
/// inside and outside.
std::pair<int, int> expectOverlay(const cv::Mat& before, const cv::Mat& after,
                                  const std::function<bool(double, double)>& inside, int band = 3) {
  int changed_expected = 0, unchanged_expected = 0, wrong = 0;
  for (int y = 0; y < after.rows; ++y)
    for (int x = 0; x < after.cols; ++x) {
      int n_inside = 0;
      for (int dy = -band; dy <= band; dy += band)
        for (int dx = -band; dx <= band; dx += band) n_inside += inside(x + dx, y + dy) ? 1 : 0;
      const bool same = after.at<cv::Vec3b>(y, x) == before.at<cv::Vec3b>(y, x);
      if (n_inside == 9) {
        ++changed_expected;
        if (same) ++wrong;
      } else if (n_inside == 0) {
        ++unchanged_expected;
        if (!same) ++wrong;
      }
    }
  EXPECT_EQ(wrong, 0);
  return {changed_expected, unchanged_expected};
}

/// A temporary folder removed after the test.
class ModelFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (std::filesystem::temp_directory_path() / "planar_model_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

planar::TriangleMesh texturedSquareMesh() {
  planar::PlanarModel model;
  model.facets.push_back(unitSquare());
  planar::View view = greyView(100);
  view.P.col(3) = view.P.leftCols<3>() * Eigen::Vector3d(0, 0, 5);  // the square 5 units in front of the camera
  return planar::toMesh(model, {view}, 0);
}

}  // namespace

// ---------------------------------------------------------------------------
// Plane

TEST(Plane, FitRecoversNoisyPlane) {
  const Eigen::Vector3d n = Eigen::Vector3d(1, 2, 3).normalized();
  const double d = -2.0;
  const Eigen::Vector3d u = n.unitOrthogonal(), v = n.cross(u);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> spread(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 500; ++i) points.push_back(-d * n + spread(rng) * u + spread(rng) * v + noise(rng) * n);
  planar::Plane fitted;
  ASSERT_TRUE(planar::Plane::fit(points, &fitted));
  planar::Plane truth{n, d};
  EXPECT_LT(fitted.angleTo(truth), 0.5);
  EXPECT_NEAR(fitted.n.norm(), 1.0, 1e-12);
  const double sign = fitted.n.dot(n) > 0 ? 1.0 : -1.0;
  EXPECT_NEAR(sign * fitted.d, d, 0.005);
}

TEST(Plane, FitRejectsTooFewCollinearAndCoincidentPoints) {
  planar::Plane plane;
  EXPECT_FALSE(planar::Plane::fit({}, &plane));
  EXPECT_FALSE(planar::Plane::fit({{0, 0, 0}, {1, 0, 0}}, &plane));
  EXPECT_FALSE(planar::Plane::fit({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, &plane));
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 20; ++i) line.push_back(Eigen::Vector3d(1, 2, 3) + i * Eigen::Vector3d(0.3, -0.2, 0.5));
  EXPECT_FALSE(planar::Plane::fit(line, &plane));
  line.push_back(Eigen::Vector3d(1, 2, 3) + Eigen::Vector3d(0, 0.5, 0.2));  // one point off the line: a plane
  EXPECT_TRUE(planar::Plane::fit(line, &plane));
  EXPECT_FALSE(planar::Plane::fit({{0, 0, 0}, {1, 0, 0}, {NAN, 0, 1}}, &plane));
}

TEST(Plane, FitOfThreePointsIsExact) {
  planar::Plane plane;
  ASSERT_TRUE(planar::Plane::fit({{0, 0, 2}, {1, 0, 2}, {0, 1, 2}}, &plane));
  EXPECT_NEAR(std::abs(plane.n.z()), 1.0, 1e-12);
  EXPECT_NEAR(plane.distance({5, -3, 2}), 0.0, 1e-12);
}

TEST(Plane, ThroughThreePoints) {
  planar::Plane plane;
  ASSERT_TRUE(planar::Plane::through({0, 0, 1}, {1, 0, 1}, {0, 1, 1}, &plane));
  EXPECT_NEAR((plane.n - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);  // right-hand rule
  EXPECT_NEAR(plane.d, -1.0, 1e-12);
  // Collinearity is relative to the points' spread: a tiny triangle is fine.
  EXPECT_TRUE(planar::Plane::through({0, 0, 0}, {1e-6, 0, 0}, {0, 1e-6, 0}, &plane));
  EXPECT_FALSE(planar::Plane::through({0, 0, 0}, {1, 1, 1}, {3, 3, 3}, &plane));
  EXPECT_FALSE(planar::Plane::through({0, 0, 0}, {1, 0, 0}, {2, 1e-9, 0}, &plane));
  EXPECT_FALSE(planar::Plane::through({1, 2, 3}, {1, 2, 3}, {0, 1, 0}, &plane));
}

TEST(Plane, AngleBetweenNormalsAsLines) {
  const planar::Plane z{Eigen::Vector3d::UnitZ(), 0.0};
  EXPECT_NEAR(z.angleTo({Eigen::Vector3d::UnitX(), 3.0}), 90.0, 1e-12);
  EXPECT_NEAR(z.angleTo({Eigen::Vector3d::UnitZ(), 5.0}), 0.0, 1e-12);
  EXPECT_NEAR(z.angleTo({-Eigen::Vector3d::UnitZ(), 0.0}), 0.0, 1e-12);
  EXPECT_NEAR(z.angleTo({Eigen::Vector3d(1, 0, -1).normalized(), 0.0}), 45.0, 1e-12);
  EXPECT_NEAR(z.angleTo({Eigen::Vector3d(0, std::sin(1e-7), std::cos(1e-7)), 0.0}), 1e-7 * 180.0 / M_PI, 1e-15);
}

// ---------------------------------------------------------------------------
// Mesh

TEST(Mesh, UnitSquareMakesTwoTrianglesFacingTheNormal) {
  for (bool clockwise : {false, true}) {
    planar::PlanarModel model;
    model.facets.push_back(unitSquare(clockwise));
    EXPECT_NEAR(model.area(), 1.0, 1e-12);
    const planar::TriangleMesh mesh = planar::toMesh(model);
    ASSERT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(mesh.vertices.size(), 4u);  // shared within the polygon
    EXPECT_EQ(mesh.triangle_facet, std::vector<int>({0, 0}));
    EXPECT_TRUE(mesh.uv.empty());
    EXPECT_NEAR(meshArea(mesh), model.area(), 1e-6);
    for (const auto& t : mesh.triangles) EXPECT_GT(triangleNormal(mesh, t).dot(Eigen::Vector3d::UnitZ()), 0.0);
    ASSERT_EQ(mesh.colours.size(), 4u);
    for (const auto& c : mesh.colours) EXPECT_EQ(c, cv::Vec3b(10, 20, 30));
  }
}

TEST(Mesh, TiltedHexagonsOfTwoFacetsKeepAreaAndOrientation) {
  // Regular hexagons of circumradius r on two tilted planes, given in either order.
  const double r = 0.7, expected = 1.5 * std::sqrt(3.0) * r * r;
  planar::PlanarModel model;
  const Eigen::Vector3d normals[] = {Eigen::Vector3d(1, 2, 3).normalized(), Eigen::Vector3d(-2, 0, 1).normalized()};
  for (const Eigen::Vector3d& normal : normals) {
    planar::Facet facet;
    facet.plane.n = normal;
    facet.plane.d = -1.0;
    const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
    std::vector<Eigen::Vector3d> hexagon;
    for (int k = 0; k < 6; ++k)
      hexagon.push_back(normal + r * std::cos(k * M_PI / 3) * u + r * std::sin(k * M_PI / 3) * v);
    if (model.facets.size() == 1) std::reverse(hexagon.begin(), hexagon.end());
    facet.polygons.push_back(hexagon);
    model.facets.push_back(facet);
  }
  EXPECT_NEAR(model.area(), 2 * expected, 1e-9);
  const planar::TriangleMesh mesh = planar::toMesh(model);
  ASSERT_EQ(mesh.triangles.size(), 8u);
  EXPECT_EQ(mesh.vertices.size(), 12u);
  EXPECT_NEAR(meshArea(mesh), model.area(), 1e-5);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    EXPECT_EQ(mesh.triangle_facet[t], t < 4 ? 0 : 1);
    EXPECT_GT(triangleNormal(mesh, mesh.triangles[t]).dot(model.facets[mesh.triangle_facet[t]].plane.n), 0.0);
  }
}

TEST(Mesh, TextureCoordinatesFromAKnownCamera) {
  planar::PlanarModel model;
  model.facets.push_back(frontSquare(1.0, 2.0));
  const planar::View view = greyView(100);
  const planar::TriangleMesh mesh = planar::toMesh(model, {view}, 0);
  ASSERT_EQ(mesh.uv.size(), mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3f& X = mesh.vertices[i];
    const double x = kFocal * X.x() / X.z() + kCx, y = kFocal * X.y() / X.z() + kCy;
    EXPECT_NEAR(mesh.uv[i].x(), (x + 0.5) / kWidth, 1e-6);
    EXPECT_NEAR(mesh.uv[i].y(), 1.0 - (y + 0.5) / kHeight, 1e-6);
  }
  // The corner (0.5, 0.5, 2) is pixel (210, 170).
  const auto corner = std::find(mesh.vertices.begin(), mesh.vertices.end(), Eigen::Vector3f(0.5f, 0.5f, 2.0f));
  ASSERT_NE(corner, mesh.vertices.end());
  const Eigen::Vector2f uv = mesh.uv[static_cast<std::size_t>(corner - mesh.vertices.begin())];
  EXPECT_NEAR(uv.x(), 210.5 / 320.0, 1e-6);
  EXPECT_NEAR(uv.y(), 1.0 - 170.5 / 240.0, 1e-6);
  // A facet behind the camera gets (0, 0).
  model.facets[0] = frontSquare(1.0, -2.0);
  for (const auto& t : planar::toMesh(model, {view}, 0).uv) EXPECT_EQ(t, Eigen::Vector2f::Zero());
}

TEST(Mesh, InvalidInputThrows) {
  planar::PlanarModel model;
  model.facets.push_back(unitSquare());
  const std::vector<planar::View> one{greyView(1)};
  EXPECT_NO_THROW(planar::toMesh(model, one, -1));
  expectThrowWith<std::invalid_argument>([&] { planar::toMesh(model, one, 1); }, "texture_view 1");
  expectThrowWith<std::invalid_argument>([&] { planar::toMesh(model, {}, 0); }, "texture_view 0");
  std::vector<planar::View> blank{greyView(1)};
  blank[0].image.release();
  expectThrowWith<std::invalid_argument>([&] { planar::toMesh(model, blank, 0); }, "no image");
  model.facets.push_back(unitSquare());
  model.facets[1].polygons.push_back({{0, 0, 0}, {1, 0, 0}});
  expectThrowWith<std::invalid_argument>([&] { planar::toMesh(model); }, "facet 1 polygon 1 has 2 vertices");
  model.facets[1].polygons[1].push_back({0, NAN, 0});
  expectThrowWith<std::invalid_argument>([&] { planar::toMesh(model); }, "facet 1 polygon 1 has a non-finite");
}

// ---------------------------------------------------------------------------
// Files

TEST_F(ModelFiles, ObjRoundTrip) {
  const planar::TriangleMesh mesh = texturedSquareMesh();
  ASSERT_EQ(mesh.uv.size(), 4u);
  const std::string path = dir_ + "/model.obj";
  planar::writeObj(mesh, path, "texture.png");
  const auto lines = readLines(path);
  EXPECT_EQ(countPrefix(lines, "v "), 4);
  EXPECT_EQ(countPrefix(lines, "vt "), 4);
  EXPECT_EQ(countPrefix(lines, "f "), 2);
  EXPECT_TRUE(contains(lines, "v 1 0 0"));
  EXPECT_TRUE(contains(lines, "f 1/1 2/2 3/3"));
  EXPECT_TRUE(contains(lines, "mtllib model.mtl"));
  EXPECT_TRUE(contains(readLines(dir_ + "/model.mtl"), "map_Kd texture.png"));
  // The vertex (1, 0, 0) is the second; its pixel is (200, 120).
  const auto v = numbersAfter(lines, "v "), vt = numbersAfter(lines, "vt ");
  ASSERT_EQ(vt.size(), 4u);
  EXPECT_EQ(v[1], std::vector<double>({1, 0, 0}));
  ASSERT_EQ(vt[1].size(), 2u);
  EXPECT_NEAR(vt[1][0], 200.5 / 320, 1e-6);
  EXPECT_NEAR(vt[1][1], 1 - 120.5 / 240, 1e-6);
}

TEST_F(ModelFiles, ObjWithoutTextureHasNoMaterial) {
  planar::PlanarModel model;
  model.facets.push_back(unitSquare());
  const std::string path = dir_ + "/plain.obj";
  planar::writeObj(planar::toMesh(model), path, "texture.png");
  const auto lines = readLines(path);
  EXPECT_EQ(countPrefix(lines, "vt "), 0);
  EXPECT_EQ(countPrefix(lines, "mtllib"), 0);
  EXPECT_TRUE(contains(lines, "f 1 2 3"));
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/plain.mtl"));
}

TEST_F(ModelFiles, PlyRoundTripWithRgbColours) {
  planar::PlanarModel model;
  model.facets.push_back(unitSquare());  // colour BGR (10, 20, 30)
  const std::string path = dir_ + "/model.ply";
  planar::writePly(planar::toMesh(model), path);
  const auto lines = readLines(path);
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines[0], "ply");
  EXPECT_TRUE(contains(lines, "format ascii 1.0"));
  EXPECT_TRUE(contains(lines, "element vertex 4"));
  EXPECT_TRUE(contains(lines, "element face 2"));
  EXPECT_TRUE(contains(lines, "property uchar red"));
  const auto body = std::find(lines.begin(), lines.end(), "end_header");
  ASSERT_NE(body, lines.end());
  const std::vector<std::string> data(body + 1, lines.end());
  ASSERT_EQ(data.size(), 6u);
  EXPECT_TRUE(contains(data, "1 0 0 30 20 10"));
  EXPECT_EQ(countPrefix(data, "3 "), 2);
  EXPECT_TRUE(contains(data, "3 0 1 2"));
}

TEST_F(ModelFiles, UnwritablePathThrowsNamingIt) {
  const planar::TriangleMesh mesh = texturedSquareMesh();
  const std::string obj = dir_ + "/no_such_folder/model.obj", ply = dir_ + "/no_such_folder/model.ply";
  expectThrowWith<std::runtime_error>([&] { planar::writeObj(mesh, obj, "texture.png"); }, obj);
  expectThrowWith<std::runtime_error>([&] { planar::writePly(mesh, ply); }, ply);
}

TEST_F(ModelFiles, InconsistentMeshThrows) {
  planar::TriangleMesh mesh = texturedSquareMesh();
  mesh.triangles.push_back({0, 1, 4});
  expectThrowWith<std::invalid_argument>([&] { planar::writeObj(mesh, dir_ + "/bad.obj"); }, "vertex 4");
  mesh.triangles.pop_back();
  mesh.colours.pop_back();
  expectThrowWith<std::invalid_argument>([&] { planar::writePly(mesh, dir_ + "/bad.ply"); }, "3 colours");
}

// ---------------------------------------------------------------------------
// Overlay

TEST(Overlay, FacetInFrontColoursItsProjectionOnly) {
  // The square of side 1 at depth 2 projects onto [110, 210] x [70, 170].
  planar::PlanarModel model;
  model.facets.push_back(frontSquare(1.0, 2.0));
  const planar::View view = greyView(90);
  const cv::Mat before = view.image.clone();
  const cv::Mat overlay = planar::drawOverlay(view, model);
  ASSERT_EQ(overlay.type(), CV_8UC3);
  ASSERT_EQ(overlay.size(), view.image.size());
  EXPECT_EQ(cv::norm(view.image, before, cv::NORM_INF), 0.0);  // the view is not drawn on
  cv::Mat grey_bgr(kHeight, kWidth, CV_8UC3, cv::Scalar(90, 90, 90));
  const auto counts =
      expectOverlay(grey_bgr, overlay, [](double x, double y) { return x >= 110 && x <= 210 && y >= 70 && y <= 170; });
  EXPECT_GT(counts.first, 80 * 80);
  EXPECT_GT(counts.second, kWidth * kHeight - 120 * 120);
}

TEST(Overlay, FacetPartlyBehindTheCameraColoursItsVisiblePart) {
  // A floor y = 0.5 below the camera, x in [-1, 1], z from -1 (behind) to 3.
  planar::PlanarModel model;
  planar::Facet floor;
  floor.plane.n = -Eigen::Vector3d::UnitY();
  floor.plane.d = 0.5;
  floor.polygons.push_back({{-1, 0.5, -1}, {-1, 0.5, 3}, {1, 0.5, 3}, {1, 0.5, -1}});
  model.facets.push_back(floor);
  const planar::View view = greyView(90);
  cv::Mat overlay;
  ASSERT_NO_THROW(overlay = planar::drawOverlay(view, model));
  // The ray through pixel (x, y) meets the floor at z = 0.5 f / (y - cy).
  const auto on_floor = [](double x, double y) {
    if (y <= kCy) return false;
    const double z = 0.5 * kFocal / (y - kCy), X = (x - kCx) / kFocal * z;
    return z <= 3.0 && std::abs(X) <= 1.0;
  };
  cv::Mat grey_bgr(kHeight, kWidth, CV_8UC3, cv::Scalar(90, 90, 90));
  const auto counts = expectOverlay(grey_bgr, overlay, on_floor);
  EXPECT_GT(counts.first, 5000);
  EXPECT_GT(counts.second, 20000);
}

TEST(Overlay, FacetBehindTheCameraLeavesTheImageUnchanged) {
  planar::PlanarModel model;
  model.facets.push_back(frontSquare(1.0, -2.0));
  const planar::View view = greyView(90);
  const cv::Mat overlay = planar::drawOverlay(view, model);
  EXPECT_EQ(cv::norm(overlay, cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(90, 90, 90)), cv::NORM_INF), 0.0);
}

TEST(Overlay, NearerFacetIsOnTopAndFacetsDifferInColour) {
  // Facet 0 near (depth 2), facet 1 far (depth 4) and larger: the centre shows facet 0.
  planar::PlanarModel model;
  model.facets.push_back(frontSquare(1.0, 2.0));
  model.facets.push_back(frontSquare(4.0, 4.0));
  const planar::View view = greyView(90);
  const cv::Mat both = planar::drawOverlay(view, model);
  planar::PlanarModel near_only;
  near_only.facets.push_back(model.facets[0]);
  const cv::Mat near = planar::drawOverlay(view, near_only);
  const cv::Point inside_near(125, 85), inside_far_only(100, 60);
  EXPECT_EQ(both.at<cv::Vec3b>(inside_near), near.at<cv::Vec3b>(inside_near));
  EXPECT_NE(both.at<cv::Vec3b>(inside_far_only), both.at<cv::Vec3b>(inside_near));
  EXPECT_NE(both.at<cv::Vec3b>(inside_far_only), cv::Vec3b(90, 90, 90));
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
