// rostest of the arm node with simulated drives (test/ros/arm.test): the URDF
// and robot_state_publisher's tf tree, homing, move_to with a PointStamped in
// the camera's optical frame, a massage over two acupoint frames this node
// publishes, each refusal (envelope, depth, unknown frame, stale frame), an
// e-stop mid-move and its reset, an injected drive fault and its reset, an
// acupoint frame lost during a press (the tool retracts), the massage as an
// actionlib action (feedback and result, cancel during a press, a new goal
// while one runs, refused goals), and the real-time scheduling the
// diagnostics report (ArmNode.*). With a CAN interface that
// does not exist (test/ros/arm_bad_interface.test, ArmNodeBadInterface.*):
// one error naming it, the node keeps running and refuses every command.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <functional>
#include <future>
#include <limits>
#include <map>
#include <mutex>
#include <thread>

#include <pthread.h>
#include <sched.h>

#include <actionlib/client/simple_action_client.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_msgs/Bool.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <urdf/model.h>

#include "massage_cell/AcupointArray.h"
#include "massage_cell/ArmState.h"
#include "massage_cell/Massage.h"
#include "massage_cell/MassageAction.h"
#include "massage_cell/MoveTo.h"
#include "massage_cell/arm/config.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

const std::string kOptical = "stereo_left_optical_frame";
const std::string kBase = "arm_base_link";

struct Fixture {
  ros::NodeHandle nh;
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener{buffer};
  tf2_ros::TransformBroadcaster broadcaster;
  std::mutex mutex;
  massage_cell::ArmState state;
  bool have_state = false;
  sensor_msgs::JointState joints;
  std::map<std::string, Eigen::Vector3d> live;  // acupoint frames published with the current stamp (in the base frame)
  std::map<std::string, Eigen::Vector3d> old;   // ... published 2 s in the past
  ros::Subscriber state_sub = nh.subscribe<massage_cell::ArmState>("/arm/state", 10, [this](const auto& m) {
    std::lock_guard<std::mutex> lock(mutex);
    state = *m;
    have_state = true;
  });
  ros::Subscriber joint_sub = nh.subscribe<sensor_msgs::JointState>("/joint_states", 10, [this](const auto& m) {
    std::lock_guard<std::mutex> lock(mutex);
    joints = *m;
  });
  diagnostic_msgs::DiagnosticStatus diagnostics;  // the arm's latest
  std::vector<rosgraph_msgs::Log> arm_log;        // /rosout lines of the arm node
  ros::Subscriber diag_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10, [this](const auto& m) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& st : m->status) {
      if (st.name.find("arm") != std::string::npos) diagnostics = st;
    }
  });
  ros::Subscriber log_sub = nh.subscribe<rosgraph_msgs::Log>("/rosout", 100, [this](const auto& m) {
    std::lock_guard<std::mutex> lock(mutex);
    if (m->name == "/arm") arm_log.push_back(*m);
  });
  ros::Publisher estop_pub = nh.advertise<std_msgs::Bool>("/arm/estop", 1, true);
  ros::Publisher fault_pub = nh.advertise<std_msgs::String>("/arm/sim/inject_fault", 1, true);
  std::atomic<bool> stop{false};
  std::thread publisher;
  massage_cell::arm::ArmConfig config =
      massage_cell::arm::loadArmConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/arm.yaml");

  Fixture() {
    publisher = std::thread([this] {
      ros::WallRate rate(20.0);
      while (!stop && ros::ok()) {
        publishFrames();
        rate.sleep();
      }
    });
  }
  ~Fixture() {
    stop = true;
    publisher.join();
  }

  /// Acupoint frames as the CECT node would: children of the left optical frame.
  void publishFrames() {
    geometry_msgs::TransformStamped base_to_optical;
    try {
      base_to_optical = buffer.lookupTransform(kOptical, kBase, ros::Time(0));
    } catch (const tf2::TransformException&) {
      return;  // robot_state_publisher not up yet
    }
    const Eigen::Isometry3d T = tf2::transformToEigen(base_to_optical);
    std::vector<geometry_msgs::TransformStamped> out;
    std::lock_guard<std::mutex> lock(mutex);
    const ros::Time now = ros::Time::now();
    for (auto* set : {&live, &old}) {
      for (const auto& [name, p] : *set) {
        geometry_msgs::TransformStamped t;
        t.header.stamp = set == &live ? now : now - ros::Duration(2.0);
        t.header.frame_id = kOptical;
        t.child_frame_id = name;
        const Eigen::Vector3d q = T * p;
        t.transform.translation.x = q.x();
        t.transform.translation.y = q.y();
        t.transform.translation.z = q.z();
        t.transform.rotation.w = 1.0;
        out.push_back(t);
      }
    }
    if (!out.empty()) broadcaster.sendTransform(out);
  }

  massage_cell::ArmState latest() {
    std::lock_guard<std::mutex> lock(mutex);
    return state;
  }
  /// The value of `key` in the arm's latest diagnostics ("" when not there yet).
  std::string diagnostic(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& kv : diagnostics.values) {
      if (kv.key == key) return kv.value;
    }
    return "";
  }
  /// The arm node's /rosout lines at `level` containing `part`.
  std::vector<std::string> logged(std::uint8_t level, const std::string& part) {
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<std::string> out;
    for (const auto& l : arm_log) {
      if (l.level == level && l.msg.find(part) != std::string::npos) out.push_back(l.msg);
    }
    return out;
  }
  Eigen::Vector3d jointPositions() {
    std::lock_guard<std::mutex> lock(mutex);
    if (joints.position.size() != 3) return Eigen::Vector3d::Constant(NAN);
    return {joints.position[0], joints.position[1], joints.position[2]};
  }
  bool waitFor(const std::function<bool()>& pred, double seconds) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
    while (ros::WallTime::now() < end) {
      if (pred()) return true;
      ros::WallDuration(0.02).sleep();
    }
    return pred();
  }
  /// The joints report the same position 0.1 s apart.
  bool waitUntilStanding(double seconds) {
    Eigen::Vector3d last = jointPositions();
    return waitFor(
        [&] {
          ros::WallDuration(0.1).sleep();
          const Eigen::Vector3d now = jointPositions();
          const bool standing = (now - last).norm() < 1e-7;
          last = now;
          return standing;
        },
        seconds);
  }
  std_srvs::Trigger::Response trigger(const std::string& name) {
    std_srvs::Trigger srv;
    EXPECT_TRUE(ros::service::waitForService(name, ros::Duration(30.0))) << name;
    EXPECT_TRUE(ros::service::call(name, srv)) << name;
    return srv.response;
  }
  massage_cell::MoveTo::Response moveTo(const std::string& frame, const Eigen::Vector3d& p, double speed = 0.0) {
    massage_cell::MoveTo srv;
    srv.request.target.header.frame_id = frame;
    srv.request.target.point.x = p.x();
    srv.request.target.point.y = p.y();
    srv.request.target.point.z = p.z();
    srv.request.speed = speed;
    EXPECT_TRUE(ros::service::call("/arm/move_to", srv));
    return srv.response;
  }
  /// A base-frame point expressed in the optical frame (through the tf tree).
  Eigen::Vector3d inOptical(const Eigen::Vector3d& p) {
    const auto t = buffer.lookupTransform(kOptical, kBase, ros::Time(0), ros::Duration(5.0));
    return tf2::transformToEigen(t) * p;
  }
  massage_cell::Massage::Response massage(massage_cell::Massage::Request req) {
    massage_cell::Massage srv;
    srv.request = std::move(req);
    EXPECT_TRUE(ros::service::call("/arm/massage", srv));
    return srv.response;
  }
  void addFrame(const std::string& name, const Eigen::Vector3d& base_point, bool stale = false) {
    std::lock_guard<std::mutex> lock(mutex);
    (stale ? old : live)[name] = base_point;
  }
  void removeFrame(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex);
    live.erase(name);
    old.erase(name);
  }
};

