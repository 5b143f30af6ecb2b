// Unit tests of the skin-marker detector (massage_cell/cect/skin_markers.h) on synthetic rectified pairs: a
// skin-coloured ellipse (the back) on a sheet, anti-aliased green (C7) and blue (L4) dots drawn at sub-pixel centres
// in the left view and shifted by a disparity in the right. main() is in test_layout.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "massage_cell/cect/skin_markers.h"

namespace cect = massage_cell::cect;

namespace {

const cv::Scalar kSkin(120, 150, 200);      // BGR: sRGB (200, 150, 120), hue 22 deg
const cv::Scalar kDarkSkin(40, 55, 80);     // sRGB (80, 55, 40)
const cv::Scalar kGrey(128, 128, 128);      // a grey sheet
const cv::Scalar kBlueSheet(190, 110, 60);  // sRGB (60, 110, 190), hue 217 deg: inside L4's range
const cv::Scalar kGreen(60, 160, 40);       // sRGB (40, 160, 60), hue 130 deg
const cv::Scalar kBlue(200, 80, 40);        // sRGB (40, 80, 200), hue 225 deg
constexpr int kShift = 4;                   // drawing's fixed point: 1/16 px
constexpr double kOne = 1 << kShift;

cv::Point fixedPoint(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kOne)), static_cast<int>(std::lround(p.y * kOne))};
}

/// The kit of config/skin_markers.yaml, written out (the detector's cases do not depend on the shipped file).
cect::SkinMarkerOptions kit() {
  cect::SkinMarkerOptions o;
  cect::SkinMarkerSpec c7, l4;
  c7.landmark = "C7";
  c7.hue_deg = 130;
  l4.landmark = "L4";
  l4.hue_deg = 225;
  o.markers = {c7, l4};
  return o;
}

struct Dot {
  cv::Point2d centre;  ///< left view
  double radius;
  cv::Scalar bgr;
  bool in_right = true, in_left = true;
  cv::Point2d right_offset{0, 0};  ///< moved by this too in the right view
};

/// A synthetic rectified pair: the back an ellipse at the image's centre, the dots in the left view at their centres
/// and in the right one `disparity` px to the left (everything at one depth).
struct Scene {
  cv::Size size{320, 240};
  cv::Scalar skin = kSkin, sheet = kGrey;
  double disparity = 23.4;
  std::vector<Dot> dots;

  cv::Point2d backCentre() const { return {size.width / 2.0, size.height / 2.0}; }
  cv::Size backAxes() const {
    return {static_cast<int>(0.22 * size.width * kOne), static_cast<int>(0.44 * size.height * kOne)};
  }
  /// One view: everything shifted `dx` px along the rows.
  cv::Mat view(double dx, bool right) const {
    cv::Mat img(size, CV_8UC3, sheet);
    cv::ellipse(img, fixedPoint(backCentre() + cv::Point2d(dx, 0)), backAxes(), 0, 0, 360, skin, cv::FILLED,
                cv::LINE_AA, kShift);
    for (const Dot& d : dots) {
      if (right ? !d.in_right : !d.in_left) continue;
      cv::circle(img, fixedPoint(d.centre + cv::Point2d(dx, 0) + (right ? d.right_offset : cv::Point2d())),
                 static_cast<int>(std::lround(d.radius * kOne)), d.bgr, cv::FILLED, cv::LINE_AA, kShift);
    }
    return img;
  }
  cv::Mat left() const { return view(0, false); }
  cv::Mat right() const { return view(-disparity, true); }
  /// The back's mask (255 on the skin ellipse, the dots included).
  cv::Mat mask() const {
    cv::Mat m = cv::Mat::zeros(size, CV_8UC1);
    cv::ellipse(m, fixedPoint(backCentre()), backAxes(), 0, 0, 360, 255, cv::FILLED, cv::LINE_8, kShift);
    return m;
  }
  cv::Vec2d range() const { return {5.0, 0.25 * size.width}; }
};

