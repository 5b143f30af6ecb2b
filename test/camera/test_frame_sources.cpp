// Unit tests of the ROS-free frame sources (massage_cell/camera/frame_source.h):
// configuration checks, natural file ordering, image-folder, video-file and
// V4L2 sources. Every test builds its own data in a fresh temporary folder.
//
// This file holds the main() of the test_camera executable (catkin links gtest
// without gtest_main); test_calibration.cpp is linked into the same binary.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "massage_cell/camera/frame_source.h"

namespace fs = std::filesystem;
using namespace massage_cell::camera;

namespace {

// ------------------------------------------------------------------ helpers --

/// Runs `fn`, expects a ConfigError and returns its message ("" and a test
/// failure when nothing or something else was thrown).
std::string configErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const ConfigError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected ConfigError, got another exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected ConfigError, nothing was thrown";
  return "";
}

::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

/// True when the two images have the same size, type and pixels.
::testing::AssertionResult sameImage(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) {
    return ::testing::AssertionFailure() << "size/type differ: " << a.cols << "x" << a.rows << " type " << a.type()
                                         << " vs " << b.cols << "x" << b.rows << " type " << b.type();
  }
  if (a.empty()) return ::testing::AssertionSuccess();
  const double diff = cv::norm(a, b, cv::NORM_INF);
  if (diff == 0.0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "pixels differ (max difference " << diff << ")";
}

/// A BGR test pattern that differs per frame index and per view (0 left,
/// 1 right, 2 mono): blue is a gradient shifted by the index, green encodes
/// the index, red encodes the view.
cv::Mat pattern(int index, int view, cv::Size size = {64, 48}) {
  cv::Mat image(size, CV_8UC3);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      image.at<cv::Vec3b>(y, x) =
          cv::Vec3b(static_cast<uchar>((x * 3 + y * 5 + index * 17) % 256), static_cast<uchar>((index * 20 + 10) % 256),
                    static_cast<uchar>(view * 80 + (x + y) % 16));
    }
  }
  return image;
}

/// The flat colour of frame `index`, view `view` in the test videos (MJPEG is
/// lossy, so videos are told apart by their mean colour).
cv::Scalar videoColour(int index, int view) {
  return cv::Scalar(30 + 40 * index, view == 0 ? 60 : 190, 220 - 40 * index);
}

::testing::AssertionResult hasColour(const cv::Mat& image, const cv::Scalar& expected, double tolerance = 12.0) {
  if (image.empty()) return ::testing::AssertionFailure() << "empty image";
  const cv::Scalar mean = cv::mean(image);
  for (int c = 0; c < 3; ++c) {
    if (std::abs(mean[c] - expected[c]) > tolerance) {
      return ::testing::AssertionFailure()
             << "mean colour (" << mean[0] << ", " << mean[1] << ", " << mean[2] << ") is not (" << expected[0] << ", "
             << expected[1] << ", " << expected[2] << ")";
    }
  }
  return ::testing::AssertionSuccess();
}

/// Writes an MJPG .avi with `frames` frames; frame i is made by `make(i)`.
/// Returns "" on success, else why the writer could not be used.
std::string writeVideo(const fs::path& path, int frames, cv::Size size, const std::function<cv::Mat(int)>& make,
                       double fps = 25.0) {
  cv::VideoWriter writer(path.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, size, true);
  if (!writer.isOpened()) {
    return "cv::VideoWriter cannot open '" + path.string() + "' with fourcc MJPG (no MJPEG AVI writer in this OpenCV)";
  }
  for (int i = 0; i < frames; ++i) writer.write(make(i));
  writer.release();
  return "";
}

/// Fills a flat-coloured frame of a test video.
cv::Mat flatFrame(cv::Size size, const cv::Scalar& colour) { return cv::Mat(size, CV_8UC3, colour); }

/// A side-by-side frame: left half coloured as view 0, right half as view 1.
cv::Mat sideBySideVideoFrame(int index, cv::Size view_size) {
  cv::Mat frame(view_size.height, view_size.width * 2, CV_8UC3);
  frame(cv::Rect(0, 0, view_size.width, view_size.height)).setTo(videoColour(index, 0));
  frame(cv::Rect(view_size.width, 0, view_size.width, view_size.height)).setTo(videoColour(index, 1));
  return frame;
}

// ------------------------------------------------------------------ fixture --

