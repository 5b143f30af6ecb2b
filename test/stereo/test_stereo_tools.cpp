// The stereo command-line tools: outputs, CSV formats, and bad input ending
// with a clear message and a non-zero exit status.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../../src/tools/package_paths.h"
#include "../ros/test_util.h"
#include "massage_cell/stereo/middlebury.h"
#include "massage_cell/stereo/pipeline.h"

namespace {

using massage_cell::test::runCommand;
using massage_cell::test::TempDir;
namespace fs = std::filesystem;

const std::string kMatch = STEREO_MATCH_TOOL;
const std::string kEval = STEREO_EVAL_TOOL;
const std::string kBench = STEREO_BENCH_TOOL;

/// The shared data sets, as the tools find them: $MASSAGE_CELL_DATA, else ../shared/data beside the package.
std::string sharedData() {
  const char* env = std::getenv("MASSAGE_CELL_DATA");
  return env != nullptr ? std::string(env) : std::string(MASSAGE_CELL_SOURCE_DIR) + "/../shared/data";
}

/// A random-texture pair whose right view is the left shifted by `d`.
void writePair(const TempDir& dir, int d, cv::Size size = {96, 64}) {
  cv::Mat texture(size.height, size.width + d, CV_8UC3);
  cv::RNG rng(3);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 255);
  // left(x) = texture(x) and right(x) = texture(x + d): left x matches right x - d.
  cv::imwrite((dir.path() / "left.png").string(), texture(cv::Rect(0, 0, size.width, size.height)));
  cv::imwrite((dir.path() / "right.png").string(), texture(cv::Rect(d, 0, size.width, size.height)));
}

void expectFailure(const std::string& command, int code, const std::string& message) {
  const auto r = runCommand(command, 60);
  EXPECT_EQ(r.exit_code, code) << command << "\n" << r.output;
  EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n" << r.output;
}