/// C7 and L4 on the back, dots of the reference view's size (25 mm ~ 14 px at 640x480), at sub-pixel centres.
Scene standardScene(cv::Size size = {320, 240}) {
  Scene s;
  s.size = size;
  const double k = size.width / 320.0;
  s.disparity = 23.4 * k;
  const double r = k == 1.0 ? 6.5 : 11.5;
  s.dots = {{{160.3 * k, 50.7 * k}, r, kGreen}, {{158.6 * k, 190.4 * k}, r, kBlue}};
  return s;
}

cect::SkinMarkers detect(const Scene& s, const cect::SkinMarkerOptions& o = kit(), bool with_mask = true) {
  return cect::detectSkinMarkers(s.left(), s.right(), with_mask ? s.mask() : cv::Mat(), s.range(), o);
}

const cect::SkinMarkerDetection* findMarker(const cect::SkinMarkers& m, const std::string& landmark) {
  for (const auto& d : m.found) {
    if (d.landmark == landmark) return &d;
  }
  return nullptr;
}

std::string problemOf(const cect::SkinMarkers& m, const std::string& landmark) {
  for (const auto& p : m.problems) {
    if (p.rfind(landmark + " ", 0) == 0) return p;
  }
  return {};
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// Both markers found where the scene drew them, within `tol` px, with its disparity.
void expectFound(const cect::SkinMarkers& m, const Scene& s, double tol = 0.3) {
  ASSERT_EQ(m.found.size(), 2u) << m.describe();
  EXPECT_TRUE(m.problems.empty()) << m.describe();
  for (std::size_t i = 0; i < 2; ++i) {
    const cect::SkinMarkerDetection* d = findMarker(m, i == 0 ? "C7" : "L4");
    ASSERT_NE(d, nullptr) << m.describe();
    const cv::Point2d c = s.dots[i].centre;
    EXPECT_NEAR(d->left.x, c.x, tol) << d->landmark;
    EXPECT_NEAR(d->left.y, c.y, tol) << d->landmark;
    EXPECT_NEAR(d->right.x, c.x - s.disparity, tol) << d->landmark;
    EXPECT_NEAR(d->right.y, c.y, tol) << d->landmark;
    EXPECT_NEAR(d->disparity, s.disparity, tol) << d->landmark;
    EXPECT_NEAR(d->diameter_px, 2.0 * s.dots[i].radius, 2.0) << d->landmark;
  }
}

TEST(SkinMarkers, BothFoundWithSubPixelCentresAndTheirDisparity) {
  for (const cv::Size size : {cv::Size(320, 240), cv::Size(640, 480)}) {
    SCOPED_TRACE(std::to_string(size.width));
    const Scene s = standardScene(size);
    const cect::SkinMarkers m = detect(s);
    expectFound(m, s);
    // Deterministic, and the whole image searched when no mask is given (nothing else is green or blue here).
    const cect::SkinMarkers again = detect(s), unmasked = detect(s, kit(), false);
    ASSERT_EQ(again.found.size(), 2u);
    EXPECT_EQ(again.found[0].left, m.found[0].left);
    EXPECT_EQ(again.found[1].right, m.found[1].right);
    expectFound(unmasked, s);
  }
}

TEST(SkinMarkers, ADotOnlyInTheLeftViewIsMissingWithAProblemNamingTheRightView) {
  Scene s = standardScene();
  s.dots[1].in_right = false;
  const cect::SkinMarkers m = detect(s);
  EXPECT_NE(findMarker(m, "C7"), nullptr) << m.describe();
  EXPECT_EQ(findMarker(m, "L4"), nullptr) << m.describe();
  const std::string p = problemOf(m, "L4");
  EXPECT_TRUE(contains(p, "L4 (blue dot): no match in the right view on rows 188..192 with disparity 5..80")) << p;
  // A right-view dot off the left one's rows (5 px below) is no match either, nor one outside the disparities.
  s.dots[1].in_right = true;
  s.dots[1].right_offset = {0, 5};
  const cect::SkinMarkers off_row = detect(s);
  EXPECT_EQ(findMarker(off_row, "L4"), nullptr) << off_row.describe();
  EXPECT_TRUE(contains(problemOf(off_row, "L4"), "no match in the right view")) << off_row.describe();
  s.dots[1].right_offset = {s.disparity - 2.0, 0};  // disparity 2
  const cect::SkinMarkers off_range = detect(s);
  EXPECT_EQ(findMarker(off_range, "L4"), nullptr) << off_range.describe();
  EXPECT_TRUE(contains(problemOf(off_range, "L4"), "no match in the right view")) << off_range.describe();
  EXPECT_NE(findMarker(off_range, "C7"), nullptr) << off_range.describe();
  // Two blue dots on its row within the disparities in the right view: refused, not guessed.
  s.dots[1].right_offset = {0, 0};
  Dot twin = s.dots[1];
  twin.centre.x -= 15.0;
  twin.in_left = false;
  s.dots.push_back(twin);
  const cect::SkinMarkers two = detect(s);
  EXPECT_EQ(findMarker(two, "L4"), nullptr) << two.describe();
  EXPECT_TRUE(contains(problemOf(two, "L4"), "L4 (blue dot): 2 matches in the right view on rows 188..192"))
      << two.describe();
}

TEST(SkinMarkers, TwoGreenDotsOnTheBackAreRefused) {
  Scene s = standardScene();
  s.dots.push_back({{175.2, 100.6}, 6.5, kGreen});
  const cect::SkinMarkers m = detect(s);
  EXPECT_EQ(findMarker(m, "C7"), nullptr) << m.describe();
  EXPECT_NE(findMarker(m, "L4"), nullptr) << m.describe();
  EXPECT_TRUE(contains(problemOf(m, "C7"), "C7 (green dot): 2 candidates in the left view, none taken"))
      << m.describe();
}

TEST(SkinMarkers, ABlueSheetAndABlueCapOutsideTheMaskAreNotTakenForL4) {
  Scene s = standardScene();
  s.sheet = kBlueSheet;
  // A blue bottle cap (white rim) lying on the sheet beside the back.
  s.dots.push_back({{40.2, 200.3}, 10.0, cv::Scalar(235, 235, 235)});
  s.dots.push_back({{40.2, 200.3}, 6.5, kBlue});
  const cect::SkinMarkers masked = detect(s);
  ASSERT_EQ(masked.found.size(), 2u) << masked.describe();
  const cect::SkinMarkerDetection* l4 = findMarker(masked, "L4");
  ASSERT_NE(l4, nullptr);
  EXPECT_NEAR(l4->left.x, s.dots[1].centre.x, 0.3);
  EXPECT_NEAR(l4->left.y, s.dots[1].centre.y, 0.3);
  // Without the mask the cap is a second candidate (the sheet itself is too large either way).
  const cect::SkinMarkers unmasked = detect(s, kit(), false);
  EXPECT_EQ(findMarker(unmasked, "L4"), nullptr) << unmasked.describe();
  EXPECT_TRUE(contains(problemOf(unmasked, "L4"), "2 candidates in the left view")) << unmasked.describe();
}

TEST(SkinMarkers, ADotCutOutOfTheMaskStillCounts) {
  // The segmentation left the dots out: C7 a hole in the mask wider than its margin, L4 a notch at the back's edge.
  Scene s = standardScene();
  const cv::Point2d bottom = s.backCentre() + cv::Point2d(0, 0.44 * s.size.height);
  s.dots[1].centre = bottom - cv::Point2d(0.3, 7.6);
  cv::Mat mask = s.mask();
  for (const Dot& d : s.dots)
    cv::circle(mask, fixedPoint(d.centre), static_cast<int>((d.radius + 2.5) * kOne), 0, cv::FILLED, cv::LINE_8,
               kShift);
  const cect::SkinMarkers m = cect::detectSkinMarkers(s.left(), s.right(), mask, s.range(), kit());
  expectFound(m, s);
}

TEST(SkinMarkers, FoundUnderAColourCastAndOnDarkSkin) {
  const Scene s = standardScene();
  for (const cv::Scalar& cast : {cv::Scalar(1.15, 1.0, 0.85), cv::Scalar(0.85, 1.0, 1.15)}) {
    SCOPED_TRACE(cast[0]);
    cv::Mat left, right;
    cv::multiply(s.left(), cast, left);
    cv::multiply(s.right(), cast, right);
    expectFound(cect::detectSkinMarkers(left, right, s.mask(), s.range(), kit()), s);
  }
  Scene dark = standardScene(cv::Size(640, 480));
  dark.skin = kDarkSkin;
  expectFound(detect(dark), dark);
  // ... and dimly lit (a third of the light).
  cv::Mat left = dark.left() * (1.0 / 3.0), right = dark.right() * (1.0 / 3.0);
  expectFound(cect::detectSkinMarkers(left, right, dark.mask(), dark.range(), kit()), dark, 0.4);
}

TEST(SkinMarkers, ADotTooSmallIsNotFound) {
  Scene s = standardScene();
  s.dots[0].radius = 1.0;  // 2 px across
  const cect::SkinMarkers m = detect(s);
  EXPECT_EQ(findMarker(m, "C7"), nullptr) << m.describe();
  EXPECT_NE(findMarker(m, "L4"), nullptr) << m.describe();
  EXPECT_TRUE(contains(problemOf(m, "C7"), "C7 (green dot): not found in the left view (refused: 1 too small)"))
      << m.describe();
  // At 4 px across it is a dot.
  s.dots[0].radius = 2.0;
  const cect::SkinMarkers small = detect(s);
  EXPECT_NE(findMarker(small, "C7"), nullptr) << small.describe();
}

TEST(SkinMarkers, AKnownPixelScaleRefusesADotOfTheWrongSize) {
  const Scene s = standardScene();  // dots 13 px across
  const cect::SkinMarkerScale right_size = [](const cv::Point2f&) { return 0.025 / 13.0; };
  const cect::SkinMarkerScale too_near = [](const cv::Point2f&) { return 0.025 / 40.0; };
  const cect::SkinMarkerScale unknown = [](const cv::Point2f&) { return std::nan(""); };
  expectFound(cect::detectSkinMarkers(s.left(), s.right(), s.mask(), s.range(), kit(), right_size), s);
  expectFound(cect::detectSkinMarkers(s.left(), s.right(), s.mask(), s.range(), kit(), unknown), s);
  const cect::SkinMarkers m = cect::detectSkinMarkers(s.left(), s.right(), s.mask(), s.range(), kit(), too_near);
  EXPECT_TRUE(m.found.empty()) << m.describe();
  EXPECT_TRUE(contains(problemOf(m, "C7"), "not found in the left view (refused: 1 not 25 mm across)")) << m.describe();
}

TEST(SkinMarkers, DescribeSaysWhatWasFoundAndWhatNot) {
  Scene s = standardScene();
  s.dots.erase(s.dots.begin() + 1);
  const cect::SkinMarkers m = detect(s);
  ASSERT_EQ(m.found.size(), 1u) << m.describe();
  const cect::SkinMarkerDetection& c7 = m.found[0];
  char expected[200];
  std::snprintf(expected, sizeof expected, "C7 at (%.1f, %.1f) d %.1f; L4 (blue dot): not found in the left view",
                c7.left.x, c7.left.y, c7.disparity);
  EXPECT_EQ(m.describe(), expected);
  EXPECT_EQ(cect::SkinMarkers().describe(), "no markers");
}

TEST(SkinMarkers, WrongImagesThrowInvalidArgument) {
  const Scene s = standardScene();
  const cv::Mat left = s.left(), right = s.right(), mask = s.mask();
  cv::Mat grey, small, left_float;
  cv::cvtColor(left, grey, cv::COLOR_BGR2GRAY);
  cv::resize(right, small, {160, 120});
  left.convertTo(left_float, CV_32FC3);
  EXPECT_THROW(cect::detectSkinMarkers(grey, right, mask, s.range(), kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left_float, right, mask, s.range(), kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left, small, mask, s.range(), kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(cv::Mat(), cv::Mat(), mask, s.range(), kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left, right, mask(cv::Rect(0, 0, 100, 100)), s.range(), kit()),
               std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left, right, left, s.range(), kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left, right, mask, {40.0, 5.0}, kit()), std::invalid_argument);
  EXPECT_THROW(cect::detectSkinMarkers(left, right, mask, s.range(), cect::SkinMarkerOptions()), std::invalid_argument);
  EXPECT_NO_THROW(cect::detectSkinMarkers(left, right, mask, s.range(), kit()));
}

TEST(SkinMarkersOptions, BadOptionsAreRejectedWithTheNamedProblem) {
  EXPECT_EQ(cect::checkSkinMarkerOptions(kit()), "");
  auto problem = [](auto change) {
    cect::SkinMarkerOptions o = kit();
    change(o);
    return cect::checkSkinMarkerOptions(o);
  };
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[1].hue_deg = 170; }), "C7 and L4: hue ranges overlap"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].hue_deg = 350, o.markers[1].hue_deg = 20; }),
                       "hue ranges overlap"));  // across 360
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[1].landmark = "T3"; }), "unknown landmark 'T3'"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[1].landmark = "C7"; }), "landmark C7 listed twice"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].hue_tolerance_deg = 0; }),
                       "C7: hue_tolerance_deg 0 is not in (0, 90)"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].hue_tolerance_deg = 90; }), "hue_tolerance_deg 90"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].hue_deg = 400; }), "hue_deg 400 is not in 0..360"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].min_saturation = 1.5; }), "min_saturation"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].min_value = -0.1; }), "min_value"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers[0].diameter_m = 0; }), "diameter_m"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.min_diameter_px = 70; }), "must be below max_diameter_px"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.min_fill = 0; }), "min_fill"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.max_area_ratio = 0.5; }), "max_area_ratio"));
  EXPECT_TRUE(contains(problem([](auto& o) { o.markers.clear(); }), "no markers"));
}

