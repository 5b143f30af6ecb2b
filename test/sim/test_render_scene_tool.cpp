// The render_scene tool: every preset writes the files its manifest lists,
// and bad input ends with a clear message and a non-zero exit status.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>

#include "../ros/test_util.h"
#include "massage_cell/camera/calibration_io.h"

namespace {

using massage_cell::test::runCommand;
using massage_cell::test::TempDir;
namespace fs = std::filesystem;

const std::string kTool = RENDER_SCENE_TOOL;
const std::string kSmall = " --width 160 --height 120 --fx 125 --supersample 1";

void expectFailure(const std::string& args, int code, const std::string& message) {
  const auto r = runCommand(kTool + " " + args, 120);
  EXPECT_EQ(r.exit_code, code) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n" << r.output;
}

/// Runs the tool; checks exit 0 and that every file of the manifest exists.
YAML::Node renderOk(const std::string& args, const TempDir& dir) {
  const auto r = runCommand(kTool + " --out " + dir.str() + " " + args, 300);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(" s"), std::string::npos) << "the tool prints its time";
  const YAML::Node manifest = YAML::LoadFile((dir.path() / "manifest.yaml").string());
  for (const auto& f : manifest["files"])
    EXPECT_TRUE(fs::exists(dir.path() / f.as<std::string>())) << f.as<std::string>();
  return manifest;
}

