// The layout's given landmarks (given_landmarks.h) and plausibility checks (layout_check.h) on hand-made landmarks:
// a straight back along the image's columns, C7 at row 100 and L4 at row 300 of the body's frame.
#include <algorithm>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "massage_cell/cect/given_landmarks.h"
#include "massage_cell/cect/layout_check.h"

using namespace massage_cell;

namespace {

/// The back's landmarks: midline at x = 320 (+ `lean` px per row) from row 40 to 420, C7 at 100, L4 at `l4_row`,
/// shoulder line at 130, 180 px wide; both landmarks measured.
cect::BackLandmarks back(double l4_row = 300.0, double lean = 0.0) {
  cect::BackLandmarks l;
  l.valid = true;
  for (int y = 40; y <= 420; ++y) {
    l.midline.emplace_back(static_cast<float>(320.0 + lean * (y - 40)), static_cast<float>(y));
    const double norm = std::hypot(1.0, lean);
    l.lateral.emplace_back(static_cast<float>(-1.0 / norm), static_cast<float>(lean / norm));
  }
  auto at = [&](double row) {
    return cv::Point2f(static_cast<float>(320.0 + lean * (row - 40)), static_cast<float>(row));
  };
  l.c7.body = at(100);
  l.l4.body = at(l4_row);
  l.shoulder_row = 130;
  l.shoulder_width = 180;
  l.waist_row = 100 + 0.8 * (l4_row - 100);
  l.measured = {"C7 at the neck's base", "the waist"};
  l.c7.detail = cect::kFromNeckBase;
  return l;
}

/// Trust rules with only the two measured-landmark rules set (no client, no configuration problem).
cect::TrustRules rules(bool c7_at_neck, bool l4_measured) {
  cect::TrustRules r;
  r.c7_at_neck = c7_at_neck;
  r.l4_measured = l4_measured;
  return r;
}

cect::AcupointModel model() {
  cect::AcupointModel m;
  m.level_fraction = {{"C7", 0.0}, {"T7", 0.36}, {"L4", 1.0}};
  m.length_per_shoulder_width = 1.22;
  m.cun_per_shoulder_width = 0.06323;  // the shipped model's: 180 px x 2 mm -> a cun of 22.8 mm, 11.4 px
  return m;
}

/// 2 mm a pixel everywhere.
const cect::PixelScale kScale = [](const cv::Point2f&) { return 0.002; };

TEST(GivenLandmarks, TheLevelsAndTheMidlinePassThroughTheGivenPixels) {
  cect::BackLandmarks l = back();
  l.along.assign(l.midline.size(), 0.0);
  const std::string problem =
      cect::applyGivenLandmarks(&l, {{"C7", {330.0f, 110.0f}, cect::LandmarkSource::kGivenClick},
                                     {"L4", {310.0f, 290.0f}, cect::LandmarkSource::kGivenService}});
  ASSERT_EQ(problem, "");
  EXPECT_NEAR(l.c7.body.x, 330.0, 1e-3);
  EXPECT_NEAR(l.c7.body.y, 110.0, 1e-3);
  EXPECT_NEAR(l.l4.body.x, 310.0, 1e-3);
  EXPECT_NEAR(l.l4.body.y, 290.0, 1e-3);
  EXPECT_TRUE(l.c7.given());
  EXPECT_TRUE(l.l4.given());
  EXPECT_TRUE(l.along.empty());  // measured from the old C7
  // The midline: through both, linear between (T7 at 36 % of the way), constant beyond.
  const cect::AcupointModel m = model();
  const cv::Point2f t7 = cect::levelPixel(l, m, "T7");
  EXPECT_NEAR(t7.y, 110.0 + 0.36 * 180.0, 0.6);
  EXPECT_NEAR(t7.x, 330.0 - 0.36 * 20.0, 0.2);
  EXPECT_NEAR(l.midline.front().x, 330.0, 1e-3);
  EXPECT_NEAR(l.midline.back().x, 310.0, 1e-3);
  for (const cv::Point2f& v : l.lateral) EXPECT_NEAR(std::hypot(v.x, v.y), 1.0, 1e-5);
  EXPECT_NE(cect::describeLandmarks(l).find(
                "used: C7 given (clicked), L4 given (service); measured: C7 at the neck's base, the waist"),
            std::string::npos)
      << cect::describeLandmarks(l);
}

TEST(GivenLandmarks, BothGivenMakeTheSpineLineStraightBetweenThem) {
  // The outline's centre bowed 15 px toward the subject's right between C7 and L4 (an arm's crease, a hand):
  // the palpated spinous processes fix the line between them, the outline's shape is kept beyond them.
  cect::BackLandmarks l = back();
  for (cv::Point2f& m : l.midline) {
    const double u = (m.y - 200.0) / 100.0;
    if (std::abs(u) < 1.0) m.x += static_cast<float>(15.0 * (1.0 - u * u));
  }
  const float above = l.midline.front().x, below = l.midline.back().x;  // rows 40 and 420: outside the bow
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"C7", {326.0f, 100.0f}, cect::LandmarkSource::kGivenMarker},
                                           {"L4", {314.0f, 300.0f}, cect::LandmarkSource::kGivenMarker}}),
            "");
  double worst = 0.0;
  for (std::size_t i = 0; i < l.midline.size(); ++i) {
    const cv::Point2f& m = l.midline[i];
    if (m.y <= 100.0f || m.y >= 300.0f) continue;
    worst = std::max(worst, std::abs(m.x - (326.0 - 0.06 * (m.y - 100.0))));
    // Across the chord: perpendicular to (-12, 200), toward the subject's left (the image's left, head up).
    EXPECT_NEAR(l.lateral[i].x * -12.0 + l.lateral[i].y * 200.0, 0.0, 1e-3);
    EXPECT_LT(l.lateral[i].x, 0.0f);
  }
  EXPECT_LT(worst, 1e-3);
  EXPECT_NEAR(l.midline.front().x, above + 6.0, 1e-3);  // shifted to join the line at C7 ...
  EXPECT_NEAR(l.midline.back().x, below - 6.0, 1e-3);   // ... and at L4
  const cv::Point2f t7 = cect::levelPixel(l, model(), "T7");
  EXPECT_NEAR(t7.x, 326.0 - 0.06 * (t7.y - 100.0), 0.05);
}