Fixture* F = nullptr;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(ArmNode, UrdfParsesAndRobotStatePublisherPublishesEveryLink) {
  urdf::Model model;
  ASSERT_TRUE(model.initParam("robot_description"));
  EXPECT_EQ(model.getRoot()->name, "table");
  std::vector<urdf::LinkSharedPtr> links;
  model.getLinks(links);
  EXPECT_EQ(links.size(), 9u);  // table, gantry (5), press_tool, tool_tip, camera mount, left optical frame
  EXPECT_FALSE(model.getLink("stereo_right_optical_frame"));  // the camera driver's, from its calibration
  for (const auto& link : links) {
    EXPECT_TRUE(F->buffer.canTransform("table", link->name, ros::Time(0), ros::Duration(10.0))) << link->name;
  }
  // The URDF's joint limits are the configured soft limits.
  for (int i = 0; i < 3; ++i) {
    const auto joint = model.getJoint(F->config.joint_names[i]);
    ASSERT_TRUE(joint) << F->config.joint_names[i];
    EXPECT_EQ(joint->type, urdf::Joint::PRISMATIC);
    EXPECT_DOUBLE_EQ(joint->limits->lower, F->config.joints[i].min);
    EXPECT_DOUBLE_EQ(joint->limits->upper, F->config.joints[i].max);
  }
}

TEST(ArmNode, RefusesMotionBeforeHoming) {
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "ready (not homed)"; }, 20.0)) << F->latest().mode;
  ASSERT_TRUE(ros::service::waitForService("/arm/move_to", ros::Duration(10.0)));
  const auto r = F->moveTo(kBase, {0.4, 0.2, 0.25});
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "not homed")) << r.message;
}

TEST(ArmNode, Homes) {
  const auto r = F->trigger("/arm/home");
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_TRUE(F->waitFor([] { return F->latest().homed && F->latest().mode == "idle"; }, 5.0));
  EXPECT_TRUE(F->waitFor([] { return (F->jointPositions() - Eigen::Vector3d(0, 0, 0.3)).norm() < 1e-5; }, 2.0))
      << F->jointPositions().transpose();
}

TEST(ArmNode, MoveToPointInTheCameraOpticalFrame) {
  const Eigen::Vector3d goal(0.4, 0.2, 0.25);
  const Eigen::Vector3d p = F->inOptical(goal);
  EXPECT_GT(p.z(), 0.5);  // in front of the camera, looking down
  const auto r = F->moveTo(kOptical, p);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_TRUE(F->waitFor([&] { return (F->jointPositions() - goal).norm() < 1e-4; }, 2.0))
      << F->jointPositions().transpose();
  // robot_state_publisher: the tool tip is there in tf too.
  EXPECT_TRUE(F->waitFor(
      [&] {
        try {
          const auto t = F->buffer.lookupTransform(kBase, "tool_tip", ros::Time(0));
          return (Eigen::Vector3d(t.transform.translation.x, t.transform.translation.y, t.transform.translation.z) -
                  goal)
                     .norm() < 1e-4;
        } catch (const tf2::TransformException&) {
          return false;
        }
      },
      2.0));
}

