// rviz/cell.rviz rendered under Xvfb (test/ros/rviz_cell.test).
//
// Three rviz windows, each on its own Xvfb screen, watch the same replayed session:
//   full      rviz/cell.rviz as it is
//   no_robot  the same with the RobotModel display disabled
//   no_cloud  the same with the PointCloud2 display disabled
// The bag waits for a subscriber on each of its topics; this test subscribes to
// /diagnostics (which nothing else in the launch reads) only once all three rviz listen
// to /stereo/points2, so every window sees the whole session. Once the last cloud has
// come and the bag's clock has stopped, the scene is static, so the three windows draw
// the same pixels except where the disabled display was: the robot is what `full` has
// and `no_robot` lacks, the cloud what `full` has and `no_cloud` lacks, counted inside
// the 3D view (found by its background colour; the panels, the fps counter and the
// wall clock of the Time panel differ between windows and are left out).
// (The acupoint markers expire 1 s of ROS time after they were received, so a window
// that got the last ones a little later may still show them when the others do not:
// ~1300 px when all of them differ, well under the thresholds: the robot covers ~69000 px
// of the ~380000 px view, the cloud ~30000 px where it is not behind the robot.)
// Screenshots (full, no_robot, no_cloud; live: the full window during the session) and
// the difference masks (robot_pixels, cloud_pixels) go next to the test's XML result:
// test_results/massage_cell/rviz_cell/.
// Skips (GTEST_SKIP, "SKIPPED" in the output) when Xvfb is not installed;
// MASSAGE_CELL_XVFB=PATH overrides the Xvfb executable (a missing path shows the skip).
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/Marker.h>
#include <xmlrpcpp/XmlRpcValue.h>
#include <yaml-cpp/yaml.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "spin_util.h"
#include "test_util.h"

namespace fs = std::filesystem;
using massage_cell::test::TempDir;

namespace {

std::string g_output_dir_from_gtest;  // the folder of --gtest_output=xml:FILE (set in main)

/// `name` on PATH (or as given when it holds a '/'), or "" when there is none.
std::string findExecutable(const std::string& name) {
  if (name.empty()) return "";
  if (name.find('/') != std::string::npos) return access(name.c_str(), X_OK) == 0 ? name : "";
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(ss, dir, ':')) {
    const fs::path candidate = fs::path(dir.empty() ? "." : dir) / name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

/// A child process (execv, own process group, environment additions), ended with
/// SIGTERM then SIGKILL on destruction.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const std::map<std::string, std::string>& env,
        const std::string& log_file, int keep_fd = -1) {
    pid_ = fork();
    if (pid_ == 0) {
      setpgid(0, 0);
      for (const auto& [k, v] : env) setenv(k.c_str(), v.c_str(), 1);
      const int log = open(log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (log >= 0) {
        dup2(log, 1);
        dup2(log, 2);
      }
      const int null = open("/dev/null", O_RDONLY);
      if (null >= 0) dup2(null, 0);
      for (int fd = 3; fd < 1024; ++fd)
        if (fd != keep_fd) close(fd);
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
  }
  ~Child() { stop(); }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    return true;
  }
  void stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 50; ++i) {
      if (!running()) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

/// An Xvfb server on a display number it picks itself (-displayfd: no race with other
/// servers or parallel tests).
class Xvfb {
 public:
  Xvfb(const std::string& exe, const std::string& log_file) {
    int fds[2];
    if (pipe(fds) != 0) return;
    child_ = std::make_unique<Child>(std::vector<std::string>{exe, "-displayfd", std::to_string(fds[1]), "-screen", "0",
                                                              "1280x800x24", "-nolisten", "tcp"},
                                     std::map<std::string, std::string>{}, log_file, fds[1]);
    close(fds[1]);
    // Xvfb writes the display number once it accepts connections.
    std::string number;
    fcntl(fds[0], F_SETFL, O_NONBLOCK);
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    char c;
    while (std::chrono::steady_clock::now() < end) {
      const ssize_t n = read(fds[0], &c, 1);
      if (n == 1) {
        if (c == '\n') break;
        number += c;
      } else if (n == 0) {
        break;
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    close(fds[0]);
    if (!number.empty()) display_ = ":" + number;
  }
  const std::string& display() const { return display_; }

 private:
  std::unique_ptr<Child> child_;
  std::string display_;
};

/// cell.rviz with the displays of class `disabled_class` switched off.
void writeVariant(const std::string& in, const std::string& out, const std::string& disabled_class) {
  YAML::Node root = YAML::LoadFile(in);
  YAML::Node displays = root["Visualization Manager"]["Displays"];
  int changed = 0;
  for (std::size_t i = 0; i < displays.size(); ++i) {
    if (displays[i]["Class"].as<std::string>() == disabled_class) {
      displays[i]["Enabled"] = false;
      displays[i]["Value"] = false;
      ++changed;
    }
  }
  ASSERT_EQ(changed, 1) << in << " should hold exactly one " << disabled_class << " display";
  YAML::Emitter emitter;
  emitter << root;
  std::ofstream(out) << emitter.c_str() << "\n";
}

/// Nodes subscribed to `topic`, from the master's system state.
std::set<std::string> subscribersOf(const std::string& topic) {
  std::set<std::string> nodes;
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, true)) return nodes;
  XmlRpc::XmlRpcValue& subs = payload[1];
  for (int i = 0; i < subs.size(); ++i) {
    if (static_cast<std::string>(subs[i][0]) != topic) continue;
    for (int j = 0; j < subs[i][1].size(); ++j) nodes.insert(static_cast<std::string>(subs[i][1][j]));
  }
  return nodes;
}

/// Pixels whose colour differs by more than `threshold` in some channel, inside `roi`.
cv::Mat differenceMask(const cv::Mat& a, const cv::Mat& b, const cv::Rect& roi, int threshold = 40) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  std::vector<cv::Mat> channels;
  cv::split(diff, channels);
  cv::Mat m = cv::max(cv::max(channels[0], channels[1]), channels[2]) > threshold;
  cv::Mat mask = cv::Mat::zeros(m.size(), CV_8U);
  m(roi).copyTo(mask(roi));
  return mask;
}

std::size_t distinctColours(const cv::Mat& bgr) {
  std::set<std::uint32_t> colours;
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) colours.insert((p[x][0] << 16) | (p[x][1] << 8) | p[x][2]);
  }
  return colours.size();
}

