// rostest of the planar node (test/ros/planar.test).
//
// StereoPairGivesPlanesWhereTheSceneIs: a stereo pair of boxes on the
// massage table, rendered by the simulator (render_scene --preset boxes), is
// published into the node; its latched ~planes (left optical frame) must put
// their corners at the rendered depth, and ~mesh be a TRIANGLE_LIST there.
// ServiceReconstructsAViewSet: the same pair as a views.yaml set through
// ~reconstruct, written as OBJ / PLY.
// BadRequestsAreRefusedAndTheNodeGoesOn: an empty path, a missing folder, a
// set of one view and an uncalibrated stereo pair are refused with the
// problem named; a good call afterwards still succeeds.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <camera_calibration_parsers/parse.h>
#include <cv_bridge/cv_bridge.h>
#include <ros/ros.h>
#include <visualization_msgs/Marker.h>
#include <opencv2/imgcodecs.hpp>

#include "massage_cell/PlanarModel.h"
#include "massage_cell/Reconstruct.h"
#include "spin_util.h"
#include "stereo_node_test.h"
#include "test_util.h"

namespace {

using namespace massage_cell::test;

const std::string kNode = "/planar_test/planar";

/// A boxes scene rendered once for all tests: the pair, its calibration and
/// the rendered depth of the left view.
struct Rendered {
  TempDir dir{"planar_node"};
  StereoPair pair;
  cv::Mat depth;  ///< CV_32F, metres, NaN where nothing is hit
  double baseline = 0.0;
};

const Rendered& rendered() {
  static Rendered* r = [] {
    auto* out = new Rendered;
    const auto run = runCommand(std::string(RENDER_SCENE_TOOL) +
                                    " --preset boxes --width 640 --height 480 --fx 500"
                                    " --supersample 1 --out " +
                                    out->dir.str(),
                                120);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    sensor_msgs::CameraInfo* info[2] = {&out->pair.left_info, &out->pair.right_info};
    sensor_msgs::Image* image[2] = {&out->pair.left, &out->pair.right};
    const char* side[2] = {"left", "right"};
    for (int i = 0; i < 2; ++i) {
      std::string name;
      EXPECT_TRUE(camera_calibration_parsers::readCalibration(
          (out->dir.path() / (std::string(side[i]) + "_camera_info.yaml")).string(), name, *info[i]));
      const cv::Mat bgr = cv::imread((out->dir.path() / (std::string(side[i]) + ".png")).string(), cv::IMREAD_COLOR);
      *image[i] = *cv_bridge::CvImage(std_msgs::Header(), "bgr8", bgr).toImageMsg();
      image[i]->header.frame_id = info[i]->header.frame_id = "stereo_left_optical_frame";
    }
    out->baseline = -out->pair.right_info.P[3] / out->pair.right_info.P[0];
    out->depth = cv::imread((out->dir.path() / "left_depth.pfm").string(), cv::IMREAD_UNCHANGED);
    return out;
  }();
  return *r;
}

/// Median relative depth error of the model's polygon vertices (left optical
/// frame) against the rendered depth at their pixels; the number compared.
double vertexDepthError(const massage_cell::PlanarModel& model, const Rendered& r, int* compared) {
  const auto& P = r.pair.left_info.P;
  std::vector<double> errors;
  for (const auto& facet : model.facets) {
    for (const auto& polygon : facet.polygons) {
      for (const auto& X : polygon.points) {
        if (!(X.z > 0.0f)) continue;
        const int u = static_cast<int>(std::lround((P[0] * X.x + P[2] * X.z) / X.z));
        const int v = static_cast<int>(std::lround((P[5] * X.y + P[6] * X.z) / X.z));
        if (u < 0 || v < 0 || u >= r.depth.cols || v >= r.depth.rows) continue;
        const float z = r.depth.at<float>(v, u);
        if (std::isfinite(z)) errors.push_back(std::abs(X.z - z) / z);
      }
    }
  }
  *compared = static_cast<int>(errors.size());
  return median(errors);
}

/// Writes DIR/views.yaml: the rendered pair as two views (left at the
/// origin, right at (baseline, 0, 0): the rendered pair is rectified).
std::string writeViewSet(const Rendered& r, int views) {
  const std::string path = r.dir.str() + "/views" + std::to_string(views) + ".yaml";
  std::ofstream out(path);
  out << "views:\n"
      << "  - {image: left.png, camera_info: left_camera_info.yaml, position: [0, 0, 0], orientation: [0, 0, 0, 1]}\n";
  if (views > 1) {
    out << "  - {image: right.png, camera_info: right_camera_info.yaml, position: [" << r.baseline
        << ", 0, 0], orientation: [0, 0, 0, 1]}\n";
  }
  return path;
}

bool call(const std::string& path, const std::string& prefix, massage_cell::Reconstruct* srv) {
  ros::NodeHandle nh;
  ros::ServiceClient client = nh.serviceClient<massage_cell::Reconstruct>(kNode + "/reconstruct");
  if (!client.waitForExistence(ros::Duration(30.0))) return false;
  srv->request.path = path;
  srv->request.output_prefix = prefix;
  return client.call(*srv);
}

TEST(PlanarNode, StereoPairGivesPlanesWhereTheSceneIs) {
  const Rendered& r = rendered();
  ASSERT_EQ(r.depth.type(), CV_32F);
  ros::NodeHandle nh;
  massage_cell::PlanarModelConstPtr model;
  visualization_msgs::MarkerConstPtr mesh;
  auto planes_sub = nh.subscribe<massage_cell::PlanarModel>(
      kNode + "/planes", 1, [&](const massage_cell::PlanarModelConstPtr& m) { model = m; });
  auto mesh_sub = nh.subscribe<visualization_msgs::Marker>(
      kNode + "/mesh", 1, [&](const visualization_msgs::MarkerConstPtr& m) { mesh = m; });
  ros::NodeHandle ns("/planar_test");
  PairPublisher input(ns, 2);
  ASSERT_TRUE(spinUntil([&] { return input.subscribed(); }, 30.0)) << "the node did not subscribe to the pair";
  ros::Time stamp;
  ASSERT_TRUE(spinUntil(
      [&] {
        if (!model || model->header.stamp != stamp) stamp = input.publish(r.pair);
        return model && model->header.frame_id == "stereo_left_optical_frame";
      },
      60.0))
      << "no ~planes from the stereo pair";
  ASSERT_GE(model->facets.size(), 1u);
  // The planes lie where the rendered scene is: their corners at its depth.
  int compared = 0;
  EXPECT_LT(vertexDepthError(*model, r, &compared), 0.02);
  EXPECT_GE(compared, 3);
  ASSERT_TRUE(spinUntil([&] { return mesh != nullptr; }, 5.0));
  EXPECT_EQ(mesh->header.frame_id, "stereo_left_optical_frame");
  EXPECT_EQ(mesh->type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_EQ(mesh->points.size() % 3, 0u);
  EXPECT_EQ(mesh->colors.size(), mesh->points.size());
  EXPECT_GE(mesh->points.size(), 3u);
}

TEST(PlanarNode, ServiceReconstructsAViewSet) {
  const Rendered& r = rendered();
  massage_cell::Reconstruct srv;
  srv.request.frame_id = "stereo_left_optical_frame";
  ASSERT_TRUE(call(writeViewSet(r, 2), r.dir.str() + "/model", &srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_EQ(srv.response.model.header.frame_id, "stereo_left_optical_frame");
  ASSERT_GE(srv.response.model.facets.size(), 1u);
  int compared = 0;
  EXPECT_LT(vertexDepthError(srv.response.model, r, &compared), 0.02);
  EXPECT_GE(compared, 3);
  const std::string obj = readFile(r.dir.str() + "/model.obj");
  const std::string ply = readFile(r.dir.str() + "/model.ply");
  EXPECT_NE(obj.find("\nf "), std::string::npos) << "no faces in model.obj";
  EXPECT_EQ(ply.rfind("ply", 0), 0u);
}

TEST(PlanarNode, BadRequestsAreRefusedAndTheNodeGoesOn) {
  const Rendered& r = rendered();
  struct Case {
    std::string path, expect;
  };
  const std::vector<Case> cases = {
      {"", "path is empty"}, {"/nonexistent/views", "/nonexistent/views"}, {writeViewSet(r, 1), "at least 2 views"}};
  for (const Case& c : cases) {
    massage_cell::Reconstruct srv;
    ASSERT_TRUE(call(c.path, "", &srv)) << "the service is gone after '" << c.path << "'";
    EXPECT_FALSE(srv.response.success) << c.path;
    EXPECT_NE(srv.response.message.find(c.expect), std::string::npos) << "'" << c.path << "': " << srv.response.message;
  }
  // An uncalibrated pair is skipped and named in the diagnostics' last error; the node goes on.
  ros::NodeHandle nh, ns("/planar_test");
  PairPublisher input(ns, 2);
  NodeStatus status;
  const ros::Subscriber diagnostics = watchDiagnostics(nh, "planar_test/planar", "planar reconstruction", status);
  waitForNode(input, status, "/planar_test");
  StereoPair bad = r.pair;
  uncalibrate(bad.left_info);
  EXPECT_TRUE(spinUntil(
      [&] {
        input.publish(bad);
        spinUntil([] { return false; }, 0.6);  // one stereo_period
        return status.text("last error").find("not calibrated") != std::string::npos;
      },
      20.0))
      << "last error: " << status.text("last error");
  massage_cell::Reconstruct good;
  ASSERT_TRUE(call(writeViewSet(r, 2), "", &good));
  EXPECT_TRUE(good.response.success) << good.response.message;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_planar_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
