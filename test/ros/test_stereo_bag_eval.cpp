// stereo_bag_eval (src/tools/stereo_bag_eval.cpp), run as a user runs it: its row on the bundled back_session
// (the first pairs), the error it reports following a ground truth moved along the acupoints' rays, and bad input
// ending with a message naming the problem and a non-zero exit status.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>
#include <yaml-cpp/yaml.h>

#include "test_util.h"

namespace {

using massage_cell::test::runCommand;
using massage_cell::test::TempDir;
namespace fs = std::filesystem;

const std::string kTool = STEREO_BAG_EVAL_TOOL;
const std::string kBag = std::string(MASSAGE_CELL_SOURCE_DIR) + "/rosbags/back_session.bag";
const std::string kGroundTruth = std::string(MASSAGE_CELL_SOURCE_DIR) + "/rosbags/back_session.ground_truth.yaml";
constexpr int kTimeout = 120;  // s a run at most (2 pairs: ~2 s)

/// The CSV rows of a run, by recording: column name -> value.
std::map<std::string, std::map<std::string, std::string>> csvRows(const std::string& output) {
  std::map<std::string, std::map<std::string, std::string>> rows;
  std::istringstream in(output);
  std::vector<std::string> header;
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string cell; std::getline(s, cell, ',');) cells.push_back(cell);
    if (header.empty()) {
      if (!cells.empty() && cells[0] == "recording") header = cells;
      continue;
    }
    if (cells.size() != header.size()) continue;  // a message, not a row
    for (std::size_t i = 0; i < cells.size(); ++i) rows[cells[0]][header[i]] = cells[i];
  }
  return rows;
}

double number(const std::map<std::string, std::string>& row, const std::string& column) {
  const auto it = row.find(column);
  if (it == row.end()) return std::nan("");
  return std::stod(it->second);
}

/// The bundled ground truth with every acupoint (or only the one named `only`) moved `shift` metres in depth along
/// its ray (same pixel).
void writeShiftedGroundTruth(const std::string& path, double shift, const std::string& only = "") {
  YAML::Node yaml = YAML::LoadFile(kGroundTruth);
  for (auto frame : yaml["frames"]) {
    for (auto point : frame["acupoints"]) {
      if (!only.empty() && point.first.as<std::string>() != only) continue;
      YAML::Node p = point.second;
      const double z = p[2].as<double>(), k = (z + shift) / z;
      for (int i = 0; i < 3; ++i) p[i] = p[i].as<double>() * k;
    }
  }
  std::ofstream(path) << yaml;
}

void expectFailure(const std::string& args, int code, const std::string& message) {
  const auto r = runCommand(kTool + " " + args, kTimeout);
  EXPECT_EQ(r.exit_code, code) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(message), std::string::npos) << args << ": expected '" << message << "' in:\n" << r.output;
  EXPECT_EQ(r.output.find("Segmentation"), std::string::npos) << r.output;
}

TEST(StereoBagEval, BackSessionRowHasPlausibleNumbers) {
  // The table as printed, with the target's line.
  const auto table = runCommand(kTool + " --recordings back_session --max-pairs 2", kTimeout);
  ASSERT_EQ(table.exit_code, 0) << table.output;
  EXPECT_NE(table.output.find("disparities 16..47 (full resolution)"), std::string::npos) << table.output;
  EXPECT_NE(table.output.find("\nback_session "), std::string::npos) << table.output;
  EXPECT_NE(table.output.find("target (median <= 4 mm and >= 95 % within 10 mm): back_session "), std::string::npos)
      << table.output;

  const auto r = runCommand(kTool + " --recordings back_session --max-pairs 2 --csv", kTimeout);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = csvRows(r.output);
  ASSERT_EQ(rows.count("back_session"), 1u) << r.output;
  const auto& row = rows.at("back_session");
  EXPECT_EQ(number(row, "pairs"), 2) << r.output;
  EXPECT_GE(number(row, "acupoints"), 100) << "108 acupoints a frame in the recording";
  // The back 0.74-0.80 m away, one disparity step 23 mm deep: the default pipeline is within ~1 cm.
  EXPECT_GE(number(row, "median_mm"), 0.0);
  EXPECT_LE(number(row, "median_mm"), 25.0) << r.output;
  EXPECT_LE(number(row, "p90_mm"), 60.0) << r.output;
  EXPECT_GE(number(row, "within_10mm_pct"), 25.0) << r.output;
  EXPECT_EQ(number(row, "no_depth"), 0) << r.output;
  EXPECT_LE(std::abs(number(row, "median_signed_mm")), 25.0) << r.output;
  EXPECT_GT(number(row, "mean_ms_per_pair"), 0.0) << r.output;
  EXPECT_TRUE(row.at("target_met") == "yes" || row.at("target_met") == "no");
}