TEST(GivenLandmarks, AGivenT7SpacesTheLevelsOnEachSideOfItByTheModel) {
  // C7 100, L4 300: the model puts T7 at 172 (0.36) and a level at 0.18 half-way to it, one at 0.68 half-way on to L4.
  // The therapist's T7 at 190 moves the levels above it in proportion to C7 -> T7, those below to T7 -> L4; C7, L4
  // and the levels beyond them stay.
  cect::AcupointModel m = model();
  m.level_fraction["T3"] = 0.18;
  m.level_fraction["T12"] = 0.68;
  m.level_fraction["L5"] = 1.1;
  cect::BackLandmarks l = back();
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"T7", {326.0f, 190.0f}, cect::LandmarkSource::kGivenMarker}}), "");
  EXPECT_FALSE(l.c7.given() || l.l4.given());
  ASSERT_EQ(l.given_levels.size(), 1u);
  EXPECT_EQ(l.given_levels[0].level, "T7");
  EXPECT_NEAR(cect::levelPixel(l, m, "T7").y, 190.0, 1e-3);
  EXPECT_NEAR(cect::levelPixel(l, m, "T3").y, 145.0, 1e-3);
  EXPECT_NEAR(cect::levelPixel(l, m, "T12").y, 245.0, 1e-3);
  EXPECT_NEAR(cect::levelPixel(l, m, "C7").y, 100.0, 1e-3);
  EXPECT_NEAR(cect::levelPixel(l, m, "L4").y, 300.0, 1e-3);
  EXPECT_NEAR(cect::levelPixel(l, m, "L5").y, 320.0, 1e-3);
  // The midline passes through it (one given: shifted by 6 px), and the layout names it, given, between C7 and L4.
  EXPECT_NEAR(cect::levelPixel(l, m, "T3").x, 326.0, 1e-3);
  const std::vector<cect::LayoutLandmark> named = cect::layoutLandmarks(l);
  ASSERT_EQ(named.size(), 3u);
  EXPECT_EQ(named[0].landmark.level, "C7");
  EXPECT_EQ(named[1].landmark.level, "T7");
  EXPECT_EQ(cect::sourceName(named[1].landmark.source), "given");
  EXPECT_EQ(cect::landmarkDetail(named[1].landmark), "marker");
  EXPECT_NEAR(named[1].pixel.y, 190.0, 1e-3);
  EXPECT_EQ(named[2].landmark.level, "L4");
  // Its layout uncertainty along the body is the given one's at T7, between C7's and L4's elsewhere.
  const double at_t7 = std::sqrt(cect::layoutCovariance(l, m, "T7", 0.002)(1, 1));
  const double at_t12 = std::sqrt(cect::layoutCovariance(l, m, "T12", 0.002)(1, 1));
  EXPECT_NEAR(at_t7, m.layout_sigma.level_given * 0.4, 1e-9);  // 200 px x 2 mm
  EXPECT_NEAR(at_t12, 0.5 * (m.layout_sigma.level_given + m.layout_sigma.l4_measured) * 0.4, 1e-9);
}