TEST(ArmNode, MassageOverTwoAcupointFrames) {
  F->addFrame("acupoint/BL23_L", {0.5, 0.18, 0.18});
  F->addFrame("acupoint/BL25_R", {0.6, 0.3, 0.17});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL25_R", ros::Time(0), ros::Duration(5.0)));
  double lowest = 1.0;
  std::atomic<bool> watching{true};
  std::thread watch([&] {
    while (watching) {
      lowest = std::min(lowest, F->latest().tool.z);
      ros::WallDuration(0.005).sleep();
    }
  });
  massage_cell::Massage::Request req;
  req.frames = {"acupoint/BL23_L", "acupoint/BL25_R"};
  req.hold = 0.3;
  req.speed = 0.03;
  const auto r = F->massage(req);
  watching = false;
  watch.join();
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.presses_done, 2);
  EXPECT_EQ(r.message, "massage done: 2 presses");
  // lower_back (from the acupoint model by name): default depth 8 mm below 0.17 m at the deepest.
  EXPECT_GE(lowest, 0.17 - 0.008 - 1e-5);
  EXPECT_LT(lowest, 0.17 - 0.006);  // the ~state samples (50 Hz) saw it at depth
  // ~state is sampled at 50 Hz: its latest message may predate the end of the retraction.
  F->waitFor([] { return std::abs(F->latest().tool.z - F->config.press.travel_height) < 1e-4; }, 1.0);
  EXPECT_NEAR(F->latest().tool.z, F->config.press.travel_height, 1e-4);
}

TEST(ArmNode, APressByForceOnTheSimulatedSkin) {
  // The session's true acupoints, as the session player publishes them: a 9 x 9 grid 15 mm apart at z 0.16 m around
  // (0.40, 0.25) in the base frame; the simulated drives press the skin through them.
  ros::Publisher skin = F->nh.advertise<massage_cell::AcupointArray>("/stereo/ground_truth/acupoints", 1, true);
  massage_cell::AcupointArray truth;
  truth.header.frame_id = kBase;
  truth.header.stamp = ros::Time::now();
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) {
      massage_cell::Acupoint a;
      a.name = "p" + std::to_string(i) + "_" + std::to_string(j);
      a.position.x = 0.40 + 0.015 * i;
      a.position.y = 0.25 + 0.015 * j;
      a.position.z = 0.16;
      a.valid = true;
      truth.acupoints.push_back(a);
    }
  skin.publish(truth);
  if (!F->latest().homed) ASSERT_TRUE(F->trigger("/arm/home").success);
  ASSERT_TRUE(F->waitFor([] { return F->latest().force_valid; }, 5.0)) << F->latest().force_source;
  std::atomic<int> wrenches{0};
  ros::Subscriber wrench_sub = F->nh.subscribe<geometry_msgs::WrenchStamped>("/arm/wrench", 10, [&](const auto& w) {
    if (w->header.frame_id == "tool_tip") ++wrenches;
  });
  std::vector<double> held;
  std::atomic<bool> watching{true};
  std::thread watch([&] {
    while (watching) {
      const massage_cell::ArmState st = F->latest();
      if (st.activity.find("holding") != std::string::npos && st.force_valid) held.push_back(st.force);
      ros::WallDuration(0.02).sleep();
    }
  });
  massage_cell::Massage::Request req;
  geometry_msgs::PointStamped p;
  p.header.frame_id = kBase;
  p.point.x = 0.40, p.point.y = 0.25, p.point.z = 0.16;
  req.points = {p};
  req.regions = {"lower_back"};
  req.mode = "force";
  req.force = 20.0;
  req.hold = 1.0;
  const auto r = F->massage(req);
  watching = false;
  watch.join();
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.presses_done, 1);
  ASSERT_GT(held.size(), 20u);  // ~state at 50 Hz over the 1 s hold
  double mean = 0.0;
  for (double f : held) mean += f / static_cast<double>(held.size());
  EXPECT_NEAR(mean, 20.0, 2.0);
  EXPECT_GT(wrenches.load(), 0);
  // Asked beyond the region's cap: refused with the limit named.
  req.force = 90.0;
  const auto refused = F->massage(req);
  EXPECT_FALSE(refused.success);
  EXPECT_NE(refused.message.find("above the lower_back limit"), std::string::npos) << refused.message;
}

TEST(ArmNode, EstopDuringAPressBacksOffTheBody) {
  F->addFrame("acupoint/BL23_L", {0.5, 0.18, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL23_L", ros::Time(0), ros::Duration(5.0)));
  auto press = std::async(std::launch::async, [] {
    massage_cell::Massage::Request req;
    req.frames = {"acupoint/BL23_L"};
    req.hold = 5.0;
    req.speed = 0.03;
    return F->massage(req);
  });
  ASSERT_TRUE(F->waitFor([] { return contains(F->latest().activity, "hold"); }, 30.0)) << F->latest().activity;
  std_msgs::Bool on;
  on.data = true;
  F->estop_pub.publish(on);
  const auto r = press.get();
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "e-stop pressed: the tool backs off to the approach point")) << r.message;
  // Released along the press line to the approach point (3 cm above the skin), then latched.
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "e-stop"; }, 10.0)) << F->latest().mode;
  EXPECT_NEAR(F->latest().tool.z, 0.18 + F->config.press.approach_height, 1e-3);
  EXPECT_TRUE(F->latest().estop_latched);
  std_msgs::Bool off;
  off.data = false;
  F->estop_pub.publish(off);
  ASSERT_TRUE(F->waitFor([] { return !F->latest().estop_active; }, 2.0));
  const auto reset = F->trigger("/arm/reset_fault");
  ASSERT_TRUE(reset.success) << reset.message;
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "idle"; }, 5.0)) << F->latest().mode;
}