TEST(StereoBagEval, ErrorFollowsAShiftedGroundTruth) {
  // The same pairs against a ground truth 5 cm farther / nearer along every acupoint's ray: each signed error moves
  // by exactly -5 / +5 cm, and the median |error| is at least ~4 cm whatever the matcher's own bias (+-1 cm).
  const std::string common = " --recordings " + kBag + " --max-pairs 2 --csv";
  const auto base = runCommand(kTool + common, kTimeout);
  ASSERT_EQ(base.exit_code, 0) << base.output;
  const double base_signed = number(csvRows(base.output)["back_session"], "median_signed_mm");
  ASSERT_TRUE(std::isfinite(base_signed)) << base.output;
  TempDir dir("stereo_bag_eval");
  for (const double shift : {0.05, -0.05}) {
    const std::string gt = (dir.path() / ("shifted" + std::to_string(shift) + ".yaml")).string();
    writeShiftedGroundTruth(gt, shift);
    const auto r = runCommand(kTool + common + " --ground-truth " + gt, kTimeout);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto row = csvRows(r.output)["back_session"];
    EXPECT_NEAR(number(row, "median_signed_mm"), base_signed - shift * 1000.0, 0.5) << "shift " << shift << "\n"
                                                                                    << r.output;
    EXPECT_GE(number(row, "median_mm"), shift > 0 ? 30.0 : 40.0) << "shift " << shift << "\n" << r.output;
    EXPECT_LE(number(row, "within_10mm_pct"), 10.0) << "shift " << shift << "\n" << r.output;
    EXPECT_EQ(row.at("target_met"), "no");
  }
}

TEST(StereoBagEval, WorstListNamesTheAcupointOffTheMost) {
  // One acupoint's truth 10 cm nearer: --worst names it first, its signed error ~+10 cm (measured deeper).
  TempDir dir("stereo_bag_eval");
  const std::string gt = (dir.path() / "one_point.yaml").string();
  writeShiftedGroundTruth(gt, -0.10, "BL23_L");
  const auto r =
      runCommand(kTool + " --recordings " + kBag + " --max-pairs 2 --worst 2 --ground-truth " + gt, kTimeout);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string head = "back_session, the 2 acupoints off the most (median |error| / signed, mm): BL23_L ";
  const auto at = r.output.find(head);
  ASSERT_NE(at, std::string::npos) << r.output;
  double magnitude = 0, signed_mm = 0;
  ASSERT_EQ(std::sscanf(r.output.c_str() + at + head.size(), "%lf / %lf", &magnitude, &signed_mm), 2) << r.output;
  EXPECT_NEAR(signed_mm, 100.0, 25.0) << r.output;
  EXPECT_NEAR(magnitude, std::abs(signed_mm), 1e-6) << r.output;
  expectFailure("--worst -1", 2, "--worst must be >= 0");
}

TEST(StereoBagEval, BadInputFailsWithAMessage) {
  TempDir dir("stereo_bag_eval");
  const std::string d = dir.str();

  // Missing files.
  expectFailure("--recordings " + d + "/missing.bag", 1, "missing.bag' not found");
  expectFailure("--recordings no_such_session", 1, "no_such_session.bag' not found");
  fs::create_symlink(kBag, dir.path() / "no_truth.bag");
  expectFailure("--recordings " + d + "/no_truth.bag", 1, "no_truth.ground_truth.yaml' not found");

  // A ground truth without frames, and one with fewer frames than the bag has pairs.
  fs::create_symlink(kBag, dir.path() / "empty_truth.bag");
  std::ofstream(dir.path() / "empty_truth.ground_truth.yaml") << "rate: 10\nframes: []\n";
  expectFailure("--recordings " + d + "/empty_truth.bag", 1, "no frames");
  std::ofstream(dir.path() / "one_frame.yaml") << "rate: 10\nframes:\n  - acupoints:\n      BL23_L: [0, 0, 0.8]\n";
  expectFailure("--recordings " + kBag + " --ground-truth " + d + "/one_frame.yaml --max-pairs 3", 1,
                "has no ground-truth frame");
  std::ofstream(dir.path() / "garbage.yaml") << "rate: [\n";
  expectFailure("--recordings " + kBag + " --ground-truth " + d + "/garbage.yaml", 1, "garbage.yaml");

  // A bag without a single stereo pair (only left images), and a bag that is no bag.
  {
    rosbag::Bag bag((dir.path() / "left_only.bag").string(), rosbag::bagmode::Write);
    sensor_msgs::Image image;
    image.header.stamp = ros::Time(1, 0);
    image.width = image.height = 8;
    image.encoding = "mono8";
    image.step = 8;
    image.data.assign(64, 128);
    bag.write("/stereo/left/image_raw", image.header.stamp, image);
  }
  fs::copy_file(kGroundTruth, dir.path() / "left_only.ground_truth.yaml");
  expectFailure("--recordings " + d + "/left_only.bag", 1, "has no stereo pair on /stereo/left/image_raw");
  expectFailure("--recordings " + kBag + " --stereo-ns /elsewhere", 1, "has no stereo pair on /elsewhere/left");
  std::ofstream(dir.path() / "not_a.bag") << "not a bag\n";
  fs::copy_file(kGroundTruth, dir.path() / "not_a.ground_truth.yaml");
  expectFailure("--recordings " + d + "/not_a.bag", 1, "not_a.bag");

  // Bad options (exit 2) and a range the images cannot hold (the node's own check).
  expectFailure("--downsample 3", 2, "--downsample must be 1, 2 or 4");
  expectFailure("--subpixel cubic", 2, "unknown sub-pixel fit 'cubic'");
  expectFailure("--max-pairs -1", 2, "--max-pairs must be >= 0");
  expectFailure("--method expansion", 2, "--method must be hbds, sgbm or wta");
  expectFailure("--no-such-option", 2, "unknown option '--no-such-option'");
  expectFailure("--recordings back_session,dressed_session --ground-truth " + kGroundTruth, 2,
                "--ground-truth needs exactly one recording");
  expectFailure("--config " + d + "/missing.yaml", 1, "missing.yaml' not found");
  expectFailure("--recordings back_session --max-pairs 1 --min-disparity 300", 1, "is wider than the image");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