TEST(GivenLandmarks, ThreeGivenMakeTheSpineLineStraightBetweenEachPair) {
  cect::BackLandmarks l = back();
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"C7", {320.0f, 100.0f}, cect::LandmarkSource::kGiven},
                                           {"L4", {320.0f, 300.0f}, cect::LandmarkSource::kGiven},
                                           {"T7", {330.0f, 170.0f}, cect::LandmarkSource::kGiven}}),
            "");
  for (std::size_t i = 0; i < l.midline.size(); ++i) {
    const cv::Point2f& m = l.midline[i];
    if (m.y > 100.0f && m.y < 170.0f) {
      EXPECT_NEAR(m.x, 320.0 + 10.0 * (m.y - 100.0) / 70.0, 1e-3);
      EXPECT_NEAR(l.lateral[i].x * 10.0 + l.lateral[i].y * 70.0, 0.0, 1e-3);  // perpendicular to its segment
    } else if (m.y > 170.0f && m.y < 300.0f) {
      EXPECT_NEAR(m.x, 330.0 - 10.0 * (m.y - 170.0) / 130.0, 1e-3);
      EXPECT_NEAR(l.lateral[i].x * -10.0 + l.lateral[i].y * 130.0, 0.0, 1e-3);
    }
  }
  EXPECT_NE(cect::describeLandmarks(l).find("used: C7 given, T7 given, L4 given;"), std::string::npos)
      << cect::describeLandmarks(l);
}

TEST(GivenLandmarks, TheRecordSaysWhereEachLandmarkCameFrom) {
  // C7 given by a skin marker (with its raw pixel and, from the back's 3D, its point), L4 as the pair measured it.
  cect::BackLandmarks l = back();
  cect::GivenLandmark marker("C7", {324.0f, 104.0f}, cect::LandmarkSource::kGivenMarker);
  marker.raw_pixel = {650.0f, 210.0f};
  const cect::PointLookup point = [](const cv::Point2f& q, cv::Point3d* p) {
    *p = cv::Point3d(q.x * 0.002, q.y * 0.002, 1.0);
    return true;
  };
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {marker}, point), "");
  EXPECT_EQ(l.c7.level, "C7");
  EXPECT_EQ(l.c7.source, cect::LandmarkSource::kGivenMarker);
  EXPECT_TRUE(l.c7.given());
  EXPECT_TRUE(l.c7.detail.empty());
  EXPECT_EQ(l.c7.raw_pixel, cv::Point2f(650.0f, 210.0f));
  EXPECT_NEAR(l.c7.point.y, 104.0 * 0.002, 1e-6);
  EXPECT_EQ(l.l4.source, cect::LandmarkSource::kMeasured);
  EXPECT_FALSE(l.l4.given());
  EXPECT_EQ(l.l4.detail, "the waist");
  EXPECT_TRUE(std::isnan(l.l4.raw_pixel.x));
  EXPECT_DOUBLE_EQ(cect::layoutSigma(model(), l.c7), model().layout_sigma.c7_given);
  EXPECT_DOUBLE_EQ(cect::layoutSigma(model(), l.l4), model().layout_sigma.l4_measured);
  const std::string used = "used: C7 given (marker), L4 measured (the waist);";
  EXPECT_NE(cect::describeLandmarks(l).find(used), std::string::npos) << cect::describeLandmarks(l);
  // The description reads the record, not the printed list of given landmarks ...
  l.given = {"C7 (clicked)", "L4 (service)"};
  EXPECT_NE(cect::describeLandmarks(l).find(used), std::string::npos) << cect::describeLandmarks(l);
  // ... and follows it.
  l.c7.source = cect::LandmarkSource::kGivenClick;
  l.l4.source = cect::LandmarkSource::kInferred;
  l.l4.detail = cect::kFromShoulderWidth;
  EXPECT_NE(cect::describeLandmarks(l).find("used: C7 given (clicked), L4 inferred (C7 and the shoulder width);"),
            std::string::npos)
      << cect::describeLandmarks(l);
}

