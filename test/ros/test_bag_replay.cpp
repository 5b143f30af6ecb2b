// rostest: replaying a bag through launch/replay.launch delivers every
// message of every topic in it. The expected counts are read from the bag
// itself with the rosbag API.
//
// Parameters (private): bag (path), timeout (s).
#include <gtest/gtest.h>

#include <map>

#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <topic_tools/shape_shifter.h>

namespace {

TEST(BagReplay, EveryMessageArrives) {
  ros::NodeHandle nh, pnh("~");
  std::string path;
  ASSERT_TRUE(pnh.getParam("bag", path));
  double timeout = 60.0;
  pnh.param("timeout", timeout, timeout);

  std::map<std::string, long> expected;
  {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    for (const auto* connection : view.getConnections()) expected[connection->topic] = 0;
    for (const auto& message : view) ++expected[message.getTopic()];
  }
  ASSERT_FALSE(expected.empty()) << path << " holds no messages";
  for (const auto& topic :
       {"/stereo/left/image_raw", "/stereo/right/image_raw", "/stereo/left/camera_info", "/stereo/right/camera_info"}) {
    ASSERT_GT(expected[topic], 0) << "the sample bag lacks " << topic;
  }

  std::map<std::string, long> received;
  std::vector<ros::Subscriber> subscribers;
  for (const auto& [topic, count] : expected) {
    const std::string name = topic;
    subscribers.push_back(nh.subscribe<topic_tools::ShapeShifter>(
        name, 1000, [&received, name](const topic_tools::ShapeShifter::ConstPtr&) { ++received[name]; }));
  }
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && received != expected && ros::WallTime::now() < end) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  for (const auto& [topic, count] : expected) {
    EXPECT_EQ(received[topic], count) << "topic " << topic;
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bag_replay");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