TEST(ArmNode, RefusalsNameTheProblem) {
  // The previous test's last retraction may still be settling (tens of
  // micrometres): start from an arm that stands still.
  Eigen::Vector3d last = F->jointPositions();
  ASSERT_TRUE(F->waitFor(
      [&] {
        ros::WallDuration(0.1).sleep();
        const Eigen::Vector3d now = F->jointPositions();
        const bool standing = (now - last).norm() < 1e-7;
        last = now;
        return standing;
      },
      3.0));
  const Eigen::Vector3d before = F->jointPositions();
  // Outside the envelope.
  auto m = F->moveTo(kBase, {1.5, 0.2, 0.2});
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "outside the workspace envelope: x above 0.760 m")) << m.message;
  massage_cell::Massage::Request req;
  geometry_msgs::PointStamped far;
  far.header.frame_id = kBase;
  far.point.x = 0.5;
  far.point.y = 0.9;
  far.point.z = 0.18;
  req.points = {far};
  auto r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "point 1: the travel point") && contains(r.message, "outside the workspace envelope"))
      << r.message;
  // Deeper than the region allows (lower_back 12 mm; GV4 is midline: 2 mm).
  F->addFrame("acupoint/GV4", {0.55, 0.25, 0.19});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/GV4", ros::Time(0), ros::Duration(5.0)));
  req = {};
  req.frames = {"acupoint/BL23_L"};
  req.depth = 0.02;
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "BL23_L: depth 20.0 mm is deeper than the lower_back limit 12.0 mm")) << r.message;
  req.frames = {"acupoint/GV4"};
  req.depth = 0.003;
  r = F->massage(req);
  EXPECT_TRUE(contains(r.message, "GV4: depth 3.0 mm is deeper than the midline limit 2.0 mm")) << r.message;
  // Unknown frame.
  req.frames = {"acupoint/NOPE"};
  req.depth = 0;
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "the frame 'acupoint/NOPE' is unknown")) << r.message;
  EXPECT_TRUE(contains(r.message, "'NOPE' is not an acupoint of the model")) << r.message;
  req.frames = {"acupoint/GV14"};  // an acupoint of the model the test never publishes: CECT has no fix for it
  r = F->massage(req);
  EXPECT_TRUE(contains(r.message, "GV14 is an acupoint of the model but CECT publishes no valid fix")) << r.message;
  req.frames = {"BL23_L"};  // without the prefix
  r = F->massage(req);
  EXPECT_TRUE(contains(r.message, "did you mean 'acupoint/BL23_L'?")) << r.message;
  m = F->moveTo("no_such_frame", {0, 0, 0});
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "'no_such_frame' is unknown")) << m.message;
  // Stale: the frame's latest transform is 2 s old.
  F->addFrame("acupoint/BL21_L", {0.45, 0.18, 0.18}, true);
  ASSERT_TRUE(F->buffer.canTransform(kOptical, "acupoint/BL21_L", ros::Time(0), ros::Duration(5.0)));
  req.frames = {"acupoint/BL21_L"};
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "'acupoint/BL21_L' is stale: its transform is 2.") &&
              contains(r.message, "limit 1.00 s"))
      << r.message;
  // Into the body: the acupoint frames are its skin (BL23_L at z 0.18 m).
  m = F->moveTo(kBase, {0.5, 0.18, 0.13});
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "the target (0.500, 0.180, 0.130) m is 50.0 mm below the body's surface"))
      << m.message;
  m = F->moveTo(kBase, {0.1, 0.05, 0.2});  // no skin known there: not below the safe height
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "below the safe height 0.250 m")) << m.message;
  req = {};
  geometry_msgs::PointStamped under;
  under.header.frame_id = kBase;
  under.point.x = 0.5;
  under.point.y = 0.18;
  under.point.z = 0.13;
  req.points = {under};
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "point 1: the target (0.500, 0.180, 0.130) m is 50.0 mm below the body's surface"))
      << r.message;
  // Request fields out of range: a NaN hold, ten thousand frames, a speed no joint can reach.
  req = {};
  req.frames = {"acupoint/BL23_L"};
  req.hold = std::numeric_limits<double>::quiet_NaN();
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "hold must be a finite number of seconds")) << r.message;
  req.hold = 0.0;
  req.frames.assign(10000, "acupoint/BL23_L");
  r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "10000 targets: at most 50 in one request")) << r.message;
  m = F->moveTo(kBase, {0.3, 0.3, 0.25}, 1e9);
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "speed 1e+09 m/s is beyond what the joints allow")) << m.message;
  // Nothing moved.
  EXPECT_LT((F->jointPositions() - before).norm(), 1e-6);
  EXPECT_EQ(F->latest().mode, "idle");
}

