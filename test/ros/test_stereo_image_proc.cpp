// rostest: Debian's stereo_image_proc, fed the driver's output unchanged,
// produces `disparity` and `points2`, and they show the bundled recording's
// plane at its known distance.
//
// Parameters (private): distance (m), tolerance (m), baseline (m), fx (px).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <stereo_msgs/DisparityImage.h>

#include "spin_util.h"
#include "test_util.h"

namespace {

using massage_cell::test::median;
using massage_cell::test::spinUntil;

class StereoImageProc : public ::testing::Test {
 protected:
  void SetUp() override {
    pnh_.param("distance", distance_, 0.8);
    pnh_.param("tolerance", tolerance_, 0.02);
    pnh_.param("baseline", baseline_, 0.06);
    pnh_.param("fx", fx_, 300.0);
  }
  ros::NodeHandle nh_, pnh_{"~"};
  double distance_ = 0.8, tolerance_ = 0.02, baseline_ = 0.06, fx_ = 300.0;
};

TEST_F(StereoImageProc, DisparityShowsThePlane) {
  stereo_msgs::DisparityImageConstPtr msg;
  ros::Subscriber sub = nh_.subscribe<stereo_msgs::DisparityImage>(
      "disparity", 2, [&](const stereo_msgs::DisparityImageConstPtr& m) { msg = m; });
  spinUntil([&] { return msg != nullptr; }, 60.0);
  ASSERT_TRUE(msg) << "no disparity from stereo_image_proc";
  EXPECT_EQ(msg->image.encoding, "32FC1");
  EXPECT_NEAR(msg->f, fx_, 1e-6);
  EXPECT_NEAR(msg->T, baseline_, 1e-6);
  const float* d = reinterpret_cast<const float*>(msg->image.data.data());
  std::vector<double> valid;
  for (std::size_t i = 0; i < msg->image.width * msg->image.height; ++i) {
    if (std::isfinite(d[i]) && d[i] >= msg->min_disparity) valid.push_back(d[i]);
  }
  ASSERT_GT(valid.size(), msg->image.width * msg->image.height / 4) << "too few valid disparities";
  const double expected = fx_ * baseline_ / distance_;
  EXPECT_NEAR(median(valid), expected, expected * tolerance_ / distance_ + 0.5);
}

TEST_F(StereoImageProc, PointCloudShowsThePlaneAtItsDistance) {
  sensor_msgs::PointCloud2ConstPtr cloud;
  ros::Subscriber sub = nh_.subscribe<sensor_msgs::PointCloud2>(
      "points2", 2, [&](const sensor_msgs::PointCloud2ConstPtr& m) { cloud = m; });
  spinUntil([&] { return cloud != nullptr; }, 60.0);
  ASSERT_TRUE(cloud) << "no points2 from stereo_image_proc";
  EXPECT_EQ(cloud->header.frame_id, "stereo_left_optical_frame");
  std::vector<double> z;
  for (sensor_msgs::PointCloud2ConstIterator<float> it(*cloud, "z"); it != it.end(); ++it) {
    if (std::isfinite(*it)) z.push_back(*it);
  }
  ASSERT_GT(z.size(), static_cast<std::size_t>(cloud->width * cloud->height / 4)) << "too few valid points";
  EXPECT_NEAR(median(z), distance_, tolerance_);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_stereo_image_proc");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