/// A fresh, empty temporary folder per test, removed afterwards.
class TempFolderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("massage_cell_test_frame_sources_" + std::to_string(::getpid()) + "_" +
                                        std::to_string(counter++) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    ASSERT_TRUE(fs::create_directories(dir_)) << dir_;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  void writeImage(const std::string& name, const cv::Mat& image) const {
    ASSERT_TRUE(cv::imwrite(path(name), image)) << "cannot write " << path(name);
  }

  void writeText(const std::string& name, const std::string& text) const {
    std::ofstream file(path(name), std::ios::binary);
    file << text;
    ASSERT_TRUE(file.good()) << "cannot write " << path(name);
  }

  /// left_0000.png ... / right_0000.png ... with the test patterns.
  void writePairs(int count, cv::Size size = {64, 48}) const {
    for (int i = 0; i < count; ++i) {
      writeImage(numbered("left_", i), pattern(i, 0, size));
      writeImage(numbered("right_", i), pattern(i, 1, size));
    }
  }

  static std::string numbered(const std::string& prefix, int i, const std::string& ext = ".png") {
    char digits[16];
    std::snprintf(digits, sizeof digits, "%04d", i);
    return prefix + digits + ext;
  }

  SourceConfig folderConfig(Layout layout = Layout::kPair) const {
    SourceConfig c;
    c.type = SourceType::kFolder;
    c.layout = layout;
    c.folder = dir_.string();
    if (layout == Layout::kPair) {
      c.patterns = {"left_*.png", "right_*.png"};
    } else {
      c.patterns = {"*.png"};
    }
    return c;
  }

  fs::path dir_;
};

using FolderSourceTest = TempFolderTest;
using FolderErrorTest = TempFolderTest;
using ListMatchingTest = TempFolderTest;
using VideoSourceTest = TempFolderTest;

// ----------------------------------------------------------------- validate --

SourceConfig validV4l2(Layout layout) {
  SourceConfig c;
  c.type = SourceType::kV4l2;
  c.layout = layout;
  c.locations = layout == Layout::kPair ? std::vector<std::string>{"/dev/video0", "/dev/video1"}
                                        : std::vector<std::string>{"/dev/video0"};
  c.width = 640;
  c.height = 480;
  c.fps = 30.0;
  c.pixel_format = "MJPG";
  c.buffer_size = 1;
  return c;
}

SourceConfig validFolder(Layout layout) {
  SourceConfig c;
  c.type = SourceType::kFolder;
  c.layout = layout;
  c.folder = "/tmp/images";
  c.patterns = layout == Layout::kPair ? std::vector<std::string>{"left*", "right*"} : std::vector<std::string>{"*"};
  return c;
}

/// validate(config) throws a ConfigError whose message contains `part`.
void expectInvalid(const SourceConfig& config, const std::string& part) {
  const std::string message = configErrorOf([&] { validate(config); });
  EXPECT_TRUE(contains(message, part));
}

TEST(ValidateTest, ValidConfigurationsPass) {
  for (Layout layout : {Layout::kMono, Layout::kPair, Layout::kSideBySide}) {
    EXPECT_NO_THROW(validate(validV4l2(layout))) << toString(layout);
    EXPECT_NO_THROW(validate(validFolder(layout))) << toString(layout);
    SourceConfig video = validV4l2(layout);
    video.type = SourceType::kVideo;
    EXPECT_NO_THROW(validate(video)) << toString(layout);
  }
  SourceConfig defaults = validV4l2(Layout::kPair);
  defaults.width = defaults.height = 0;
  defaults.fps = 0.0;
  defaults.pixel_format.clear();
  defaults.buffer_size = 32;
  EXPECT_NO_THROW(validate(defaults));
}

TEST(ValidateTest, NegativeSizesAndRates) {
  SourceConfig c = validV4l2(Layout::kPair);
  c.width = -1;
  expectInvalid(c, "width");
  c = validV4l2(Layout::kPair);
  c.height = -480;
  expectInvalid(c, "height");
  c = validV4l2(Layout::kPair);
  c.fps = -5.0;
  expectInvalid(c, "fps");
  c = validV4l2(Layout::kPair);
  c.fps = std::nan("");
  expectInvalid(c, "fps");
  c = validFolder(Layout::kPair);
  c.rate = -1.0;
  expectInvalid(c, "rate");
  c = validFolder(Layout::kPair);
  c.rate = 5000.0;
  expectInvalid(c, "rate");
}

TEST(ValidateTest, BufferSizeOutOfRange) {
  SourceConfig c = validV4l2(Layout::kMono);
  c.buffer_size = 0;
  expectInvalid(c, "buffer");
  c.buffer_size = 33;
  expectInvalid(c, "buffer");
  c.buffer_size = -3;
  expectInvalid(c, "buffer");
}

TEST(ValidateTest, PixelFormatMustHaveFourCharacters) {
  SourceConfig c = validV4l2(Layout::kMono);
  c.pixel_format = "MJP";
  expectInvalid(c, "pixel_format");
  c.pixel_format = "YUYV2";
  expectInvalid(c, "pixel_format");
}