TEST(ArmNode, StereosSurfaceKeepsMovesOutOfTheBackBetweenAcupointsAndTheShoulder) {
  // Two acupoints 10 cm apart at the skin's 0.15 m, the back rising 4 cm between them (the spine); a shoulder 5 cm
  // above them where no acupoint is. Stereo's surface (the hbds node's `surface`) in the camera's optical frame.
  F->addFrame("acupoint/SURFACE_A", {0.40, 0.35, 0.15});
  F->addFrame("acupoint/SURFACE_B", {0.50, 0.35, 0.15});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/SURFACE_B", ros::Time(0), ros::Duration(5.0)));
  const auto skin = [](double x, double y) {
    return 0.15 + 0.04 * std::exp(-std::pow((x - 0.45) / 0.02, 2)) +
           0.05 * std::exp(-(std::pow((x - 0.25) / 0.03, 2) + std::pow((y - 0.42) / 0.03, 2)));
  };
  sensor_msgs::PointCloud2 cloud;
  cloud.header.frame_id = kOptical;
  cloud.header.stamp = ros::Time::now();
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(1, "xyz");
  std::vector<Eigen::Vector3d> points;
  for (double x = 0.18; x <= 0.56; x += 0.008) {
    for (double y = 0.28; y <= 0.46; y += 0.008) points.push_back(F->inOptical({x, y, skin(x, y)}));
  }
  modifier.resize(points.size());
  sensor_msgs::PointCloud2Iterator<float> it(cloud, "x");
  for (const Eigen::Vector3d& p : points) {
    it[0] = static_cast<float>(p.x());
    it[1] = static_cast<float>(p.y());
    it[2] = static_cast<float>(p.z());
    ++it;
  }
  // arm.launch's default topic for ~surface (the hbds node's in the stereo namespace).
  ros::Publisher pub = F->nh.advertise<sensor_msgs::PointCloud2>("/stereo/surface", 1, true);
  pub.publish(cloud);
  // 3 cm into the back halfway between the acupoints (1 cm above their height: the acupoints alone let it pass); the
  // surface's highest point within a cell (its samples 8 mm apart) is 29.6 mm above the target.
  massage_cell::MoveTo::Response m;
  ASSERT_TRUE(F->waitFor(
      [&] {
        m = F->moveTo(kBase, {0.45, 0.35, 0.16});
        return contains(m.message, "below the surface stereo sees");
      },
      5.0))
      << m.message;
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(
      contains(m.message, "the target (0.450, 0.350, 0.160) m is 29.6 mm below the surface stereo sees (limit 12.0 mm"))
      << m.message;
  // 3 cm into the shoulder, where no acupoint is.
  m = F->moveTo(kBase, {0.25, 0.42, 0.17});
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(
      contains(m.message, "the target (0.250, 0.420, 0.170) m is 28.9 mm below the surface stereo sees (limit 12.0 mm"))
      << m.message;
  F->removeFrame("acupoint/SURFACE_A");
  F->removeFrame("acupoint/SURFACE_B");
  modifier.resize(0);  // stereo sees nothing: the next tests' moves are not held to this back
  cloud.header.stamp = ros::Time::now();
  pub.publish(cloud);
  ros::WallDuration(0.3).sleep();
}

TEST(ArmNode, EstopMidMoveAndReset) {
  const Eigen::Vector3d start = F->jointPositions();
  auto move = std::async(std::launch::async, [] { return F->moveTo(kBase, {0.1, 0.4, 0.25}); });
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "moving"; }, 5.0));
  ASSERT_TRUE(F->waitFor([&] { return (F->jointPositions() - start).norm() > 0.02; }, 5.0));  // well under way
  std_msgs::Bool on;
  on.data = true;
  F->estop_pub.publish(on);
  const auto r = move.get();
  EXPECT_FALSE(r.success);
  EXPECT_EQ(r.message, "e-stop pressed");
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "e-stop"; }, 2.0));
  EXPECT_TRUE(F->latest().estop_latched);
  ASSERT_TRUE(F->waitUntilStanding(2.0));  // the quick-stop ramp: 0.1 m/s at 2 m/s^2 is 50 ms
  const Eigen::Vector3d stopped = F->jointPositions();
  ros::WallDuration(0.5).sleep();                           // an observation window: nothing may move in it
  EXPECT_LT((F->jointPositions() - stopped).norm(), 1e-6);  // standing
  auto reset = F->trigger("/arm/reset_fault");
  EXPECT_FALSE(reset.success);
  EXPECT_TRUE(contains(reset.message, "e-stop is still pressed")) << reset.message;
  std_msgs::Bool off;
  off.data = false;
  F->estop_pub.publish(off);
  ASSERT_TRUE(F->waitFor([] { return !F->latest().estop_active; }, 2.0));
  EXPECT_TRUE(F->latest().estop_latched);  // latched until reset
  const auto refused = F->moveTo(kBase, {0.3, 0.3, 0.25});
  EXPECT_FALSE(refused.success);
  EXPECT_TRUE(contains(refused.message, "e-stop is latched")) << refused.message;
  reset = F->trigger("/arm/reset_fault");
  ASSERT_TRUE(reset.success) << reset.message;
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "idle"; }, 2.0));
  EXPECT_TRUE(F->latest().homed);
  EXPECT_TRUE(F->moveTo(kBase, {0.3, 0.3, 0.25}).success);
}

TEST(ArmNode, InjectedDriveFaultAndReset) {
  const Eigen::Vector3d start = F->jointPositions();
  auto move = std::async(std::launch::async, [] { return F->moveTo(kBase, {0.6, 0.1, 0.25}); });
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "moving"; }, 5.0));
  ASSERT_TRUE(F->waitFor([&] { return (F->jointPositions() - start).norm() > 0.01; }, 5.0));
  std_msgs::String fault;
  fault.data = "Y 0x2310";
  F->fault_pub.publish(fault);
  const auto r = move.get();
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "aborted by a fault")) << r.message;
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "fault"; }, 2.0));
  std::string faults;
  for (const auto& f : F->latest().faults) faults += f + "\n";
  EXPECT_TRUE(contains(faults, "EMCY 0x2310 continuous over-current")) << faults;
  EXPECT_TRUE(F->waitFor([] { return F->latest().axis_state.at(1) == "fault"; }, 2.0)) << F->latest().axis_state.at(1);
  const auto refused = F->moveTo(kBase, {0.3, 0.3, 0.25});
  EXPECT_TRUE(contains(refused.message, "the arm is in fault")) << refused.message;
  const auto reset = F->trigger("/arm/reset_fault");
  ASSERT_TRUE(reset.success) << reset.message;
  EXPECT_TRUE(F->latest().faults.empty() || F->waitFor([] { return F->latest().faults.empty(); }, 1.0));
  EXPECT_TRUE(F->moveTo(kBase, {0.3, 0.3, 0.25}).success);
}

