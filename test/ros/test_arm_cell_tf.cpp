// rostest of the tf tree that cell.launch builds with the arm on
// (test/ros/arm_cell_tf.test: the bundled bag, the CECT node, the arm node
// with simulated drives, robot_state_publisher with urdf/massage_arm.urdf):
// every frame has exactly one parent and one publisher on /tf + /tf_static;
// the URDF owns the camera mount (table -> stereo_camera_mount ->
// stereo_left_optical_frame), the camera (here its recording) only the left
// -> right optical edge from its calibration; the camera's frames and the
// acupoint frames join the arm's tree under the same names.
#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <set>
#include <sstream>

#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

namespace {

struct Edge {
  std::set<std::string> parents, publishers, topics;
};

std::mutex mutex;
std::map<std::string, Edge> edges;  // by child frame

void record(const ros::MessageEvent<const tf2_msgs::TFMessage>& event, const std::string& topic) {
  std::lock_guard<std::mutex> lock(mutex);
  for (const auto& t : event.getConstMessage()->transforms) {
    Edge& e = edges[t.child_frame_id];
    e.parents.insert(t.header.frame_id);
    e.publishers.insert(event.getPublisherName());
    e.topics.insert(topic);
  }
}

// Free functions: roscpp passes the publisher's name only to callbacks it sees taking a MessageEvent.
void onTf(const ros::MessageEvent<const tf2_msgs::TFMessage>& event) { record(event, "/tf"); }
void onTfStatic(const ros::MessageEvent<const tf2_msgs::TFMessage>& event) { record(event, "/tf_static"); }

std::string join(const std::set<std::string>& s) {
  std::string out;
  for (const auto& x : s) out += (out.empty() ? "" : ", ") + x;
  return out;
}

std::map<std::string, Edge> snapshot() {
  std::lock_guard<std::mutex> lock(mutex);
  return edges;
}

bool waitFor(const std::function<bool()>& pred, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::WallTime::now() < end && ros::ok()) {
    if (pred()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return pred();
}

bool hasAcupoint() {
  for (const auto& [child, e] : snapshot()) {
    if (child.rfind("acupoint/", 0) == 0) return true;
  }
  return false;
}

TEST(ArmCellTf, EveryFrameHasOneParentAndOnePublisher) {
  ASSERT_TRUE(waitFor([] { return snapshot().count("stereo_right_optical_frame") && hasAcupoint(); }, 90.0))
      << "no camera or acupoint frames";
  ros::WallDuration(3.0).sleep();  // more of the replay: late second publishers would show up
  const auto all = snapshot();
  std::ostringstream tree;
  for (const auto& [child, e] : all) {
    tree << join(e.parents) << " -> " << child << "  [" << join(e.publishers) << " on " << join(e.topics) << "]\n";
  }
  for (const auto& [child, e] : all) {
    EXPECT_EQ(e.parents.size(), 1u) << child << " has parents " << join(e.parents) << "\n" << tree.str();
    EXPECT_EQ(e.publishers.size(), 1u) << child << " is published by " << join(e.publishers) << "\n" << tree.str();
  }
  // The URDF (robot_state_publisher) owns the mount ...
  for (const char* child : {"arm_base_link", "stereo_camera_mount", "stereo_left_optical_frame"}) {
    ASSERT_TRUE(all.count(child)) << child << "\n" << tree.str();
    EXPECT_EQ(join(all.at(child).publishers), "/robot_state_publisher") << child;
  }
  EXPECT_EQ(join(all.at("stereo_camera_mount").parents), "table");
  EXPECT_EQ(join(all.at("stereo_left_optical_frame").parents), "stereo_camera_mount");
  // ... the camera (its recording, played as a live camera by the session player) the left -> right edge from the
  // calibration.
  EXPECT_EQ(join(all.at("stereo_right_optical_frame").parents), "stereo_left_optical_frame");
  EXPECT_EQ(join(all.at("stereo_right_optical_frame").publishers), "/stereo/session_player");
  // The acupoints hang under the camera's left optical frame, as the arm expects them.
  for (const auto& [child, e] : all) {
    if (child.rfind("acupoint/", 0) != 0) continue;
    EXPECT_EQ(join(e.parents), "stereo_left_optical_frame") << child;
  }
}

TEST(ArmCellTf, CameraAndAcupointFramesJoinTheArmsTree) {
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  std::string acupoint;
  for (const auto& [child, e] : snapshot()) {
    if (child.rfind("acupoint/", 0) == 0) acupoint = child;
  }
  ASSERT_FALSE(acupoint.empty());
  for (const std::string& frame : {std::string("stereo_right_optical_frame"), acupoint}) {
    std::string error;
    EXPECT_TRUE(waitFor([&] { return buffer.canTransform("arm_base_link", frame, ros::Time(0), &error); }, 10.0))
        << frame << ": " << error;
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_arm_cell_tf");
  ros::NodeHandle nh;
  ros::Subscriber tf_sub = nh.subscribe("/tf", 100, onTf);
  ros::Subscriber static_sub = nh.subscribe("/tf_static", 100, onTfStatic);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