TEST(ValidateTest, SideBySideWidthMustBeEven) {
  SourceConfig c = validV4l2(Layout::kSideBySide);
  c.width = 1281;
  expectInvalid(c, "width");
  c.width = 1280;
  EXPECT_NO_THROW(validate(c));
  // An odd width is fine for a single camera.
  c = validV4l2(Layout::kMono);
  c.width = 641;
  EXPECT_NO_THROW(validate(c));
}

TEST(ValidateTest, WrongNumberOfLocations) {
  SourceConfig c = validV4l2(Layout::kPair);
  c.locations = {"/dev/video0"};
  expectInvalid(c, "pair");
  c = validV4l2(Layout::kMono);
  c.locations = {"/dev/video0", "/dev/video1"};
  expectInvalid(c, "mono");
  c = validV4l2(Layout::kSideBySide);
  c.locations = {"/dev/video0", "/dev/video1"};
  expectInvalid(c, "side_by_side");
  c = validV4l2(Layout::kMono);
  c.locations.clear();
  expectInvalid(c, "device");
  c = validV4l2(Layout::kPair);
  c.type = SourceType::kVideo;
  c.locations = {"left.avi", "right.avi", "third.avi"};
  expectInvalid(c, "video file");
  c = validV4l2(Layout::kPair);
  c.locations = {"/dev/video0", ""};
  expectInvalid(c, "empty device");
}

TEST(ValidateTest, FolderNameAndPatterns) {
  SourceConfig c = validFolder(Layout::kPair);
  c.folder.clear();
  expectInvalid(c, "folder");
  c = validFolder(Layout::kPair);
  c.patterns = {"left*"};
  expectInvalid(c, "pattern");
  c = validFolder(Layout::kMono);
  c.patterns = {"left*", "right*"};
  expectInvalid(c, "pattern");
  c = validFolder(Layout::kSideBySide);
  c.patterns = {"left*", "right*"};
  expectInvalid(c, "pattern");
  c = validFolder(Layout::kMono);
  c.patterns.clear();
  expectInvalid(c, "pattern");
  c = validFolder(Layout::kPair);
  c.patterns = {"left*", ""};
  expectInvalid(c, "pattern");
}

TEST(ValidateTest, OpenSourceValidatesFirst) {
  SourceConfig c = validFolder(Layout::kPair);
  c.buffer_size = 0;
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), "buffer"));
}

TEST(ParseTest, KnownAndUnknownNames) {
  EXPECT_EQ(parseSourceType("v4l2"), SourceType::kV4l2);
  EXPECT_EQ(parseSourceType("folder"), SourceType::kFolder);
  EXPECT_EQ(parseSourceType("video"), SourceType::kVideo);
  EXPECT_EQ(parseLayout("mono"), Layout::kMono);
  EXPECT_EQ(parseLayout("pair"), Layout::kPair);
  EXPECT_EQ(parseLayout("side_by_side"), Layout::kSideBySide);
  for (SourceType t : {SourceType::kV4l2, SourceType::kFolder, SourceType::kVideo}) {
    EXPECT_EQ(parseSourceType(toString(t)), t);
  }
  for (Layout l : {Layout::kMono, Layout::kPair, Layout::kSideBySide}) EXPECT_EQ(parseLayout(toString(l)), l);

  EXPECT_TRUE(contains(configErrorOf([] { parseSourceType("usb"); }), "usb"));
  EXPECT_TRUE(contains(configErrorOf([] { parseSourceType("V4L2"); }), "V4L2"));
  EXPECT_TRUE(contains(configErrorOf([] { parseSourceType(""); }), "source"));
  EXPECT_TRUE(contains(configErrorOf([] { parseLayout("stereo"); }), "stereo"));
  EXPECT_TRUE(contains(configErrorOf([] { parseLayout("side-by-side"); }), "side-by-side"));
}

// ------------------------------------------------------------- natural order --

TEST(NaturalLessTest, NumbersCompareByValue) {
  EXPECT_TRUE(naturalLess("left_2.png", "left_10.png"));
  EXPECT_FALSE(naturalLess("left_10.png", "left_2.png"));
  EXPECT_TRUE(naturalLess("left_9.png", "left_10.png"));
  EXPECT_TRUE(naturalLess("frame1_part2", "frame1_part10"));
  EXPECT_TRUE(naturalLess("a99999999999999999999b", "a100000000000000000000b"));  // beyond 64 bits
  EXPECT_TRUE(naturalLess("left_10.png", "right_1.png"));
  EXPECT_TRUE(naturalLess("left", "left_1"));
  EXPECT_FALSE(naturalLess("left_1", "left"));
}