TEST(GivenLandmarks, OneGivenShiftsTheMidlineAndKeepsTheOther) {
  cect::BackLandmarks l = back();
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"C7", {324.0f, 92.0f}, cect::LandmarkSource::kGiven}}), "");
  EXPECT_NEAR(l.c7.body.y, 92.0, 1e-3);
  EXPECT_NEAR(l.l4.body.y, 300.0, 1e-3);
  EXPECT_NEAR(l.l4.body.x, 324.0, 1e-3);
  EXPECT_TRUE(l.c7.given());
  EXPECT_FALSE(l.l4.given());
}

TEST(GivenLandmarks, APalpatedC7JustAboveTheSilhouettesTopExtendsTheMidline) {
  cect::BackLandmarks l = back(300.0, 0.05);  // the midline leans 0.05 px a row; its top is row 40
  const std::size_t before = l.midline.size();
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"C7", {317.0f, 20.0f}, cect::LandmarkSource::kGiven}}),
            "");  // 20 rows above its top
  EXPECT_EQ(l.midline.size(), before + 20);
  EXPECT_NEAR(l.midline.front().y, 20.0, 1e-3);
  EXPECT_NEAR(l.c7.body.x, 317.0, 1e-3);
  EXPECT_NEAR(l.c7.body.y, 20.0, 1e-3);
  EXPECT_EQ(l.lateral.size(), l.midline.size());
  // Farther than 15 % of C7 -> L4 (200 rows: 30 rows) beyond the back is not this back's C7.
  cect::BackLandmarks far = back();
  EXPECT_NE(cect::applyGivenLandmarks(&far, {{"C7", {320.0f, 5.0f}, cect::LandmarkSource::kGiven}})
                .find("not on the back's rows"),
            std::string::npos);
}

TEST(GivenLandmarks, InATurnedBodyFrameTheGivenImagePixelIsKept) {
  cect::BackLandmarks l = back();
  const double a = 10.0 * M_PI / 180.0;  // body frame -> image: a rotation by 10 degrees and a shift
  l.to_image = cv::Matx23d(std::cos(a), -std::sin(a), 40.0, std::sin(a), std::cos(a), -20.0);
  const cv::Point2f c7_image = cect::toImage(l, cv::Point2f(318.0f, 104.0f));
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {{"C7", c7_image, cect::LandmarkSource::kGiven}}), "");
  const cv::Point2f back_again = cect::toImage(l, l.c7.body);
  EXPECT_NEAR(back_again.x, c7_image.x, 1e-3);
  EXPECT_NEAR(back_again.y, c7_image.y, 1e-3);
}

TEST(GivenLandmarks, BadLandmarksAreRefusedNamingTheProblemAndChangeNothing) {
  const cect::BackLandmarks before = back();
  auto problem = [&](const std::vector<cect::GivenLandmark>& given) {
    cect::BackLandmarks l = before;
    const std::string p = cect::applyGivenLandmarks(&l, given);
    EXPECT_EQ(l.c7.body, before.c7.body);
    EXPECT_EQ(l.l4.body, before.l4.body);
    EXPECT_EQ(l.midline, before.midline);
    EXPECT_FALSE(l.c7.given() || l.l4.given());
    return p;
  };
  EXPECT_NE(problem({{"T3", {320.0f, 150.0f}, cect::LandmarkSource::kGiven}})
                .find("unknown landmark 'T3' (one of: C7, T7, L4)"),
            std::string::npos);
  EXPECT_NE(problem({{"T7", {320.0f, 320.0f}, cect::LandmarkSource::kGiven}})
                .find("landmark T7 at (320.0, 320.0) is not between C7 and L4"),
            std::string::npos);
  EXPECT_NE(problem({{"C7", {320.0f, 180.0f}, cect::LandmarkSource::kGiven},
                     {"T7", {320.0f, 170.0f}, cect::LandmarkSource::kGiven}})
                .find("not between C7 and L4"),
            std::string::npos);
  EXPECT_NE(problem({{"C7", {320.0f, 100.0f}, cect::LandmarkSource::kGiven},
                     {"C7", {320.0f, 110.0f}, cect::LandmarkSource::kGiven}})
                .find("given twice"),
            std::string::npos);
  EXPECT_NE(problem({{"L4", {320.0f, 480.0f}, cect::LandmarkSource::kGiven}}).find("not on the back's rows"),
            std::string::npos);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(problem({{"L4", {nan, 200.0f}, cect::LandmarkSource::kGiven}}).find("not finite"), std::string::npos);
  EXPECT_NE(problem({{"C7", {320.0f, 250.0f}, cect::LandmarkSource::kGiven},
                     {"L4", {320.0f, 200.0f}, cect::LandmarkSource::kGiven}})
                .find("not below C7"),
            std::string::npos);
  cect::BackLandmarks none;
  EXPECT_NE(
      cect::applyGivenLandmarks(&none, {{"C7", {320.0f, 100.0f}, cect::LandmarkSource::kGiven}}).find("no landmarks"),
      std::string::npos);
  cect::BackLandmarks l = before;
  EXPECT_EQ(cect::applyGivenLandmarks(&l, {}), "");  // nothing given: nothing to do
  EXPECT_EQ(cect::checkGivenLandmarkName("L4"), "");
}

