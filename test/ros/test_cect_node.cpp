// rostest of the CECT acupoint node (test/ros/cect.test).
//
// BagOutputs: rosbags/back_session.bag is replayed (sim time) into the node
// in /stereo. `acupoints` must carry every acupoint of config/acupoints.yaml
// with input stamps in the left optical frame; while the bag plays,
// ~get_acupoint answers in the optical frame and in the right optical frame
// (the bag's /tf_static) and fails clearly for an unknown name and an unknown
// frame; ~localize_pixels answers for pixels on and off the back; afterwards a
// tf frame acupoint/<name> exists for every acupoint, and the published
// acupoints agree with the ground truth (rosbags/back_session.ground_truth.yaml,
// left optical frame) within `tolerance` (model placement error included).
// BadInputIsSkipped: a second node in /bad_input is fed by this test: before
// any pair ~localize_pixels says so; a good pair gives acupoints; pairs with
// an image smaller than its camera_info, an uncalibrated camera, a vertical
// (non-horizontal) pair and grey images are skipped and named in the
// diagnostics; a pair without a back gives acupoints that are all invalid
// with a reason; the node stays alive and processes a good pair afterwards.
//
// Parameters (private): bag, ground_truth, acupoints (paths), tolerance (m, 0.03).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/Point.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <yaml-cpp/yaml.h>

#include "massage_cell/AcupointArray.h"
#include "massage_cell/GetAcupoint.h"
#include "massage_cell/LocalizePixels.h"
#include "massage_cell/cect/acupoint_model.h"
#include "spin_util.h"
#include "test_util.h"

namespace {

using massage_cell::AcupointArray;
using massage_cell::AcupointArrayConstPtr;
using massage_cell::GetAcupoint;
using massage_cell::LocalizePixels;
using massage_cell::test::median;
using massage_cell::test::spinUntil;

const std::string kOptical = "stereo_left_optical_frame";
const std::string kRightOptical = "stereo_right_optical_frame";

/// Status values of one node's "acupoints (cect)" diagnostics.
struct CectStatus {
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

ros::Subscriber watchDiagnostics(ros::NodeHandle& nh, const std::string& node, CectStatus& status) {
  return nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 50, [&status, node](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        for (const auto& s : msg->status) {
          if (s.name != node + ": acupoints (cect)") continue;
          status.seen = true;
          for (const auto& kv : s.values) status.values[kv.key] = kv.value;
        }
      });
}

int countValid(const AcupointArray& msg) {
  return static_cast<int>(
      std::count_if(msg.acupoints.begin(), msg.acupoints.end(), [](const auto& a) { return a.valid; }));
}

const massage_cell::Acupoint* findPoint(const AcupointArray& msg, const std::string& name) {
  for (const auto& a : msg.acupoints)
    if (a.name == name) return &a;
  return nullptr;
}

Eigen::Vector3d vec(const geometry_msgs::Point& p) { return Eigen::Vector3d(p.x, p.y, p.z); }

class CectNode : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(pnh_.getParam("bag", bag_path_));
    ASSERT_TRUE(pnh_.getParam("ground_truth", ground_truth_path_));
    std::string acupoints_path;
    ASSERT_TRUE(pnh_.getParam("acupoints", acupoints_path));
    pnh_.param("tolerance", tolerance_, tolerance_);
    names_ = massage_cell::cect::loadAcupointModel(acupoints_path).names();
    ASSERT_FALSE(names_.empty());
  }
  ros::NodeHandle nh_, pnh_{"~"};
  std::string bag_path_, ground_truth_path_;
  double tolerance_ = 0.03;
  std::vector<std::string> names_;
};

// ------------------------------------------------------------------ bag --

