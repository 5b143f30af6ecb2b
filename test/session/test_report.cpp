// The massage session's report: the records and their summary, index.html, the
// pictures, and a press by force's figures and plot.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/session/report.h"

namespace report = massage_cell::session;

namespace {

cv::Mat grey3(const cv::Mat& grey) {
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// A press by force at 50 Hz: seek 0-1 s, ramp 1-1.5 s to 30 N overshooting to 34 N, hold 1.5-3.5 s (1.4 s at
/// 30 N ± 1, then 0.6 s at 26 N: more than 10 % off), release 3.5-4 s tracking its set-point within 10 %, back off;
/// the cap 40 N throughout.
std::vector<report::ForceSample> syntheticPress() {
  std::vector<report::ForceSample> trace;
  for (int i = 0; i < 225; ++i) {
    report::ForceSample s;
    s.t = 0.02 * i;
    s.limit = 40.0;
    if (i < 50) {
      s.phase = "seek";
      s.force = 0.0;
    } else if (i < 75) {
      s.phase = "ramp";
      s.target = 30.0 * (i - 50) / 25.0;
      s.force = i == 74 ? 34.0 : s.target;  // the peak lies outside the hold
    } else if (i < 175) {
      s.phase = "hold";
      s.target = 30.0;
      s.force = i < 145 ? 30.0 + ((i % 2) ? 1.0 : -1.0) : 26.0;
    } else if (i < 200) {
      s.phase = "release";
      s.target = 30.0 * (200 - i) / 25.0;
      s.force = s.target;
    } else {
      s.phase = "back off";
      s.force = 0.0;
    }
    trace.push_back(s);
  }
  return trace;
}

/// Whether a pixel within `r` of (x, y) has about `colour`.
bool colourNear(const cv::Mat& image, int x, int y, const cv::Scalar& colour, int r = 2) {
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y + dy, x + dx);
      if (std::abs(p[0] - colour[0]) + std::abs(p[1] - colour[1]) + std::abs(p[2] - colour[2]) < 40) return true;
    }
  }
  return false;
}

int redPixelsInRow(const cv::Mat& image, int row, const cv::Rect& area) {
  int n = 0;
  for (int x = area.x; x < area.x + area.width; ++x) n += image.at<cv::Vec3b>(row, x) == cv::Vec3b(0, 0, 255) ? 1 : 0;
  return n;
}

}  // namespace

TEST(SessionReport, CountsPressesWithinTheTolerance) {
  report::SessionReport r;
  r.pairs = 120;
  report::PressRecord a;
  a.acupoint = "BL23_L";
  a.success = a.measured = true;
  a.tool_at_depth = Eigen::Vector3d(0.1, 0.2, 0.05);
  a.truth_at_depth = Eigen::Vector3d(0.1, 0.203, 0.05);
  a.targeted = true;
  a.target_at_depth = Eigen::Vector3d(0.1, 0.2, 0.051);
  report::PressRecord b = a;
  b.acupoint = "BL23_R";
  b.truth_at_depth.y() = 0.21;
  report::PressRecord c;
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
  report::PressRecord p;
  p.acupoint = "BL23_L";
  p.success = p.measured = p.by_force = true;
  p.force_held = 29.6;
  p.tool_at_depth = Eigen::Vector3d(0.1, 0.2, 0.145);    // 5 mm into the skin: the body's answer to the force
  p.truth_at_depth = Eigen::Vector3d(0.1, 0.203, 0.15);  // the true skin point, not pushed down
  EXPECT_NEAR(p.error(), 0.003, 1e-12);                  // across the skin only
  EXPECT_NEAR(p.indentation(), 0.005, 1e-12);
  report::SessionReport r;
  r.presses = {p};
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("29.6 N held, tool 3.0 mm from the ground truth across the skin and 5.0 mm into it"),
            std::string::npos)
      << s;
  p.by_force = false;  // the same numbers read as a press to a depth: the depth counts
  EXPECT_NEAR(p.error(), std::hypot(0.003, 0.005), 1e-12);
}

