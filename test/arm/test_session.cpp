// The massage session's routine file, the stable-fix test and the report.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include <opencv2/imgproc.hpp>

#include "massage_cell/arm/session.h"

namespace arm = massage_cell::arm;

namespace {

cv::Mat grey3(const cv::Mat& grey) {
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

std::string writeFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string loadError(const std::string& text) {
  try {
    arm::SessionConfig::load(writeFile("session.yaml", text));
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SessionConfig, TheShippedRoutineLoads) {
  const arm::SessionConfig c = arm::SessionConfig::load(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/session.yaml");
  EXPECT_GE(c.acupoints.size(), 6u);
  EXPECT_EQ(c.technique, "press");
  EXPECT_GT(c.depth, 0.0);
  EXPECT_EQ(c.mode, "force");  // the main job presses by force
  EXPECT_EQ(c.frame_prefix, "acupoint/");
}

TEST(SessionConfig, BadFilesAreNamed) {
  EXPECT_NE(loadError("acupoints: []\n").find("acupoints"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14, GV14]\n").find("twice"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\ntechnique: slap\n").find("technique"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\ndepth: 0.5\n").find("depth"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nrepeat: 2\n").find("unknown field 'repeat'"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nmode: push\n").find("mode: expected force or depth"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nforce: 300\n").find("force"), std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14\n").find("session.yaml"), std::string::npos) << "a YAML error names the file";
  EXPECT_THROW(arm::SessionConfig::load("/nonexistent/session.yaml"), std::runtime_error);
}

TEST(StableFix, SettlesOnlyWithEnoughCloseEstimates) {
  arm::StableFix fix(1.0, 4, 0.003);
  for (int i = 0; i < 3; ++i) fix.add("BL23_L", 0.1 * i, Eigen::Vector3d(0.1, 0.0, 0.7), true);
  EXPECT_FALSE(fix.stable("BL23_L", 0.2)) << "3 of 4 samples";
  fix.add("BL23_L", 0.3, Eigen::Vector3d(0.1, 0.001, 0.7), true);
  EXPECT_TRUE(fix.stable("BL23_L", 0.3));
  EXPECT_NEAR(fix.mean("BL23_L", 0.3).y(), 0.00025, 1e-12);
  EXPECT_FALSE(fix.stable("BL23_L", 1.35)) << "the window has passed";
  fix.add("BL23_L", 0.4, Eigen::Vector3d(0.1, 0.02, 0.7), true);
  EXPECT_FALSE(fix.stable("BL23_L", 0.4)) << "a jump of 2 cm";
  for (int i = 0; i < 4; ++i) fix.add("GV14", 2.0 + 0.1 * i, Eigen::Vector3d(0, 0, 0.7), true);
  fix.add("GV14", 2.4, Eigen::Vector3d::Zero(), false);
  EXPECT_FALSE(fix.stable("GV14", 2.4)) << "an invalid estimate starts over";
  EXPECT_EQ(fix.unstable({"GV14", "NEVER_SEEN"}, 2.4).size(), 2u);
  EXPECT_FALSE(fix.mean("NEVER_SEEN", 0.0).allFinite());
}

TEST(SessionReport, CountsPressesWithinTheTolerance) {
  arm::SessionReport r;
  r.pairs = 120;
  arm::PressRecord a;
  a.acupoint = "BL23_L";
  a.success = a.measured = true;
  a.tool_at_depth = Eigen::Vector3d(0.1, 0.2, 0.05);
  a.truth_at_depth = Eigen::Vector3d(0.1, 0.203, 0.05);
  a.targeted = true;
  a.target_at_depth = Eigen::Vector3d(0.1, 0.2, 0.051);
  arm::PressRecord b = a;
  b.acupoint = "BL23_R";
  b.truth_at_depth.y() = 0.21;
  arm::PressRecord c;
  c.acupoint = "GV14";
  c.message = "'acupoint/GV14' is stale";
  r.presses = {a, b, c};
  r.fix = {{"BL18_L", 0.005, Eigen::Vector3d(0.0, 0.004, -0.003)}};
  EXPECT_EQ(r.summary(0.005).find("layout:"), std::string::npos) << "no landmarks known: no line";
  r.landmarks = "C7 given (marker), L4 measured (the waist)";
  EXPECT_EQ(r.within(0.005), 1);
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("  layout: C7 given (marker), L4 measured (the waist)\n"), std::string::npos) << s;
  EXPECT_NE(s.find("press BL23_L: done"), std::string::npos) << s;
  EXPECT_NE(s.find("3.0 mm from the ground truth (1.0 mm from CECT's acupoint)"), std::string::npos) << s;
  EXPECT_NE(s.find("press GV14: FAILED"), std::string::npos) << s;
  EXPECT_NE(s.find("fix   BL18_L: 5.0 mm from the ground truth (x +0.0, y +4.0, z -3.0 mm)"), std::string::npos) << s;
  EXPECT_NE(s.find("is stale"), std::string::npos) << s;
  EXPECT_NE(s.find("result: 2 of 3 presses done, 1 within 5 mm"), std::string::npos) << s;
}

TEST(SessionReport, APressByForceIsMeasuredAcrossTheSkinWithItsForce) {
  arm::PressRecord p;
  p.acupoint = "BL23_L";
  p.success = p.measured = p.by_force = true;
  p.force_held = 29.6;
  p.tool_at_depth = Eigen::Vector3d(0.1, 0.2, 0.145);    // 5 mm into the skin: the body's answer to the force
  p.truth_at_depth = Eigen::Vector3d(0.1, 0.203, 0.15);  // the true skin point, not pushed down
  EXPECT_NEAR(p.error(), 0.003, 1e-12);                  // across the skin only
  EXPECT_NEAR(p.indentation(), 0.005, 1e-12);
  arm::SessionReport r;
  r.presses = {p};
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("29.6 N held, tool 3.0 mm from the ground truth across the skin and 5.0 mm into it"),
            std::string::npos)
      << s;
  p.by_force = false;  // the same numbers read as a press to a depth: the depth counts
  EXPECT_NEAR(p.error(), std::hypot(0.003, 0.005), 1e-12);
}

TEST(SessionReport, LatencyQuantilesAndTheHtmlPage) {
  arm::LatencyRecord l{"camera stamp -> acupoint tf", {}};
  EXPECT_TRUE(std::isnan(l.quantile(0.5)));
  for (int i = 1; i <= 100; ++i) l.samples.push_back(0.001 * i);
  EXPECT_DOUBLE_EQ(l.quantile(0.5), 0.050);
  EXPECT_DOUBLE_EQ(l.quantile(0.95), 0.095);
  EXPECT_DOUBLE_EQ(l.quantile(1.0), 0.100);
  arm::SessionReport r;
  r.latencies = {l};
  arm::PressRecord p;
  p.acupoint = "BL23_L";
  p.message = "refused: <envelope> & more";
  r.presses = {p};
  EXPECT_NE(r.summary(0.005).find("latency camera stamp -> acupoint tf: p50 50 ms, p95 95 ms (100)"), std::string::npos)
      << r.summary(0.005);
  const std::string dir = ::testing::TempDir();
  r.writeHtml(dir, 0.005, {{"acupoints.png", "the acupoints"}});
  std::ifstream in(dir + "/index.html");
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("<td>BL23_L</td><td>failed</td>"), std::string::npos) << html;
  EXPECT_NE(html.find("refused: &lt;envelope&gt; &amp; more"), std::string::npos) << "escaped";
  EXPECT_NE(html.find("src=\"acupoints.png\""), std::string::npos);
  EXPECT_NE(html.find("<td>95</td>"), std::string::npos) << "p95 in ms";
  EXPECT_THROW(r.writeHtml("/nonexistent/dir", 0.005, {}), std::runtime_error);
}

TEST(SessionPictures, MarksLandWhereTheyAreSaid) {
  const cv::Mat grey(100, 120, CV_8UC1, cv::Scalar(128));
  const cv::Mat a = arm::drawAcupoints(grey, {{"GV14", {30, 40}}}, {{"GV14", {80, 60}}});
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(a.at<cv::Vec3b>(40, 30), cv::Vec3b(0, 0, 255)) << "the estimate, red";
  EXPECT_EQ(a.at<cv::Vec3b>(60, 80), cv::Vec3b(0, 200, 0)) << "the truth, a green cross";
  EXPECT_EQ(a.at<cv::Vec3b>(5, 5), cv::Vec3b(128, 128, 128));
  // Not the routine's: a small dark dot, no name beside it.
  const cv::Mat named = arm::drawAcupoints(grey, {{"BL23_L", {30, 40}, true}}, {});
  const cv::Mat dot = arm::drawAcupoints(grey, {{"BL23_L", {30, 40}, false}}, {});
  EXPECT_EQ(dot.at<cv::Vec3b>(40, 30), cv::Vec3b(0, 0, 160));
  const cv::Mat l = arm::drawAcupoints(grey, {}, {}, {{"C7 marker", {60, 50}}});
  const cv::Vec3b tip = l.at<cv::Vec3b>(50, 60 + 2 * std::max(2, 120 / 160));  // the diamond's right tip
  EXPECT_TRUE(tip[0] > 200 && tip[1] > 200 && tip[2] < 60) << "a landmark's cyan diamond: " << tip;
  EXPECT_EQ(l.at<cv::Vec3b>(50, 60), cv::Vec3b(128, 128, 128)) << "hollow";
  EXPECT_GT(cv::norm(named(cv::Rect(33, 25, 60, 15)), grey3(grey)(cv::Rect(33, 25, 60, 15)), cv::NORM_L1), 0.0)
      << "the routine's point is named";
  EXPECT_EQ(cv::norm(dot(cv::Rect(33, 25, 60, 15)), grey3(grey)(cv::Rect(33, 25, 60, 15)), cv::NORM_L1), 0.0)
      << "the others are not";
  const cv::Mat t = arm::drawTrajectory(grey, {{10, 50}, {110, 50}});
  EXPECT_NE(t.at<cv::Vec3b>(50, 60), cv::Vec3b(128, 128, 128)) << "the path is drawn";
  cv::Mat d(10, 10, CV_32F, cv::Scalar(0.0f));
  d(cv::Rect(0, 0, 5, 10)).setTo(20.0f);
  d.at<float>(0, 0) = 40.0f;
  const cv::Mat c = arm::colourDisparity(d);
  EXPECT_EQ(c.at<cv::Vec3b>(5, 8), cv::Vec3b(0, 0, 0)) << "invalid: black";
  EXPECT_NE(c.at<cv::Vec3b>(5, 2), c.at<cv::Vec3b>(0, 0)) << "near and far differ";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
