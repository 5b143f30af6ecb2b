// The massage session's routine file and the stable-fix test (the report's tests: test/session/test_report.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <string>

#include "massage_cell/arm/session.h"

namespace arm = massage_cell::arm;

namespace {

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
  // ... and strokes one Bladder line, whose points the fix waits for too (after the pressed ones, each once).
  ASSERT_EQ(c.strokes.size(), 1u);
  EXPECT_GE(c.strokes[0].size(), 2u);
  const std::vector<std::string> all = c.allAcupoints();
  EXPECT_TRUE(std::equal(c.acupoints.begin(), c.acupoints.end(), all.begin()));
  for (const std::string& a : c.strokes[0]) EXPECT_EQ(std::count(all.begin(), all.end(), a), 1) << a;
}

TEST(SessionConfig, StrokesArePathsByForce) {
  const arm::SessionConfig c = arm::SessionConfig::load(
      writeFile("strokes.yaml", "acupoints: [BL15_L]\nmode: force\nstrokes: [[BL13_L, BL15_L, BL23_L]]\n"));
  EXPECT_EQ(c.allAcupoints(), (std::vector<std::string>{"BL15_L", "BL13_L", "BL23_L"}));
  EXPECT_NE(loadError("acupoints: [GV14]\nmode: force\nstrokes: [[BL13_L]]\n").find("strokes[0]: expected a path"),
            std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nmode: force\nstrokes: [[BL13_L, BL13_L]]\n").find("twice"),
            std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nmode: depth\nstrokes: [[BL13_L, BL15_L]]\n").find("needs mode force"),
            std::string::npos);
  EXPECT_NE(loadError("acupoints: [GV14]\nmode: force\nstroke_force: -1\n").find("stroke_force"), std::string::npos);
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

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
