// rostest: the simulator's camera_info files load with camera_info_manager,
// and image_geometry's StereoCameraModel reproduces the rendered geometry:
// a ground-truth point projects to its pixel (rectified pair) and the GT
// disparity triangulates back to the GT point.
#include <gtest/gtest.h>

#include <camera_info_manager/camera_info_manager.h>
#include <image_geometry/stereo_camera_model.h>
#include <ros/ros.h>
#include <opencv2/imgcodecs.hpp>

#include "test_util.h"

namespace {

using massage_cell::test::runCommand;
using massage_cell::test::TempDir;

TEST(SimCalibration, LoadsWithCameraInfoManagerAndImageGeometryReproducesTheProjection) {
  TempDir dir;
  const auto r = runCommand(std::string(RENDER_SCENE_TOOL) +
                                " --preset back --width 200 --height 150 --fx 160 "
                                "--supersample 1 --out " +
                                dir.str(),
                            120);
  ASSERT_EQ(r.exit_code, 0) << r.output;

  ros::NodeHandle nh_left("sim_left"), nh_right("sim_right");
  camera_info_manager::CameraInfoManager left(nh_left, "sim_left", "file://" + dir.str() + "/left_camera_info.yaml");
  camera_info_manager::CameraInfoManager right(nh_right, "sim_right",
                                               "file://" + dir.str() + "/right_camera_info.yaml");
  ASSERT_TRUE(left.isCalibrated());
  ASSERT_TRUE(right.isCalibrated());
  sensor_msgs::CameraInfo li = left.getCameraInfo(), ri = right.getCameraInfo();
  li.header.frame_id = ri.header.frame_id = "sim_left_optical_frame";
  image_geometry::StereoCameraModel model;
  ASSERT_TRUE(model.fromCameraInfo(li, ri));
  EXPECT_NEAR(model.baseline(), 0.10, 1e-9);

  const cv::Mat points = cv::imread(dir.str() + "/left_points.pfm", cv::IMREAD_UNCHANGED);
  const cv::Mat disparity = cv::imread(dir.str() + "/left_disparity.pfm", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(points.type(), CV_32FC3);
  ASSERT_EQ(disparity.type(), CV_32F);
  int checked = 0;
  for (int y = 5; y < points.rows; y += 11) {
    for (int x = 3; x < points.cols; x += 13) {
      const cv::Vec3f p = points.at<cv::Vec3f>(y, x);
      const float d = disparity.at<float>(y, x);
      if (!std::isfinite(p[0]) || !std::isfinite(d)) continue;
      const cv::Point2d pixel = model.left().project3dToPixel(cv::Point3d(p[0], p[1], p[2]));
      EXPECT_NEAR(pixel.x, x, 0.01);
      EXPECT_NEAR(pixel.y, y, 0.01);
      cv::Point3d q;
      model.projectDisparityTo3d(cv::Point2d(x, y), d, q);
      EXPECT_NEAR(q.x, p[0], 1e-4);
      EXPECT_NEAR(q.y, p[1], 1e-4);
      EXPECT_NEAR(q.z, p[2], 1e-4);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_sim_calibration");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
