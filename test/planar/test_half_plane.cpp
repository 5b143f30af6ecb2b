// Half-planes about the edges of a synthetic textured cube (exact edges,
// exact points on the faces): the thesis's feature-point search and
// Baillard's sweep find the faces; extension and merging give the cube's
// three visible faces.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "massage_cell/planar/extend.h"
#include "massage_cell/planar/half_plane.h"
#include "massage_cell/planar/photo_consistency.h"
#include "synthetic_cube.h"

namespace mp = massage_cell::planar;
using mp::test::facePlane;
using mp::test::makeSyntheticCube;

namespace {

/// Faces of the cube that contain both ends of the line.
std::vector<int> facesOfEdge(const mp::test::SyntheticCube& cube, const mp::LineTrack& line) {
  std::vector<int> out;
  for (int k = 0; k < 3; ++k) {
    const mp::Plane p = facePlane(cube.faces[static_cast<std::size_t>(k)]);
    if (std::abs(p.distance(line.a)) < 1e-9 && std::abs(p.distance(line.b)) < 1e-9) out.push_back(k);
  }
  return out;
}

/// Checks every half-plane lies on a face of its edge within max_deg, and
/// returns how many (edge, face) pairs were found.
int checkHalfPlanes(const mp::test::SyntheticCube& cube, const std::vector<mp::HalfPlane>& found, double max_deg) {
  std::set<std::pair<int, int>> pairs;
  for (const mp::HalfPlane& h : found) {
    const auto faces = facesOfEdge(cube, cube.lines[static_cast<std::size_t>(h.line)]);
    int best = -1;
    double best_angle = 180.0;
    for (int k : faces) {
      const double a = h.plane.angleTo(facePlane(cube.faces[static_cast<std::size_t>(k)]));
      if (a < best_angle) {
        best_angle = a;
        best = k;
      }
    }
    EXPECT_LE(best_angle, max_deg) << "line " << h.line << " side " << h.side;
    EXPECT_GE(h.score, 0.65);
    if (best >= 0) pairs.insert({h.line, best});
  }
  EXPECT_EQ(pairs.size(), found.size()) << "one half-plane per (edge, face)";
  return static_cast<int>(pairs.size());
}

}  // namespace

TEST(HalfPlaneGeometry, PlaneAboutLineContainsTheLineAndItsAngle) {
  const Eigen::Vector3d p(0.2, -0.1, 1.0);
  const Eigen::Vector3d d = Eigen::Vector3d(1, 2, -0.5).normalized();
  for (double angle : {0.0, 0.4, 1.3, 2.9}) {
    const mp::Plane plane = mp::planeAboutLine(p, d, angle);
    EXPECT_NEAR(plane.distance(p), 0.0, 1e-12);
    EXPECT_NEAR(plane.distance(p + 3.0 * d), 0.0, 1e-12);
    // A point of the plane off the line has that angle about the line.
    const Eigen::Vector3d off = plane.n.cross(d).normalized();
    for (double s : {0.5, -0.5}) {
      const double a = mp::angleAboutLine(p, d, p + s * off + 0.2 * d);
      EXPECT_NEAR(std::min(std::abs(a - angle), M_PI - std::abs(a - angle)), 0.0, 1e-9);
    }
  }
}