TEST_F(CectNode, BagOutputs) {
  // Ground truth: the acupoints per frame in the left optical frame; frame i
  // is the bag's i-th pair (10 Hz from its first stamp).
  const YAML::Node gt = YAML::LoadFile(ground_truth_path_);
  const double gt_rate = gt["rate"].as<double>();
  std::vector<std::map<std::string, Eigen::Vector3d>> truth;
  for (const auto& frame : gt["frames"]) {
    truth.emplace_back();
    for (const auto& point : frame["acupoints"]) {
      truth.back()[point.first.as<std::string>()] =
          Eigen::Vector3d(point.second[0].as<double>(), point.second[1].as<double>(), point.second[2].as<double>());
    }
  }
  ASSERT_GT(truth.size(), 10u);
  for (const auto& name : names_) ASSERT_TRUE(truth[0].count(name)) << name << " has no ground truth";
  ros::Time first_stamp;
  {
    rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{"/stereo/left/camera_info"}));
    ASSERT_NE(view.begin(), view.end());
    first_stamp = view.begin()->instantiate<sensor_msgs::CameraInfo>()->header.stamp;
  }
  auto truthAt = [&](const ros::Time& stamp) -> const std::map<std::string, Eigen::Vector3d>& {
    const long index = std::lround((stamp - first_stamp).toSec() * gt_rate);
    EXPECT_GE(index, 0);
    EXPECT_LT(index, static_cast<long>(truth.size()));
    return truth[std::clamp<long>(index, 0, static_cast<long>(truth.size()) - 1)];
  };

  tf2_ros::Buffer tf_buffer(ros::Duration(60.0));
  tf2_ros::TransformListener tf_listener(tf_buffer);
  std::vector<AcupointArrayConstPtr> arrays;
  std::set<ros::Time> input_stamps;
  CectStatus status;
  int tf_messages = 0;  // the bag waits for a subscriber on every topic, /tf_static too
  std::vector<ros::Subscriber> subs;
  subs.push_back(nh_.subscribe<AcupointArray>("/stereo/acupoints", 100,
                                              [&](const AcupointArrayConstPtr& m) { arrays.push_back(m); }));
  subs.push_back(nh_.subscribe<sensor_msgs::CameraInfo>(
      "/stereo/left/camera_info", 100,
      [&](const sensor_msgs::CameraInfoConstPtr& m) { input_stamps.insert(m->header.stamp); }));
  subs.push_back(
      nh_.subscribe<tf2_msgs::TFMessage>("/tf_static", 10, [&](const tf2_msgs::TFMessageConstPtr&) { ++tf_messages; }));
  subs.push_back(watchDiagnostics(nh_, "stereo/cect", status));  // the last subscriber the bag waits for

  // 1. Acupoints with every point valid, while the bag plays (50 pairs in 5
  // s): the services below need current estimates (max_age), so go on after
  // 15 pairs at most.
  const std::size_t n = names_.size();
  auto allValid = [&] { return !arrays.empty() && countValid(*arrays.back()) == static_cast<int>(n); };
  ASSERT_TRUE(spinUntil([&] { return allValid() || arrays.size() >= 15; }, 40.0))
      << "no acupoints from /stereo/cect (" << arrays.size() << " messages, " << input_stamps.size() << " input pairs)";
  ASSERT_FALSE(arrays.empty()) << "no acupoints from /stereo/cect";
  const AcupointArrayConstPtr first_full = arrays.back();
  EXPECT_TRUE(allValid()) << "only " << countValid(*first_full) << " of " << n << " acupoints valid; e.g. " << [&] {
    for (const auto& a : first_full->acupoints)
      if (!a.valid) return a.name + ": " + a.reason;
    return std::string();
  }();

  // 2. ~get_acupoint while the estimates are current.
  ros::ServiceClient get_client = nh_.serviceClient<GetAcupoint>("/stereo/cect/get_acupoint");
  ros::ServiceClient localize_client = nh_.serviceClient<LocalizePixels>("/stereo/cect/localize_pixels");
  ASSERT_TRUE(get_client.waitForExistence(ros::Duration(5.0)));
  ASSERT_TRUE(localize_client.waitForExistence(ros::Duration(5.0)));
  const std::string probe = std::find(names_.begin(), names_.end(), "GV9") != names_.end() ? "GV9" : names_.front();
  GetAcupoint optical;
  optical.request.name = probe;
  ASSERT_TRUE(get_client.call(optical));
  ASSERT_TRUE(optical.response.success) << optical.response.message;
  EXPECT_EQ(optical.response.point.header.frame_id, kOptical);
  spinUntil([&] { return input_stamps.count(optical.response.point.header.stamp) > 0; }, 2.0);
  EXPECT_TRUE(input_stamps.count(optical.response.point.header.stamp)) << "the estimate's stamp is no input stamp";
  const Eigen::Vector3d probe_position = vec(optical.response.point.point);
  EXPECT_LT((probe_position - truthAt(optical.response.point.header.stamp).at(probe)).norm(), tolerance_)
      << probe << " from get_acupoint: " << probe_position.transpose();
  EXPECT_GT(optical.response.covariance[0], 0.0);
  EXPECT_GT(optical.response.covariance[8], 0.0);

  GetAcupoint right;  // the bag's static transform: the right camera 0.1 m along +x, no rotation
  right.request.name = probe;
  right.request.target_frame = kRightOptical;
  ASSERT_TRUE(get_client.call(right));
  ASSERT_TRUE(right.response.success) << right.response.message;
  EXPECT_EQ(right.response.point.header.frame_id, kRightOptical);
  const Eigen::Vector3d in_right = vec(right.response.point.point);
  EXPECT_LT((in_right - (probe_position - Eigen::Vector3d(0.1, 0.0, 0.0))).norm(), 0.01)
      << probe << " in " << kRightOptical << ": " << in_right.transpose() << ", in " << kOptical << ": "
      << probe_position.transpose();

  GetAcupoint unknown;
  unknown.request.name = "NO_SUCH_POINT";
  ASSERT_TRUE(get_client.call(unknown));
  EXPECT_FALSE(unknown.response.success);
  EXPECT_NE(unknown.response.message.find("unknown acupoint 'NO_SUCH_POINT'"), std::string::npos)
      << unknown.response.message;
  EXPECT_NE(unknown.response.message.find(probe), std::string::npos) << "the known names are listed";

  GetAcupoint bad_frame;
  bad_frame.request.name = probe;
  bad_frame.request.target_frame = "no_such_frame";
  ASSERT_TRUE(get_client.call(bad_frame));
  EXPECT_FALSE(bad_frame.response.success);
  EXPECT_NE(bad_frame.response.message.find("'no_such_frame'"), std::string::npos) << bad_frame.response.message;

  // 3. ~localize_pixels: the probe's pixel and the image centre are on the
  // back, a corner of the image (the table) and a pixel outside it are not.
  const massage_cell::Acupoint* probe_point = findPoint(*arrays.back(), probe);
  ASSERT_NE(probe_point, nullptr);
  ASSERT_TRUE(std::isfinite(probe_point->u) && std::isfinite(probe_point->v));
  LocalizePixels localize;
  for (const auto& [u, v] : std::vector<std::pair<double, double>>{
           {probe_point->u, probe_point->v}, {159.5, 119.5}, {3.0, 3.0}, {-50.0, -50.0}}) {
    geometry_msgs::Point p;
    p.x = u;
    p.y = v;
    localize.request.pixels.push_back(p);
  }
  ASSERT_TRUE(localize_client.call(localize));
  const auto& answer = localize.response;
  ASSERT_TRUE(answer.success) << answer.message;
  ASSERT_EQ(answer.points.size(), 4u);
  ASSERT_EQ(answer.valid.size(), 4u);
  ASSERT_EQ(answer.reasons.size(), 4u);
  ASSERT_EQ(answer.covariances.size(), 36u);
  EXPECT_EQ(answer.header.frame_id, kOptical);
  // The node may have seen a pair whose camera_info has not reached us yet.
  spinUntil([&] { return input_stamps.count(answer.header.stamp) > 0; }, 2.0);
  EXPECT_TRUE(input_stamps.count(answer.header.stamp));
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(answer.valid[i]) << "pixel " << i << ": " << answer.reasons[i];
    EXPECT_GT(answer.points[i].z, 0.6) << "pixel " << i;
    EXPECT_LT(answer.points[i].z, 1.0) << "pixel " << i;
    EXPECT_GT(answer.covariances[9 * i], 0.0);
  }
  // The probe's own pixel lands on (the unfiltered version of) the probe.
  EXPECT_LT((vec(answer.points[0]) - probe_position).norm(), 0.02) << vec(answer.points[0]).transpose();
  for (int i = 2; i < 4; ++i) {
    EXPECT_FALSE(answer.valid[i]) << "pixel " << i << " is off the back";
    EXPECT_FALSE(answer.reasons[i].empty()) << "pixel " << i << " has no reason";
  }

  // 4. Every pair of the bag, and the node's output for the last one.
  spinUntil([&] { return input_stamps.size() >= truth.size(); }, 20.0);
  ASSERT_EQ(input_stamps.size(), truth.size()) << "the bag did not replay every pair";
  spinUntil([&] { return arrays.back()->header.stamp == *input_stamps.rbegin(); }, 5.0);
  spinUntil([] { return false; }, 1.5);  // the last diagnostics

  // 5. A tf frame for every acupoint (tf keeps 60 s here).
  std::vector<std::string> missing;
  for (const auto& name : names_) {
    if (!spinUntil([&] { return tf_buffer.canTransform(kOptical, "acupoint/" + name, ros::Time(0)); }, 0.5)) {
      missing.push_back(name);
    }
  }
  EXPECT_TRUE(missing.empty()) << missing.size() << " acupoints have no tf frame acupoint/<name>: " << [&] {
    std::string list;
    for (const auto& name : missing) list += (list.empty() ? "" : ", ") + name;
    return list;
  }();

  // 6. Every message: all names in model order, input stamps, the left
  // optical frame; the tf frames at a message's stamp are its positions; the
  // positions agree with the ground truth.
  std::vector<double> errors;
  std::map<std::string, std::vector<double>> errors_of;
  int tf_checked = 0;
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    const AcupointArray& msg = *arrays[k];
    EXPECT_TRUE(input_stamps.count(msg.header.stamp)) << "acupoints stamp " << msg.header.stamp << " is no input stamp";
    EXPECT_EQ(msg.header.frame_id, kOptical);
    ASSERT_EQ(msg.acupoints.size(), n);
    const auto& t = truthAt(msg.header.stamp);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = msg.acupoints[i];
      EXPECT_EQ(a.name, names_[i]);
      EXPECT_FALSE(a.region.empty()) << a.name;
      if (!a.valid) {
        EXPECT_FALSE(a.reason.empty()) << a.name << " is invalid without a reason";
        continue;
      }
      EXPECT_GT(a.covariance[0], 0.0) << a.name;
      const double e = (vec(a.position) - t.at(a.name)).norm();
      if (k >= 5) {  // the filter has settled
        errors.push_back(e);
        errors_of[a.name].push_back(e);
      }
    }
    if (k == arrays.size() / 2) {
      for (const std::string& name : {probe, names_.back()}) {
        const massage_cell::Acupoint* a = findPoint(msg, name);
        if (!a || !a->valid) continue;
        geometry_msgs::TransformStamped tf;
        ASSERT_NO_THROW(tf = tf_buffer.lookupTransform(kOptical, "acupoint/" + name, msg.header.stamp));
        EXPECT_NEAR(tf.transform.translation.x, a->position.x, 1e-6);
        EXPECT_NEAR(tf.transform.translation.y, a->position.y, 1e-6);
        EXPECT_NEAR(tf.transform.translation.z, a->position.z, 1e-6);
        EXPECT_DOUBLE_EQ(tf.transform.rotation.w, 1.0);
        ++tf_checked;
      }
    }
  }
  EXPECT_GT(tf_checked, 0);
  ASSERT_FALSE(errors.empty());
  EXPECT_LT(median(errors), tolerance_) << "median acupoint error over all pairs and points";
  long within = std::count_if(errors.begin(), errors.end(), [&](double e) { return e <= tolerance_; });
  EXPECT_GE(within, static_cast<long>(0.8 * errors.size()))
      << within << " of " << errors.size() << " acupoint positions within " << tolerance_ << " m";
  for (const std::string name : {"GV14", "GV9", "GV3", "BL23_L", "BL23_R", "EX_B2_T5_L", "GB21_R"}) {
    if (!errors_of.count(name)) continue;
    EXPECT_LT(median(errors_of[name]), tolerance_) << name << ": median error";
  }

  // 7. Diagnostics of the node on the bag.
  ASSERT_TRUE(status.seen) << "no diagnostics from stereo/cect";
  EXPECT_EQ(status.count("bad pairs"), 0) << status.text("last error");
  EXPECT_EQ(status.count("pairs received"), static_cast<long>(truth.size()));
  EXPECT_GE(status.count("pairs processed"), static_cast<long>(arrays.size()));
  EXPECT_EQ(status.count("pairs without acupoints"), 0) << status.text("last reason");
  EXPECT_EQ(status.count("acupoints"), static_cast<long>(n));
  EXPECT_GT(tf_messages, 0) << "no /tf_static from the bag";
}