/// The screenshot with the mask's pixels painted over in `colour` (for humans).
cv::Mat overlay(const cv::Mat& shot, const cv::Mat& mask, const cv::Scalar& colour) {
  cv::Mat out = shot.clone();
  out.setTo(colour, mask);
  return out;
}

}  // namespace

TEST(RvizCell, RendersRobotAndCloud) {
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };

  const char* xvfb_env = std::getenv("MASSAGE_CELL_XVFB");
  const std::string xvfb = findExecutable(xvfb_env ? xvfb_env : "Xvfb");
  if (xvfb.empty()) {
    const std::string msg = std::string("rviz_cell SKIPPED: Xvfb is not installed (") +
                            (xvfb_env ? std::string("MASSAGE_CELL_XVFB=") + xvfb_env : "no Xvfb on PATH") +
                            "); apt-get install xvfb imagemagick rviz (scripts/debian_packages.txt) to render "
                            "rviz/cell.rviz";
    std::cout << msg << std::endl;
    GTEST_SKIP() << msg;
  }
  const std::string rviz = findExecutable("rviz");
  ASSERT_FALSE(rviz.empty()) << "no rviz on PATH: apt-get install rviz";
  const std::string import = findExecutable("import");
  ASSERT_FALSE(import.empty()) << "no ImageMagick 'import' on PATH: apt-get install imagemagick";

  ros::NodeHandle nh, pnh("~");
  std::string config;
  ASSERT_TRUE(pnh.getParam("config", config)) << "~config (the rviz config under test) is not set";
  std::string out_dir = g_output_dir_from_gtest;
  if (out_dir.empty()) pnh.param<std::string>("output_dir", out_dir, "/tmp/massage_cell_rviz_cell");
  fs::create_directories(out_dir);
  std::cout << "rviz_cell: screenshots in " << out_dir << std::endl;

  TempDir tmp("rviz_cell");
  const std::string no_robot = (tmp.path() / "no_robot.rviz").string();
  const std::string no_cloud = (tmp.path() / "no_cloud.rviz").string();
  writeVariant(config, no_robot, "rviz/RobotModel");
  writeVariant(config, no_cloud, "rviz/PointCloud2");
  if (HasFatalFailure()) return;

  // rviz writes ~/.rviz: keep it in the temp folder, the logs where ROS keeps them.
  const char* home = std::getenv("HOME");
  const char* ros_home = std::getenv("ROS_HOME");
  const std::string ros_home_value = ros_home ? ros_home : std::string(home ? home : "/tmp") + "/.ros";

  struct Window {
    std::string name, config;
    std::unique_ptr<Xvfb> x;
    std::unique_ptr<Child> rviz;
    cv::Mat shot;
  };
  std::vector<Window> windows(3);
  windows[0].name = "full";
  windows[0].config = config;
  windows[1].name = "no_robot";
  windows[1].config = no_robot;
  windows[2].name = "no_cloud";
  windows[2].config = no_cloud;
  std::set<std::string> rviz_nodes;
  for (auto& w : windows) {
    w.x = std::make_unique<Xvfb>(xvfb, (tmp.path() / ("xvfb_" + w.name + ".log")).string());
    ASSERT_FALSE(w.x->display().empty()) << "Xvfb did not start: " << (tmp.path() / ("xvfb_" + w.name + ".log"));
    const std::string node = "rviz_cell_test_" + w.name;
    rviz_nodes.insert("/" + node);
    w.rviz = std::make_unique<Child>(std::vector<std::string>{rviz, "-d", w.config, "__name:=" + node},
                                     std::map<std::string, std::string>{{"DISPLAY", w.x->display()},
                                                                        {"LIBGL_ALWAYS_SOFTWARE", "1"},
                                                                        {"HOME", tmp.str()},
                                                                        {"ROS_HOME", ros_home_value},
                                                                        {"XDG_RUNTIME_DIR", tmp.str()}},
                                     (fs::path(out_dir) / ("rviz_" + w.name + ".log")).string());
    std::cout << "rviz_cell: " << w.name << " on " << w.x->display() << std::endl;
  }

  // Every window has loaded its displays (the images are the config's last ones) and the
  // two that draw the cloud listen to it, before the bag is let go.
  const std::set<std::string> cloud_nodes = {"/rviz_cell_test_full", "/rviz_cell_test_no_robot"};
  auto windows_ready = [&] {
    const auto image_subs = subscribersOf("/stereo/left/image_raw");
    const auto cloud_subs = subscribersOf("/stereo/points2");
    for (const auto& n : rviz_nodes)
      if (!image_subs.count(n) || (cloud_nodes.count(n) && !cloud_subs.count(n))) return false;
    return true;
  };
  // Three rviz windows with software GL start in 10-35 s on 2 cores beside the rest of the suite: a wait, not a sleep.
  constexpr double kSubscribeWait = 90.0;
  const bool subscribed = massage_cell::test::spinUntil(windows_ready, kSubscribeWait);
  for (auto& w : windows)
    ASSERT_TRUE(w.rviz->running()) << "rviz (" << w.name << ") exited: see its log in " << out_dir;
  if (!subscribed) {
    std::string seen;
    for (const auto& n : subscribersOf("/stereo/left/image_raw")) seen += " " + n;
    seen += "; of /stereo/points2:";
    for (const auto& n : subscribersOf("/stereo/points2")) seen += " " + n;
    FAIL() << "the rviz windows did not subscribe within " << kSubscribeWait
           << " s; subscribers of /stereo/left/image_raw:" << seen;
  }
  std::cout << "rviz_cell: windows up after " << elapsed() << " s" << std::endl;

  int clouds = 0, meshes = 0;
  ros::WallTime last_cloud, last_clock;
  const boost::function<void(const sensor_msgs::PointCloud2ConstPtr&)> on_cloud =
      [&](const sensor_msgs::PointCloud2ConstPtr&) {
        ++clouds;
        last_cloud = ros::WallTime::now();
      };
  const boost::function<void(const visualization_msgs::MarkerConstPtr&)> on_mesh =
      [&](const visualization_msgs::MarkerConstPtr&) { ++meshes; };
  const boost::function<void(const rosgraph_msgs::ClockConstPtr&)> on_clock = [&](const rosgraph_msgs::ClockConstPtr&) {
    last_clock = ros::WallTime::now();
  };
  const boost::function<void(const diagnostic_msgs::DiagnosticArrayConstPtr&)> on_diagnostics =
      [](const diagnostic_msgs::DiagnosticArrayConstPtr&) {};
  ros::Subscriber cloud_sub = nh.subscribe<sensor_msgs::PointCloud2>("/stereo/points2", 2, on_cloud);
  ros::Subscriber mesh_sub = nh.subscribe<visualization_msgs::Marker>("/stereo/planar/mesh", 2, on_mesh);
  ros::Subscriber clock_sub = nh.subscribe<rosgraph_msgs::Clock>("/clock", 10, on_clock);
  // The gate: the bag plays once /diagnostics has a subscriber too.
  ros::Subscriber gate = nh.subscribe<diagnostic_msgs::DiagnosticArray>("/diagnostics", 1, on_diagnostics);

  ASSERT_TRUE(massage_cell::test::spinUntil([&] { return clouds > 0; }, 40.0))
      << "no cloud on /stereo/points2 within 40 s of starting the bag";
  std::cout << "rviz_cell: first cloud after " << elapsed() << " s" << std::endl;
  // The session is over when the clouds and the bag's clock have stopped. On the way,
  // live.png: the full window while the session plays, with the acupoint markers (they
  // expire 1 s after the last pair, so the static screenshots usually lack them).
  const std::string live_shot =
      import + " -display " + windows[0].x->display() + " -window root " + (fs::path(out_dir) / "live.png").string();
  bool live_taken = false;
  massage_cell::test::spinUntil(
      [&] {
        if (!live_taken && clouds >= 2 && (ros::WallTime::now() - last_cloud).toSec() > 1.0) {
          live_taken = true;
          massage_cell::test::runCommand(live_shot, 30);
        }
        const ros::WallTime now = ros::WallTime::now();
        return (now - last_cloud).toSec() > 3.0 && (last_clock.isZero() || (now - last_clock).toSec() > 2.0);
      },
      40.0);
  std::cout << "rviz_cell: " << clouds << " clouds, " << meshes << " plane meshes; static after " << elapsed() << " s"
            << std::endl;
  ros::WallDuration(2.0).sleep();  // rviz draws the last messages

  for (auto& w : windows) {
    const std::string file = (fs::path(out_dir) / (w.name + ".png")).string();
    const auto r = massage_cell::test::runCommand(import + " -display " + w.x->display() + " -window root " + file, 30);
    ASSERT_EQ(r.exit_code, 0) << "import failed: " << r.output;
    w.shot = cv::imread(file, cv::IMREAD_COLOR);
    ASSERT_FALSE(w.shot.empty()) << "cannot read " << file;
    ASSERT_EQ(w.shot.size(), cv::Size(1280, 800)) << file;
  }
  for (auto& w : windows) w.rviz->stop();
  std::cout << "rviz_cell: screenshots after " << elapsed() << " s" << std::endl;

  const cv::Mat& full = windows[0].shot;
  // The 3D view: the bounding box of the background colour of cell.rviz (Global Options).
  YAML::Node root = YAML::LoadFile(config);
  std::stringstream bg(root["Visualization Manager"]["Global Options"]["Background Color"].as<std::string>());
  int r = 0, g = 0, b = 0;
  char sep;
  bg >> r >> sep >> g >> sep >> b;
  cv::Mat background;
  cv::inRange(windows[1].shot, cv::Scalar(b, g, r), cv::Scalar(b, g, r), background);
  std::vector<cv::Point> bg_pixels;
  cv::findNonZero(background, bg_pixels);
  ASSERT_GT(bg_pixels.size(), 20000u) << "no 3D view (background " << r << "," << g << "," << b
                                      << ") in the screenshot without the robot: " << out_dir;
  const cv::Rect view = cv::boundingRect(bg_pixels);

  const cv::Mat robot = differenceMask(full, windows[1].shot, view);
  const cv::Mat cloud = differenceMask(full, windows[2].shot, view);
  cv::imwrite((fs::path(out_dir) / "robot_pixels.png").string(), overlay(full, robot, cv::Scalar(255, 0, 255)));
  cv::imwrite((fs::path(out_dir) / "cloud_pixels.png").string(), overlay(full, cloud, cv::Scalar(0, 255, 0)));

  const int robot_pixels = cv::countNonZero(robot);
  const int cloud_pixels = cv::countNonZero(cloud);
  cv::Scalar mean, stddev;
  cv::meanStdDev(full(view), mean, stddev);
  const std::size_t view_colours = distinctColours(full(view));
  // The image panels right of the 3D view: camera pictures, not "No Image".
  const int right_x = std::min(full.cols - 1, view.x + view.width + 20);
  const cv::Mat right = full(cv::Rect(right_x, view.y, full.cols - right_x, view.height));
  const std::size_t image_colours = distinctColours(right);
  std::cout << "rviz_cell: 3D view " << view << ", " << view_colours << " colours, stddev " << stddev[0] << "/"
            << stddev[1] << "/" << stddev[2] << "; robot " << robot_pixels << " px, cloud " << cloud_pixels
            << " px; image panels " << image_colours << " colours; total " << elapsed() << " s" << std::endl;

  EXPECT_GT(view.area(), full.cols * full.rows / 5) << "the 3D view is too small: " << view;
  EXPECT_GT(view_colours, 500u) << "the 3D view looks blank";
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 30.0) << "the 3D view looks blank";
  EXPECT_GT(robot_pixels, view.area() / 20) << "the robot (RobotModel) hardly shows: robot_pixels.png in " << out_dir;
  EXPECT_GT(cloud_pixels, view.area() / 40) << "the cloud (PointCloud2) hardly shows: cloud_pixels.png in " << out_dir;
  EXPECT_GT(image_colours, 1000u) << "the image panels show no camera picture: full.png in " << out_dir;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  const std::string output = testing::GTEST_FLAG(output);
  if (output.rfind("xml:", 0) == 0) {
    const fs::path xml(output.substr(4));
    if (xml.has_parent_path()) g_output_dir_from_gtest = (xml.parent_path() / "rviz_cell").string();
  }
  ros::init(argc, argv, "test_rviz_cell");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