TEST(HalfPlaneScore, TheTrueFacePeaksAndTiltedPlanesScoreLess) {
  const auto cube = makeSyntheticCube();
  const mp::HalfPlaneSearch search(cube.views, cube.points, cube.lines, mp::HalfPlaneParams{});
  // Line 5 is the edge (e, 0, e)-(e, e, e) between the +x and +z faces.
  const int line = 5;
  const int ref = search.referenceView(line);
  ASSERT_GE(ref, 0);
  const mp::LineTrack& L = cube.lines[line];
  const Eigen::Vector3d d = L.direction();
  for (int k : {0, 2}) {
    const mp::Plane face = facePlane(cube.faces[static_cast<std::size_t>(k)]);
    // The side of the line's image on which this face lies scores it best.
    const int side = search.score(line, 1, ref, face) > search.score(line, -1, ref, face) ? 1 : -1;
    const double a = mp::angleAboutLine(L.a, d, L.a + face.n.cross(d));
    const double s0 = search.score(line, side, ref, face);
    EXPECT_GT(s0, 0.95) << "face " << k;
    double previous = s0;
    for (double tilt : {0.05, 0.1, 0.2, 0.35}) {
      const double s = search.score(line, side, ref, mp::planeAboutLine(L.a, d, a + tilt));
      EXPECT_LT(s, previous) << "face " << k << " tilted by " << tilt << " rad";
      previous = s;
    }
    EXPECT_LT(previous, s0 - 0.05) << "face " << k;
    const mp::Plane other = facePlane(cube.faces[static_cast<std::size_t>(2 - k)]);
    EXPECT_LT(search.score(line, side, ref, other), s0 - 0.15) << "the other face's plane on face " << k;
  }
}

TEST(HalfPlaneSearch, FeaturePointsFindEveryVisibleFaceOfEveryEdge) {
  const auto cube = makeSyntheticCube();
  const mp::HalfPlaneSearch search(cube.views, cube.points, cube.lines, mp::HalfPlaneParams{});
  mp::SearchStats stats;
  const auto found = search.byFeaturePoints(&stats);
  // Three inner edges with two faces each, six outline edges with one face
  // (the black background beside them has no texture to verify).
  EXPECT_EQ(checkHalfPlanes(cube, found, 0.2), 12);
  for (const mp::HalfPlane& h : found) EXPECT_GE(h.points.size(), 5u);
  EXPECT_GT(stats.candidates, 0);
  EXPECT_LE(stats.candidates, 18 * 3) << "a few candidates per side, not 180";
}

TEST(HalfPlaneSearch, TheSweepFindsTheSameFacesAtTenTimesTheCandidates) {
  const auto cube = makeSyntheticCube();
  const mp::HalfPlaneSearch search(cube.views, cube.points, cube.lines, mp::HalfPlaneParams{});
  mp::SearchStats sweep, points;
  const auto swept = search.bySweep(&sweep);
  search.byFeaturePoints(&points);
  EXPECT_EQ(checkHalfPlanes(cube, swept, 1.0), 12);
  EXPECT_GE(sweep.candidates, 10 * points.candidates);
}

TEST(HalfPlaneSearch, ATexturelessSetHasNoHalfPlanes) {
  auto cube = makeSyntheticCube();
  for (auto& view : cube.views) view.image.setTo(cv::Scalar::all(128));
  const mp::HalfPlaneSearch search(cube.views, cube.points, cube.lines, mp::HalfPlaneParams{});
  EXPECT_TRUE(search.byFeaturePoints().empty());
  EXPECT_TRUE(search.bySweep().empty());
  EXPECT_DOUBLE_EQ(search.score(5, 1, 0, facePlane(cube.faces[0])), -1.0);
}

TEST(HalfPlaneSearch, BadParametersAreNamed) {
  const auto cube = makeSyntheticCube(2);
  mp::HalfPlaneParams params;
  params.min_ncc = 1.5;
  try {
    mp::HalfPlaneSearch(cube.views, cube.points, cube.lines, params);
    FAIL() << "min_ncc 1.5 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("min_ncc"), std::string::npos) << e.what();
  }
  params = mp::HalfPlaneParams{};
  params.sample_step = std::nan("");
  EXPECT_THROW(mp::HalfPlaneSearch(cube.views, cube.points, cube.lines, params), std::invalid_argument);
  EXPECT_THROW(mp::HalfPlaneSearch({cube.views[0]}, cube.points, cube.lines, mp::HalfPlaneParams{}),
               std::invalid_argument);
}