TEST(NaturalLessTest, LeadingZeros) {
  EXPECT_TRUE(naturalLess("left_0002.png", "left_0010.png"));
  EXPECT_TRUE(naturalLess("left_0002.png", "left_10.png"));
  EXPECT_TRUE(naturalLess("left_9.png", "left_010.png"));
  EXPECT_FALSE(naturalLess("left_010.png", "left_9.png"));
  // Same value: a strict order all the same (fewer leading zeros first), never both ways.
  EXPECT_NE(naturalLess("left_2.png", "left_02.png"), naturalLess("left_02.png", "left_2.png"));
}

TEST(NaturalLessTest, IsIrreflexiveAndSortsNaturally) {
  EXPECT_FALSE(naturalLess("left_10.png", "left_10.png"));
  EXPECT_FALSE(naturalLess("", ""));
  EXPECT_TRUE(naturalLess("", "a"));
  std::vector<std::string> names = {"img_10.png", "img_1.png", "img_002.png", "img_20.png", "img_3.png", "img_0.png"};
  std::sort(names.begin(), names.end(), naturalLess);
  EXPECT_EQ(names, (std::vector<std::string>{"img_0.png", "img_1.png", "img_002.png", "img_3.png", "img_10.png",
                                             "img_20.png"}));
}

TEST_F(ListMatchingTest, FiltersByGlobAndSortsNaturally) {
  for (const char* name : {"left_10.png", "left_2.png", "left_1.png", "right_2.png", "right_1.png", "right_10.png",
                           "notes.txt", "left_3.jpg", ".left_4.png"}) {
    writeText(name, "x");
  }
  fs::create_directory(dir_ / "left_99.png");  // a folder is no image file

  EXPECT_EQ(listMatching(dir_.string(), "left*.png"),
            (std::vector<std::string>{"left_1.png", "left_2.png", "left_10.png"}));
  EXPECT_EQ(listMatching(dir_.string(), "right*"),
            (std::vector<std::string>{"right_1.png", "right_2.png", "right_10.png"}));
  EXPECT_EQ(listMatching(dir_.string(), "left*"),
            (std::vector<std::string>{"left_1.png", "left_2.png", "left_3.jpg", "left_10.png"}));
  EXPECT_EQ(listMatching(dir_.string(), "*.txt"), (std::vector<std::string>{"notes.txt"}));
  EXPECT_TRUE(listMatching(dir_.string(), "center*").empty());
  // Hidden files (".left_4.png", "._left_1.png" resource forks, ...) never match a leading '*'.
  EXPECT_EQ(listMatching(dir_.string(), "*.png"),
            (std::vector<std::string>{"left_1.png", "left_2.png", "left_10.png", "right_1.png", "right_2.png",
                                      "right_10.png"}));
}

// -------------------------------------------------------- side-by-side split --

TEST(SplitSideBySideTest, SplitsIntoHalves) {
  cv::Mat frame(6, 8, CV_8UC1);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 8; ++x) frame.at<uchar>(y, x) = static_cast<uchar>(y * 8 + x);
  const auto halves = splitSideBySide(frame);
  ASSERT_EQ(halves.size(), 2u);
  EXPECT_TRUE(sameImage(halves[0], frame(cv::Rect(0, 0, 4, 6))));
  EXPECT_TRUE(sameImage(halves[1], frame(cv::Rect(4, 0, 4, 6))));
  EXPECT_EQ(halves[1].at<uchar>(0, 0), 4);
  EXPECT_EQ(halves[0].data, frame.data);  // views share the frame's memory
}

TEST(SplitSideBySideTest, OddWidthThrows) {
  const cv::Mat frame(4, 7, CV_8UC3, cv::Scalar::all(0));
  EXPECT_TRUE(contains(configErrorOf([&] { splitSideBySide(frame); }), "7"));
  EXPECT_THROW(splitSideBySide(cv::Mat(4, 1, CV_8UC1)), ConfigError);
}

// -------------------------------------------------------------- folder source --

TEST_F(FolderSourceTest, PairInNaturalOrder) {
  // No zero padding: lexical order would be 1, 10, 11, 12, 2, ...
  const int count = 12;
  for (int i = 1; i <= count; ++i) {
    writeImage("left_" + std::to_string(i) + ".png", pattern(i, 0));
    writeImage("right_" + std::to_string(i) + ".png", pattern(i, 1));
  }
  writeText("notes.txt", "not an image");
  const auto source = openSource(folderConfig());
  EXPECT_EQ(source->views(), 2);
  EXPECT_EQ(source->frameCount(), count);
  EXPECT_EQ(source->viewSize(), cv::Size(64, 48));
  EXPECT_FALSE(source->isLive());
  EXPECT_DOUBLE_EQ(source->nominalRate(), 10.0);
  EXPECT_TRUE(source->warnings().empty());
  EXPECT_TRUE(contains(source->describe(), dir_.string()));

  for (int i = 1; i <= count; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    const ReadResult r = source->read(frame);
    ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
    EXPECT_EQ(frame.index, i - 1);
    EXPECT_TRUE(contains(frame.name, "left_" + std::to_string(i) + ".png"));
    ASSERT_EQ(frame.views.size(), 2u);
    EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 0)));
    EXPECT_TRUE(sameImage(frame.views[1], pattern(i, 1)));
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);  // stays at the end
}