TEST(SessionReport, AStrokeIsMeasuredFromItsTruePathWithItsGlideAtTheForce) {
  report::SessionReport r;
  report::PressRecord press;
  press.acupoint = "BL23_L";
  press.success = true;
  report::PressRecord stroke;
  stroke.acupoint = "BL13_L -> BL23_L";
  stroke.stroke = true;
  stroke.success = true;
  stroke.path_error = 0.0042;
  stroke.tracking_error = 0.0003;
  // 1 s gliding: 0.5 s within 10 % of 20 N, 0.5 s out; the ramp before it does not count.
  stroke.force_trace = {{0.0, 5.0, 10.0, 40.0, "ramp"},
                        {0.5, 21.0, 20.0, 40.0, "glide"},
                        {1.0, 25.0, 20.0, 40.0, "glide"},
                        {1.5, 10.0, 5.0, 40.0, "release"}};
  r.presses = {press, stroke};
  const report::ForceFigures f = r.presses[1].force();
  EXPECT_TRUE(f.has_hold);
  EXPECT_DOUBLE_EQ(f.hold_seconds, 1.0);
  EXPECT_DOUBLE_EQ(f.within_seconds, 0.5);
  EXPECT_EQ(r.within(0.005), 1);  // the stroke, 4.2 mm from its true path; the press was not measured
  EXPECT_EQ(r.within(0.004), 0);
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("stroke BL13_L -> BL23_L: done in 0.0 s, tool within 4.2 mm of the true path across the skin "
                   "(0.3 mm of the path it was given)"),
            std::string::npos)
      << s;
  EXPECT_NE(s.find("result: 1 of 1 presses and 1 of 1 strokes done, 1 within 5 mm"), std::string::npos) << s;
}

TEST(SessionReport, LatencyQuantilesAndTheHtmlPage) {
  report::LatencyRecord l{"camera stamp -> acupoint tf", {}};
  EXPECT_TRUE(std::isnan(l.quantile(0.5)));
  for (int i = 1; i <= 100; ++i) l.samples.push_back(0.001 * i);
  EXPECT_DOUBLE_EQ(l.quantile(0.5), 0.050);
  EXPECT_DOUBLE_EQ(l.quantile(0.95), 0.095);
  EXPECT_DOUBLE_EQ(l.quantile(1.0), 0.100);
  report::SessionReport r;
  r.latencies = {l};
  report::PressRecord p;
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
  const cv::Mat a = report::drawAcupoints(grey, {{"GV14", {30, 40}}}, {{"GV14", {80, 60}}});
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(a.at<cv::Vec3b>(40, 30), cv::Vec3b(0, 0, 255)) << "the estimate, red";
  EXPECT_EQ(a.at<cv::Vec3b>(60, 80), cv::Vec3b(0, 200, 0)) << "the truth, a green cross";
  EXPECT_EQ(a.at<cv::Vec3b>(5, 5), cv::Vec3b(128, 128, 128));
  // Not the routine's: a small dark dot, no name beside it.
  const cv::Mat named = report::drawAcupoints(grey, {{"BL23_L", {30, 40}, true}}, {});
  const cv::Mat dot = report::drawAcupoints(grey, {{"BL23_L", {30, 40}, false}}, {});
  EXPECT_EQ(dot.at<cv::Vec3b>(40, 30), cv::Vec3b(0, 0, 160));
  const cv::Mat l = report::drawAcupoints(grey, {}, {}, {{"C7 marker", {60, 50}}});
  const cv::Vec3b tip = l.at<cv::Vec3b>(50, 60 + 2 * std::max(2, 120 / 160));  // the diamond's right tip
  EXPECT_TRUE(tip[0] > 200 && tip[1] > 200 && tip[2] < 60) << "a landmark's cyan diamond: " << tip;
  EXPECT_EQ(l.at<cv::Vec3b>(50, 60), cv::Vec3b(128, 128, 128)) << "hollow";
  EXPECT_GT(cv::norm(named(cv::Rect(33, 25, 60, 15)), grey3(grey)(cv::Rect(33, 25, 60, 15)), cv::NORM_L1), 0.0)
      << "the routine's point is named";
  EXPECT_EQ(cv::norm(dot(cv::Rect(33, 25, 60, 15)), grey3(grey)(cv::Rect(33, 25, 60, 15)), cv::NORM_L1), 0.0)
      << "the others are not";
  const cv::Mat t = report::drawTrajectory(grey, {{10, 50}, {110, 50}});
  EXPECT_NE(t.at<cv::Vec3b>(50, 60), cv::Vec3b(128, 128, 128)) << "the path is drawn";
  cv::Mat d(10, 10, CV_32F, cv::Scalar(0.0f));
  d(cv::Rect(0, 0, 5, 10)).setTo(20.0f);
  d.at<float>(0, 0) = 40.0f;
  const cv::Mat c = report::colourDisparity(d);
  EXPECT_EQ(c.at<cv::Vec3b>(5, 8), cv::Vec3b(0, 0, 0)) << "invalid: black";
  EXPECT_NE(c.at<cv::Vec3b>(5, 2), c.at<cv::Vec3b>(0, 0)) << "near and far differ";
}

