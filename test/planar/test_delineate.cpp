// Delineation on a synthetic textured cube (exact faces): a facet grows from
// a small polygon to its whole face, a facet on a wrong plane is dropped, the
// feature points of a face no facet covers propose its plane, and the black
// (untextured) background is never claimed.
#include <gtest/gtest.h>

#include <cmath>

#include "massage_cell/planar/delineate.h"
#include "synthetic_cube.h"

namespace mp = massage_cell::planar;
using mp::test::facePlane;
using mp::test::makeSyntheticCube;

namespace {

mp::DelineateParams on() {
  mp::DelineateParams p;
  p.enabled = true;
  return p;
}

/// A facet on a face, its polygon the face's square shrunk about its centre to `fraction`.
mp::Facet faceFacet(const mp::test::CubeFace& face, double fraction, const mp::Plane& plane) {
  mp::Facet f;
  f.plane = plane;
  const Eigen::Vector3d c = face.corner + 0.5 * face.ex + 0.5 * face.ey;
  const double h = 0.5 * fraction;
  std::vector<Eigen::Vector3d> square = {c - h * face.ex - h * face.ey, c + h * face.ex - h * face.ey,
                                         c + h * face.ex + h * face.ey, c - h * face.ex + h * face.ey};
  // Onto the facet's plane along the face normal (a tilted plane gets a tilted square).
  for (Eigen::Vector3d& X : square) X -= plane.distance(X) / plane.n.dot(face.normal) * face.normal;
  if ((square[1] - square[0]).cross(square[2] - square[1]).dot(plane.n) < 0.0)
    std::reverse(square.begin(), square.end());
  f.polygons = {square};
  return f;
}

/// Pixels of a view inside the projections of the polygons.
cv::Mat polygonsMask(const mp::View& view, const std::vector<std::vector<Eigen::Vector3d>>& polygons) {
  cv::Mat mask = cv::Mat::zeros(view.image.size(), CV_8U);
  for (const auto& polygon : polygons) {
    std::vector<cv::Point> pts;
    for (const Eigen::Vector3d& X : polygon) {
      Eigen::Vector2d p;
      EXPECT_TRUE(mp::project(view.P, X, &p));
      pts.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
    cv::fillConvexPoly(mask, pts, 255);
  }
  return mask;
}

cv::Mat faceMask(const mp::View& view, const mp::test::CubeFace& face) {
  return polygonsMask(view,
                      {{face.corner, face.corner + face.ex, face.corner + face.ex + face.ey, face.corner + face.ey}});
}

/// Share of the face covered by the facet, and share of the facet outside the face, in view v.
std::pair<double, double> coverage(const mp::View& view, const mp::Facet& facet, const mp::test::CubeFace& face) {
  const cv::Mat f = polygonsMask(view, facet.polygons), truth = faceMask(view, face);
  const double covered = cv::countNonZero(f & truth), outside = cv::countNonZero(f & ~truth);
  return {covered / cv::countNonZero(truth), outside / std::max(1, cv::countNonZero(f))};
}

mp::Plane tilted(const mp::test::CubeFace& face, double degrees) {
  const Eigen::Vector3d c = face.corner + 0.5 * face.ex + 0.5 * face.ey;
  mp::Plane p;
  p.n = Eigen::AngleAxisd(degrees * M_PI / 180.0, face.ex.normalized()) * face.normal;
  p.d = -p.n.dot(c);
  return p;
}

}  // namespace

TEST(Delineate, ASmallFacetGrowsToItsWholeFace) {
  const auto cube = makeSyntheticCube();
  mp::PlanarModel model;
  for (const auto& face : cube.faces) model.facets.push_back(faceFacet(face, 0.25, facePlane(face)));
  mp::DelineateStats stats;
  const mp::PlanarModel out = mp::delineate(cube.views, {}, model, on(), &stats);
  ASSERT_EQ(out.facets.size(), 3u);
  EXPECT_EQ(stats.delineated, 3);
  EXPECT_EQ(stats.dropped, 0);
  for (std::size_t k = 0; k < 3; ++k) {
    for (const mp::View& view : cube.views) {
      const auto [covered, outside] = coverage(view, out.facets[k], cube.faces[k]);
      EXPECT_GE(covered, 0.85) << "face " << k << " in " << view.name;
      // Up to half a 9 px window over the black background (see facetRegion).
      EXPECT_LE(outside, 0.12) << "face " << k << " in " << view.name;
    }
    EXPECT_LT(out.facets[k].plane.angleTo(facePlane(cube.faces[k])), 1e-9) << "the plane is kept as it was";
  }
}

TEST(Delineate, AFacetOnAWrongPlaneIsDropped) {
  const auto cube = makeSyntheticCube();
  mp::PlanarModel model;
  for (const auto& face : cube.faces) model.facets.push_back(faceFacet(face, 0.6, facePlane(face)));
  model.facets.push_back(faceFacet(cube.faces[2], 0.6, tilted(cube.faces[2], 15.0)));
  mp::DelineateStats stats;
  const mp::PlanarModel out = mp::delineate(cube.views, {}, model, on(), &stats);
  EXPECT_EQ(stats.dropped, 1);
  ASSERT_EQ(out.facets.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) EXPECT_LT(out.facets[k].plane.angleTo(facePlane(cube.faces[k])), 1e-9);
}

TEST(Delineate, TheBlackBackgroundIsUntexturedAndTheFacesAreLabelled) {
  const auto cube = makeSyntheticCube();
  mp::PlanarModel model;
  for (const auto& face : cube.faces) model.facets.push_back(faceFacet(face, 0.5, facePlane(face)));
  const cv::Mat labels = mp::labelPixels(cube.views, 0, model, on());
  ASSERT_EQ(labels.type(), CV_32S);
  EXPECT_EQ(labels.at<int>(5, 5), -2) << "the corner of the image is black";
  for (std::size_t k = 0; k < 3; ++k) {
    const cv::Mat truth = faceMask(cube.views[0], cube.faces[k]);
    cv::Mat inner;
    cv::erode(truth, inner, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(15, 15)));
    const double mine = cv::countNonZero(inner & (labels == static_cast<int>(k)));
    EXPECT_GE(mine / cv::countNonZero(inner), 0.9) << "face " << k;
  }
}