TEST(LayoutCheck, AGivenT7OffTheModelsProportionsIsUsedAndNotedBeyondThePopulationRefused) {
  // C7 100, L4 300, the model's T7 at 0.36 (row 172): a marker at row 175 agrees; one at row 190 (0.45) disagrees
  // with the model's proportions by more than 0.06 but lies within the population's spread (0.20): used, the
  // disagreement noted; one at row 220 (0.60, T10's place and more) is refused.
  const auto checked = [](float row) {
    cect::BackLandmarks l = back();
    EXPECT_EQ(cect::applyGivenLandmarks(&l, {{"T7", {320.0f, row}, cect::LandmarkSource::kGivenMarker}}), "");
    return cect::checkLayout(l, model(), kScale);
  };
  const cect::LayoutCheck agrees = checked(175.0f);
  EXPECT_TRUE(agrees.trusted) << agrees.reason();
  EXPECT_TRUE(agrees.notes.empty());
  const cect::LayoutCheck noted = checked(190.0f);
  EXPECT_TRUE(noted.trusted) << noted.reason();
  ASSERT_EQ(noted.notes.size(), 1u);
  EXPECT_EQ(noted.notes[0],
            "T7 (given) lies at 0.45 of C7 -> L4, the model's 0.36: more than 0.06 off the model's proportions (used "
            "as given)");
  const cect::LayoutCheck refused = checked(220.0f);
  EXPECT_FALSE(refused.trusted);
  EXPECT_NE(refused.reason().find("T7 (given) lies at 0.60 of C7 -> L4, the model's 0.36 +- 0.20 (the population's "
                                  "spread): C7, T7 or L4 is not where it was given"),
            std::string::npos)
      << refused.reason();
}

TEST(LayoutCheck, GivenLandmarksBesideTheSpineAreNotTrusted) {
  // 2 mm a pixel, C7 -> L4 0.4 m, a cun of 20.7 mm from it: C7 and L4 clicked 50 px (100 mm) to the image's right of
  // the measured midline (a mis-click, or the previous client's landmarks) are refused, naming each; the same clicks 2
  // px (4 mm) off pass.
  const auto checked = [](float dx, const cect::PixelScale& scale) {
    cect::BackLandmarks l = back();
    EXPECT_EQ(cect::applyGivenLandmarks(&l, {{"C7", {320.0f + dx, 100.0f}, cect::LandmarkSource::kGivenClick},
                                             {"L4", {320.0f + dx, 300.0f}, cect::LandmarkSource::kGivenClick}}),
              "");
    return cect::checkLayout(l, model(), scale);
  };
  const cect::LayoutCheck beside = checked(50.0f, kScale);
  EXPECT_FALSE(beside.trusted);
  EXPECT_NE(beside.reason().find("the given C7 (clicked) lies 100 mm (4.8 cun) to the subject's right of the back's "
                                 "midline (a spine lies within 2.5 cun of it): not on the spine"),
            std::string::npos)
      << beside.reason();
  EXPECT_NE(beside.reason().find("the given L4 (clicked) lies 100 mm"), std::string::npos) << beside.reason();
  EXPECT_TRUE(checked(2.0f, kScale).trusted) << checked(2.0f, kScale).reason();
  EXPECT_TRUE(checked(-12.0f, kScale).trusted) << "24 mm, 1.2 cun: a spine may lie there";
  // To the subject's left (the image's left, head up), and on a photo (no scale: in cun of the shoulder width).
  EXPECT_NE(checked(-50.0f, kScale).reason().find("to the subject's left"), std::string::npos);
  const cect::LayoutCheck photo = checked(50.0f, cect::PixelScale());
  EXPECT_FALSE(photo.trusted);
  EXPECT_NE(photo.reason().find("the given C7 (clicked) lies 4.8 cun to the subject's right"), std::string::npos)
      << photo.reason();
  // One given T7 beside the spine moves the whole midline with it: refused too.
  cect::BackLandmarks t7 = back();
  ASSERT_EQ(cect::applyGivenLandmarks(&t7, {{"T7", {360.0f, 172.0f}, cect::LandmarkSource::kGivenClick}}), "");
  EXPECT_NE(cect::checkLayout(t7, model(), kScale).reason().find("the given T7 (clicked) lies 80 mm"),
            std::string::npos);
}