TEST(ForceFigures, PeakAndTimeWithinTenPercentCountOnlyTheHold) {
  const report::ForceFigures f = report::forceFigures(syntheticPress());
  EXPECT_TRUE(f.has_hold);
  EXPECT_DOUBLE_EQ(f.peak, 34.0) << "the ramp's overshoot";
  EXPECT_DOUBLE_EQ(f.limit, 40.0);
  EXPECT_NEAR(f.hold_seconds, 2.0, 1e-9) << "100 hold samples of 20 ms";
  EXPECT_NEAR(f.within_seconds, 1.4, 1e-9) << "the ramp and release track their set-point too, but are not the hold";
  EXPECT_NEAR(f.withinFraction(), 0.7, 1e-9);
  // Exactly 10 % off counts; a force not known does not.
  std::vector<report::ForceSample> edge = {
      {0.0, 33.0, 30.0, 40.0, "hold"}, {0.1, NAN, 30.0, 40.0, "hold"}, {0.2, 30.0, 30.0, 40.0, "release"}};
  const report::ForceFigures e = report::forceFigures(edge);
  EXPECT_NEAR(e.hold_seconds, 0.2, 1e-12);
  EXPECT_NEAR(e.within_seconds, 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(e.peak, 33.0) << "NaN is no peak";
}

TEST(ForceFigures, ATraceWithoutAHoldGivesZeroAndSaysSo) {
  std::vector<report::ForceSample> trace = syntheticPress();
  trace.resize(70);  // failed during the ramp
  const report::ForceFigures f = report::forceFigures(trace);
  EXPECT_FALSE(f.has_hold);
  EXPECT_EQ(f.hold_seconds, 0.0);
  EXPECT_EQ(f.within_seconds, 0.0);
  EXPECT_EQ(f.withinFraction(), 0.0);
  EXPECT_GT(f.peak, 0.0);
  EXPECT_FALSE(report::forceFigures({}).has_hold);
  EXPECT_EQ(report::forceFigures({}).peak, 0.0);
  report::PressRecord p;
  p.acupoint = "BL23_L";
  p.force_trace = trace;
  report::SessionReport r;
  r.presses = {p};
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("BL23_L: FAILED in 0.0 s; peak 22.8 N, no hold phase (0 s within ±10 % of the set-point)"),
            std::string::npos)
      << s;
}

TEST(ForceFigures, TheSummaryShowsThePeakAndTheHoldWithinTenPercent) {
  report::PressRecord force;
  force.acupoint = "BL15_L";
  force.success = true;
  force.force_trace = syntheticPress();
  report::PressRecord depth;
  depth.acupoint = "BL15_R";
  depth.success = true;
  report::SessionReport r;
  r.presses = {force, depth};
  const std::string s = r.summary(0.005);
  EXPECT_NE(s.find("press BL15_L: done in 0.0 s; peak 34.0 N, 1.4 of 2.0 s of hold within ±10 % of the set-point "
                   "(70 %)\n"),
            std::string::npos)
      << s;
  EXPECT_NE(s.find("press BL15_R: done in 0.0 s\n"), std::string::npos) << "a press to a depth has no force figures\n"
                                                                        << s;
}