TEST(Delineate, TheFeaturePointsOfAFaceWithoutFacetProposeItsPlane) {
  const auto cube = makeSyntheticCube();
  mp::PlanarModel model;  // the +x and +y faces only
  for (std::size_t k = 0; k < 2; ++k) model.facets.push_back(faceFacet(cube.faces[k], 0.8, facePlane(cube.faces[k])));
  const mp::DelineateParams params = on();
  const cv::Mat labels = mp::labelPixels(cube.views, 0, model, params);
  const std::vector<mp::Facet> extra = mp::pointPlanes(cube.views, 0, cube.points, model, labels, params);
  ASSERT_FALSE(extra.empty());
  EXPECT_LT(extra.front().plane.angleTo(facePlane(cube.faces[2])), 1.0);
  EXPECT_GE(extra.front().support_points, 30) << "most of the top face's 40 points";

  mp::DelineateStats stats;
  const mp::PlanarModel out = mp::delineate(cube.views, cube.points, model, params, &stats);
  EXPECT_GE(stats.point_planes, 1);
  bool top = false;
  for (const mp::Facet& f : out.facets) {
    if (f.plane.angleTo(facePlane(cube.faces[2])) < 1.0 && coverage(cube.views[0], f, cube.faces[2]).first >= 0.8)
      top = true;
  }
  EXPECT_TRUE(top) << "the top face is delineated from its points' plane";
  EXPECT_EQ(mp::pointPlanes(cube.views, 0, {}, model, labels, params).size(), 0u) << "no points, no planes";
}

TEST(Delineate, DisabledOrEmptyLeavesTheModel) {
  const auto cube = makeSyntheticCube();
  mp::PlanarModel model;
  model.facets.push_back(faceFacet(cube.faces[0], 0.25, facePlane(cube.faces[0])));
  const mp::DelineateParams off;  // the default
  EXPECT_FALSE(off.enabled);
  const mp::PlanarModel same = mp::delineate(cube.views, cube.points, model, off);
  ASSERT_EQ(same.facets.size(), 1u);
  EXPECT_EQ(same.facets[0].polygons, model.facets[0].polygons);
  EXPECT_TRUE(mp::delineate(cube.views, cube.points, mp::PlanarModel{}, on()).facets.empty());
}

TEST(Delineate, BadParametersAreNamed) {
  const auto check = [](auto edit, const std::string& field) {
    mp::DelineateParams p;
    edit(p);
    try {
      p.validate();
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  check([](mp::DelineateParams& p) { p.window = 4; }, "window");
  check([](mp::DelineateParams& p) { p.min_ncc = 1.5; }, "min_ncc");
  check([](mp::DelineateParams& p) { p.min_texture = -1.0; }, "min_texture");
  check([](mp::DelineateParams& p) { p.min_agreeing = 2.0; }, "min_agreeing");
  check([](mp::DelineateParams& p) { p.min_judged = 0; }, "min_judged");
  check([](mp::DelineateParams& p) { p.reach = std::nan(""); }, "reach");
  check([](mp::DelineateParams& p) { p.point_planes = -1; }, "point_planes");
  check([](mp::DelineateParams& p) { p.min_plane_points = 2; }, "min_plane_points");
  check([](mp::DelineateParams& p) { p.coplanar_pixels = 0.0; }, "coplanar_pixels");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