TEST(LayoutCheck, AGivenLandmarkFarFromTheSameOneMeasuredWaitsForConfirmation) {
  // C7 measured at the neck's base at row 100 and L4 at the waist at row 300 (2 mm a pixel). A given C7 20 rows
  // (40 mm) lower disagrees beyond both sigmas (3 x hypot(0.025, 0.012) of C7 -> L4, ~33 mm): not trusted until
  // confirmed, the reason naming both positions; 5 rows (10 mm) agrees.
  const auto checked = [](const std::vector<cect::GivenLandmark>& given) {
    cect::BackLandmarks l = back();
    EXPECT_EQ(cect::applyGivenLandmarks(&l, given), "");
    return cect::checkLayout(l, model(), kScale);
  };
  const cect::LayoutCheck apart = checked({{"C7", {320.0f, 120.0f}, cect::LandmarkSource::kGivenClick}});
  EXPECT_FALSE(apart.trusted);
  EXPECT_NE(apart.reason().find("the given C7 (clicked) at pixel (320, 120) and C7 measured at the neck's base at "
                                "(320, 100) lie 40 mm apart along the body (more than 3.0 sigma of both): confirm the "
                                "given one"),
            std::string::npos)
      << apart.reason();
  EXPECT_TRUE(checked({{"C7", {320.0f, 120.0f}, cect::LandmarkSource::kGivenClick, true}}).trusted) << "confirmed";
  EXPECT_TRUE(checked({{"C7", {320.0f, 105.0f}, cect::LandmarkSource::kGivenClick}}).trusted);
  // L4 55 rows (110 mm) above the waist's: refused; 20 rows (40 mm, within 3 x hypot(0.075, 0.012)) agrees.
  EXPECT_NE(checked({{"L4", {320.0f, 245.0f}, cect::LandmarkSource::kGivenService}})
                .reason()
                .find("L4 measured at the waist"),
            std::string::npos);
  EXPECT_TRUE(checked({{"L4", {320.0f, 280.0f}, cect::LandmarkSource::kGivenService}}).trusted);
  // A C7 the pair did not measure at a neck's base has nothing to disagree with.
  cect::BackLandmarks top = back();
  top.c7.detail = cect::kFromBackTop;
  ASSERT_EQ(cect::applyGivenLandmarks(&top, {{"C7", {320.0f, 120.0f}, cect::LandmarkSource::kGivenClick}}), "");
  EXPECT_EQ(cect::checkLayout(top, model(), kScale).reason().find("confirm"), std::string::npos);
}

TEST(GivenLandmarks, AClickIsNamedByTheNearestLevelOnlyWhenThatIsUnambiguous) {
  // C7 at row 100, T7 at 172, L4 at 300 on the midline x = 320.
  const cect::BackLandmarks l = back();
  EXPECT_EQ(cect::nameClick(l, model(), {322.0f, 104.0f}).name, "C7");
  EXPECT_EQ(cect::nameClick(l, model(), {318.0f, 295.0f}).name, "L4");
  // Halfway between C7 and T7: refused, naming both.
  const cect::ClickName between = cect::nameClick(l, model(), {320.0f, 136.0f});
  EXPECT_EQ(between.name, "");
  EXPECT_NE(between.problem.find("about as near C7 (36 px) as T7 (36 px)"), std::string::npos) << between.problem;
  EXPECT_NE(cect::nameClick(cect::BackLandmarks(), model(), {320.0f, 104.0f}).problem.find("no layout"),
            std::string::npos);
}