TEST(RenderSceneTool, BackPresetWritesImagesGroundTruthAndCalibration) {
  TempDir dir;
  const YAML::Node m = renderOk("--preset back --subject 7" + kSmall, dir);
  for (const char* f : {"left.png", "right.png", "left_depth.pfm", "right_depth.pfm", "left_disparity.pfm",
                        "right_disparity.pfm", "left_points.pfm", "left_labels.png", "left_visible.png",
                        "left_camera_info.yaml", "right_camera_info.yaml", "acupoints.yaml", "manifest.yaml"}) {
    EXPECT_TRUE(fs::exists(dir.path() / f)) << f;
  }
  const cv::Mat left = cv::imread((dir.path() / "left.png").string());
  EXPECT_EQ(left.size(), cv::Size(160, 120));
  const cv::Mat disparity = cv::imread((dir.path() / "left_disparity.pfm").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(disparity.type(), CV_32F);
  const YAML::Node acupoints = YAML::LoadFile((dir.path() / "acupoints.yaml").string());
  ASSERT_TRUE(acupoints["BL23_L"]);
  const double z = acupoints["GV4"][2].as<double>();
  EXPECT_GT(z, 0.5);  // in the left optical frame: in front of the camera
  EXPECT_LT(z, 0.95);
  const auto info = massage_cell::camera::readCameraInfoYaml((dir.path() / "right_camera_info.yaml").string());
  EXPECT_LT(info.P[3], 0.0);
  EXPECT_EQ(m["subject"]["index"].as<int>(), 7);
}

TEST(RenderSceneTool, RawPairHasNoDisparityButDistortedCalibration) {
  TempDir dir;
  renderOk("--preset back --raw" + kSmall, dir);
  EXPECT_FALSE(fs::exists(dir.path() / "left_disparity.pfm"));
  const auto info = massage_cell::camera::readCameraInfoYaml((dir.path() / "left_camera_info.yaml").string());
  EXPECT_NE(info.D[0], 0.0);
}

TEST(RenderSceneTool, SessionWritesNumberedPairsAndPerFrameGroundTruth) {
  TempDir dir;
  renderOk("--preset back --frames 3 --rate 10" + kSmall, dir);
  for (const char* f : {"left_0000.png", "right_0002.png", "ground_truth.yaml"})
    EXPECT_TRUE(fs::exists(dir.path() / f)) << f;
  const YAML::Node gt = YAML::LoadFile((dir.path() / "ground_truth.yaml").string());
  ASSERT_EQ(gt["frames"].size(), 3u);
  EXPECT_NEAR(gt["frames"][2]["time"].as<double>(), 0.2, 1e-9);
  // Breathing moves the upper back between frames.
  EXPECT_NE(gt["frames"][0]["acupoints"]["BL15_L"][2].as<double>(),
            gt["frames"][2]["acupoints"]["BL15_L"][2].as<double>());
}

TEST(RenderSceneTool, OtherPresets) {
  {
    TempDir dir;
    const YAML::Node m = renderOk("--preset efficiency_layers" + kSmall, dir);
    EXPECT_EQ(m["right_views"].size(), 8u);
    EXPECT_TRUE(fs::exists(dir.path() / "right_8.png"));
    EXPECT_EQ(m["right_views"][7]["levels"].as<int>(), 64);
  }
  {
    TempDir dir;
    renderOk("--preset efficiency_gradient" + kSmall, dir);
    EXPECT_TRUE(fs::exists(dir.path() / "left_disparity_1.pfm"));
  }
  {
    TempDir dir;
    renderOk("--preset boxes --boxes 2" + kSmall, dir);
    const cv::Mat labels = cv::imread((dir.path() / "left_labels.png").string(), cv::IMREAD_UNCHANGED);
    double hi = 0;
    cv::minMaxLoc(labels, nullptr, &hi);
    EXPECT_GE(hi, 10.0) << "box faces carry labels 10+";
  }
  {
    TempDir dir;
    const YAML::Node m = renderOk("--preset multiview --views 3" + kSmall, dir);
    EXPECT_TRUE(fs::exists(dir.path() / "view_2.png"));
    EXPECT_TRUE(m["cameras"]["view_1"]["projection"]);
  }
}

TEST(RenderSceneTool, DressedBackWritesWhichAcupointsAreInView) {
  TempDir dir;
  const YAML::Node m = renderOk(
      "--preset back --varied 3 --arms along --arm-angle 10 --head --hair nape --hair-colour blond"
      " --towel light_blue --towel-weave waffle --towel-edge L4-0.02 --sheet peach --raw --toe-in 2"
      " --sticker C7=green --sticker L4=blue --sticker-size 0.03 --baseline 0.08 --frame-top C7+0.03 --frame-bottom "
      "L4-0.15 --width 320 --height 240 --fx 250 --supersample 1",
      dir);
  EXPECT_EQ(m["dressing"]["arms"].as<std::string>(), "along");
  ASSERT_EQ(m["dressing"]["stickers"].size(), 2u);
  EXPECT_EQ(m["dressing"]["stickers"][1].as<std::string>(), "L4=blue");
  EXPECT_DOUBLE_EQ(m["dressing"]["sticker_diameter"].as<double>(), 0.03);
  EXPECT_EQ(m["subject"]["varied"].as<int>(), 3);
  EXPECT_FALSE(m["rectified"].as<bool>());
  const YAML::Node truth = YAML::LoadFile((dir.path() / "acupoints_truth.yaml").string());
  ASSERT_TRUE(truth["acupoints"]["BL26_L"]);
  EXPECT_FALSE(truth["acupoints"]["BL26_L"]["in_view"].as<bool>());  // L5: under the towel
  EXPECT_EQ(truth["acupoints"]["BL26_L"]["reason"].as<std::string>(), "under the towel");
  EXPECT_TRUE(truth["acupoints"]["BL15_L"]["in_view"].as<bool>());
  EXPECT_EQ(truth["acupoints"]["BL15_L"]["label"].as<std::string>(), "back");
  EXPECT_EQ(truth["acupoints"]["BL15_L"]["right_pixel"].size(), 2u);
  EXPECT_TRUE(truth["landmarks"]["C7"]);
  EXPECT_GT(m["acupoints_in_view"].as<int>(), 50);
  const cv::Mat labels = cv::imread((dir.path() / "left_labels.png").string(), cv::IMREAD_UNCHANGED);
  for (int label : {1, 2, 4, 5, 8}) EXPECT_GT(cv::countNonZero(labels == label), 0) << label;
}

TEST(RenderSceneTool, BodyBuildsAndSkinTypes) {
  TempDir dir;
  const YAML::Node m = renderOk("--preset back --build female --bmi 34 --stature 1.62 --skin-type 5" + kSmall, dir);
  EXPECT_EQ(m["subject"]["build"].as<std::string>(), "female");
  EXPECT_EQ(m["subject"]["skin_type"].as<int>(), 5);
  EXPECT_NEAR(m["subject"]["skin_albedo"][0].as<double>(), 0.30, 1e-6);
  EXPECT_TRUE(fs::exists(dir.path() / "acupoints_truth.yaml"));
}

TEST(RenderSceneTool, BadInputFailsWithAMessage) {
  TempDir dir;
  const std::string out = " --out " + dir.str();
  expectFailure("--preset bogus" + out, 2, "unknown preset 'bogus'");
  expectFailure("--preset back --subject 29" + out, 2, "unknown subject 29");
  expectFailure("--preset back --width 0" + out, 2, "--width / --height must be in 1..16384");
  expectFailure("--preset back --light sideways" + out, 2, "--light must be");
  expectFailure("--preset back --frames x" + out, 2, "--frames: expected an integer");
  expectFailure("--preset back" + kSmall + " --shift 2.0" + out, 1, "the back is not in view");
  expectFailure("--preset back" + kSmall + " --out /proc/massage_cell/forbidden", 1, "cannot create output folder");
  expectFailure("--preset back", 2, "--out: an output folder is required");
  expectFailure("--preset back --arms sideways" + out, 2, "unknown arm pose 'sideways'");
  expectFailure("--preset back --toe-in 3" + out, 2, "--toe-in needs --raw");
  expectFailure("--preset back --towel white --towel-edge C7+0.3" + out, 2, "towel_edge_x");
  expectFailure("--preset back --towel white --towel-edge X9" + out, 2, "unknown vertebral level 'X9'");
  expectFailure("--preset back --frame-top C7" + out, 2, "--frame-top and --frame-bottom go together");
  expectFailure("--preset back --subject 3 --varied 2" + out, 2, "exclusive");
  expectFailure("--preset back --skin-type 7" + out, 2, "--skin-type must be in 1..6");
  expectFailure("--preset back --arm-angle 30" + out, 2, "--arm-angle must be in 0..20");
  expectFailure("--preset boxes --head" + out, 2, "for the back preset");
  expectFailure("--preset back --sticker C7" + out, 2, "--sticker expects LANDMARK=COLOUR");
  expectFailure("--preset back --sticker C7=teal" + out, 2, "unknown sticker colour 'teal'");
  expectFailure("--preset back --sticker Q9=green" + out, 2, "'Q9', which is not a landmark");
  expectFailure("--preset back --sticker C7=green --sticker-size 0.5" + out, 2, "diameter");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