TEST(ArmNode, AStrokeOnTheSimulatedSkinWatchesEveryFrameOfItsPath) {
  // Three acupoint frames on the simulated skin (APressByForceOnTheSimulatedSkin's grid, latched: z 0.16 m around
  // (0.40, 0.25)), 4 cm apart along x: a stroke glides through them at 20 N ...
  const std::vector<std::string> names = {"acupoint/BL13_L", "acupoint/BL17_L", "acupoint/BL21_L"};
  for (int i = 0; i < 3; ++i) F->addFrame(names[i], {0.36 + 0.04 * i, 0.25, 0.16});
  for (const std::string& n : names)
    ASSERT_TRUE(F->buffer.canTransform(kBase, n, ros::Time(0), ros::Duration(5.0))) << n;
  if (!F->latest().homed) ASSERT_TRUE(F->trigger("/arm/home").success);
  ASSERT_TRUE(F->waitFor([] { return F->latest().force_valid; }, 5.0)) << F->latest().force_source;
  massage_cell::Massage::Request req;
  req.frames = names;
  req.technique = "stroke";
  req.mode = "force";
  req.force = 20.0;
  auto r = F->massage(req);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.presses_done, 1);
  EXPECT_NEAR(F->latest().tool.x, 0.44, 0.002);  // up over the path's end
  // ... and when a frame of its path (not the one it started at) is no longer refreshed, it backs off.
  auto call = std::async(std::launch::async, [&] { return F->massage(req); });
  ASSERT_TRUE(F->waitFor([] { return F->latest().press_phase == "glide"; }, 60.0)) << F->latest().activity;
  F->removeFrame(names[2]);
  r = call.get();
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "acupoint frame 'acupoint/BL21_L' is stale")) << r.message;
  EXPECT_LT(F->latest().tool.x, 0.435);  // stopped on its way, not at the end
  F->waitFor([] { return std::abs(F->latest().tool.z - F->config.press.travel_height) < 1e-4; }, 1.0);
  EXPECT_NEAR(F->latest().tool.z, F->config.press.travel_height, 1e-4);
  for (int i = 0; i < 2; ++i) F->removeFrame(names[i]);
}

TEST(ArmNode, LostAcupointFrameDuringAPressRetracts) {
  F->addFrame("acupoint/BL22_L", {0.45, 0.2, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL22_L", ros::Time(0), ros::Duration(5.0)));
  massage_cell::Massage::Request req;
  req.frames = {"acupoint/BL22_L"};
  req.hold = 20.0;
  req.speed = 0.03;
  auto call = std::async(std::launch::async, [&] { return F->massage(req); });
  ASSERT_TRUE(F->waitFor([] { return contains(F->latest().activity, "hold"); }, 60.0)) << F->latest().activity;
  F->removeFrame("acupoint/BL22_L");  // the subject moved away: the frame is no longer refreshed
  const auto r = call.get();
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "massage aborted: acupoint frame 'acupoint/BL22_L' is stale")) << r.message;
  EXPECT_TRUE(contains(r.message, "tool retracted to")) << r.message;
  // ~state is sampled at 50 Hz: its latest message may predate the end of the retraction.
  F->waitFor([] { return std::abs(F->latest().tool.z - F->config.press.travel_height) < 1e-4; }, 1.0);
  EXPECT_NEAR(F->latest().tool.z, F->config.press.travel_height, 1e-4);
  EXPECT_EQ(r.presses_done, 0);
}

// --- ~massage as an actionlib action ----------------------------------------------------------

using MassageClient = actionlib::SimpleActionClient<massage_cell::MassageAction>;
using GoalState = actionlib::SimpleClientGoalState;

/// An action client of /arm/massage (spun by main's AsyncSpinner) that keeps every feedback of its goal.
struct MassageGoal {
  MassageClient client{"/arm/massage", false};
  std::mutex mutex;
  std::vector<massage_cell::MassageFeedback> feedback;

  void send(const massage_cell::MassageGoal& goal) {
    ASSERT_TRUE(client.waitForServer(ros::Duration(10.0)));
    client.sendGoal(goal, MassageClient::SimpleDoneCallback(), MassageClient::SimpleActiveCallback(),
                    [this](const massage_cell::MassageFeedbackConstPtr& f) {
                      std::lock_guard<std::mutex> lock(mutex);
                      feedback.push_back(*f);
                    });
  }
  bool saw(const std::function<bool(const massage_cell::MassageFeedback&)>& pred) {
    std::lock_guard<std::mutex> lock(mutex);
    return std::any_of(feedback.begin(), feedback.end(), pred);
  }
  /// Waits up to `seconds` for a feedback whose activity contains `part`.
  bool waitForActivity(const std::string& part, double seconds) {
    return F->waitFor([&] { return saw([&](const auto& f) { return contains(f.activity, part); }); }, seconds);
  }
};

/// A goal of one press on `frame`, holding `hold` s.
massage_cell::MassageGoal pressGoal(const std::string& frame, double hold) {
  massage_cell::MassageGoal goal;
  goal.frames = {frame};
  goal.hold = hold;
  goal.speed = 0.03;
  return goal;
}

