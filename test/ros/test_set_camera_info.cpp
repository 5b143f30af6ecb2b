// rostest: left/set_camera_info and right/set_camera_info save the new
// calibration to the camera_info_url, the driver publishes it from then on,
// and a fresh camera_info_manager reloads the saved file.
//
// Parameters (private): left_url, right_url (the driver's camera_info_url).
#include <gtest/gtest.h>

#include <filesystem>

#include <camera_calibration_parsers/parse.h>
#include <camera_info_manager/camera_info_manager.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/SetCameraInfo.h>

namespace {

sensor_msgs::CameraInfo makeInfo(double fx, double tx) {
  sensor_msgs::CameraInfo info;
  info.width = 320;
  info.height = 240;
  info.distortion_model = "plumb_bob";
  info.D = {0.01, -0.02, 0.0, 0.0, 0.0};
  info.K = {fx, 0, 160, 0, fx, 120, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {fx, 0, 160, tx, 0, fx, 120, 0, 0, 0, 1, 0};
  return info;
}

std::string pathOf(const std::string& url) { return url.substr(std::string("file://").size()); }

/// Waits for a camera_info on `topic` whose K[0] equals `fx`.
bool waitForFx(ros::NodeHandle& nh, const std::string& topic, double fx, double timeout) {
  bool seen = false;
  ros::Subscriber sub = nh.subscribe<sensor_msgs::CameraInfo>(topic, 5, [&](const sensor_msgs::CameraInfoConstPtr& m) {
    if (m->K[0] == fx) seen = true;
  });
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && !seen && ros::WallTime::now() < end) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  return seen;
}

class SetCameraInfo : public ::testing::TestWithParam<std::string> {};

TEST_P(SetCameraInfo, SavesPublishesAndReloads) {
  const std::string side = GetParam();
  ros::NodeHandle nh, pnh("~");
  std::string url;
  ASSERT_TRUE(pnh.getParam(side + "_url", url));
  const double fx = side == "left" ? 412.5 : 413.5;
  const double tx = side == "left" ? 0.0 : -fx * 0.07;

  ros::ServiceClient client = nh.serviceClient<sensor_msgs::SetCameraInfo>(side + "/set_camera_info");
  ASSERT_TRUE(client.waitForExistence(ros::Duration(20.0))) << side << "/set_camera_info not offered";
  sensor_msgs::SetCameraInfo srv;
  srv.request.camera_info = makeInfo(fx, tx);
  ASSERT_TRUE(client.call(srv));
  EXPECT_TRUE(srv.response.success) << srv.response.status_message;

  // Saved: the file parses back to what was sent.
  std::string name;
  sensor_msgs::CameraInfo saved;
  ASSERT_TRUE(camera_calibration_parsers::readCalibration(pathOf(url), name, saved)) << "nothing saved at " << url;
  EXPECT_EQ(saved.K[0], fx);
  EXPECT_EQ(saved.P[3], tx);
  EXPECT_EQ(saved.D[1], -0.02);
  EXPECT_EQ(name, "sample_" + side);

  // Published from now on.
  EXPECT_TRUE(waitForFx(nh, side + "/camera_info", fx, 10.0)) << "the driver never published the new calibration";

  // Reloaded by a fresh manager (what the driver does at its next start).
  ros::NodeHandle other("reload_" + side);
  camera_info_manager::CameraInfoManager manager(other, "sample_" + side, url);
  ASSERT_TRUE(manager.isCalibrated());
  EXPECT_EQ(manager.getCameraInfo().K[0], fx);
  EXPECT_EQ(manager.getCameraInfo().P[3], tx);
}

INSTANTIATE_TEST_SUITE_P(BothCameras, SetCameraInfo, ::testing::Values("left", "right"));

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_set_camera_info");
  ros::NodeHandle nh, pnh("~");
  const int result = RUN_ALL_TESTS();
  std::string url;  // the saved calibrations' folder is this run's own: remove it
  if (pnh.getParam("left_url", url)) {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(pathOf(url)).parent_path(), ec);
  }
  return result;
}
