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
// GivenLandmarksMoveTheLayout: a third node in /landmarks: ~set_landmark
// refuses before any pair, an unknown name and a pixel outside the image; C7
// given by pixel moves GV14 there; an rviz click (Publish Point) near GV3
// moves L4 (the nearer landmark) to it, a click on ~debug_image near GV14
// moves C7; ~save_client_profile refuses before any pair and with C7 alone,
// and with C7 and L4 both given writes the client's C7 -> L4; ~clear_landmarks
// brings the automatic layout back.
//
// Parameters (private): bag, ground_truth, acupoints (paths), tolerance (m, 0.03).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <geometry_msgs/Point.h>
#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <Eigen/Core>
#include <opencv2/imgproc.hpp>

#include "massage_cell/AcupointArray.h"
#include "massage_cell/GetAcupoint.h"
#include "massage_cell/LocalizePixels.h"
#include "massage_cell/SaveClientProfile.h"
#include "massage_cell/SetLandmark.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/tracker.h"
#include "spin_util.h"
#include "stereo_node_test.h"
#include "test_util.h"

namespace {

using massage_cell::AcupointArray;
using massage_cell::AcupointArrayConstPtr;
using massage_cell::GetAcupoint;
using massage_cell::LocalizePixels;
using massage_cell::SaveClientProfile;
using massage_cell::SetLandmark;
using namespace massage_cell::test;

const std::string kOptical = "stereo_left_optical_frame";
const std::string kRightOptical = "stereo_right_optical_frame";

const std::string kDiagnostics = "acupoints (cect)";  // the node's diagnostics task

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

/// The third node (/landmarks) as the landmark tests drive it; CectNode::connectToLandmarksNode connects it. Neither
/// copied nor moved: its subscriptions hold it.
struct LandmarksNode {
  LandmarksNode() : ns("/landmarks"), input(ns) {}
  LandmarksNode(const LandmarksNode&) = delete;
  LandmarksNode& operator=(const LandmarksNode&) = delete;

  /// `pair` published with a new stamp: the node's acupoints for it (null when none came within 15 s).
  AcupointArrayConstPtr layoutOf(const StereoPair& pair) {
    const ros::Time stamp = input.publish(pair);
    if (!spinUntil([&] { return !outputs.empty() && outputs.back()->header.stamp == stamp; }, 15.0)) return nullptr;
    return outputs.back();
  }
  /// ~set_landmark with `name` at the raw left pixel (u, v): the node's response (the call itself must go through).
  SetLandmark::Response setLandmark(const std::string& name, double u, double v) {
    SetLandmark call;
    call.request.name = name;
    call.request.u = u;
    call.request.v = v;
    EXPECT_TRUE(set_client.call(call));
    return call.response;
  }

  StereoPair good;  ///< the bag's first pair
  ros::NodeHandle ns;
  PairPublisher input;
  std::vector<AcupointArrayConstPtr> outputs;  ///< the node's acupoints, as they came
  ros::Subscriber acupoints, diagnostics;
  NodeStatus status;
  ros::ServiceClient set_client, clear_client;  ///< ~set_landmark, ~clear_landmarks
};

class CectNode : public StereoNodeTest {
 protected:
  CectNode() : StereoNodeTest(0.03) {}
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(StereoNodeTest::SetUp());
    std::string acupoints_path;
    ASSERT_TRUE(pnh_.getParam("acupoints", acupoints_path));
    names_ = massage_cell::cect::loadAcupointModel(acupoints_path).names();
    ASSERT_FALSE(names_.empty());
  }

  /// The landmark tests' first step: `node` holds the bag's first pair and is connected to the third node
  /// (/landmarks): the node subscribed to its pair input and sending diagnostics, its acupoints collected, its
  /// ~set_landmark and ~clear_landmarks there. No pair published yet.
  void connectToLandmarksNode(LandmarksNode* node) {
    ASSERT_NO_FATAL_FAILURE(readFirstPair(bag_path_, &node->good));
    node->acupoints = node->ns.subscribe<AcupointArray>(
        "acupoints", 10, [node](const AcupointArrayConstPtr& m) { node->outputs.push_back(m); });
    node->diagnostics = watchDiagnostics(nh_, "landmarks/cect", kDiagnostics, node->status);
    ASSERT_NO_FATAL_FAILURE(waitForNode(node->input, node->status, "/landmarks"));
    node->set_client = node->ns.serviceClient<SetLandmark>("cect/set_landmark");
    node->clear_client = node->ns.serviceClient<std_srvs::Trigger>("cect/clear_landmarks");
    ASSERT_TRUE(node->set_client.waitForExistence(ros::Duration(5.0)));
    ASSERT_TRUE(node->clear_client.waitForExistence(ros::Duration(5.0)));
  }