TEST_F(FolderSourceTest, RateFromConfig) {
  writePairs(2);
  SourceConfig c = folderConfig();
  c.rate = 25.0;
  EXPECT_DOUBLE_EQ(openSource(c)->nominalRate(), 25.0);
  c.rate = 0.5;
  EXPECT_DOUBLE_EQ(openSource(c)->nominalRate(), 0.5);
}

TEST_F(FolderSourceTest, LoopWrapsToFirstFrame) {
  writePairs(3);
  SourceConfig c = folderConfig();
  c.loop = true;
  const auto source = openSource(c);
  EXPECT_EQ(source->frameCount(), 3);
  for (int n = 0; n < 8; ++n) {
    const int i = n % 3;
    SCOPED_TRACE("read " + std::to_string(n));
    Frame frame;
    const ReadResult r = source->read(frame);
    ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
    EXPECT_EQ(frame.index, i);
    ASSERT_EQ(frame.views.size(), 2u);
    EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 0)));
    EXPECT_TRUE(sameImage(frame.views[1], pattern(i, 1)));
  }
}

TEST_F(FolderSourceTest, SideBySideSplitsHalves) {
  const cv::Size view(40, 30);
  for (int i = 0; i < 3; ++i) {
    cv::Mat both;
    cv::hconcat(pattern(i, 0, view), pattern(i, 1, view), both);
    writeImage(numbered("sbs_", i), both);
  }
  SourceConfig c = folderConfig(Layout::kSideBySide);
  c.patterns = {"sbs_*.png"};
  const auto source = openSource(c);
  EXPECT_EQ(source->views(), 2);
  EXPECT_EQ(source->viewSize(), view);
  EXPECT_EQ(source->frameCount(), 3);
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
    ASSERT_EQ(frame.views.size(), 2u);
    EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 0, view)));
    EXPECT_TRUE(sameImage(frame.views[1], pattern(i, 1, view)));
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
}

TEST_F(FolderSourceTest, SideBySideOddWidthIsConfigError) {
  writeImage("sbs_0.png", pattern(0, 0, {41, 30}));
  SourceConfig c = folderConfig(Layout::kSideBySide);
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), "odd width"));
}

TEST_F(FolderSourceTest, MonoGivesOneView) {
  for (int i = 0; i < 4; ++i) writeImage(numbered("cam_", i), pattern(i, 2));
  writeImage("other.png", pattern(9, 2));  // not matched by the pattern
  SourceConfig c = folderConfig(Layout::kMono);
  c.patterns = {"cam_*.png"};
  const auto source = openSource(c);
  EXPECT_EQ(source->views(), 1);
  EXPECT_EQ(source->frameCount(), 4);
  for (int i = 0; i < 4; ++i) {
    Frame frame;
    ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
    ASSERT_EQ(frame.views.size(), 1u);
    EXPECT_EQ(frame.index, i);
    EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 2))) << "frame " << i;
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
}

TEST_F(FolderSourceTest, SixteenBitPngStaysMono16) {
  std::vector<cv::Mat> images;
  for (int i = 0; i < 2; ++i) {
    cv::Mat image(24, 32, CV_16UC1);
    for (int y = 0; y < image.rows; ++y)
      for (int x = 0; x < image.cols; ++x)
        image.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(1000 * (i + 1) + 997 * x + 31 * y);
    images.push_back(image);
    writeImage(numbered("depth_", i), image);
  }
  SourceConfig c = folderConfig(Layout::kMono);
  const auto source = openSource(c);
  for (int i = 0; i < 2; ++i) {
    Frame frame;
    ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
    ASSERT_EQ(frame.views.size(), 1u);
    EXPECT_EQ(frame.views[0].type(), CV_16UC1);
    EXPECT_TRUE(sameImage(frame.views[0], images[i])) << "frame " << i;
  }
}

TEST_F(FolderSourceTest, FourChannelPngBecomesBgr) {
  cv::Mat bgra(24, 32, CV_8UC4);
  for (int y = 0; y < bgra.rows; ++y)
    for (int x = 0; x < bgra.cols; ++x)
      bgra.at<cv::Vec4b>(y, x) =
          cv::Vec4b(static_cast<uchar>(x * 7), static_cast<uchar>(y * 9), 77, static_cast<uchar>(x * 8 % 256));
  writeImage("rgba_0.png", bgra);
  cv::Mat expected;
  cv::cvtColor(bgra, expected, cv::COLOR_BGRA2BGR);
  const auto source = openSource(folderConfig(Layout::kMono));
  Frame frame;
  ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
  ASSERT_EQ(frame.views.size(), 1u);
  EXPECT_EQ(frame.views[0].type(), CV_8UC3);
  EXPECT_TRUE(sameImage(frame.views[0], expected));
}