TEST(SkinMarkers, TheDotsPixelsAreMarkedButASheetOfTheirColourIsNot) {
  Scene s = standardScene();
  s.sheet = kBlueSheet;  // all around the back: a component far larger than a dot
  const cv::Mat marks = cect::skinMarkerPixels(s.left(), kit());
  ASSERT_EQ(marks.type(), CV_8UC1);
  for (const Dot& d : s.dots) {
    EXPECT_EQ(marks.at<std::uint8_t>(cvRound(d.centre.y), cvRound(d.centre.x)), 255);
    // ... with its anti-aliased rim, and not much beyond.
    EXPECT_EQ(marks.at<std::uint8_t>(cvRound(d.centre.y), cvRound(d.centre.x + d.radius + 1)), 255);
    EXPECT_EQ(marks.at<std::uint8_t>(cvRound(d.centre.y), cvRound(d.centre.x + d.radius + 5)), 0);
  }
  EXPECT_EQ(marks.at<std::uint8_t>(5, 5), 0) << "the blue sheet is no dot";
  EXPECT_LT(cv::countNonZero(marks), 2 * CV_PI * 9.5 * 9.5);
  EXPECT_THROW(cect::skinMarkerPixels(cv::Mat(10, 10, CV_8UC1), kit()), std::invalid_argument);
}