TEST(LayoutCheck, ABackWithoutDepthOnItsMidlineIsNotTrustedInStereo) {
  // The pair's 3D has no depth on the midline (a back found in part): its size cannot be checked, which is no pass.
  const cect::PixelScale none = [](const cv::Point2f&) { return std::numeric_limits<double>::quiet_NaN(); };
  const cect::LayoutCheck c = cect::checkLayout(back(), model(), none);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("C7 -> L4 not measured: too few points of the midline between them have a depth"),
            std::string::npos)
      << c.reason();
  // A photo has no 3D at all (no scale function): its proportions alone decide.
  EXPECT_TRUE(cect::checkLayout(back(), model(), cect::PixelScale()).trusted);
}

TEST(LayoutCheck, AnAdultBackInProportionIsTrusted) {
  const cect::LayoutCheck c = cect::checkLayout(back(), model(), kScale);
  EXPECT_TRUE(c.trusted) << c.reason();
  EXPECT_EQ(c.reason(), "");
  EXPECT_NEAR(c.length_m, 0.40, 1e-9);
  EXPECT_NEAR(c.shoulder_width_m, 0.36, 1e-9);
  EXPECT_NEAR(c.length_per_shoulder_width, 200.0 / 180.0, 1e-9);
  EXPECT_NEAR(c.shoulder_below_c7, 30.0 / 200.0, 1e-9);
}

TEST(LayoutCheck, ASqueezedLayoutIsNotTrustedAndSaysWhy) {
  // L4 100 rows below C7: 0.2 m, and 0.56 shoulder widths.
  const cect::LayoutCheck c = cect::checkLayout(back(200.0), model(), kScale);
  EXPECT_FALSE(c.trusted);
  ASSERT_EQ(c.problems.size(), 2u) << c.reason();
  EXPECT_EQ(c.problems[0], "C7 -> L4 0.200 m is outside 0.280..0.580 m");
  EXPECT_EQ(c.problems[1], "C7 -> L4 over the shoulder width 0.56 is outside 0.79..1.65");
}

TEST(LayoutCheck, WithoutAScaleOnlyTheProportionsAreChecked) {
  const cect::PixelScale none;
  const cect::LayoutCheck ok = cect::checkLayout(back(), model(), none);
  EXPECT_TRUE(ok.trusted) << ok.reason();
  EXPECT_TRUE(std::isnan(ok.length_m));
  const cect::LayoutCheck squeezed = cect::checkLayout(back(200.0), model(), none);
  EXPECT_FALSE(squeezed.trusted);
  EXPECT_NE(squeezed.reason().find("layout not trusted: C7 -> L4 over the shoulder width 0.56 is outside 0.79..1.65"),
            std::string::npos)
      << squeezed.reason();
}

TEST(LayoutCheck, ProportionsTheModelImposedAreNotCheckedAgainstThemselves) {
  // L4 inferred from the shoulder width (no waist): the length over the shoulder width is the model's by
  // construction, so only the sizes are checked; C7 from the shoulder line likewise.
  cect::BackLandmarks l = back(200.0);
  l.l4.source = cect::LandmarkSource::kInferred;
  l.l4.detail = cect::kFromShoulderWidth;
  l.c7.source = cect::LandmarkSource::kInferred;
  l.c7.detail = cect::kFromShoulderLine;
  const cect::AcupointModel m = model();
  const cect::LayoutCheck c =
      cect::checkLayout(l, m, cect::PixelScale(), rules(false, false));  // the proportions alone here
  EXPECT_TRUE(c.trusted) << c.reason();
  EXPECT_TRUE(std::isnan(c.length_per_shoulder_width));
  EXPECT_TRUE(std::isnan(c.shoulder_below_c7));
  // ... but a given L4 is the therapist's, and the proportion is checked again.
  l.l4.source = cect::LandmarkSource::kGiven;
  EXPECT_FALSE(cect::checkLayout(l, m, cect::PixelScale(), rules(false, false)).trusted);
}

TEST(LayoutCheck, AC7NotMeasuredAtANecksBaseIsNotTrustedUnlessGiven) {
  cect::BackLandmarks top = back();
  top.c7.detail = cect::kFromBackTop;  // the back's top taken for the neck's base
  const cect::LayoutCheck c = cect::checkLayout(top, model(), kScale);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("C7 not measured: no neck's base in view, the back's top taken for it; give C7"),
            std::string::npos)
      << c.reason();
  cect::BackLandmarks shoulders = top;
  shoulders.c7.source = cect::LandmarkSource::kInferred;
  shoulders.c7.detail = cect::kFromShoulderLine;
  EXPECT_NE(
      cect::checkLayout(shoulders, model(), kScale).reason().find("C7 not measured: taken from the shoulder line"),
      std::string::npos);
  top.c7.source = cect::LandmarkSource::kGiven;  // a therapist's C7
  EXPECT_TRUE(cect::checkLayout(top, model(), kScale).trusted);
  EXPECT_TRUE(cect::checkLayout(shoulders, model(), kScale, rules(false, true)).trusted);
}