  std::vector<std::string> names_;
};

// ------------------------------------------------------------------ bag --

TEST_F(CectNode, BagOutputs) {
  // Ground truth: the acupoints per frame in the left optical frame.
  GroundTruth gt;
  ASSERT_NO_FATAL_FAILURE(loadGroundTruth(ground_truth_path_, bag_path_, &gt));
  const auto& truth = gt.frames;
  for (const auto& name : names_) ASSERT_TRUE(truth[0].count(name)) << name << " has no ground truth";
  auto truthAt = [&](const ros::Time& stamp) -> const std::map<std::string, Eigen::Vector3d>& {
    const long index = gt.index(stamp);
    EXPECT_GE(index, 0);
    EXPECT_LT(index, static_cast<long>(truth.size()));
    return truth[std::clamp<long>(index, 0, static_cast<long>(truth.size()) - 1)];
  };

  tf2_ros::Buffer tf_buffer(ros::Duration(60.0));
  tf2_ros::TransformListener tf_listener(tf_buffer);
  std::vector<AcupointArrayConstPtr> arrays;
  BagInputs bag;
  const std::set<ros::Time>& input_stamps = bag.stamps;
  NodeStatus status;
  std::vector<ros::Subscriber> subs = bag.subscribe(nh_);
  subs.push_back(nh_.subscribe<AcupointArray>("/stereo/acupoints", 100,
                                              [&](const AcupointArrayConstPtr& m) { arrays.push_back(m); }));
  subs.push_back(watchDiagnostics(nh_, "stereo/cect", kDiagnostics, status));  // the last subscriber the bag waits for

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
  ASSERT_TRUE(spinUntil([&] { return arrays.back()->header.stamp == *input_stamps.rbegin(); }, 15.0))
      << "no acupoints for the bag's last pair";
  // The diagnostics are published once a second on the wall clock: wait for the one that has counted the bag's last
  // pair and every pair whose acupoints came (a loaded machine can still be processing the last one).
  const auto last_counted = [&] {
    return status.count("pairs received") >= static_cast<long>(truth.size()) &&
           status.count("pairs processed") >= static_cast<long>(arrays.size());
  };
  ASSERT_TRUE(spinUntil(last_counted, 10.0))
      << "no diagnostics counting the bag's last pair: " << status.count("pairs received") << " pairs received, "
      << status.count("pairs processed") << " processed, " << arrays.size() << " acupoint messages";

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
  std::size_t valid_min = n, valid_max = 0;
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    const AcupointArray& msg = *arrays[k];
    const auto valid = static_cast<std::size_t>(
        std::count_if(msg.acupoints.begin(), msg.acupoints.end(), [](const auto& a) { return a.valid; }));
    valid_min = std::min(valid_min, valid);
    valid_max = std::max(valid_max, valid);
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

  // The node's figures on the bag, re-measured by every run (README, cect).
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  std::printf(
      "cect on the bag: %zu pairs in, %zu acupoint messages, %zu..%zu of %zu points valid; "
      "error to the ground-truth acupoints (after 5 messages): median %.1f mm, p90 %.1f mm, max %.1f mm\n",
      truth.size(), arrays.size(), valid_min, valid_max, n, 1e3 * median(errors),
      1e3 * sorted[static_cast<std::size_t>(0.9 * (sorted.size() - 1))], 1e3 * sorted.back());

  // 7. Diagnostics of the node on the bag (the one that counted the bag's last pair: waited for in 4).
  ASSERT_TRUE(status.seen) << "no diagnostics from stereo/cect";
  EXPECT_EQ(status.count("bad pairs"), 0) << status.text("last error");
  EXPECT_EQ(status.count("pairs received"), static_cast<long>(truth.size()));
  EXPECT_GE(status.count("pairs processed"), static_cast<long>(arrays.size()));
  EXPECT_EQ(status.count("pairs without acupoints"), 0) << status.text("last reason");
  EXPECT_EQ(status.count("acupoints"), static_cast<long>(n));
  EXPECT_GT(bag.tf_messages, 0) << "no /tf_static from the bag";
  std::printf("cect on the bag: diagnostics: %s pairs processed, %s dropped, last processing %s ms, CECT %s ms\n",
              status.text("pairs processed").c_str(), status.text("dropped pairs").c_str(),
              status.text("last processing time (ms)").c_str(), status.text("last CECT time (ms)").c_str());
}