TEST(ForcePlot, ThePlotShowsTheCapTheSetPointAndTheMeasuredForce) {
  const std::vector<report::ForceSample> trace = syntheticPress();
  const cv::Size size(640, 360);
  const cv::Mat plot = report::drawForcePlot(trace, "press 1: BL15_L", size);
  ASSERT_EQ(plot.type(), CV_8UC3);
  EXPECT_EQ(plot.size(), size);
  const report::ForcePlotAxes a = report::forcePlotAxes(trace, size);
  ASSERT_TRUE(cv::Rect(0, 0, 640, 360).contains(a.area.tl()) && cv::Rect(0, 0, 641, 361).contains(a.area.br()));
  EXPECT_GE(a.f_max, 40.0) << "the cap is on the plot";
  EXPECT_LE(a.f_max, 60.0) << "and not lost at its bottom";
  EXPECT_EQ(a.f_min, 0.0);
  EXPECT_GE(a.t_max, 4.48);
  EXPECT_EQ(a.row(a.f_min), a.area.y + a.area.height - 1);
  EXPECT_EQ(a.row(a.f_max), a.area.y);
  EXPECT_EQ(a.col(0.0), a.area.x);
  // The cap: a red line across the plot at the row of 40 N, and nowhere near it.
  const int limit_row = a.row(40.0);
  EXPECT_GE(redPixelsInRow(plot, limit_row, a.area), a.area.width * 9 / 10) << "row " << limit_row;
  EXPECT_EQ(redPixelsInRow(plot, limit_row - 3, a.area), 0);
  EXPECT_EQ(redPixelsInRow(plot, limit_row + 3, a.area), 0);
  EXPECT_EQ(redPixelsInRow(plot, a.row(30.0), a.area), 0);
  // Late in the hold the measured force (26 N) is off its set-point (30 N): both curves, each where it belongs.
  EXPECT_TRUE(colourNear(plot, a.col(3.2), a.row(26.0), report::kMeasuredColour)) << "the measured force";
  EXPECT_TRUE(colourNear(plot, a.col(3.2), a.row(30.0), report::kTargetColour)) << "the set-point";
  EXPECT_FALSE(colourNear(plot, a.col(3.2), a.row(30.0), report::kMeasuredColour));
  EXPECT_TRUE(colourNear(plot, a.col(2.0), a.row(30.0), report::kMeasuredColour)) << "early in the hold, on target";
  EXPECT_TRUE(colourNear(plot, a.col(0.5), a.row(0.0) - 1, report::kMeasuredColour)) << "no force while seeking";
  EXPECT_TRUE(report::drawForcePlot({}, "nothing").empty()) << "no trace (a press to a depth): no plot";
  // A force a little below 0 (noise before contact) is shown, without giving the plot's height to it.
  std::vector<report::ForceSample> noisy = trace;
  noisy[10].force = -1.5;
  const report::ForcePlotAxes n = report::forcePlotAxes(noisy, size);
  EXPECT_LT(n.f_min, -1.5);
  EXPECT_GE(n.f_min, -0.1 * n.f_max);
  EXPECT_GT(n.row(-1.5), n.row(0.0)) << "below the 0 line";
}

TEST(ForcePlot, TheHtmlShowsEveryPressByForceItsPlot) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "force_plot_report";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  report::PressRecord force;
  force.acupoint = "BL15_L";
  force.success = true;
  force.force_trace = syntheticPress();
  report::PressRecord depth;
  depth.acupoint = "BL15_R";
  depth.success = true;
  report::SessionReport r;
  r.presses = {depth, force};
  r.writeHtml(dir.string(), 0.005, {{"acupoints.png", "the acupoints"}});
  const std::string html = readFile((dir / "index.html").string());
  EXPECT_NE(html.find("src=\"force_2_BL15_L.png\""), std::string::npos) << html;
  EXPECT_NE(html.find("<td>34.0</td><td>1.4 of 2.0 (70 %)</td>"), std::string::npos) << "peak, within ±10 %\n" << html;
  EXPECT_EQ(html.find("force_1_"), std::string::npos) << "a press to a depth has no plot";
  EXPECT_NE(html.find("src=\"acupoints.png\""), std::string::npos);
  const cv::Mat png = cv::imread((dir / "force_2_BL15_L.png").string());
  EXPECT_EQ(png.size(), cv::Size(640, 360)) << "the plot is written beside index.html";
  EXPECT_FALSE(std::filesystem::exists(dir / "force_1_BL15_R.png"));
  EXPECT_EQ(report::forcePlotFile(0, "BL 15/L"), "force_1_BL_15_L.png") << "a file name, whatever the acupoint";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
