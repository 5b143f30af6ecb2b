// session_player: plays a recorded stereo session (a bag of the stereo
// driver's output) as a live camera — every frame restamped with the current
// time, in a loop — so the cell runs on wall-clock time like with a real
// camera (tf lookups, staleness limits and latencies mean what they say;
// rosbag play with simulated time jumps back at every loop).
//
// Publishes (in its namespace): left/image_raw, right/image_raw,
//   left/camera_info, right/camera_info (one stamp per pair), /tf_static (the
//   recording's, latched, restamped), and with ~ground_truth
//   ground_truth/acupoints (massage_cell/AcupointArray: the recording's true
//   acupoints of the frame being played, same stamp and frame as the pair).
// Parameters: ~bag (path, required), ~ground_truth (the recording's sidecar
//   YAML, optional), ~rate (1.0: the recording's pace), ~loop (true),
//   ~delay (1.0 s before the first frame), ~topic_prefix ("/stereo": the
//   recorded topics' namespace).
// Exits 1 with a message naming the problem when the bag or sidecar cannot
// be read, or holds no complete pairs; 0 at the end of a non-looping play.
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>
#include <yaml-cpp/yaml.h>

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "massage_cell/AcupointArray.h"
#include "typed_param.h"

namespace {

using massage_cell::nodes::readParam;

struct Frame {
  sensor_msgs::Image left, right;
  sensor_msgs::CameraInfo left_info, right_info;
  ros::Time recorded;
};

/// The recording's pairs in order, matched by stamp, and its static transforms.
std::vector<Frame> readBag(const std::string& path, const std::string& prefix, tf2_msgs::TFMessage* tf_static) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::map<ros::Time, Frame> by_stamp;
  std::map<ros::Time, int> parts;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    const std::string& topic = m.getTopic();
    if (topic == "/tf_static") {
      if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
        tf_static->transforms.insert(tf_static->transforms.end(), tf->transforms.begin(), tf->transforms.end());
      }
      continue;
    }
    const bool left = topic.rfind(prefix + "/left/", 0) == 0, right = topic.rfind(prefix + "/right/", 0) == 0;
    if (!left && !right) continue;
    if (auto image = m.instantiate<sensor_msgs::Image>()) {
      (left ? by_stamp[image->header.stamp].left : by_stamp[image->header.stamp].right) = *image;
      ++parts[image->header.stamp];
    } else if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
      (left ? by_stamp[info->header.stamp].left_info : by_stamp[info->header.stamp].right_info) = *info;
      ++parts[info->header.stamp];
    }
  }
  std::vector<Frame> frames;
  for (auto& [stamp, frame] : by_stamp) {
    if (parts[stamp] != 4) continue;  // an incomplete pair (the recording's first or last) is left out
    frame.recorded = stamp;
    frames.push_back(frame);
  }
  return frames;
}

/// Per frame index: the recording's true acupoints (name -> position in the left optical frame).
std::vector<std::map<std::string, geometry_msgs::Point>> readGroundTruth(const std::string& path) {
  const YAML::Node root = YAML::LoadFile(path);
  if (!root["frames"] || !root["frames"].IsSequence())
    throw std::runtime_error(path + ": no 'frames' list (expected the renderer's ground_truth.yaml)");
  std::vector<std::map<std::string, geometry_msgs::Point>> out;
  for (const YAML::Node& f : root["frames"]) {
    std::map<std::string, geometry_msgs::Point> points;
    for (const auto& kv : f["acupoints"]) {
      const auto xyz = kv.second.as<std::vector<double>>();
      if (xyz.size() != 3)
        throw std::runtime_error(path + ": acupoint " + kv.first.as<std::string>() + " is not [x, y, z]");
      geometry_msgs::Point p;
      p.x = xyz[0];
      p.y = xyz[1];
      p.z = xyz[2];
      points[kv.first.as<std::string>()] = p;
    }
    out.push_back(points);
  }
  return out;
}

