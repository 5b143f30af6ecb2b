// config/arm.yaml loads; every kind of mistake is an ArmConfigError naming the field.
#include <gtest/gtest.h>

#include <stdlib.h>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <regex>

#include "massage_cell/arm/config.h"
#include "massage_cell/arm/node_options.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::arm;

const std::string kConfigDir = std::string(MASSAGE_CELL_SOURCE_DIR) + "/config";

std::string fileText() {
  std::ifstream in(kConfigDir + "/arm.yaml");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The shipped file with one line replaced (regex on the whole text).
std::string edited(const std::string& pattern, const std::string& replacement) {
  const std::string text = fileText();
  const std::string out = std::regex_replace(text, std::regex(pattern), replacement);
  EXPECT_NE(out, text) << "pattern not found: " << pattern;
  return out;
}

std::string errorOf(const std::string& text) {
  try {
    parseArmConfig(text, "arm.yaml", kConfigDir);
  } catch (const ArmConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ArmConfig, ShippedFileLoads) {
  const ArmConfig c = loadArmConfig(kConfigDir + "/arm.yaml");
  EXPECT_EQ(c.axis_names[0], "X");
  EXPECT_EQ(c.axis_names[2], "Z");
  EXPECT_EQ(c.joint_names[1], "arm_y_joint");
  EXPECT_DOUBLE_EQ(c.joints[0].max, 0.78);
  EXPECT_DOUBLE_EQ(c.joints[2].max_velocity, 0.05);
  EXPECT_EQ(c.axis(1).node_id, 2);
  EXPECT_EQ(c.regions.size(), 4u);
  EXPECT_DOUBLE_EQ(c.limitsOf("midline").max_depth, 0.002);
  EXPECT_DOUBLE_EQ(c.limitsOf("no such region").max_depth, 0.002);  // the default region's
  EXPECT_NEAR(c.press.max_normal_tilt, M_PI / 4, 1e-12);
  // The acupoint model's regions.
  EXPECT_EQ(c.regionOf("BL23_L"), "lower_back");
  EXPECT_EQ(c.regionOf("BL13_R"), "upper_back");
  EXPECT_EQ(c.regionOf("GV4"), "midline");
  EXPECT_EQ(c.regionOf("GB21_L"), "shoulder");
  EXPECT_EQ(c.regionOf("XX1"), "");
  EXPECT_GT(c.acupoint_regions.size(), 50u);
  // Tool offset: forward and inverse.
  const Eigen::Vector3d q(0.1, 0.2, 0.3);
  EXPECT_TRUE(c.jointsOf(c.toolOf(q)).isApprox(q));
}

TEST(ArmConfig, MistakesAreNamed) {
  EXPECT_NE(
      errorOf(edited("watchdog_timeout: 1.0", "watchdog_timeout: 1.0\nwatchdog: 1")).find("watchdog: unknown field"),
      std::string::npos);
  EXPECT_NE(errorOf(edited("X: \\{min: 0.0, max: 0.78", "X: {min: 0.0, max: 0.85"))
                .find("joints.X.max: 0.85 m is beyond the drive's software limit 0.8 m"),
            std::string::npos)
      << errorOf(edited("X: \\{min: 0.0, max: 0.78", "X: {min: 0.0, max: 0.85"));
  EXPECT_NE(errorOf(edited("max: \\[0.76, 0.46, 0.30\\]", "max: [0.76, 0.49, 0.30]"))
                .find("workspace: the y range [0, 0.49] m is not inside what the joint limits reach"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("default_region: midline", "default_region: neck"))
                .find("default_region: 'neck' is not one of regions"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("lower_back: \\{max_depth: 0.012, default_depth: 0.008,",
                           "lower_back: {max_depth: 0.012, default_depth: 0.02,"))
                .find("regions.lower_back.default_depth: must be > 0 and <= max_depth"),
            std::string::npos);
  // Force mode: a region's default force above its cap, a press by force without the force section.
  EXPECT_NE(errorOf(edited("default_force: 30.0, max_force: 60.0", "default_force: 65.0, max_force: 60.0"))
                .find("regions.lower_back.default_force: must be above force_control.contact_force"),
            std::string::npos);
  EXPECT_EQ(errorOf(edited("  mode: depth ", "  mode: force ")), "");
  EXPECT_NE(errorOf(edited("max_pressure: 35.0, ", "")).find("regions.lower_back: presses by force"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("  mode: depth ", "  mode: forced ")).find("press.mode: 'forced' is neither"),
            std::string::npos);
  // acupoints.yaml names lower_back: removing that region from the table is caught.
  EXPECT_NE(errorOf(edited("  lower_back: \\{max_depth: 0.012, default_depth: 0.008,.*\n.*\n", ""))
                .find("has region 'lower_back', which regions does not list"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("can_config: can_axes.yaml", "can_config: nowhere.yaml")).find("can_config: "),
            std::string::npos);
  EXPECT_NE(errorOf(edited("axes: \\[X, Y, Z\\]", "axes: [X, Y, W]")).find("W"), std::string::npos);
  EXPECT_NE(errorOf(edited("speed: 0.01 ", "speed: fast ")).find("press.speed: expected a number, got 'fast'"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("travel_height: 0.28", "travel_height: 0.5")).find("press.travel_height"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("estop_release: true", "estop_release: maybe"))
                .find("press.estop_release: expected true or false, got 'maybe'"),
            std::string::npos);
  EXPECT_NE(errorOf(edited("max_targets: 50", "max_targets: 0")).find("press.max_targets"), std::string::npos);
  EXPECT_NE(errorOf("joints: [").find("not valid YAML"), std::string::npos);
  EXPECT_THROW(loadArmConfig("/nonexistent/arm.yaml"), ArmConfigError);
}

// A list where a name belongs made yaml-cpp's own exception escape, naming
// no file (found by fuzz_yaml_loaders).
TEST(ArmConfig, AcupointFileOfTheWrongShapeIsNamed) {
  const std::string path = ::testing::TempDir() + "/acupoints_wrong_shape.yaml";
  std::ofstream(path) << "points:\n  - {name: [BL23_L, BL23_R], region: lower_back}\n";
  try {
    loadAcupointRegions(path);
    ADD_FAILURE() << "no error";
  } catch (const ArmConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  std::ofstream(path) << "points: 3\n";
  EXPECT_THROW(loadAcupointRegions(path), ArmConfigError);
  std::remove(path.c_str());
}

// ------------------------------------------------------------ node options --

std::string writeTemp(const std::string& text) {
  char path[] = "/tmp/test_arm_node_options_XXXXXX";
  const int fd = mkstemp(path);
  EXPECT_GE(fd, 0);
  std::FILE* f = fdopen(fd, "w");
  std::fputs(text.c_str(), f);
  std::fclose(f);
  return path;
}

TEST(NodeOptions, ShippedFileSetsTheNodeSection) {
  const NodeOptions o = loadNodeOptions(kConfigDir + "/arm.yaml");
  EXPECT_EQ(o.can_interface, "sim");
  EXPECT_EQ(o.base_frame, "arm_base_link");
  EXPECT_DOUBLE_EQ(o.max_target_age, 1.0);  // the file's value, not the struct's default (0.5)
  EXPECT_EQ(o.acupoint_prefix, "acupoint/");
  EXPECT_NO_THROW(validate(o));
}

TEST(NodeOptions, MissingSectionKeepsTheDefaults) {
  const std::string path = writeTemp("joints: {}\n");
  const NodeOptions o = loadNodeOptions(path);
  std::remove(path.c_str());
  EXPECT_EQ(o.can_interface, "sim");
  EXPECT_DOUBLE_EQ(o.publish_rate, 50.0);
  EXPECT_EQ(o.realtime.priority, 0);
}

TEST(NodeOptions, WrongTypeNamesTheFileAndSection) {
  const std::string path = writeTemp("node:\n  publish_rate: fast\n");
  try {
    loadNodeOptions(path);
    ADD_FAILURE() << "no error for publish_rate: fast";
  } catch (const ArmConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": node:"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

TEST(NodeOptions, ValidateNamesTheBadOption) {
  auto problem = [](const std::function<void(NodeOptions&)>& edit) {
    NodeOptions o;
    edit(o);
    try {
      validate(o);
    } catch (const ArmConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(problem([](NodeOptions&) {}), "");
  EXPECT_EQ(problem([](NodeOptions& o) { o.publish_rate = 0.0; }).rfind("publish_rate must be > 0", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.publish_rate = std::nan(""); }).rfind("publish_rate", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.max_target_age = -1.0; }).rfind("max_target_age", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.tf_timeout = -0.1; }).rfind("tf_timeout must be >= 0", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.command_timeout = 0.0; }).rfind("command_timeout", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.can_interface.clear(); }).rfind("can_interface", 0), 0u);
  EXPECT_EQ(problem([](NodeOptions& o) { o.realtime.priority = 100; }).rfind("realtime_priority", 0), 0u);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