TEST(LayoutCheck, AnL4InferredFromTheShoulderWidthIsNotTrustedUnlessGiven) {
  cect::BackLandmarks l = back();
  l.l4.source = cect::LandmarkSource::kInferred;
  l.l4.detail = cect::kFromShoulderWidth;  // arms along the flanks: no waist, L4 from C7 and the shoulder width
  const cect::LayoutCheck c = cect::checkLayout(l, model(), kScale);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("L4 not measured: no waist in view, only inferred from C7 and the shoulder width; give L4"),
            std::string::npos)
      << c.reason();
  EXPECT_TRUE(cect::checkLayout(l, model(), kScale, rules(true, false)).trusted) << "the rule off";
  l.l4.source = cect::LandmarkSource::kGiven;  // a therapist's L4, or a skin marker
  EXPECT_TRUE(cect::checkLayout(l, model(), kScale).trusted) << cect::checkLayout(l, model(), kScale).reason();
}

TEST(LayoutCheck, WithC7AndL4GivenTheShoulderLineIsNotChecked) {
  // Arms raised beside the head: the "shoulder line" 0.6 m wide and far below C7; with both landmarks given the
  // cun comes from C7 -> L4 and the shoulder line is not used.
  cect::BackLandmarks l = back();
  l.shoulder_width = 300;
  l.shoulder_row = 230;
  EXPECT_FALSE(cect::checkLayout(l, model(), kScale).trusted);
  l.c7.source = l.l4.source = cect::LandmarkSource::kGiven;
  const cect::LayoutCheck c = cect::checkLayout(l, model(), kScale);
  EXPECT_TRUE(c.trusted) << c.reason();
  // ... but the length still is.
  l.l4.body = cv::Point2f(320.0f, 180.0f);
  EXPECT_NE(cect::checkLayout(l, model(), kScale).reason().find("C7 -> L4 0.160 m"), std::string::npos);
}

TEST(LayoutCheck, TheShoulderLineFarBelowC7IsNotTrusted) {
  cect::BackLandmarks l = back();
  l.shoulder_row = 220;  // 0.6 of C7 -> L4 below C7: the "shoulders" are the waist's widening or the arms
  const cect::LayoutCheck c = cect::checkLayout(l, model(), kScale);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("the shoulder line below C7 (of C7 -> L4) 0.60 is outside -0.10..0.45"), std::string::npos)
      << c.reason();
}

TEST(LayoutCheck, AChildSizedOrGiantBackIsNotTrusted) {
  const cect::PixelScale small = [](const cv::Point2f&) { return 0.001; },
                         big = [](const cv::Point2f&) { return 0.004; };
  EXPECT_NE(cect::checkLayout(back(), model(), small).reason().find("C7 -> L4 0.200 m is outside 0.280..0.580 m"),
            std::string::npos);
  EXPECT_NE(
      cect::checkLayout(back(), model(), big).reason().find("the shoulder width 0.720 m is outside 0.280..0.650 m"),
      std::string::npos);
  // An L4 misread 10 cm toward the feet on an adult back: 0.60 m is longer than a 2.10 m client's C7 -> L4.
  EXPECT_NE(cect::checkLayout(back(400.0), model(), kScale).reason().find("C7 -> L4 0.600 m is outside 0.280..0.580 m"),
            std::string::npos)
      << cect::checkLayout(back(400.0), model(), kScale).reason();
  cect::BackLandmarks none;
  none.reason = "mask is empty";
  EXPECT_EQ(cect::checkLayout(none, model(), kScale).reason(), "layout not trusted: no landmarks: mask is empty");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

TEST(LayoutCheck, AStaleGivenLandmarkIsNotTrusted) {
  cect::BackLandmarks l = back();
  cect::GivenLandmark c7("C7", {320.0f, 100.0f}, cect::LandmarkSource::kGivenClick);
  c7.stale = "the back moved 30 mm and turned 0.0 deg since it was given (more than 20 mm or 5 deg)";
  ASSERT_EQ(cect::applyGivenLandmarks(&l, {c7}), "");
  const cect::LayoutCheck c = cect::checkLayout(l, model(), kScale);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("the given C7 (clicked) is stale: the back moved 30 mm"), std::string::npos) << c.reason();
}