// ------------------------------------------------------------ bad input --

/// The pair as a camera of twice the resolution would see it: images scaled up,
/// K and P with them (pixel centres kept: c' = 2 c + 0.5).
void doubleResolution(StereoPair* pair) {
  for (sensor_msgs::Image* image : {&pair->left, &pair->right}) {
    const int channels = static_cast<int>(image->step / image->width);
    const cv::Mat in(static_cast<int>(image->height), static_cast<int>(image->width), CV_8UC(channels),
                     image->data.data(), image->step);
    cv::Mat out;
    cv::resize(in, out, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
    image->width *= 2;
    image->height *= 2;
    image->step *= 2;
    image->data.assign(out.data, out.data + out.total() * out.elemSize());
  }
  for (sensor_msgs::CameraInfo* info : {&pair->left_info, &pair->right_info}) {
    info->width *= 2;
    info->height *= 2;
    for (int row = 0; row < 2; ++row) {
      for (int j = 0; j < 3; ++j) info->K[3 * row + j] *= 2.0;
      for (int j = 0; j < 4; ++j) info->P[4 * row + j] *= 2.0;
    }
    info->K[2] += 0.5;
    info->K[5] += 0.5;
    info->P[2] += 0.5;
    info->P[6] += 0.5;
  }
}

TEST_F(CectNode, BadInputIsSkipped) {
  // A good pair from the bag, to be altered.
  StereoPair good;
  ASSERT_NO_FATAL_FAILURE(readFirstPair(bag_path_, &good));

  ros::NodeHandle ns("/bad_input");
  PairPublisher input(ns);
  std::vector<AcupointArrayConstPtr> outputs;
  ros::Subscriber sub =
      ns.subscribe<AcupointArray>("acupoints", 10, [&](const AcupointArrayConstPtr& m) { outputs.push_back(m); });
  NodeStatus status;
  ros::Subscriber diag = watchDiagnostics(nh_, "bad_input/cect", kDiagnostics, status);
  ASSERT_NO_FATAL_FAILURE(waitForNode(input, status, "/bad_input"));

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

  auto outputFor = [&](const ros::Time& stamp) -> AcupointArrayConstPtr {
    for (const auto& m : outputs)
      if (m->header.stamp == stamp) return m;
    return nullptr;
  };

  // A good pair: acupoints.
  ros::Time stamp = input.publish(good);
  ASSERT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0)) << "no acupoints for a good pair";
  EXPECT_GT(countValid(*outputFor(stamp)), static_cast<int>(names_.size()) / 2);

  // Each bad pair must be counted, named in the diagnostics and give no output.
  auto expectSkipped = [&](const std::string& what, const StereoPair& pair, const std::string& message) {
    EXPECT_FALSE(outputFor(publishBadPair(input, status, what, pair, message))) << what << ": acupoints were published";
  };

  StereoPair p = good;  // right image smaller than its camera_info
  halve(p.right);
  expectSkipped("image smaller than camera_info", p, "but its camera_info says");

  p = good;  // uncalibrated left camera
  uncalibrate(p.left_info);
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
  stamp = input.publish(p);
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
  stamp = input.publish(good);
  EXPECT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0))
      << "no acupoints for the good pair after the bad ones";
  EXPECT_TRUE(spinUntil([&] { return status.count("pairs processed") == 3; }, 3.0)) << "diagnostics: processed pairs";
  EXPECT_GT(countValid(*outputFor(stamp)), static_cast<int>(names_.size()) / 2) << "the filter starts afresh";
  EXPECT_EQ(status.count("bad pairs"), 4);
  EXPECT_TRUE(ros::service::exists("/bad_input/cect/get_acupoint", false)) << "the node is gone";

  // The same pair at twice the resolution: processed decimated (~max_width), its
  // acupoints' pixels in the camera's own (doubled) pixels.
  const AcupointArrayConstPtr normal = outputFor(stamp);
  p = good;
  doubleResolution(&p);
  stamp = input.publish(p);
  ASSERT_TRUE(spinUntil([&] { return outputFor(stamp) != nullptr; }, 15.0)) << "no acupoints for the doubled pair";
  const AcupointArrayConstPtr doubled = outputFor(stamp);
  int compared = 0;
  for (std::size_t i = 0; i < doubled->acupoints.size() && i < normal->acupoints.size(); ++i) {
    const auto &a = normal->acupoints[i], &b = doubled->acupoints[i];
    if (!std::isfinite(a.u) || !std::isfinite(b.u)) continue;
    ++compared;
    EXPECT_NEAR(b.u, 2.0 * a.u + 0.5, 2.0) << a.name;
    EXPECT_NEAR(b.v, 2.0 * a.v + 0.5, 2.0) << a.name;
  }
  EXPECT_GT(compared, static_cast<int>(names_.size()) / 2);
  EXPECT_GT(countValid(*doubled), static_cast<int>(names_.size()) / 2);
}