/// The arm back to idle with the tool at the travel height (~state is sampled at 50 Hz: its latest message may
/// predate the end of the retraction).
void expectIdleAtTravelHeight() {
  EXPECT_TRUE(F->waitFor([] { return F->latest().mode == "idle"; }, 1.0)) << F->latest().mode;
  F->waitFor([] { return std::abs(F->latest().tool.z - F->config.press.travel_height) < 1e-4; }, 1.0);
  EXPECT_NEAR(F->latest().tool.z, F->config.press.travel_height, 1e-4);
}

TEST(ArmNode, ActionMassageSucceedsWithFeedback) {
  F->addFrame("acupoint/BL22_L", {0.45, 0.2, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL22_L", ros::Time(0), ros::Duration(5.0)));
  MassageGoal run;
  run.send(pressGoal("acupoint/BL22_L", 0.3));
  ASSERT_TRUE(run.client.waitForResult(ros::Duration(60.0))) << F->latest().activity;
  const GoalState state = run.client.getState();
  EXPECT_EQ(state.toString(), "SUCCEEDED") << state.getText();
  const auto result = run.client.getResult();
  ASSERT_TRUE(result);
  EXPECT_TRUE(result->success) << result->message;
  EXPECT_EQ(result->message, "massage done: 1 press");
  EXPECT_EQ(result->presses_done, 1);
  // The feedback named the target (index and acupoint) and the arm's activity, and counted the press.
  EXPECT_TRUE(run.saw([](const auto& f) {
    return f.target == 0 && f.target_name == "BL22_L" && f.activity == "press 1/1 BL22_L: hold" && f.presses_done == 0;
  }));
  EXPECT_TRUE(run.saw([](const auto& f) { return f.presses_done == 1; }));
  expectIdleAtTravelHeight();
}

TEST(ArmNode, ActionCancelDuringAPressBacksOff) {
  F->addFrame("acupoint/BL22_L", {0.45, 0.2, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL22_L", ros::Time(0), ros::Duration(5.0)));
  MassageGoal run;
  run.send(pressGoal("acupoint/BL22_L", 20.0));
  ASSERT_TRUE(run.waitForActivity("hold", 30.0)) << F->latest().activity;
  // One massage at a time: the service is refused while the goal runs.
  massage_cell::Massage::Request req;
  req.frames = {"acupoint/BL22_L"};
  const auto busy = F->massage(req);
  EXPECT_FALSE(busy.success);
  EXPECT_TRUE(contains(busy.message, "busy: massaging")) << busy.message;
  run.client.cancelGoal();
  ASSERT_TRUE(run.client.waitForResult(ros::Duration(10.0))) << F->latest().activity;  // not the 20 s hold
  const GoalState state = run.client.getState();
  EXPECT_EQ(state.toString(), "PREEMPTED") << state.getText();
  const auto result = run.client.getResult();
  ASSERT_TRUE(result);
  EXPECT_FALSE(result->success);
  EXPECT_TRUE(contains(result->message, "massage goal canceled; tool retracted to")) << result->message;
  EXPECT_EQ(result->presses_done, 0);
  // Preempted once the arm stands: backed off the body, up at the travel height.
  expectIdleAtTravelHeight();
}

TEST(ArmNode, ActionNewGoalStopsTheRunningMassageFirst) {
  F->addFrame("acupoint/BL22_L", {0.45, 0.2, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL22_L", ros::Time(0), ros::Duration(5.0)));
  MassageGoal first, second;
  first.send(pressGoal("acupoint/BL22_L", 20.0));
  ASSERT_TRUE(first.waitForActivity("hold", 30.0)) << F->latest().activity;
  second.send(pressGoal("acupoint/BL22_L", 0.3));
  ASSERT_TRUE(first.client.waitForResult(ros::Duration(10.0))) << F->latest().activity;
  const GoalState state = first.client.getState();
  EXPECT_EQ(state.toString(), "PREEMPTED") << state.getText();
  ASSERT_TRUE(first.client.getResult());
  EXPECT_TRUE(contains(first.client.getResult()->message, "massage goal preempted by a new goal; tool retracted to"))
      << first.client.getResult()->message;
  // The new goal started after the old massage backed off: it retracted first, then pressed once.
  EXPECT_TRUE(first.saw([](const auto& f) { return contains(f.activity, "retract"); }));
  ASSERT_TRUE(second.client.waitForResult(ros::Duration(60.0))) << F->latest().activity;
  EXPECT_EQ(second.client.getState().toString(), "SUCCEEDED") << second.client.getState().getText();
  ASSERT_TRUE(second.client.getResult());
  EXPECT_EQ(second.client.getResult()->presses_done, 1);
  EXPECT_TRUE(second.saw([](const auto& f) { return f.activity == "press 1/1 BL22_L: hold"; }));
  expectIdleAtTravelHeight();
}

TEST(ArmNode, ActionRefusedGoalsAreAborted) {
  F->addFrame("acupoint/BL22_L", {0.45, 0.2, 0.18});
  ASSERT_TRUE(F->buffer.canTransform(kBase, "acupoint/BL22_L", ros::Time(0), ros::Duration(5.0)));
  const auto expectAborted = [](const massage_cell::MassageGoal& goal, const std::string& why) {
    MassageGoal run;
    run.send(goal);
    ASSERT_TRUE(run.client.waitForResult(ros::Duration(10.0)));
    const GoalState state = run.client.getState();
    EXPECT_EQ(state.toString(), "ABORTED") << state.getText();
    EXPECT_TRUE(contains(state.getText(), why)) << state.getText();
    ASSERT_TRUE(run.client.getResult());
    EXPECT_FALSE(run.client.getResult()->success);
    EXPECT_TRUE(contains(run.client.getResult()->message, why)) << run.client.getResult()->message;
  };
  expectAborted(massage_cell::MassageGoal(), "massage refused: no target (frames or points) given");
  expectAborted(pressGoal("acupoint/NOPE", 0.3), "the frame 'acupoint/NOPE' is unknown");
  massage_cell::MassageGoal deep = pressGoal("acupoint/BL22_L", 0.3);
  deep.depth = 0.02;
  expectAborted(deep, "BL22_L: depth 20.0 mm is deeper than the lower_back limit 12.0 mm");
  EXPECT_EQ(F->latest().mode, "idle");
}

/// Whether this machine lets a process use SCHED_FIFO 50 (the node's default realtime_priority).
bool mayUseFifo() {
  bool ok = false;
  std::thread t([&] {
    sched_param p{};
    p.sched_priority = 50;
    ok = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) == 0;
  });
  t.join();
  return ok;
}

TEST(ArmNode, DiagnosticsReportTheRealtimeScheduling) {
  ASSERT_TRUE(F->waitFor([] { return !F->diagnostic("real-time scheduling").empty(); }, 10.0));
  const std::string rt = F->diagnostic("real-time scheduling");
  if (mayUseFifo()) {
    EXPECT_EQ(rt, "SCHED_FIFO priority 50");  // config/arm.yaml node.realtime_priority
    EXPECT_TRUE(F->logged(rosgraph_msgs::Log::WARN, "real-time").empty());
  } else {
    EXPECT_TRUE(contains(rt, "normal (SCHED_OTHER): SCHED_FIFO priority 50 refused")) << rt;
    EXPECT_TRUE(contains(rt, "ulimit -r 50")) << rt;
    EXPECT_EQ(F->logged(rosgraph_msgs::Log::WARN, "real-time scheduling not as configured").size(), 1u);
  }
}

// --- arm_bad_interface.test: can_interface can9 (no such interface) ----------------------------

TEST(ArmNodeBadInterface, LogsOneErrorNamingTheInterfaceAndKeepsRunning) {
  ASSERT_TRUE(F->waitFor([] { return F->latest().mode == "fault"; }, 20.0)) << F->latest().mode;
  const massage_cell::ArmState s = F->latest();
  ASSERT_EQ(s.faults.size(), 1u);
  EXPECT_TRUE(contains(s.faults[0], "the CAN interface 'can9' is not available")) << s.faults[0];
  EXPECT_TRUE(contains(s.faults[0], "does not exist")) << s.faults[0];
  EXPECT_EQ(s.bus_state, "down");
  EXPECT_FALSE(s.homed);
  // The one error came at start-up (before this test listened on /rosout);
  // the retries every 2 s repeat nothing. (That /rosout reaches us is
  // checked by RefusesEveryCommandWithTheReason: the refusals are WARNs.)
  const std::size_t errors_before = F->logged(rosgraph_msgs::Log::ERROR, "").size();
  ros::WallDuration(5.0).sleep();  // an observation window over two retries: no new error may come
  EXPECT_TRUE(F->waitFor([] { return F->latest().header.stamp > ros::Time::now() - ros::Duration(0.5); }, 2.0))
      << "the node stopped publishing ~state";
  EXPECT_EQ(F->logged(rosgraph_msgs::Log::ERROR, "").size(), errors_before);
  EXPECT_TRUE(F->logged(rosgraph_msgs::Log::FATAL, "").empty());
  ASSERT_TRUE(F->waitFor([] { return !F->diagnostic("CAN interface").empty(); }, 5.0));
  std::lock_guard<std::mutex> lock(F->mutex);
  EXPECT_EQ(F->diagnostics.level, diagnostic_msgs::DiagnosticStatus::ERROR);
  EXPECT_TRUE(contains(F->diagnostics.message, "'can9' is not available")) << F->diagnostics.message;
}

TEST(ArmNodeBadInterface, RefusesEveryCommandWithTheReason) {
  const std::string why = "refused: the CAN interface 'can9' is not available";
  for (const char* name : {"home", "reset_fault", "stop"}) {
    const auto r = F->trigger(std::string("/arm/") + name);
    EXPECT_FALSE(r.success) << name;
    EXPECT_TRUE(contains(r.message, std::string(name) + " " + why)) << r.message;
  }
  const auto m = F->moveTo(kBase, {0.4, 0.2, 0.25});
  EXPECT_FALSE(m.success);
  EXPECT_TRUE(contains(m.message, "move_to " + why)) << m.message;
  massage_cell::Massage::Request req;
  req.frames = {"acupoint/BL23_L"};
  const auto r = F->massage(req);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(contains(r.message, "massage " + why)) << r.message;
  const std::string warning = "home " + why;  // each refusal is also a WARN on /rosout
  EXPECT_TRUE(F->waitFor([&] { return !F->logged(rosgraph_msgs::Log::WARN, warning).empty(); }, 2.0));
  std_msgs::Bool on;  // the e-stop input is taken (and kept for when the interface appears)
  on.data = true;
  F->estop_pub.publish(on);
  ros::WallDuration(0.3).sleep();  // an observation window: the e-stop taken without an interface changes nothing
  EXPECT_EQ(F->latest().mode, "fault");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_arm_node");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  Fixture fixture;
  F = &fixture;
  const int result = RUN_ALL_TESTS();
  F = nullptr;
  return result;
}