TEST_F(FolderSourceTest, CorruptImageIsBadFrameAndReadingContinues) {
  writePairs(6);
  writeText(numbered("left_", 3), "\x89PNG garbage, not an image at all");
  const auto source = openSource(folderConfig());
  EXPECT_EQ(source->frameCount(), 6);
  for (int i = 0; i < 6; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    const ReadResult r = source->read(frame);
    EXPECT_EQ(frame.index, i);
    if (i == 3) {
      EXPECT_EQ(r.status, ReadStatus::kBadFrame);
      EXPECT_TRUE(contains(r.message, "left_0003.png"));
      EXPECT_TRUE(frame.views.empty());
    } else {
      ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
      ASSERT_EQ(frame.views.size(), 2u);
      EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 0)));
      EXPECT_TRUE(sameImage(frame.views[1], pattern(i, 1)));
    }
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
}

TEST_F(FolderSourceTest, CorruptFirstImageStillOpens) {
  writePairs(3);
  writeText(numbered("right_", 0), "");
  const auto source = openSource(folderConfig());
  EXPECT_EQ(source->viewSize(), cv::Size(64, 48));
  EXPECT_FALSE(source->warnings().empty());
  Frame frame;
  const ReadResult r = source->read(frame);
  EXPECT_EQ(r.status, ReadStatus::kBadFrame);
  EXPECT_TRUE(contains(r.message, "right_0000.png"));
  ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
  EXPECT_EQ(frame.index, 1);
  EXPECT_TRUE(sameImage(frame.views[1], pattern(1, 1)));
}

TEST_F(FolderSourceTest, SizeChangeIsBadFrame) {
  writePairs(4);
  writeImage(numbered("left_", 2), pattern(2, 0, {80, 60}));
  writeImage(numbered("right_", 2), pattern(2, 1, {80, 60}));
  const auto source = openSource(folderConfig());
  EXPECT_EQ(source->viewSize(), cv::Size(64, 48));
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    const ReadResult r = source->read(frame);
    if (i == 2) {
      EXPECT_EQ(r.status, ReadStatus::kBadFrame);
      EXPECT_TRUE(contains(r.message, "left_0002.png"));
      EXPECT_TRUE(contains(r.message, "80x60"));
    } else {
      ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
      EXPECT_TRUE(sameImage(frame.views[0], pattern(i, 0)));
    }
  }
}

TEST_F(FolderSourceTest, TypeChangeIsBadFrame) {
  writePairs(3);
  cv::Mat grey;
  cv::cvtColor(pattern(1, 0), grey, cv::COLOR_BGR2GRAY);
  writeImage(numbered("left_", 1), grey);
  writeImage(numbered("right_", 1), grey);
  const auto source = openSource(folderConfig());
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kOk);
  EXPECT_EQ(source->read(frame).status, ReadStatus::kBadFrame);
  EXPECT_EQ(source->read(frame).status, ReadStatus::kOk);
}

// ------------------------------------------------------------- folder errors --

TEST_F(FolderErrorTest, MissingFolder) {
  SourceConfig c = folderConfig();
  c.folder = path("does_not_exist");
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), c.folder));
}

TEST_F(FolderErrorTest, PathIsAFile) {
  writeText("plain_file", "x");
  SourceConfig c = folderConfig();
  c.folder = path("plain_file");
  const std::string message = configErrorOf([&] { openSource(c); });
  EXPECT_TRUE(contains(message, c.folder));
  EXPECT_TRUE(contains(message, "not a folder"));
}

TEST_F(FolderErrorTest, EmptyFolder) {
  const std::string message = configErrorOf([&] { openSource(folderConfig()); });
  EXPECT_TRUE(contains(message, dir_.string()));
  EXPECT_TRUE(contains(message, "left_*.png"));
}

TEST_F(FolderErrorTest, NoFileMatchesRightPattern) {
  for (int i = 0; i < 2; ++i) writeImage(numbered("left_", i), pattern(i, 0));
  writeImage("notes.png", pattern(0, 1));
  const std::string message = configErrorOf([&] { openSource(folderConfig()); });
  EXPECT_TRUE(contains(message, "right_*.png"));
}

