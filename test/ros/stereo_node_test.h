// What the rostests of the stereo-pair nodes (hbds, cect) share: the test
// fixture's parameters, the bundled bag's ground truth and its first pair,
// a publisher of pairs into a node under test, the node's diagnostics.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>
#include <yaml-cpp/yaml.h>
#include <Eigen/Core>

#include "spin_util.h"

namespace massage_cell::test {

/// The private parameters bag, ground_truth (paths) and tolerance (m).
class StereoNodeTest : public ::testing::Test {
 protected:
  explicit StereoNodeTest(double tolerance) : tolerance_(tolerance) {}
  void SetUp() override {
    ASSERT_TRUE(pnh_.getParam("bag", bag_path_));
    ASSERT_TRUE(pnh_.getParam("ground_truth", ground_truth_path_));
    pnh_.param("tolerance", tolerance_, tolerance_);
  }
  ros::NodeHandle nh_, pnh_{"~"};
  std::string bag_path_, ground_truth_path_;
  double tolerance_;
};

/// The acupoints of every frame of the bag (rosbags/*.ground_truth.yaml, left
/// optical frame, metres); frame i is the bag's i-th pair, `rate` pairs a
/// second from the stamp of its first one.
struct GroundTruth {
  double rate = 0.0;
  ros::Time first_stamp;
  std::vector<std::map<std::string, Eigen::Vector3d>> frames;

  long index(const ros::Time& stamp) const { return std::lround((stamp - first_stamp).toSec() * rate); }
};

/// Reads `yaml_path` and the first /stereo/left/camera_info stamp of `bag_path`.
inline void loadGroundTruth(const std::string& yaml_path, const std::string& bag_path, GroundTruth* gt) {
  const YAML::Node yaml = YAML::LoadFile(yaml_path);
  gt->rate = yaml["rate"].as<double>();
  gt->frames.clear();
  for (const auto& frame : yaml["frames"]) {
    gt->frames.emplace_back();
    for (const auto& point : frame["acupoints"]) {
      gt->frames.back()[point.first.as<std::string>()] =
          Eigen::Vector3d(point.second[0].as<double>(), point.second[1].as<double>(), point.second[2].as<double>());
    }
  }
  ASSERT_GT(gt->frames.size(), 10u);
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{"/stereo/left/camera_info"}));
  ASSERT_NE(view.begin(), view.end());
  gt->first_stamp = view.begin()->instantiate<sensor_msgs::CameraInfo>()->header.stamp;
}

/// One stereo pair as a node takes it.
struct StereoPair {
  sensor_msgs::Image left, right;
  sensor_msgs::CameraInfo left_info, right_info;
};

/// The first pair of the bag's /stereo topics.
inline void readFirstPair(const std::string& bag_path, StereoPair* pair) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag);
  int found = 0;
  for (const auto& m : view) {
    if (found == 15) break;
    const std::string& topic = m.getTopic();
    if (topic == "/stereo/left/image_raw" && !(found & 1))
      pair->left = *m.instantiate<sensor_msgs::Image>(), found |= 1;
    if (topic == "/stereo/right/image_raw" && !(found & 2))
      pair->right = *m.instantiate<sensor_msgs::Image>(), found |= 2;
    if (topic == "/stereo/left/camera_info" && !(found & 4))
      pair->left_info = *m.instantiate<sensor_msgs::CameraInfo>(), found |= 4;
    if (topic == "/stereo/right/camera_info" && !(found & 8))
      pair->right_info = *m.instantiate<sensor_msgs::CameraInfo>(), found |= 8;
  }
  ASSERT_EQ(found, 15) << "the bag lacks a stereo pair";
}

/// Half the width and height of the image (its data cut to match): an image
/// smaller than its camera_info says.
inline void halve(sensor_msgs::Image& image) {
  image.width /= 2;
  image.height /= 2;
  image.step /= 2;
  image.data.resize(image.step * image.height);
}

/// A camera_info of an uncalibrated camera (K and P all zero).
inline void uncalibrate(sensor_msgs::CameraInfo& info) {
  std::fill(info.K.begin(), info.K.end(), 0.0);
  std::fill(info.P.begin(), info.P.end(), 0.0);
}

/// Publishes pairs into the node whose inputs are in `ns`.
class PairPublisher {
 public:
  explicit PairPublisher(ros::NodeHandle& ns, int queue_size = 5)
      : left_(ns.advertise<sensor_msgs::Image>("left/image_raw", queue_size)),
        left_info_(ns.advertise<sensor_msgs::CameraInfo>("left/camera_info", queue_size)),
        right_(ns.advertise<sensor_msgs::Image>("right/image_raw", queue_size)),
        right_info_(ns.advertise<sensor_msgs::CameraInfo>("right/camera_info", queue_size)) {}