// ------------------------------------------------------------ landmarks --

/// The acupoint `name`'s placed raw pixel in `msg` (NaN when not placed).
cv::Point2d placedPixel(const AcupointArray& msg, const std::string& name) {
  const massage_cell::Acupoint* a = findPoint(msg, name);
  return a ? cv::Point2d(a->u, a->v) : cv::Point2d(std::nan(""), std::nan(""));
}

TEST_F(CectNode, GivenLandmarksMoveTheLayout) {
  LandmarksNode node;
  ASSERT_NO_FATAL_FAILURE(connectToLandmarksNode(&node));
  const StereoPair& good = node.good;
  ros::Publisher clicks = node.ns.advertise<geometry_msgs::PointStamped>("clicked_point", 5);
  ros::Publisher image_clicks = node.ns.advertise<geometry_msgs::PointStamped>("cect/debug_image_mouse_left", 5);
  ASSERT_TRUE(spinUntil([&] { return clicks.getNumSubscribers() > 0 && image_clicks.getNumSubscribers() > 0; }, 5.0));

  ros::ServiceClient save_client = node.ns.serviceClient<SaveClientProfile>("cect/save_client_profile");
  ASSERT_TRUE(save_client.waitForExistence(ros::Duration(5.0)));
  const std::string profile_path = "/tmp/test_cect_node_profile_" + std::to_string(::getpid()) + ".yaml";
  std::remove(profile_path.c_str());
  auto saveProfile = [&](const std::string& path) {
    SaveClientProfile call;
    call.request.path = path;
    call.request.client = "test client";
    EXPECT_TRUE(save_client.call(call));
    return call.response;
  };

  // Before any pair there is no view to place a landmark in, nor a layout to save.
  SetLandmark::Response early = node.setLandmark("C7", 160.0, 60.0);
  EXPECT_FALSE(early.success);
  EXPECT_NE(early.message.find("no stereo pair analysed yet"), std::string::npos) << early.message;
  SaveClientProfile::Response early_save = saveProfile(profile_path);
  EXPECT_FALSE(early_save.success);
  EXPECT_NE(early_save.message.find("no pair analysed yet"), std::string::npos) << early_save.message;

  // 1. The automatic layout.
  const AcupointArrayConstPtr automatic = node.layoutOf(good);
  ASSERT_TRUE(automatic) << "no acupoints for a good pair";
  const cv::Point2d gv14 = placedPixel(*automatic, "GV14"), gv3 = placedPixel(*automatic, "GV3");
  ASSERT_TRUE(std::isfinite(gv14.x) && std::isfinite(gv3.x)) << "GV14 and GV3 placed";

  // 2. C7 given 8 px toward the feet by ~set_landmark: GV14 (at C7) moves there, GV3 (at L4) stays.
  SetLandmark::Response c7 = node.setLandmark("C7", gv14.x, gv14.y + 8.0);
  ASSERT_TRUE(c7.success) << c7.message;
  EXPECT_NE(c7.message.find("C7 (service)"), std::string::npos) << c7.message;
  SetLandmark::Response unknown = node.setLandmark("T3", gv14.x, gv14.y);
  EXPECT_FALSE(unknown.success);
  EXPECT_NE(unknown.message.find("unknown landmark 'T3'"), std::string::npos) << unknown.message;
  SetLandmark::Response outside = node.setLandmark("L4", -100.0, -100.0);
  EXPECT_FALSE(outside.success);
  EXPECT_NE(outside.message.find("outside"), std::string::npos) << outside.message;
  AcupointArrayConstPtr given = node.layoutOf(good);
  ASSERT_TRUE(given);
  EXPECT_NEAR(placedPixel(*given, "GV14").x, gv14.x, 0.6);
  EXPECT_NEAR(placedPixel(*given, "GV14").y, gv14.y + 8.0, 0.6);
  EXPECT_NEAR(placedPixel(*given, "GV3").y, gv3.y, 0.6);
  // C7 alone does not measure the client's C7 -> L4: no profile.
  SaveClientProfile::Response one_given = saveProfile(profile_path);
  EXPECT_FALSE(one_given.success);
  EXPECT_NE(one_given.message.find("C7 and L4 must both be given"), std::string::npos) << one_given.message;
  EXPECT_FALSE(std::ifstream(profile_path).good()) << "nothing written";

  // 3. rviz's Publish Point 2 cm toward the feet of GV3's 3D point: the nearest landmark, L4, goes there.
  const massage_cell::Acupoint* gv3_point = findPoint(*given, "GV3");
  ASSERT_TRUE(gv3_point && gv3_point->valid) << "GV3 localised";
  geometry_msgs::PointStamped click;
  click.header.frame_id = kOptical;
  click.point = gv3_point->position;
  click.point.y += 0.02;  // the optical frame's y: down the image, toward the feet
  const auto& P = good.left_info.P;
  const double expected_v = P[5] * click.point.y / click.point.z + P[6];
  clicks.publish(click);
  bool moved = false;
  for (int k = 0; k < 5 && !moved; ++k) {  // the click and a pair may cross
    given = node.layoutOf(good);
    ASSERT_TRUE(given);
    moved = std::abs(placedPixel(*given, "GV3").y - expected_v) < 1.0;
  }
  EXPECT_TRUE(moved) << "GV3 at v " << placedPixel(*given, "GV3").y << ", the click at v " << expected_v
                     << " (it was at " << gv3.y << ")";
  EXPECT_NEAR(placedPixel(*given, "GV14").y, gv14.y + 8.0, 0.6) << "C7 stays given";

  // 4. ~save_client_profile with C7 and L4 both given: the file holds the C7 -> L4 the node reports, and it is the
  // given landmarks' length: C7 -> L4 along the body's axis (the chord between them, measureLevelsIn3D), so within
  // the depth noise of the straight line between the layout's 3D points at C7 and L4 (the automatic layout's is
  // printed beside it). No path refused.
  SaveClientProfile::Response saved = saveProfile(profile_path);
  ASSERT_TRUE(saved.success) << saved.message;
  EXPECT_NE(saved.message.find("client 'test client'"), std::string::npos) << saved.message;
  const massage_cell::cect::ClientProfile profile = massage_cell::cect::loadClientProfile(profile_path);
  EXPECT_EQ(profile.client, "test client");
  const std::size_t reported_at = saved.message.find("C7 -> L4 ");
  ASSERT_NE(reported_at, std::string::npos) << saved.message;
  const double reported = std::stod(saved.message.substr(reported_at + 9));
  EXPECT_NEAR(profile.c7_to_l4_m, reported, 1e-5) << "the file's C7 -> L4 is not the one the node reports";
  // The straight line between the layout's points at C7 and L4 (GV14 below C7's spinous process, GV3 below L4's),
  // CECT's 3D of each.
  auto chordOf = [&](const AcupointArray& layout) {
    const massage_cell::Acupoint *gv14_at = findPoint(layout, "GV14"), *gv3_at = findPoint(layout, "GV3");
    if (!gv14_at || !gv3_at || !gv14_at->valid || !gv3_at->valid) return std::nan("");
    return (vec(gv3_at->position) - vec(gv14_at->position)).norm();
  };
  // The two points' depth noise and their offsets from the levels' rows (1-1.5 cm seen); beyond the profile's own
  // length tolerance (3 cm) the saved length would refuse this very client in the next session.
  constexpr double kChordSlack = 0.03;
  const double chord = chordOf(*given);
  ASSERT_TRUE(std::isfinite(chord)) << "GV14 and GV3 of the given layout not localised: "
                                    << (findPoint(*given, "GV14") ? findPoint(*given, "GV14")->reason : "");
  std::printf("saved C7 -> L4 %.4f m; straight line between the given C7 and L4 %.4f m (automatic ones %.4f m)\n",
              profile.c7_to_l4_m, chord, chordOf(*automatic));
  EXPECT_NEAR(profile.c7_to_l4_m, chord, kChordSlack) << "not the given layout's C7 -> L4";
  std::remove(profile_path.c_str());
  SaveClientProfile::Response no_path = saveProfile("");
  EXPECT_FALSE(no_path.success);
  EXPECT_NE(no_path.message.find("no path"), std::string::npos) << no_path.message;

  // 5. A click on ~debug_image (scaled up to at least 960 px, the node's debug width) 4 px above the automatic C7:
  // C7, the nearer landmark, goes there.
  const double k = massage_cell::cect::debugImageScale(static_cast<int>(good.left_info.width), 960);
  geometry_msgs::PointStamped pixel;
  pixel.point.x = (gv14.x + 0.5) * k - 0.5;
  pixel.point.y = (gv14.y - 4.0 + 0.5) * k - 0.5;
  image_clicks.publish(pixel);
  moved = false;
  for (int i = 0; i < 5 && !moved; ++i) {
    given = node.layoutOf(good);
    ASSERT_TRUE(given);
    moved = std::abs(placedPixel(*given, "GV14").y - (gv14.y - 4.0)) < 0.6;
  }
  EXPECT_TRUE(moved) << "GV14 at v " << placedPixel(*given, "GV14").y << ", the click at v " << gv14.y - 4.0;

  // 6. ~clear_landmarks: the automatic layout again.
  std_srvs::Trigger clear;
  ASSERT_TRUE(node.clear_client.call(clear));
  EXPECT_TRUE(clear.response.success);
  EXPECT_NE(clear.response.message.find("C7 (clicked)"), std::string::npos) << clear.response.message;
  EXPECT_NE(clear.response.message.find("L4 (clicked)"), std::string::npos) << clear.response.message;
  const AcupointArrayConstPtr cleared = node.layoutOf(good);
  ASSERT_TRUE(cleared);
  EXPECT_NEAR(placedPixel(*cleared, "GV14").y, gv14.y, 0.3);
  EXPECT_NEAR(placedPixel(*cleared, "GV3").y, gv3.y, 0.3);
}

}  // namespace