TEST_F(FolderErrorTest, LeftAndRightCountsDiffer) {
  for (int i = 0; i < 7; ++i) writeImage(numbered("left_", i), pattern(i, 0, {16, 8}));
  for (int i = 0; i < 4; ++i) writeImage(numbered("right_", i), pattern(i, 1, {16, 8}));
  std::string message = configErrorOf([&] { openSource(folderConfig()); });
  // The folder path may hold digits of its own: look at the rest of the message.
  for (auto at = message.find(dir_.string()); at != std::string::npos; at = message.find(dir_.string())) {
    message.erase(at, dir_.string().size());
  }
  EXPECT_TRUE(contains(message, "7"));
  EXPECT_TRUE(contains(message, "4"));
}

TEST_F(FolderErrorTest, FirstPairSizesDiffer) {
  // Only the first pair differs: a configuration error all the same (the
  // first readable pair sets the size), not a bad frame to skip.
  for (int i = 0; i < 3; ++i) {
    writeImage(numbered("left_", i), pattern(i, 0, {64, 48}));
    writeImage(numbered("right_", i), pattern(i, 1, i == 0 ? cv::Size(32, 24) : cv::Size(64, 48)));
  }
  const std::string message = configErrorOf([&] { openSource(folderConfig()); });
  EXPECT_TRUE(contains(message, "64x48"));
  EXPECT_TRUE(contains(message, "32x24"));
}

TEST_F(FolderErrorTest, NoReadableImage) {
  for (int i = 0; i < 3; ++i) {
    writeText(numbered("left_", i), "garbage " + std::to_string(i));
    writeText(numbered("right_", i), "garbage " + std::to_string(i));
  }
  const std::string message = configErrorOf([&] { openSource(folderConfig()); });
  EXPECT_TRUE(contains(message, dir_.string()));
  EXPECT_TRUE(contains(message, "no readable image"));
}

// ---------------------------------------------------------------- video files --

TEST_F(VideoSourceTest, PairOfMjpgFiles) {
  const cv::Size size(64, 48);
  for (int v = 0; v < 2; ++v) {
    const std::string why = writeVideo(dir_ / (v == 0 ? "left.avi" : "right.avi"), 5, size,
                                       [&](int i) { return flatFrame(size, videoColour(i, v)); });
    if (!why.empty()) GTEST_SKIP() << why;
  }
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kPair;
  c.locations = {path("left.avi"), path("right.avi")};
  const auto source = openSource(c);
  EXPECT_EQ(source->views(), 2);
  EXPECT_EQ(source->viewSize(), size);
  EXPECT_EQ(source->frameCount(), 5);
  EXPECT_FALSE(source->isLive());
  EXPECT_NEAR(source->nominalRate(), 25.0, 1e-6);
  for (int i = 0; i < 5; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    const ReadResult r = source->read(frame);
    ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
    EXPECT_EQ(frame.index, i);
    ASSERT_EQ(frame.views.size(), 2u);
    for (int v = 0; v < 2; ++v) {
      EXPECT_EQ(frame.views[v].size(), size);
      EXPECT_EQ(frame.views[v].type(), CV_8UC3);
      EXPECT_TRUE(hasColour(frame.views[v], videoColour(i, v))) << "view " << v;
    }
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
}

TEST_F(VideoSourceTest, LoopRewinds) {
  const cv::Size size(64, 48);
  const std::string why =
      writeVideo(dir_ / "mono.avi", 4, size, [&](int i) { return flatFrame(size, videoColour(i, 0)); });
  if (!why.empty()) GTEST_SKIP() << why;
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kMono;
  c.locations = {path("mono.avi")};
  c.loop = true;
  c.rate = 7.0;
  const auto source = openSource(c);
  EXPECT_EQ(source->views(), 1);
  EXPECT_DOUBLE_EQ(source->nominalRate(), 7.0);
  EXPECT_EQ(source->frameCount(), 4);
  for (int n = 0; n < 10; ++n) {
    const int i = n % 4;
    SCOPED_TRACE("read " + std::to_string(n));
    Frame frame;
    const ReadResult r = source->read(frame);
    ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
    EXPECT_EQ(frame.index, i);
    ASSERT_EQ(frame.views.size(), 1u);
    EXPECT_TRUE(hasColour(frame.views[0], videoColour(i, 0)));
  }
}

TEST_F(VideoSourceTest, PairLoopRewindsBothFiles) {
  const cv::Size size(64, 48);
  for (int v = 0; v < 2; ++v) {
    const std::string why = writeVideo(dir_ / (v == 0 ? "left.avi" : "right.avi"), 3, size,
                                       [&](int i) { return flatFrame(size, videoColour(i, v)); });
    if (!why.empty()) GTEST_SKIP() << why;
  }
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kPair;
  c.locations = {path("left.avi"), path("right.avi")};
  c.loop = true;
  const auto source = openSource(c);
  for (int n = 0; n < 7; ++n) {
    const int i = n % 3;
    SCOPED_TRACE("read " + std::to_string(n));
    Frame frame;
    const ReadResult r = source->read(frame);
    ASSERT_EQ(r.status, ReadStatus::kOk) << r.message;
    EXPECT_EQ(frame.index, i);
    ASSERT_EQ(frame.views.size(), 2u);
    EXPECT_TRUE(hasColour(frame.views[0], videoColour(i, 0)));
    EXPECT_TRUE(hasColour(frame.views[1], videoColour(i, 1)));
  }
}

TEST_F(VideoSourceTest, SideBySideSplitsHalves) {
  const cv::Size view(64, 48);
  const std::string why = writeVideo(dir_ / "sbs.avi", 3, {view.width * 2, view.height},
                                     [&](int i) { return sideBySideVideoFrame(i, view); });
  if (!why.empty()) GTEST_SKIP() << why;
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kSideBySide;
  c.locations = {path("sbs.avi")};
  const auto source = openSource(c);
  EXPECT_EQ(source->views(), 2);
  EXPECT_EQ(source->viewSize(), view);
  EXPECT_EQ(source->frameCount(), 3);
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    ASSERT_EQ(source->read(frame).status, ReadStatus::kOk);
    ASSERT_EQ(frame.views.size(), 2u);
    EXPECT_EQ(frame.views[0].size(), view);
    EXPECT_EQ(frame.views[1].size(), view);
    // Stay clear of the seam, where JPEG blocks mix the two colours.
    const cv::Rect inner(4, 4, view.width - 8, view.height - 8);
    EXPECT_TRUE(hasColour(frame.views[0](inner), videoColour(i, 0)));
    EXPECT_TRUE(hasColour(frame.views[1](inner), videoColour(i, 1)));
  }
  Frame frame;
  EXPECT_EQ(source->read(frame).status, ReadStatus::kEnd);
}