TEST(SkinMarkers, AnOptionalMarkerWithoutItsDotIsAbsentNotAProblem) {
  cect::SkinMarkerOptions o = kit();
  cect::SkinMarkerSpec t7;
  t7.landmark = "T7";
  t7.colour = "magenta";
  t7.hue_deg = 315;
  t7.optional = true;
  o.markers.push_back(t7);
  const Scene s = standardScene();
  const cect::SkinMarkers m = detect(s, o);
  expectFound(m, s);
  ASSERT_EQ(m.absent.size(), 1u) << m.describe();
  EXPECT_EQ(m.absent[0], "T7 (magenta dot)");
  EXPECT_TRUE(contains(m.describe(), "T7 (magenta dot): optional, not on the back")) << m.describe();
  // The same marker required: its absence is a problem.
  o.markers.back().optional = false;
  const cect::SkinMarkers required = detect(s, o);
  EXPECT_TRUE(required.absent.empty());
  EXPECT_TRUE(contains(problemOf(required, "T7"), "not found in the left view")) << required.describe();
}

TEST(SkinMarkersOptions, TheShippedKitLoadsAndFindsTheKitsDots) {
  const cect::SkinMarkerOptions o =
      cect::loadSkinMarkerOptions(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/skin_markers.yaml");
  ASSERT_EQ(o.markers.size(), 3u);
  EXPECT_EQ(o.markers[0].landmark, "C7");
  EXPECT_EQ(o.markers[1].landmark, "L4");
  EXPECT_EQ(o.markers[2].landmark, "T7");
  EXPECT_EQ(o.markers[0].colour, "green");
  EXPECT_EQ(o.markers[1].colour, "blue");
  EXPECT_EQ(o.markers[2].colour, "magenta");
  EXPECT_FALSE(o.markers[0].optional || o.markers[1].optional);
  EXPECT_TRUE(o.markers[2].optional);
  EXPECT_DOUBLE_EQ(o.markers[0].diameter_m, 0.025);
  EXPECT_EQ(cect::checkSkinMarkerOptions(o), "");
  const Scene s = standardScene(cv::Size(640, 480));
  expectFound(detect(s, o), s);
}

/// Writes `text` to a temporary YAML file and returns its path.
std::string tempYaml(const std::string& name, const std::string& text) {
  const std::string path = testing::TempDir() + "/" + name + ".yaml";
  std::ofstream(path) << text;
  return path;
}

/// The message loadSkinMarkerOptions throws for the file at `path`, or "" when it loads.
std::string loadError(const std::string& path) {
  try {
    cect::loadSkinMarkerOptions(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return {};
}

TEST(SkinMarkersOptions, LoadingErrorsNameTheFileAndTheKey) {
  const std::string good = "markers:\n  - {landmark: C7, hue_deg: 130}\n  - {landmark: L4, hue_deg: 225}\n";
  EXPECT_EQ(loadError(tempYaml("skin_markers_good", good)), "");
  const std::string unknown = tempYaml("skin_markers_unknown", good + "max_diameter: 50\n");
  std::string e = loadError(unknown);
  EXPECT_TRUE(contains(e, unknown) && contains(e, "unknown key 'max_diameter'")) << e;
  e = loadError(tempYaml("skin_markers_unknown_marker", "markers:\n  - {landmark: C7, hue_deg: 130, color: green}\n"));
  EXPECT_TRUE(contains(e, "markers[0]: unknown key 'color'")) << e;
  e = loadError(tempYaml("skin_markers_type", good + "min_fill: [1, 2]\n"));
  EXPECT_TRUE(contains(e, "key 'min_fill' has the wrong type")) << e;
  e = loadError(tempYaml("skin_markers_no_hue", "markers:\n  - {landmark: C7}\n"));
  EXPECT_TRUE(contains(e, "missing key 'hue_deg'")) << e;
  e = loadError(tempYaml("skin_markers_overlap",
                         "markers:\n  - {landmark: C7, hue_deg: 130}\n"
                         "  - {landmark: L4, hue_deg: 150}\n"));
  EXPECT_TRUE(contains(e, "hue ranges overlap")) << e;
  e = loadError(tempYaml("skin_markers_bad", "markers: [\n"));
  EXPECT_TRUE(contains(e, "not valid YAML")) << e;
  e = loadError("/nonexistent/skin_markers.yaml");
  EXPECT_TRUE(contains(e, "/nonexistent/skin_markers.yaml") && contains(e, "cannot open the file")) << e;
}

}  // namespace
