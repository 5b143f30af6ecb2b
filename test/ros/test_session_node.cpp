// The cell's main job end to end (test/ros/session.test): massage_session run
// as a user runs it, against cell.launch on the bundled recording played as a
// live camera. A two-acupoint routine completes at 1x: both presses done
// within 2 cm of the recording's ground truth, the report printed and written
// (index.html, the pictures); a routine naming an unknown acupoint fails with
// a line that names it; a bad routine file exits 2 naming the field. With
// --markers (test/ros/markers_session.test: the skin-marker recording) the
// report must say that C7, T7 and L4 came from the markers.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;
bool g_markers = false;  ///< --markers: the layout's C7, T7 and L4 must be given by skin markers
using massage_cell::test::runCommand;
using massage_cell::test::TempDir;

std::string writeRoutine(const TempDir& dir, const std::string& name, const std::string& text) {
  const std::string path = dir.str() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string session(const std::string& routine, const std::string& report) {
  return std::string(MASSAGE_SESSION) + " __ns:=stereo __name:=session_under_test _session:=" + routine +
         (report.empty() ? "" : " _report:=" + report);
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(SessionNode, AShortRoutineCompletesAtOneTimesWithItsReport) {
  TempDir dir("session_node");
  const std::string routine =
      writeRoutine(dir, "routine.yaml", "acupoints: [BL23_L, BL15_R]\nhold: 0.5\ndepth: 0.003\nfix_timeout: 60\n");
  const auto run = runCommand(session(routine, dir.str() + "/report"), 180);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(contains(run.output, "result: 2 of 2 presses done")) << run.output;
  EXPECT_TRUE(contains(run.output, "press BL23_L: done")) << run.output;
  EXPECT_TRUE(contains(run.output, "tool at depth")) << "the presses are measured against the truth\n" << run.output;
  EXPECT_TRUE(contains(run.output, "latency camera stamp -> acupoint tf: p50")) << run.output;
  EXPECT_TRUE(contains(run.output, "the session went well")) << run.output;
  EXPECT_TRUE(contains(run.output, "  layout: C7 ")) << "the report names the layout's landmarks\n" << run.output;
  if (g_markers) {
    EXPECT_TRUE(contains(run.output, "layout: C7 given (marker), T7 given (marker), L4 given (marker)")) << run.output;
  }
  for (const char* file : {"index.html", "acupoints.png", "trajectory.png"}) {
    EXPECT_TRUE(fs::exists(dir.path() / "report" / file)) << file << "\n" << run.output;
  }
}

TEST(SessionNode, AnAcupointThatIsNeverFoundFailsNamingIt) {
  TempDir dir("session_node");
  const std::string routine =
      writeRoutine(dir, "routine.yaml", "acupoints: [BL23_L, NOT_AN_ACUPOINT]\nhold: 0.5\nfix_timeout: 5\n");
  const auto run = runCommand(session(routine, ""), 60);
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(contains(run.output, "no stable fix within 5 s for: ")) << run.output;
  EXPECT_TRUE(contains(run.output, "NOT_AN_ACUPOINT")) << run.output;
  EXPECT_TRUE(contains(run.output, "the session FAILED")) << run.output;
}

TEST(SessionNode, ABadRoutineFileExitsTwoNamingTheField) {
  TempDir dir("session_node");
  const auto run =
      runCommand(session(writeRoutine(dir, "routine.yaml", "acupoints: [BL23_L]\ntechnique: slap\n"), ""), 30);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "technique")) << run.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  for (int i = 1; i < argc; ++i) g_markers = g_markers || std::string(argv[i]) == "--markers";
  return RUN_ALL_TESTS();
}