TEST_F(VideoSourceTest, MissingFile) {
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kMono;
  c.locations = {path("missing.avi")};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), path("missing.avi")));
}

TEST_F(VideoSourceTest, MissingRightFile) {
  const cv::Size size(64, 48);
  const std::string why =
      writeVideo(dir_ / "left.avi", 2, size, [&](int i) { return flatFrame(size, videoColour(i, 0)); });
  if (!why.empty()) GTEST_SKIP() << why;
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kPair;
  c.locations = {path("left.avi"), path("right.avi")};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), path("right.avi")));
}

TEST_F(VideoSourceTest, DifferentFrameCounts) {
  const cv::Size size(64, 48);
  for (int v = 0; v < 2; ++v) {
    const std::string why = writeVideo(dir_ / (v == 0 ? "left.avi" : "right.avi"), v == 0 ? 6 : 3, size,
                                       [&](int i) { return flatFrame(size, videoColour(i, v)); });
    if (!why.empty()) GTEST_SKIP() << why;
  }
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kPair;
  c.locations = {path("left.avi"), path("right.avi")};
  const std::string message = configErrorOf([&] { openSource(c); });
  EXPECT_TRUE(contains(message, "left.avi"));
  EXPECT_TRUE(contains(message, "right.avi"));
}

TEST_F(VideoSourceTest, TextFileIsNoVideo) {
  writeText("notes.txt", "This is a text file, not a video.\n");
  writeText("fake.avi", "This is a text file named like a video.\n");
  for (const char* name : {"notes.txt", "fake.avi"}) {
    SCOPED_TRACE(name);
    SourceConfig c;
    c.type = SourceType::kVideo;
    c.layout = Layout::kMono;
    c.locations = {path(name)};
    EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), path(name)));
  }
}

TEST_F(VideoSourceTest, FolderIsNoVideo) {
  SourceConfig c;
  c.type = SourceType::kVideo;
  c.layout = Layout::kMono;
  c.locations = {dir_.string()};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), dir_.string()));
}

// ---------------------------------------------------------------------- V4L2 --

TEST(V4l2SourceTest, MissingDevicePath) {
  SourceConfig c;
  c.type = SourceType::kV4l2;
  c.layout = Layout::kMono;
  c.locations = {"/dev/video_massage_cell_missing"};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), "/dev/video_massage_cell_missing"));
  c.layout = Layout::kPair;
  c.locations = {"/dev/video_massage_cell_missing", "/dev/video_massage_cell_missing_too"};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), "/dev/video_massage_cell_missing"));
}

TEST(V4l2SourceTest, IndexMapsToDevicePath) {
  if (fs::exists("/dev/video99")) GTEST_SKIP() << "/dev/video99 exists on this machine";
  SourceConfig c;
  c.type = SourceType::kV4l2;
  c.layout = Layout::kSideBySide;
  c.locations = {"99"};
  EXPECT_TRUE(contains(configErrorOf([&] { openSource(c); }), "/dev/video99"));
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
