// rostest: bad input to the camera drivers. Every configuration error stops
// the node at start-up with a message naming the problem and a non-zero exit
// status; a single bad frame is logged, counted in diagnostics and skipped
// while the node keeps running.
//
// The node executables are run as child processes of this test (paths
// compiled in), against the rostest master.
#include <gtest/gtest.h>

#include <fstream>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <opencv2/imgcodecs.hpp>

#include "test_util.h"

namespace {

using massage_cell::test::Child;
using massage_cell::test::readFile;
using massage_cell::test::runCommand;
using massage_cell::test::TempDir;

int run_counter = 0;

/// Runs the driver executable with private parameters; expects a non-zero
/// exit within the time limit and `expected` in its output.
void expectStartupError(const std::string& executable, const std::string& params, const std::string& expected) {
  const std::string name = "bad_input_" + std::to_string(run_counter++);
  const auto result = runCommand(executable + " __name:=" + name + " " + params, 30);
  EXPECT_NE(result.exit_code, -1) << "the node did not exit by itself\n" << result.output;
  EXPECT_NE(result.exit_code, 0) << "the node exited with status 0\n" << result.output;
  EXPECT_NE(result.output.find(expected), std::string::npos)
      << "expected the message to contain '" << expected << "', got:\n"
      << result.output;
}

void writePair(const TempDir& dir, int index, cv::Size left, cv::Size right, int value) {
  char name[64];
  std::snprintf(name, sizeof name, "left_%04d.png", index);
  cv::imwrite((dir.path() / name).string(), cv::Mat(left, CV_8UC3, cv::Scalar(value, value, value)));
  std::snprintf(name, sizeof name, "right_%04d.png", index);
  cv::imwrite((dir.path() / name).string(), cv::Mat(right, CV_8UC3, cv::Scalar(value, value, value)));
}

const std::string kStereo = STEREO_CAMERA_NODE;
const std::string kMono = MONO_CAMERA_NODE;
const std::string kFolder = " _source:=folder _left/pattern:=left_*.png _right/pattern:=right_*.png _folder:=";

TEST(StartupErrors, MissingDevice) {
  expectStartupError(kStereo, "_source:=v4l2 _left/device:=/dev/video_massage_missing _right/device:=/dev/video_x",
                     "V4L2 device '/dev/video_massage_missing' does not exist");
  expectStartupError(kMono, "_source:=v4l2 _device:=/dev/video_massage_missing", "does not exist");
}

TEST(StartupErrors, MissingFolder) {
  expectStartupError(kStereo, kFolder + "/nonexistent/massage_cell",
                     "image folder '/nonexistent/massage_cell' does not exist");
  expectStartupError(kMono, "_source:=folder _folder:=/nonexistent/massage_cell", "does not exist");
}

TEST(StartupErrors, EmptyFolder) {
  TempDir dir;
  expectStartupError(kStereo, kFolder + dir.str(), "has no file matching 'left_*.png'");
}

TEST(StartupErrors, LeftAndRightCountsDiffer) {
  TempDir dir;
  for (int i = 0; i < 3; ++i) writePair(dir, i, {64, 48}, {64, 48}, 10 * i);
  std::filesystem::remove(dir.path() / "right_0002.png");
  expectStartupError(kStereo, kFolder + dir.str(), "has 3 left images ('left_*.png') but 2 right images");
}

TEST(StartupErrors, LeftAndRightSizesDiffer) {
  TempDir dir;
  for (int i = 0; i < 2; ++i) writePair(dir, i, {64, 48}, {80, 60}, 10 * i);
  expectStartupError(kStereo, kFolder + dir.str(), "differ in size");
}

TEST(StartupErrors, NoReadableImage) {
  TempDir dir;
  for (const char* name : {"left_0000.png", "right_0000.png"}) std::ofstream(dir.path() / name) << "not an image";
  expectStartupError(kStereo, kFolder + dir.str(), "holds no readable image");
}

TEST(StartupErrors, MissingVideo) {
  expectStartupError(kStereo, "_source:=video _left/file:=/nonexistent/l.avi _right/file:=/nonexistent/r.avi",
                     "video file '/nonexistent/l.avi' does not exist");
  expectStartupError(kStereo, "_source:=video _layout:=side_by_side", "parameter ~file is not set");
}

TEST(StartupErrors, MalformedCalibration) {
  TempDir dir;
  writePair(dir, 0, {64, 48}, {64, 48}, 50);
  const auto yaml = dir.path() / "bad.yaml";
  std::ofstream(yaml) << "image_width: [unclosed\n  camera_matrix: {rows: 3\n";
  expectStartupError(kStereo, kFolder + dir.str() + " _left/camera_info_url:=file://" + yaml.string(), "is malformed");
}

TEST(StartupErrors, CalibrationSizeDiffersFromImages) {
  TempDir dir;
  writePair(dir, 0, {64, 48}, {64, 48}, 50);
  expectStartupError(
      kStereo,
      kFolder + dir.str() +
          " _left/camera_name:=sample_left _left/camera_info_url:=package://massage_cell/data/sample_stereo/left.yaml",
      "left camera calibration is for 320x240 images but the camera delivers 64x48");
}

TEST(StartupErrors, InvalidParameterValues) {
  TempDir dir;
  writePair(dir, 0, {64, 48}, {64, 48}, 50);
  const std::string base = kFolder + dir.str();
  expectStartupError(kStereo, base + " _rate:=-1", "rate must be >= 0");
  expectStartupError(kStereo, base + " _layout:=triple", "layout 'triple' is not one of");
  expectStartupError(kStereo, base + " _width:=abc", "parameter ~width must be an integer");
  expectStartupError(kStereo, base + " _loop:=3", "parameter ~loop must be true or false");
  expectStartupError(kStereo, base + " _capture_delay:=-2", "capture_delay must be in [0, 10]");
  expectStartupError(kStereo, base + " _camera_name:=bad-name", "may hold only letters, digits and '_'");
  expectStartupError(kStereo, base + " _left/camera_info_url:=http://example.invalid/l.yaml",
                     "is not a file:// or package:// URL");
  expectStartupError(kStereo, "_source:=gige", "source 'gige' is not one of");
  expectStartupError(kStereo, "_source:=v4l2 _pixel_format:=MJPEG", "pixel_format must be a four-character code");
}

TEST(RunningErrors, BadFrameIsLoggedCountedAndSkipped) {
  TempDir dir;
  for (int i = 0; i < 6; ++i) writePair(dir, i, {64, 48}, {64, 48}, 10 * (i + 1));
  std::ofstream(dir.path() / "left_0002.png", std::ios::trunc) << "truncated";  // value 30 never published
  const std::string log = (dir.path() / "node.log").string();
  Child node(kStereo + " __name:=bad_frame __ns:=/bad_frame" + kFolder + dir.str() + " _rate:=20 _loop:=true", log);

  ros::NodeHandle nh("/bad_frame");
  std::vector<int> values;
  long bad_frames = 0;
  message_filters::Subscriber<sensor_msgs::Image> l(nh, "left/image_raw", 50), r(nh, "right/image_raw", 50);
  using Policy = message_filters::sync_policies::ExactTime<sensor_msgs::Image, sensor_msgs::Image>;
  message_filters::Synchronizer<Policy> sync(Policy(50), l, r);
  struct Collector {
    std::vector<int>* values;
    void onPair(const sensor_msgs::ImageConstPtr& a, const sensor_msgs::ImageConstPtr&) {
      values->push_back(a->data[0]);
    }
  } collector{&values};
  sync.registerCallback(&Collector::onPair, &collector);
  ros::Subscriber diag = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 20, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        for (const auto& status : msg->status) {
          if (status.name.find("bad_frame") == std::string::npos || status.name.find("source") == std::string::npos)
            continue;
          for (const auto& kv : status.values) {
            if (kv.key == "bad frames") bad_frames = std::stol(kv.value);
          }
        }
      });
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::ok() && (values.size() < 20 || bad_frames < 2) && ros::WallTime::now() < end) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  EXPECT_TRUE(node.running()) << "the node stopped on a bad frame:\n" << readFile(log);
  EXPECT_GE(values.size(), 20u) << "pairs stopped arriving";
  EXPECT_GE(bad_frames, 2) << "diagnostics do not count the bad frame (it comes once per loop)";
  for (int v : values) EXPECT_NE(v, 30) << "the bad frame's partner was published";
  node.stop();
  EXPECT_NE(readFile(log).find("left_0002.png"), std::string::npos) << "the log does not name the bad file:\n"
                                                                    << readFile(log);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_driver_errors");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