TEST(ExtendAndMerge, TheCubesThreeFacesAtRightAngles) {
  const auto cube = makeSyntheticCube();
  const mp::HalfPlaneSearch search(cube.views, cube.points, cube.lines, mp::HalfPlaneParams{});
  const auto found = search.byFeaturePoints();
  mp::ExtendStats stats;
  const mp::PlanarModel model =
      mp::extendAndMerge(cube.views, cube.points, cube.lines, found, mp::ExtendParams{}, &stats);
  ASSERT_EQ(model.facets.size(), 3u) << stats.half_planes << " half-planes, " << stats.extended << " extended";
  std::set<int> seen;
  for (const mp::Facet& f : model.facets) {
    int face = -1;
    for (int k = 0; k < 3; ++k) {
      if (f.plane.angleTo(facePlane(cube.faces[static_cast<std::size_t>(k)])) < 0.2) face = k;
    }
    ASSERT_GE(face, 0);
    seen.insert(face);
    double area = 0.0;
    for (const auto& poly : f.polygons) {
      for (const Eigen::Vector3d& X : poly) {
        EXPECT_NEAR(facePlane(cube.faces[static_cast<std::size_t>(face)]).distance(X), 0.0, 1e-3);
      }
      for (std::size_t i = 1; i + 1 < poly.size(); ++i)
        area += 0.5 * (poly[i] - poly[0]).cross(poly[i + 1] - poly[0]).norm();
    }
    EXPECT_NEAR(area, cube.edge * cube.edge, 0.1 * cube.edge * cube.edge) << "face " << face;
  }
  EXPECT_EQ(seen.size(), 3u);
}

TEST(PhotoConsistency, AWholeFaceTellsItsPlaneFromATiltedOne) {
  const auto cube = makeSyntheticCube();
  const mp::PhotoConsistency photo(cube.views);
  const mp::test::CubeFace& face = cube.faces[2];  // +z, seen by every view
  const mp::Plane top = facePlane(face);
  // The face's projection in view 0, sampled on a grid, and its corners.
  std::vector<Eigen::Vector2d> pixels, corners;
  for (double s = 0.05; s <= 0.951; s += 0.03) {
    for (double t = 0.05; t <= 0.951; t += 0.03) {
      Eigen::Vector2d q;
      ASSERT_TRUE(mp::project(cube.views[0].P, face.corner + s * face.ex + t * face.ey, &q));
      pixels.push_back(q);
    }
  }
  for (double s : {0.05, 0.95}) {
    for (double t : {0.05, 0.95}) {
      Eigen::Vector2d q;
      mp::project(cube.views[0].P, face.corner + s * face.ex + t * face.ey, &q);
      corners.push_back(q);
    }
  }
  const auto samples = photo.sample(0, pixels, corners);
  ASSERT_TRUE(samples.textured);
  const double right = photo.score(samples, top);
  EXPECT_GT(right, 0.9);
  // The plane turned by 10 degrees about the face's edge along ey at s = 1.
  const mp::LineTrack& L = cube.lines[5];
  const double a = mp::angleAboutLine(L.a, L.direction(), L.a + top.n.cross(L.direction()));
  for (double tilt : {0.17, -0.17}) {
    EXPECT_LT(photo.score(samples, mp::planeAboutLine(L.a, L.direction(), a + tilt)), right - 0.3) << tilt;
  }
  // Untextured samples cannot be scored.
  auto grey = cube;
  for (auto& view : grey.views) view.image.setTo(cv::Scalar::all(90));
  const mp::PhotoConsistency flat(grey.views);
  EXPECT_FALSE(flat.sample(0, pixels, corners).textured);
  EXPECT_DOUBLE_EQ(flat.score(flat.sample(0, pixels, corners), top), -1.0);
}

TEST(ExtendAndMerge, AHalfPlaneOfAMissingLineIsAnError) {
  const auto cube = makeSyntheticCube(2);
  mp::HalfPlane bogus;
  bogus.line = 99;
  EXPECT_THROW(mp::extendAndMerge(cube.views, cube.points, cube.lines, {bogus}, mp::ExtendParams{}),
               std::invalid_argument);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