/// Both images of `pair` moved `rows` rows down (the top row repeated above): the subject slid toward the feet,
/// parallel to the image plane, by rows x the metres per pixel.
StereoPair slid(StereoPair pair, int rows) {
  for (sensor_msgs::Image* image : {&pair.left, &pair.right}) {
    std::vector<std::uint8_t>& d = image->data;
    const std::size_t step = image->step, n = step * static_cast<std::size_t>(rows);
    std::copy_backward(d.begin(), d.end() - static_cast<std::ptrdiff_t>(n), d.end());
    for (int r = 1; r < rows; ++r) std::copy_n(d.begin(), step, d.begin() + static_cast<std::ptrdiff_t>(r * step));
  }
  return pair;
}

TEST_F(CectNode, AClientWhoMovesMakesTheGivenLandmarksStale) {
  LandmarksNode node;
  ASSERT_NO_FATAL_FAILURE(connectToLandmarksNode(&node));
  const StereoPair& good = node.good;
  ros::ServiceClient confirm_client = node.ns.serviceClient<std_srvs::Trigger>("cect/confirm_landmarks");
  ASSERT_TRUE(confirm_client.waitForExistence(ros::Duration(5.0)));
  auto give = [&](const std::string& name, const cv::Point2d& at) {
    const SetLandmark::Response response = node.setLandmark(name, at.x, at.y);
    EXPECT_TRUE(response.success) << response.message;
  };
  // The metres per pixel at the back: f 250 px, the back ~0.8 m away -> ~3.2 mm; 3 cm ~ 9 rows, 5 mm ~ 2 rows.
  const AcupointArrayConstPtr automatic = node.layoutOf(good);
  ASSERT_TRUE(automatic);
  const massage_cell::Acupoint* gv14 = findPoint(*automatic, "GV14");
  ASSERT_TRUE(gv14 && gv14->valid) << (gv14 ? gv14->reason : "");
  const double mpp = gv14->position.z / good.left_info.K[0];
  const int small_move = static_cast<int>(std::lround(0.005 / mpp)),
            large_move = static_cast<int>(std::lround(0.03 / mpp));

  // 0. Requests that name no place, or a place off the skin, are refused with the reason.
  SetLandmark nothing;
  nothing.request.name = "L4";
  ASSERT_TRUE(node.set_client.call(nothing));
  EXPECT_FALSE(nothing.response.success);
  EXPECT_NE(nothing.response.message.find("no point and no pixel"), std::string::npos) << nothing.response.message;
  SetLandmark deep;
  deep.request.name = "C7";
  deep.request.point.header.frame_id = kOptical;
  deep.request.point.point = gv14->position;
  deep.request.point.point.z += 0.69;  // 0.69 m below the skin, on the same ray
  ASSERT_TRUE(node.set_client.call(deep));
  EXPECT_FALSE(deep.response.success);
  EXPECT_NE(deep.response.message.find("from the skin measured at its pixel"), std::string::npos)
      << deep.response.message;

  // 1. C7 and L4 given 10 cm to the subject's right of the spine (a mis-click, or the previous client's places): not
  // trusted, the reason naming them; where the automatic layout has them (on the spine): trusted.
  const cv::Point2d beside(0.10 / mpp, 0.0);
  give("C7", placedPixel(*automatic, "GV14") + beside);
  give("L4", placedPixel(*automatic, "GV3") + beside);
  AcupointArrayConstPtr refused = node.layoutOf(good);
  ASSERT_TRUE(refused);
  EXPECT_FALSE(findPoint(*refused, "GV14")->valid);
  EXPECT_NE(findPoint(*refused, "GV14")->reason.find("the given C7 (service) lies"), std::string::npos)
      << findPoint(*refused, "GV14")->reason;
  EXPECT_NE(findPoint(*refused, "GV14")->reason.find("to the subject's right of the back's midline"),
            std::string::npos);
  give("C7", placedPixel(*automatic, "GV14"));
  give("L4", placedPixel(*automatic, "GV3"));
  AcupointArrayConstPtr given = node.layoutOf(good);
  ASSERT_TRUE(given);
  ASSERT_TRUE(findPoint(*given, "GV14")->valid) << findPoint(*given, "GV14")->reason;
  // 2. Breathing-sized: the client moved 5 mm: the landmarks follow the back.
  given = node.layoutOf(slid(good, small_move));
  ASSERT_TRUE(given);
  EXPECT_TRUE(findPoint(*given, "GV14")->valid) << findPoint(*given, "GV14")->reason;
  EXPECT_NEAR(placedPixel(*given, "GV14").y, placedPixel(*automatic, "GV14").y + small_move, 1.0) << "followed";
  // 3. The client slid 3 cm: no layout is trusted, each point saying why, until the landmarks are confirmed again.
  given = node.layoutOf(slid(good, large_move));
  ASSERT_TRUE(given);
  EXPECT_FALSE(findPoint(*given, "GV14")->valid);
  EXPECT_NE(findPoint(*given, "GV14")->reason.find("is stale: the back moved"), std::string::npos)
      << findPoint(*given, "GV14")->reason;
  EXPECT_EQ(std::count_if(given->acupoints.begin(), given->acupoints.end(),
                          [](const massage_cell::Acupoint& a) { return a.valid; }),
            0);
  given = node.layoutOf(slid(good, large_move));  // still not trusted on the next pair
  ASSERT_TRUE(given);
  EXPECT_FALSE(findPoint(*given, "GV14")->valid);
  std_srvs::Trigger confirm;
  ASSERT_TRUE(confirm_client.call(confirm));
  EXPECT_TRUE(confirm.response.success) << confirm.response.message;
  given = node.layoutOf(slid(good, large_move));
  ASSERT_TRUE(given);
  EXPECT_TRUE(findPoint(*given, "GV14")->valid) << "confirmed: " << findPoint(*given, "GV14")->reason;
  EXPECT_NEAR(placedPixel(*given, "GV14").y, placedPixel(*automatic, "GV14").y + large_move, 1.0)
      << "C7 carried with the back and confirmed there";
  std_srvs::Trigger clear;
  ASSERT_TRUE(node.clear_client.call(clear));
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cect_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