  /// The node subscribes to all four inputs.
  bool subscribed() const {
    return left_.getNumSubscribers() && right_.getNumSubscribers() && left_info_.getNumSubscribers() &&
           right_info_.getNumSubscribers();
  }
  /// The pair with `stamp` on all four messages.
  void publish(StereoPair pair, const ros::Time& stamp) {
    for (auto* header : {&pair.left.header, &pair.right.header, &pair.left_info.header, &pair.right_info.header}) {
      header->stamp = stamp;
    }
    left_.publish(pair.left);
    left_info_.publish(pair.left_info);
    right_.publish(pair.right);
    right_info_.publish(pair.right_info);
  }
  /// The pair with a new stamp (1001 s, 1002 s, ...); returns it.
  ros::Time publish(const StereoPair& pair) {
    const ros::Time stamp(++stamp_seconds_, 0);
    publish(pair, stamp);
    return stamp;
  }

 private:
  ros::Publisher left_, left_info_, right_, right_info_;
  int stamp_seconds_ = 1000;
};

/// The values of one status of a node's diagnostics.
struct NodeStatus {
  bool seen = false;
  std::map<std::string, std::string> values;
  long count(const std::string& key) const {
    const auto it = values.find(key);
    return it == values.end() ? -1 : std::stol(it->second);
  }
  std::string text(const std::string& key) const {
    const auto it = values.find(key);
    return it == values.end() ? "" : it->second;
  }
};

/// Fills `status` from the diagnostics status "<node>: <task>" (node without
/// its leading '/').
inline ros::Subscriber watchDiagnostics(ros::NodeHandle& nh, const std::string& node, const std::string& task,
                                        NodeStatus& status) {
  const std::string name = node + ": " + task;
  return nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 50, [&status, name](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        for (const auto& s : msg->status) {
          if (s.name != name) continue;
          status.seen = true;
          for (const auto& kv : s.values) status.values[kv.key] = kv.value;
        }
      });
}

/// Waits until the node in `ns` has subscribed to every input of `pub` and
/// sent `status`, then lets the connections settle.
inline void waitForNode(const PairPublisher& pub, const NodeStatus& status, const std::string& ns) {
  ASSERT_TRUE(spinUntil([&] { return pub.subscribed() && status.seen; }, 15.0))
      << "the node in " << ns << " did not subscribe to its inputs (or sends no diagnostics)";
  ros::WallDuration(0.5).sleep();  // connections of the synchronised subscribers settle
}

/// Publishes a bad pair: the node must count it as bad and say `message` in
/// its last error. Returns the pair's stamp (no output may have it).
inline ros::Time publishBadPair(PairPublisher& pub, const NodeStatus& status, const std::string& what,
                                const StereoPair& pair, const std::string& message) {
  const long before = std::max(0L, status.count("bad pairs"));
  const ros::Time stamp = pub.publish(pair);
  EXPECT_TRUE(spinUntil([&] { return status.count("bad pairs") > before; }, 6.0)) << what << ": not counted as bad";
  EXPECT_NE(status.text("last error").find(message), std::string::npos)
      << what << ": last error '" << status.text("last error") << "' does not say '" << message << "'";
  return stamp;
}

/// The bag's replay as the test sees it: the stamps of its pairs, its
/// camera_infos, its /tf_static (the bag waits for a subscriber on every
/// topic, /tf_static too).
struct BagInputs {
  std::set<ros::Time> stamps;
  sensor_msgs::CameraInfoConstPtr left_info, right_info;
  int tf_messages = 0;

  std::vector<ros::Subscriber> subscribe(ros::NodeHandle& nh) {
    std::vector<ros::Subscriber> subs;
    subs.push_back(nh.subscribe<sensor_msgs::CameraInfo>("/stereo/left/camera_info", 100,
                                                         [this](const sensor_msgs::CameraInfoConstPtr& m) {
                                                           left_info = m;
                                                           stamps.insert(m->header.stamp);
                                                         }));
    subs.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
        "/stereo/right/camera_info", 100, [this](const sensor_msgs::CameraInfoConstPtr& m) { right_info = m; }));
    subs.push_back(nh.subscribe<tf2_msgs::TFMessage>("/tf_static", 10,
                                                     [this](const tf2_msgs::TFMessageConstPtr&) { ++tf_messages; }));
    return subs;
  }
};

}  // namespace massage_cell::test
