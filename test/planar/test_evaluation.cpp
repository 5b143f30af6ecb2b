// Multi-view sets with exact planes (sim/multiview_set.h) and the scoring of
// planar models (planar/evaluation.h): the rendered planes hold for the
// rendered surface points and P projects them onto their pixels; a model of
// the exact facets scores zero error and full coverage, a tilted facet shows
// in the pair errors, a missing one in the count; the facet index image keeps
// the nearest facet; the Merton College I reference has its facades and roofs.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "massage_cell/planar/evaluation.h"
#include "massage_cell/sim/multiview_set.h"
#include "massage_cell/sim/renderer.h"
#include "merton_data.h"

namespace planar = massage_cell::planar;
namespace sim = massage_cell::sim;

namespace {

using massage_cell::planar::test::mertonFolder;

sim::MultiViewOptions smallOptions() {
  sim::MultiViewOptions o;
  o.views = 3;
  o.width = 320;
  o.height = 240;
  o.fx = 300.0;
  return o;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Rendered once for all tests.
const sim::MultiViewSet& boxesSet() {
  static const sim::MultiViewSet set = [] {
    const auto start = std::chrono::steady_clock::now();
    sim::MultiViewSet s = sim::renderBoxesViews(3, smallOptions());
    std::cout << "renderBoxesViews(3 boxes, 3 views 320x240, supersample 2): " << secondsSince(start) << " s\n";
    return s;
  }();
  return set;
}

int indexOf(const sim::MultiViewSet& set, const std::string& name) {
  for (std::size_t i = 0; i < set.planes.size(); ++i) {
    if (set.planes[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

const sim::TruePlane* findPlane(const sim::MultiViewSet& set, const std::string& name) {
  const int i = indexOf(set, name);
  return i < 0 ? nullptr : &set.planes[static_cast<std::size_t>(i)];
}

std::vector<planar::View> viewsOf(const sim::MultiViewSet& set) {
  std::vector<planar::View> views;
  for (std::size_t i = 0; i < set.images.size(); ++i) {
    views.push_back({"view " + std::to_string(i), set.images[i], set.P[i]});
  }
  return views;
}

/// World point of a pixel from the set's depth and camera.
Eigen::Vector3d backProject(const sim::CameraModel& camera, int x, int y, double depth) {
  return camera.world_from_camera * (camera.K.inverse() * Eigen::Vector3d(x, y, 1.0) * depth);
}

/// Every third pixel (in x and y) of the plane in every view, back-projected.
std::vector<Eigen::Vector3d> planePoints(const sim::MultiViewSet& set, const sim::TruePlane& plane) {
  constexpr int step = 3;
  std::vector<Eigen::Vector3d> points;
  for (std::size_t v = 0; v < set.labels.size(); ++v) {
    for (int y = 0; y < set.labels[v].rows; y += step) {
      for (int x = 0; x < set.labels[v].cols; x += step) {
        if (set.labels[v].at<std::uint8_t>(y, x) != plane.label) continue;
        points.push_back(backProject(set.cameras[v], x, y, set.depth[v].at<float>(y, x)));
      }
    }
  }
  return points;
}

/// The true planes as the evaluation's reference: visibility masks from the
/// labels (or none), points sampled on the visible facets.
std::vector<planar::ReferencePlane> referencesOf(const sim::MultiViewSet& set, bool with_masks) {
  std::vector<planar::ReferencePlane> refs;
  for (const sim::TruePlane& p : set.planes) {
    planar::ReferencePlane r;
    r.name = p.name;
    r.plane.n = p.n;
    r.plane.d = p.d;
    for (std::size_t v = 0; with_masks && v < set.labels.size(); ++v) r.visible.push_back(set.labels[v] == p.label);
    r.points = planePoints(set, p);
    refs.push_back(r);
  }
  return refs;
}

/// One facet per true plane: the scene's triangles of its label on it
/// (whole faces; the nearest-facet rule hides what is covered).
planar::PlanarModel exactModel(const sim::MultiViewSet& set) {
  planar::PlanarModel model;
  for (const sim::TruePlane& p : set.planes) {
    planar::Facet facet;
    facet.plane.n = p.n;
    facet.plane.d = p.d;
    for (const sim::Mesh& mesh : set.scene.meshes) {
      for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        if ((mesh.triangle_labels.empty() ? mesh.label : mesh.triangle_labels[t]) != p.label) continue;
        std::vector<Eigen::Vector3d> triangle;
        for (int k = 0; k < 3; ++k) triangle.push_back(mesh.vertices[mesh.triangles[t][k]].cast<double>());
        const bool on_plane = std::all_of(triangle.begin(), triangle.end(), [&](const Eigen::Vector3d& X) {
          return std::abs(facet.plane.distance(X)) < 1e-5;
        });
        if (on_plane) facet.polygons.push_back(triangle);
      }
    }
    model.facets.push_back(facet);
  }
  return model;
}

/// The facet turned by `degrees` about `axis` (unit, in its plane) through its vertices' centroid.
void tilt(planar::Facet& facet, const Eigen::Vector3d& axis, double degrees) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int count = 0;
  for (const auto& polygon : facet.polygons) {
    for (const Eigen::Vector3d& X : polygon) {
      centre += X;
      ++count;
    }
  }
  centre /= count;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(degrees * M_PI / 180.0, axis).toRotationMatrix();
  for (auto& polygon : facet.polygons) {
    for (Eigen::Vector3d& X : polygon) X = centre + R * (X - centre);
  }
  facet.plane.n = R * facet.plane.n;
  facet.plane.d = -facet.plane.n.dot(centre);
}

}  // namespace

// ---------------------------------------------------------------------------
// Multi-view sets

TEST(MultiViewSet, BoxesViewsHaveTheTableAndTheBoxFaces) {
  const sim::MultiViewSet& set = boxesSet();
  ASSERT_EQ(set.images.size(), 3u);
  ASSERT_EQ(set.cameras.size(), 3u);
  ASSERT_EQ(set.P.size(), 3u);
  ASSERT_EQ(set.labels.size(), 3u);
  ASSERT_EQ(set.depth.size(), 3u);
  for (const cv::Mat& image : set.images) {
    EXPECT_EQ(image.type(), CV_8UC3);
    EXPECT_EQ(image.size(), cv::Size(320, 240));
  }
  const sim::TruePlane* table = findPlane(set, "table");
  ASSERT_NE(table, nullptr) << "the table top is not among the planes";
  EXPECT_EQ(table->label, sim::kLabelTable);
  EXPECT_NEAR(table->n.z(), 1.0, 1e-9);
  EXPECT_NEAR(table->d, 0.0, 1e-9);
  int box_faces = 0;
  for (const sim::TruePlane& p : set.planes) {
    std::cout << "  " << p.name << " (label " << int(p.label) << "): n " << p.n.transpose() << ", d " << p.d << "\n";
    if (p.label >= sim::kLabelBoxFace) ++box_faces;
  }
  EXPECT_GE(box_faces, 6);
  EXPECT_NE(findPlane(set, "box 0 +z"), nullptr);
  EXPECT_GT(set.scene_depth, 0.5 * smallOptions().distance);
  EXPECT_LT(set.scene_depth, 1.5 * smallOptions().distance);
}

TEST(MultiViewSet, PlanesHoldForTheRenderedPointsAndPProjectsThemOntoTheirPixels) {
  const sim::MultiViewSet& set = boxesSet();
  const sim::Renderer renderer(set.scene);
  sim::RenderOptions quick;
  quick.supersample = 1;
  for (std::size_t v = 0; v < set.cameras.size(); ++v) {
    const sim::ViewRender r = renderer.render(set.cameras[v], sim::Lighting(), quick);
    EXPECT_EQ(cv::norm(r.labels, set.labels[v], cv::NORM_INF), 0.0) << "view " << v;
    const Eigen::Vector3d centre = set.cameras[v].centre();
    for (const sim::TruePlane& p : set.planes) {
      int checked = 0;
      for (int y = 0; y < r.labels.rows; ++y) {
        for (int x = 0; x < r.labels.cols; ++x) {
          if (r.labels.at<std::uint8_t>(y, x) != p.label) continue;
          const cv::Vec3f q = r.points.at<cv::Vec3f>(y, x);
          const Eigen::Vector3d X(q[0], q[1], q[2]);
          ASSERT_LT(std::abs(p.n.dot(X) + p.d), 1e-4) << p.name << " view " << v << " pixel " << x << "," << y;
          const Eigen::Vector3d u = set.P[v] * X.homogeneous();
          ASSERT_LT((u.head<2>() / u.z() - Eigen::Vector2d(x, y)).norm(), 0.5) << p.name << " view " << v;
          EXPECT_NEAR(set.depth[v].at<float>(y, x), r.depth.at<float>(y, x), 1e-6);
          ++checked;
        }
      }
      if (checked > 0) {
        EXPECT_GT(p.n.dot(centre) + p.d, 0.0) << p.name << " faces away from camera " << v;
      }
    }
  }
}

TEST(MultiViewSet, BadOptionsAreRejectedByName) {
  const auto message = [](sim::MultiViewOptions o) {
    try {
      sim::renderBoxesViews(1, o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  sim::MultiViewOptions o = smallOptions();
  o.views = 1;
  EXPECT_NE(message(o).find("views"), std::string::npos) << message(o);
  o = smallOptions();
  o.width = 0;
  EXPECT_NE(message(o).find("width"), std::string::npos) << message(o);
  o = smallOptions();
  o.fx = 0.0;
  EXPECT_NE(message(o).find("fx"), std::string::npos) << message(o);
  o = smallOptions();
  o.distance = -1.0;
  EXPECT_NE(message(o).find("distance"), std::string::npos) << message(o);
  EXPECT_THROW(sim::renderCubeViews(0.0, smallOptions()), std::invalid_argument);
}

TEST(MultiViewSet, CubeShowsThreePerpendicularTexturedFacesInEveryView) {
  const auto start = std::chrono::steady_clock::now();
  const sim::MultiViewSet set = sim::renderCubeViews(0.2, smallOptions());
  std::cout << "renderCubeViews(3 views 320x240, supersample 2): " << secondsSince(start) << " s\n";
  ASSERT_EQ(set.planes.size(), 3u);
  for (std::size_t a = 0; a < 3; ++a) {
    for (std::size_t b = a + 1; b < 3; ++b) EXPECT_NEAR(set.planes[a].n.dot(set.planes[b].n), 0.0, 1e-6);
  }
  EXPECT_NE(findPlane(set, "cube +z"), nullptr);
  for (std::size_t v = 0; v < set.images.size(); ++v) {
    cv::Mat grey;
    cv::cvtColor(set.images[v], grey, cv::COLOR_BGR2GRAY);
    for (const sim::TruePlane& p : set.planes) {
      const cv::Mat mask = set.labels[v] == p.label;
      EXPECT_GT(cv::countNonZero(mask), 500) << p.name << " in view " << v;
      cv::Scalar mean, stddev;
      cv::meanStdDev(grey, mean, stddev, mask);
      EXPECT_GT(stddev[0], 10.0) << p.name << " in view " << v << " is not textured";
    }
    const cv::Mat background = set.labels[v] == sim::kLabelBackground;
    EXPECT_LT(cv::mean(grey, background)[0], 5.0) << "background of view " << v << " is not black";
  }
}

// ---------------------------------------------------------------------------
// Facet index image

TEST(FacetIndexImage, NearestFacetWinsAndWhatIsBehindTheCameraIsLeftOut) {
  planar::View view{"synthetic", cv::Mat::zeros(101, 101, CV_8UC3), planar::Projection::Zero()};
  view.P << 100, 0, 50, 0, 0, 100, 50, 0, 0, 0, 1, 0;  // K [I | 0]: z = depth
  const auto square = [](double lo, double hi, double z) {
    planar::Facet f;
    f.plane.n = -Eigen::Vector3d::UnitZ();
    f.plane.d = z;
    f.polygons.push_back({{lo, lo, z}, {lo, hi, z}, {hi, hi, z}, {hi, lo, z}});
    return f;
  };
  planar::PlanarModel model;
  model.facets = {square(0.0, 0.5, 1.0), square(-0.5, 0.5, 2.0), square(-0.5, 0.5, -1.0)};
  // A wall x = -0.3 from behind the camera to z = 3: only its front part is seen.
  planar::Facet wall;
  wall.plane.n = Eigen::Vector3d::UnitX();
  wall.plane.d = 0.3;
  wall.polygons.push_back({{-0.3, -0.1, -2.0}, {-0.3, 0.1, -2.0}, {-0.3, 0.1, 3.0}, {-0.3, -0.1, 3.0}});
  model.facets.push_back(wall);
  const cv::Mat index = planar::facetIndexImage(model, view);
  ASSERT_EQ(index.type(), CV_32S);
  EXPECT_EQ(index.at<int>(62, 62), 1) << "the near square must hide the far one";
  EXPECT_EQ(index.at<int>(95, 95), 1);
  EXPECT_EQ(index.at<int>(37, 37), 2);
  EXPECT_EQ(index.at<int>(30, 60), 2);
  EXPECT_EQ(index.at<int>(5, 5), 0);
  EXPECT_EQ(cv::countNonZero(index == 3), 0) << "a facet behind the camera was drawn";
  // Column 50 - 30 / z of the wall: z = 0.75 at column 10, 1.5 at 30 (before
  // the far square), 2.5 at 38 (behind it).
  EXPECT_EQ(index.at<int>(50, 10), 4) << "the wall's near part is missing";
  EXPECT_EQ(index.at<int>(50, 30), 4);
  EXPECT_EQ(index.at<int>(50, 38), 2) << "the wall shows through the far square";
  // Swapping the squares' order changes nothing but their numbers.
  std::swap(model.facets[0], model.facets[1]);
  const cv::Mat swapped = planar::facetIndexImage(model, view);
  EXPECT_EQ(swapped.at<int>(62, 62), 2);
  EXPECT_EQ(swapped.at<int>(37, 37), 1);
}

// ---------------------------------------------------------------------------
// Scoring

TEST(EvaluateModel, ExactFacetsScoreNoErrorAndFullCoverage) {
  const sim::MultiViewSet& set = boxesSet();
  const std::vector<planar::ReferencePlane> refs = referencesOf(set, true);
  const planar::Evaluation e = planar::evaluateModel(exactModel(set), viewsOf(set), refs, 10.0, 0.01);
  ASSERT_EQ(e.matches.size(), refs.size());
  EXPECT_EQ(e.reconstructed, static_cast<int>(refs.size()));
  for (const planar::PlaneMatch& m : e.matches) {
    EXPECT_EQ(m.facet, m.reference) << refs[m.reference].name;
    EXPECT_NEAR(m.angle_deg, 0.0, 1e-5) << refs[m.reference].name;
  }
  EXPECT_GE(e.coverage, 0.95);
  EXPECT_FALSE(e.pair_errors.empty());
  EXPECT_NEAR(e.max_pair_error_deg, 0.0, 1e-6);
  EXPECT_NEAR(e.vertex_distance_max, 0.0, 1e-9);
  std::cout << "exact model: " << e.reconstructed << " planes, coverage " << e.coverage << ", " << e.pair_errors.size()
            << " pairs\n";
}

TEST(EvaluateModel, WithoutMasksFacetsAreMatchedByTheReferencePoints) {
  const sim::MultiViewSet& set = boxesSet();
  const std::vector<planar::ReferencePlane> refs = referencesOf(set, false);
  const planar::Evaluation e = planar::evaluateModel(exactModel(set), viewsOf(set), refs, 10.0, 0.01);
  EXPECT_EQ(e.reconstructed, static_cast<int>(refs.size()));
  for (const planar::PlaneMatch& m : e.matches) {
    EXPECT_EQ(m.facet, m.reference) << refs[m.reference].name;
    EXPECT_TRUE(std::isnan(m.coverage));
  }
  EXPECT_TRUE(std::isnan(e.coverage));
}

TEST(EvaluateModel, AFacetTiltedByThreeDegreesShowsInThePairErrors) {
  const sim::MultiViewSet& set = boxesSet();
  const int top = indexOf(set, "box 2 +z"), side = indexOf(set, "box 2 -x");
  ASSERT_GE(top, 0);
  ASSERT_GE(side, 0) << "the cameras no longer see box 2's -x face";
  planar::PlanarModel model = exactModel(set);
  const Eigen::Vector3d axis = set.planes[top].n.cross(set.planes[side].n).normalized();
  tilt(model.facets[top], axis, 3.0);
  const planar::Evaluation e = planar::evaluateModel(model, viewsOf(set), referencesOf(set, true), 10.0, 0.01);
  EXPECT_EQ(e.reconstructed, static_cast<int>(set.planes.size()));
  EXPECT_NEAR(e.matches[top].angle_deg, 3.0, 1e-6);
  EXPECT_NEAR(e.max_pair_error_deg, 3.0, 1e-6);
  bool seen = false;
  for (const planar::PairAngleError& p : e.pair_errors) {
    if (p.reference_a != top && p.reference_b != top) {
      EXPECT_NEAR(p.error_deg, 0.0, 1e-6);
    }
    if ((p.reference_a == top && p.reference_b == side) || (p.reference_a == side && p.reference_b == top)) {
      EXPECT_NEAR(p.error_deg, 3.0, 1e-6);
      seen = true;
    }
  }
  EXPECT_TRUE(seen) << "no pair error between box 2's top and its -x side";
  EXPECT_GT(e.mean_pair_error_deg, 0.0);
  EXPECT_GT(e.vertex_distance_max, 1e-3);
}

TEST(EvaluateModel, AMissingFacetIsNotReconstructed) {
  const sim::MultiViewSet& set = boxesSet();
  const int missing = indexOf(set, "box 1 +z");
  ASSERT_GE(missing, 0);
  const std::vector<planar::ReferencePlane> refs = referencesOf(set, true);
  planar::PlanarModel model = exactModel(set);
  const double exact_coverage = planar::evaluateModel(model, viewsOf(set), refs, 10.0, 0.01).coverage;
  model.facets.erase(model.facets.begin() + missing);
  const planar::Evaluation e = planar::evaluateModel(model, viewsOf(set), refs, 10.0, 0.01);
  EXPECT_EQ(e.reconstructed, static_cast<int>(set.planes.size()) - 1);
  EXPECT_EQ(e.matches[missing].facet, -1);
  EXPECT_EQ(e.matches[missing].coverage, 0.0);
  EXPECT_TRUE(std::isnan(e.matches[missing].angle_deg));
  EXPECT_LT(e.coverage, exact_coverage);
}

TEST(EvaluateModel, BadArgumentsAreRejected) {
  const sim::MultiViewSet& set = boxesSet();
  const std::vector<planar::View> views = viewsOf(set);
  std::vector<planar::ReferencePlane> refs = referencesOf(set, true);
  EXPECT_THROW(planar::evaluateModel({}, views, refs, 10.0, 0.0), std::invalid_argument);
  EXPECT_THROW(planar::evaluateModel({}, views, refs, 0.0, 0.01), std::invalid_argument);
  refs[0].visible.pop_back();
  EXPECT_THROW(planar::evaluateModel({}, views, refs, 10.0, 0.01), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// VGG reference

// Merton College I's world frame has x up (the cameras' image rows run along
// -x). Its 3D points are corners on the buildings: two facades and their
// roofs; the lawn has almost none (3 points near the ground x = 0 off the facades).
TEST(VggReference, MertonCollegeHasTwoFacadesAndTheirRoofs) {
  const std::string folder = mertonFolder();
  if (!std::filesystem::exists(folder + "/3D/p3d")) GTEST_SKIP() << "Merton College I not found at " << folder;
  EXPECT_EQ(planar::loadVggPoints(folder).size(), 717u);
  EXPECT_EQ(planar::loadVggLines(folder).size(), 295u);
  const std::vector<planar::ReferencePlane> planes = planar::vggReferencePlanes(folder, 0.05, 20);
  ASSERT_GE(planes.size(), 4u);
  for (const planar::ReferencePlane& p : planes) {
    double low = p.points[0].x(), high = low;
    for (const Eigen::Vector3d& X : p.points) {
      low = std::min(low, X.x());
      high = std::max(high, X.x());
    }
    std::cout << "  " << p.name << ": n " << p.plane.n.transpose() << ", d " << p.plane.d << ", " << p.points.size()
              << " points at heights " << low << ".." << high << "\n";
  }
  for (std::size_t a = 0; a < 4; ++a) {
    for (std::size_t b = a + 1; b < 4; ++b) {
      std::cout << "  angle " << planes[a].name << " / " << planes[b].name << ": "
                << planes[a].plane.angleTo(planes[b].plane) << " deg\n";
    }
  }
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_LT(std::abs(planes[i].plane.n.x()), 0.1) << planes[i].name << " is not a (vertical) facade";
    EXPECT_GE(planes[i].points.size(), 100u) << planes[i].name;
  }
  EXPECT_NEAR(planes[0].plane.angleTo(planes[1].plane), 90.0, 5.0) << "the two facades";
  for (std::size_t i = 2; i < 4; ++i) {
    EXPECT_GT(std::abs(planes[i].plane.n.x()), 0.4) << planes[i].name << " is not a roof slope";
    EXPECT_LT(std::abs(planes[i].plane.n.x()), 0.9) << planes[i].name << " is not a roof slope";
    EXPECT_GE(planes[i].points.size(), 50u) << planes[i].name;
  }
  for (std::size_t i = 1; i < planes.size(); ++i) EXPECT_LE(planes[i].points.size(), planes[i - 1].points.size());
  // Deterministic: the same planes again.
  const std::vector<planar::ReferencePlane> again = planar::vggReferencePlanes(folder, 0.05, 20);
  ASSERT_EQ(again.size(), planes.size());
  for (std::size_t i = 0; i < planes.size(); ++i) EXPECT_EQ(again[i].points.size(), planes[i].points.size());
}

TEST(VggReference, MissingOrMalformedFilesAreNamed) {
  const std::filesystem::path folder = std::filesystem::temp_directory_path() / "massage_cell_test_vgg_malformed";
  std::filesystem::create_directories(folder / "3D");
  const auto what = [&]() {
    try {
      planar::vggReferencePlanes(folder.string(), 0.05, 20);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  std::filesystem::remove(folder / "3D" / "p3d");
  EXPECT_NE(what().find("3D/p3d"), std::string::npos) << what();
  std::ofstream(folder / "3D" / "p3d") << "1 2 3\n4 5\n";
  EXPECT_NE(what().find("line 2"), std::string::npos) << what();
  std::ofstream(folder / "3D" / "p3d") << "1 2 3\n4 5 x\n";
  EXPECT_NE(what().find("line 2"), std::string::npos) << what();
  std::filesystem::remove_all(folder);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