TEST(StereoMatch, WritesPfmAndPngWithTheRightDisparity) {
  TempDir dir;
  writePair(dir, 6);
  const std::string images = " " + (dir.path() / "left.png").string() + " " + (dir.path() / "right.png").string();
  for (const std::string method : {"wta", "hbds", "sgbm"}) {
    const std::string out = (dir.path() / method).string();
    // Winner-takes-all unrefined: with AD-census its left band (no match there) holds the range's lowest levels,
    // and FFD + MDC carry them 50 px into this pure-noise texture (a known weakness, not what this test is about).
    const std::string refine = method == "wta" ? " --refine none" : "";
    const auto r = runCommand(kMatch + images + " --method " + method + refine + " --dmin 0 --dmax 15 -o " + out, 120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    ASSERT_TRUE(fs::exists(out + ".png")) << method;
    const cv::Mat d = cv::imread(out + ".pfm", cv::IMREAD_UNCHANGED);
    ASSERT_EQ(d.type(), CV_32F) << method;
    // Away from the left border (no match there) the shift is found.
    EXPECT_NEAR(d.at<float>(32, 60), 6.0f, 0.5f) << method;
  }
}

TEST(StereoMatch, HelpPrintsEveryOptionWithTheLibrarysDefault) {
  const auto r = runCommand(kMatch + " --help", 30);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // The help is long: every block printed whole, to the last option (a fixed-size format buffer cut it off).
  for (const char* line :
       {"--cost C", "(default ad-census)", "--overlap M", "default 1)", "(default ffd-mdc)", "--subpixel F",
        "--no-lr-check", "--lr-tolerance T", "--threads N        worker threads, 0 = all cores (default 0)"}) {
    EXPECT_NE(r.output.find(line), std::string::npos) << line << " missing in:\n" << r.output;
  }
  EXPECT_NE(r.output.find("(default on)"), std::string::npos) << "the left-right check's default";
}

TEST(StereoMatch, BadInputFailsWithAMessage) {
  TempDir dir;
  writePair(dir, 4);
  const std::string l = (dir.path() / "left.png").string(), r = (dir.path() / "right.png").string();
  cv::imwrite((dir.path() / "small.png").string(), cv::Mat(32, 48, CV_8UC3, cv::Scalar(1, 2, 3)));
  cv::imwrite((dir.path() / "deep.png").string(), cv::Mat(64, 96, CV_16UC1, cv::Scalar(1000)));
  std::ofstream(dir.path() / "empty.png").close();
  const std::string out = " -o " + (dir.path() / "out").string();
  expectFailure(kMatch + " " + l + " " + (dir.path() / "small.png").string() + " --dmax 8" + out, 1, "size");
  expectFailure(kMatch + " " + l + " " + (dir.path() / "empty.png").string() + " --dmax 8" + out, 1,
                "cannot read image");
  expectFailure(kMatch + " " + l + " " + r + " --dmin 5 --dmax 5" + out, 2, "--dmax must be greater than --dmin");
  expectFailure(kMatch + " " + l + " " + r + " --dmax 200" + out, 1, "wider than the image");
  expectFailure(
      kMatch + " " + (dir.path() / "deep.png").string() + " " + (dir.path() / "deep.png").string() + " --dmax 8" + out,
      1, "type");
  expectFailure(kMatch + " " + l + " /nonexistent/right.png --dmax 8" + out, 1,
                "missing image '/nonexistent/right.png'");
  expectFailure(kMatch + " " + l + " " + r + " --dmax 8 --method magic" + out, 2, "unknown method 'magic'");
  expectFailure(kMatch + " " + l + " " + r + " --dmax 8", 2, "-o OUT is required");
}

// OpenCV 4.6's 3-way SGBM terminates the process (an assertion in a
// destructor) when no column can be matched (found by fuzz_stereo_match).
TEST(Match, SgbmWithNoColumnToMatchIsAllInvalid) {
  namespace ms = massage_cell::stereo;
  ms::StereoParams p;
  p.cost.dmin = 3;
  p.cost.dmax = 8;
  cv::Mat left(16, 11, CV_8UC3), right(16, 11, CV_8UC3);
  cv::randu(left, 0, 256);
  cv::randu(right, 0, 256);
  const ms::MatchResult narrow = ms::match(left, right, ms::Method::kSgbm, p);
  ASSERT_EQ(narrow.disparity.size(), left.size());
  EXPECT_EQ(cv::countNonZero(narrow.disparity == narrow.disparity), 0) << "a pixel got a disparity";
  // The guard does not refuse a pair with matchable columns: blocky texture
  // shifted by 5 px (left(x) = right(x - 5)) is matched at 5 there.
  cv::Mat blocks(8, 20, CV_8UC3), wide;
  cv::randu(blocks, 0, 256);
  cv::resize(blocks, wide, cv::Size(), 4, 4, cv::INTER_NEAREST);
  const ms::MatchResult ok =
      ms::match(wide(cv::Rect(0, 0, 64, 32)), wide(cv::Rect(5, 0, 64, 32)), ms::Method::kSgbm, p);
  const cv::Mat matchable = ok.disparity(cv::Rect(24, 4, 36, 24));
  EXPECT_GT(cv::countNonZero(cv::abs(matchable - 5.0f) <= 1.0f), matchable.total() / 2);
}

TEST(StereoEval, MissingDataFailsWithAMessage) {
  expectFailure(kEval + " --data /nonexistent/middlebury --scenes teddy --methods wta", 1,
                "missing Middlebury scene folder '/nonexistent/middlebury/teddy'");
  expectFailure(kEval + " --methods magic", 2, "unknown method 'magic'");
  expectFailure(kBench + " --plot /tmp/x.png", 2, "--plot needs --sweep");
}

TEST(StereoBench, CellFramesPrintTimesAndAccuracy) {
  // The table holds both scenes for each method with bad-pixel percentages
  // against the simulator's exact GT; HBDS (polished or not) must beat the
  // winner-takes-all map it starts from by a wide margin at 1 px.
  const auto r = runCommand(kBench +
                                " --scenes '' --frame --frame-size 320x240 --frame-levels 32 --repeat 1"
                                " --frame-methods hbds,wta --polish 1",
                            180);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Cell scenes (simulator) at 320x240, 32 levels"), std::string::npos) << r.output;
  auto badOf = [&](const std::string& row) {
    const auto at = r.output.find(row);
    if (at == std::string::npos) {
      ADD_FAILURE() << row << " missing in:\n" << r.output;
      return -1.0;
    }
    const std::string line = r.output.substr(at, r.output.find('\n', at) - at);
    const auto pct = line.find('%');  // the first percentage: bad > 1 px
    return pct == std::string::npos ? -1.0 : std::stod(line.substr(line.rfind(' ', pct) + 1));
  };
  for (const char* scene : {"back/320x240          ", "boxes/320x240         "}) {
    const double hbds = badOf(std::string(scene) + " hbds"), wta = badOf(std::string(scene) + " wta");
    EXPECT_GE(hbds, 0.0) << scene;
    EXPECT_LT(hbds, 20.0) << scene;
    EXPECT_LT(hbds, 0.5 * wta) << scene;
  }
  // At half resolution (the node's downsample 2) the disparity is judged in full-resolution pixels: brought back to
  // the full size and doubled, it stays close to the truth (halved, nearly every pixel would be bad by > 1 px).
  const auto half = runCommand(kBench +
                                   " --scenes '' --frame --frame-size 320x240 --frame-levels 32 --repeat 1"
                                   " --frame-methods hbds --frame-downsample 2 --refine none --no-lr-check",
                               180);
  ASSERT_EQ(half.exit_code, 0) << half.output;
  for (const char* scene : {"back/320x240          ", "boxes/320x240         "}) {
    const auto at = half.output.find(std::string(scene) + " hbds/2");
    ASSERT_NE(at, std::string::npos) << half.output;
    const std::string line = half.output.substr(at, half.output.find('\n', at) - at);
    const auto pct = line.find('%');
    ASSERT_NE(pct, std::string::npos) << line;
    EXPECT_LT(std::stod(line.substr(line.rfind(' ', pct) + 1)), 50.0) << line;
  }
  expectFailure(kBench + " --frame --frame-downsample 3", 2, "--frame-downsample factors must be 1, 2 or 4");
  expectFailure(kBench + " --frame --frame-levels 1", 2, "--frame-levels must be >= 2");
  expectFailure(kBench + " --frame --frame-size 20x10", 2, "--frame-size must be between");
  expectFailure(kBench + " --frame --repeat 0", 2, "--repeat must be in 1..100");
  expectFailure(kMatch + " a.png b.png --dmax 8 --polish -1 -o x", 2, "--polish must be >= 0");
  expectFailure(kMatch + " a.png b.png --dmax 8 --polish 4 --polish-coarse 9 -o x", 2,
                "--polish-coarse must be in 0..8");
}

TEST(StereoEval, CsvOnMiddlebury) {
  const std::string root = massage_cell::tools::middleburyDir(sharedData());
  if (!fs::exists(fs::path(root) / "tsukuba" / "left.png")) {
    GTEST_SKIP() << "Middlebury data not found at " << root << " (set MASSAGE_CELL_MIDDLEBURY)";
  }
  const auto r = runCommand(kEval + " --scenes tsukuba --methods wta --refine none --no-lr-check --csv", 120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::istringstream lines(r.output);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "scene,method,mask,threshold,bad_percent,time_ms");
  int rows = 0;
  while (std::getline(lines, line)) {
    if (line.rfind("tsukuba,wta,", 0) == 0) ++rows;
  }
  EXPECT_EQ(rows, 9) << r.output;
}

TEST(StereoEval, Middlebury2005ScenesAndTheSgbmReference) {
  namespace stereo = massage_cell::stereo;
  const std::string root = massage_cell::tools::middlebury2005Dir(sharedData());
  if (!fs::exists(fs::path(root) / "dolls" / "left.png")) {
    GTEST_SKIP() << "Middlebury 2005 data not found at " << root << " (set MASSAGE_CELL_MIDDLEBURY2005)";
  }
  // The derived masks: nonocc = known GT whose match is inside the right image, disc inside nonocc.
  const stereo::MiddleburyScene dolls = stereo::loadMiddleburyScene(root, "dolls");
  EXPECT_EQ(dolls.dmax, 79);
  long nonocc = 0, outside = 0, disc = 0;
  for (int y = 0; y < dolls.ground_truth.rows; ++y) {
    for (int x = 0; x < dolls.ground_truth.cols; ++x) {
      const float g = dolls.ground_truth.at<float>(y, x);
      if (dolls.nonocc.at<uchar>(y, x)) {
        ++nonocc;
        if (!(g > 0.0f) || x < g) ++outside;
      }
      if (dolls.disc.at<uchar>(y, x)) {
        ++disc;
        if (!dolls.nonocc.at<uchar>(y, x)) ++outside;
      }
    }
  }
  EXPECT_EQ(outside, 0);
  EXPECT_GT(nonocc, dolls.ground_truth.total() * 8 / 10);  // the band x < d is ~10 % of the image
  EXPECT_LT(nonocc, dolls.ground_truth.total() * 95 / 100);
  EXPECT_GT(disc, 0);
  EXPECT_LT(disc, nonocc / 2);
  // stereo_eval on a 2005 scene: SGBM's row, its filled reference and the ratio table.
  const auto r = runCommand(kEval + " --scenes dolls --methods wta,sgbm", 120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dolls    sgbm+fill"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("relative to sgbm+fill"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("dolls    wta+ffd-mdc+lr "), std::string::npos) << r.output;  // the defaults
  expectFailure(kEval + " --scenes lighthouse --methods wta", 1, "unknown Middlebury scene 'lighthouse'");
}

TEST(StereoEval, PicturesOnMiddlebury) {
  const std::string root = massage_cell::tools::middleburyDir(sharedData());
  if (!fs::exists(fs::path(root) / "tsukuba" / "left.png")) {
    GTEST_SKIP() << "Middlebury data not found at " << root << " (set MASSAGE_CELL_MIDDLEBURY)";
  }
  TempDir dir;
  const std::string pics = (dir.path() / "pics").string();
  const auto plain =
      runCommand(kEval + " --scenes tsukuba --methods wta --refine none --no-lr-check --pictures " + pics, 120);
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  const auto refined =
      runCommand(kEval + " --scenes tsukuba --methods wta --refine ffd-mdc --no-lr-check --pictures " + pics, 120);
  ASSERT_EQ(refined.exit_code, 0) << refined.output;
  EXPECT_NE(refined.output.find("wta+ffd-mdc"), std::string::npos) << refined.output;
  const cv::Mat a = cv::imread(pics + "/tsukuba_wta.png"), b = cv::imread(pics + "/tsukuba_wta+ffd-mdc.png");
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  EXPECT_EQ(a.cols, 2 * 384);  // disparity | errors
  EXPECT_EQ(b.cols, 3 * 384);  // ... | fattening mask
  EXPECT_EQ(a.rows, 288);
  // WTA is wrong in many nonocc pixels: the error panel shows red ones.
  cv::Mat red;
  cv::inRange(a(cv::Rect(384, 0, 384, 288)), cv::Scalar(0, 0, 250), cv::Scalar(10, 10, 255), red);
  EXPECT_GT(cv::countNonZero(red), 384 * 288 / 20);
  expectFailure(kEval + " --refine magic", 2, "unknown refinement 'magic'");
  expectFailure(kEval + " --refiners none,magic", 2, "unknown refinement 'magic'");
  expectFailure(kEval + " --refiners wmf --filter-radius 0", 2, "radius must be in 1..64");
  // --refiners: one row per refinement in the thesis's table layout.
  const auto table =
      runCommand(kEval + " --scenes tsukuba --methods wta --refiners none,wmf,ffd-2dbf --no-lr-check", 120);
  ASSERT_EQ(table.exit_code, 0) << table.output;
  for (const char* row : {"\nwta                |", "\nwta+wmf            |", "\nwta+ffd-2dbf       |"}) {
    EXPECT_NE(table.output.find(row), std::string::npos) << row << " in\n" << table.output;
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