// ------------------------------------------------------------ bad input --

struct StereoPair {
  sensor_msgs::Image left, right;
  sensor_msgs::CameraInfo left_info, right_info;
};

TEST_F(CectNode, BadInputIsSkipped) {
  // A good pair from the bag, to be altered.
  StereoPair good;
  {
    rosbag::Bag bag(bag_path_, rosbag::bagmode::Read);
    rosbag::View view(bag);
    int found = 0;
    for (const auto& m : view) {
      if (found == 15) break;
      const std::string& topic = m.getTopic();
      if (topic == "/stereo/left/image_raw" && !(found & 1))
        good.left = *m.instantiate<sensor_msgs::Image>(), found |= 1;
      if (topic == "/stereo/right/image_raw" && !(found & 2))
        good.right = *m.instantiate<sensor_msgs::Image>(), found |= 2;
      if (topic == "/stereo/left/camera_info" && !(found & 4))
        good.left_info = *m.instantiate<sensor_msgs::CameraInfo>(), found |= 4;
      if (topic == "/stereo/right/camera_info" && !(found & 8))
        good.right_info = *m.instantiate<sensor_msgs::CameraInfo>(), found |= 8;
    }
    ASSERT_EQ(found, 15) << "the bag lacks a stereo pair";
  }

  ros::NodeHandle ns("/bad_input");
  ros::Publisher left_pub = ns.advertise<sensor_msgs::Image>("left/image_raw", 5);
  ros::Publisher right_pub = ns.advertise<sensor_msgs::Image>("right/image_raw", 5);
  ros::Publisher left_info_pub = ns.advertise<sensor_msgs::CameraInfo>("left/camera_info", 5);
  ros::Publisher right_info_pub = ns.advertise<sensor_msgs::CameraInfo>("right/camera_info", 5);
  std::vector<AcupointArrayConstPtr> outputs;
  ros::Subscriber sub =
      ns.subscribe<AcupointArray>("acupoints", 10, [&](const AcupointArrayConstPtr& m) { outputs.push_back(m); });
  CectStatus status;
  ros::Subscriber diag = watchDiagnostics(nh_, "bad_input/cect", status);
  ASSERT_TRUE(spinUntil(
      [&] {
        return left_pub.getNumSubscribers() && right_pub.getNumSubscribers() && left_info_pub.getNumSubscribers() &&
               right_info_pub.getNumSubscribers() && status.seen;
      },
      15.0))
      << "the node in /bad_input did not subscribe to its inputs (or sends no diagnostics)";
  ros::WallDuration(0.5).sleep();  // connections of the synchronised subscribers settle

  // Before any pair, ~localize_pixels says there is nothing to localise in.
  ros::ServiceClient localize_client = ns.serviceClient<LocalizePixels>("cect/localize_pixels");
  ASSERT_TRUE(localize_client.waitForExistence(ros::Duration(5.0)));
  LocalizePixels early;
  early.request.pixels.resize(1);
  early.request.pixels[0].x = 160;
  early.request.pixels[0].y = 120;
  ASSERT_TRUE(localize_client.call(early));
  EXPECT_FALSE(early.response.success);
  EXPECT_NE(early.response.message.find("no stereo pair analysed yet"), std::string::npos) << early.response.message;
  ASSERT_EQ(early.response.valid.size(), 1u);
  EXPECT_FALSE(early.response.valid[0]);

  int stamp_seconds = 1000;
  auto publish = [&](StereoPair pair) {
    const ros::Time stamp(++stamp_seconds, 0);
    for (auto* header : {&pair.left.header, &pair.right.header, &pair.left_info.header, &pair.right_info.header}) {
      header->stamp = stamp;
    }
    left_pub.publish(pair.left);
    left_info_pub.publish(pair.left_info);
    right_pub.publish(pair.right);
    right_info_pub.publish(pair.right_info);
    return stamp;
  };
  auto outputFor = [&](const ros::Time& stamp) -> AcupointArrayConstPtr {
    for (const auto& m : outputs)
      if (m->header.stamp == stamp) return m;
    return nullptr;
  };

  // A good pair: acupoints.
  ros::Time stamp = publish(good);
  ASSERT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0)) << "no acupoints for a good pair";
  EXPECT_GT(countValid(*outputFor(stamp)), static_cast<int>(names_.size()) / 2);

  // Each bad pair must be counted, named in the diagnostics and give no output.
  auto expectSkipped = [&](const std::string& what, const StereoPair& pair, const std::string& message) {
    const long before = std::max(0L, status.count("bad pairs"));
    const ros::Time bad_stamp = publish(pair);
    EXPECT_TRUE(spinUntil([&] { return status.count("bad pairs") > before; }, 6.0)) << what << ": not counted as bad";
    EXPECT_NE(status.text("last error").find(message), std::string::npos)
        << what << ": last error '" << status.text("last error") << "' does not say '" << message << "'";
    EXPECT_FALSE(outputFor(bad_stamp)) << what << ": acupoints were published";
  };

  StereoPair p = good;  // right image smaller than its camera_info
  p.right.width /= 2;
  p.right.height /= 2;
  p.right.step /= 2;
  p.right.data.resize(p.right.step * p.right.height);
  expectSkipped("image smaller than camera_info", p, "but its camera_info says");

  p = good;  // uncalibrated left camera
  std::fill(p.left_info.K.begin(), p.left_info.K.end(), 0.0);
  std::fill(p.left_info.P.begin(), p.left_info.P.end(), 0.0);
  expectSkipped("uncalibrated camera_info", p, "not calibrated");

  p = good;  // a vertical pair: the baseline in P[7] instead of P[3]
  p.right_info.P[7] = p.right_info.P[3];
  p.right_info.P[3] = 0.0;
  expectSkipped("vertical pair", p, "-fx * baseline");

  p = good;  // grey images: no skin colour to segment
  for (auto* image : {&p.left, &p.right}) {
    image->encoding = "mono8";
    image->step = image->width;
    image->data.assign(image->step * image->height, 0x80);
  }
  expectSkipped("mono8", p, "has no colour");

  // A pair without a back (an empty table): acupoints, all invalid with a
  // reason; ~localize_pixels says why; no bad pair (the input is fine).
  p = good;
  for (auto* image : {&p.left, &p.right}) image->data.assign(image->data.size(), 0xC8);  // uniform light grey
  stamp = publish(p);
  ASSERT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0)) << "no acupoints for a pair without a back";
  EXPECT_EQ(countValid(*outputFor(stamp)), 0);
  for (const auto& a : outputFor(stamp)->acupoints) EXPECT_FALSE(a.reason.empty()) << a.name;
  LocalizePixels empty_view = early;
  ASSERT_TRUE(localize_client.call(empty_view));
  EXPECT_FALSE(empty_view.response.success);
  EXPECT_NE(empty_view.response.message.find("no usable view of the back"), std::string::npos)
      << empty_view.response.message;
  EXPECT_TRUE(spinUntil([&] { return status.count("pairs without acupoints") == 1; }, 3.0))
      << "diagnostics: pairs without acupoints";

  // The node is alive and still processes a good pair.
  stamp = publish(good);
  EXPECT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0))
      << "no acupoints for the good pair after the bad ones";
  EXPECT_TRUE(spinUntil([&] { return status.count("pairs processed") == 3; }, 3.0)) << "diagnostics: processed pairs";
  EXPECT_GT(countValid(*outputFor(stamp)), static_cast<int>(names_.size()) / 2) << "the filter starts afresh";
  EXPECT_EQ(status.count("bad pairs"), 4);
  EXPECT_TRUE(ros::service::exists("/bad_input/cect/get_acupoint", false)) << "the node is gone";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cect_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