massage_cell::AcupointArray truthMessage(const std::map<std::string, geometry_msgs::Point>& truth,
                                         const std_msgs::Header& header) {
  massage_cell::AcupointArray msg;
  msg.header = header;
  for (const auto& [name, p] : truth) {
    massage_cell::Acupoint a;
    a.name = name;
    a.position = p;
    a.valid = true;
    a.u = a.v = std::numeric_limits<float>::quiet_NaN();
    msg.acupoints.push_back(a);
  }
  return msg;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "session_player");
  ros::NodeHandle nh, pnh("~");
  std::string bag_path, truth_path, prefix = "/stereo";
  double rate = 1.0, delay = 1.0;
  bool loop = true;
  try {
    readParam(pnh, "bag", &bag_path);
    readParam(pnh, "ground_truth", &truth_path);
    readParam(pnh, "rate", &rate);
    readParam(pnh, "loop", &loop);
    readParam(pnh, "delay", &delay);
    readParam(pnh, "topic_prefix", &prefix);
  } catch (const massage_cell::nodes::ParamError& e) {
    ROS_FATAL("session_player: %s", e.what());
    return 1;
  }
  if (!(rate > 0.0) || rate > 100.0) {
    ROS_FATAL("session_player: ~rate %.3f is out of range (0 < rate <= 100; 1 = the recording's pace)", rate);
    return 1;
  }
  std::vector<Frame> frames;
  tf2_msgs::TFMessage tf_static;
  std::vector<std::map<std::string, geometry_msgs::Point>> truth;
  try {
    if (bag_path.empty()) throw std::runtime_error("~bag is not set");
    frames = readBag(bag_path, prefix, &tf_static);
    if (frames.size() < 2)
      throw std::runtime_error(bag_path + " holds " + std::to_string(frames.size()) + " complete stereo pairs under " +
                               prefix + " (need >= 2)");
    if (!truth_path.empty()) truth = readGroundTruth(truth_path);
  } catch (const std::exception& e) {
    ROS_FATAL("session_player: %s", e.what());
    return 1;
  }
  const double period = (frames.back().recorded - frames.front().recorded).toSec() / (frames.size() - 1) / rate;
  ROS_INFO("session_player: %zu pairs from %s at %.1f Hz%s%s", frames.size(), bag_path.c_str(), 1.0 / period,
           loop ? ", looping" : "", truth.empty() ? "" : ", with ground truth");

  auto left = nh.advertise<sensor_msgs::Image>("left/image_raw", 2);
  auto right = nh.advertise<sensor_msgs::Image>("right/image_raw", 2);
  auto left_info = nh.advertise<sensor_msgs::CameraInfo>("left/camera_info", 2);
  auto right_info = nh.advertise<sensor_msgs::CameraInfo>("right/camera_info", 2);
  auto truth_pub = nh.advertise<massage_cell::AcupointArray>("ground_truth/acupoints", 2);
  auto tf_pub = ros::NodeHandle().advertise<tf2_msgs::TFMessage>("/tf_static", 1, /*latch=*/true);
  for (auto& t : tf_static.transforms) t.header.stamp = ros::Time::now();
  if (!tf_static.transforms.empty()) tf_pub.publish(tf_static);

  ros::Duration(delay).sleep();
  ros::Rate pace(1.0 / period);
  std::size_t played = 0;
  while (ros::ok()) {
    const std::size_t i = played % frames.size();
    if (!loop && played == frames.size()) break;
    Frame f = frames[i];
    std_msgs::Header header = f.left.header;
    header.stamp = ros::Time::now();
    for (std_msgs::Header* h : {&f.left.header, &f.right.header, &f.left_info.header, &f.right_info.header})
      h->stamp = header.stamp;
    left_info.publish(f.left_info);
    right_info.publish(f.right_info);
    left.publish(f.left);
    right.publish(f.right);
    if (!truth.empty()) truth_pub.publish(truthMessage(truth[i % truth.size()], header));
    ++played;
    ros::spinOnce();
    pace.sleep();
  }
  return 0;
}
