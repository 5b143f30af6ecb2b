// cect/evaluation.h: the levels, the spine line and the layout scored against a known back, and the summaries'
// counting of refused and wrongly trusted pairs. A flat back 1 m below a rectified camera (f 500 px: 2 mm a pixel),
// the body along the image's columns, head up.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "../../src/cect/stats_detail.h"  // the library's private statistics (one quantile for CECT and its tools)
#include "massage_cell/cect/evaluation.h"

using namespace massage_cell;

namespace {

constexpr double kF = 500.0, kZ = 1.0;
constexpr int kW = 640, kH = 480;
constexpr double kCx = (kW - 1) / 2.0, kCy = (kH - 1) / 2.0;
constexpr double kMmPerPx = 1000.0 * kZ / kF;

camera::StereoModel geometry() {
  camera::CameraCalibration l;
  l.width = kW;
  l.height = kH;
  l.D.assign(5, 0.0);
  l.K = {kF, 0, kCx, 0, kF, kCy, 0, 0, 1};
  l.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  l.P = {kF, 0, kCx, 0, 0, kF, kCy, 0, 0, 0, 1, 0};
  camera::CameraCalibration r = l;
  r.P[3] = -kF * 0.1;
  return camera::StereoModel(l, r);
}

Eigen::Vector3d onBack(double u, double v) { return {(u - kCx) / kF * kZ, (v - kCy) / kF * kZ, kZ}; }

cect::AcupointModel model() {
  cect::AcupointModel m;
  m.level_fraction = {{"C7", 0.0}, {"T7", 0.5}, {"L4", 1.0}};
  m.points = {{"GV14", "C7", 0.0, "midline"}, {"GV9", "T7", 0.0, "midline"}, {"GV3", "L4", 0.0, "midline"}};
  return m;
}

/// The true back: C7, T7, L4 on the column kCx at rows 100, 200, 300; a plane at kZ wherever `surface` is on.
cect::BackTruth truth(bool surface = true) {
  cect::BackTruth t;
  t.levels = {{"C7", onBack(kCx, 100)}, {"T7", onBack(kCx, 200)}, {"L4", onBack(kCx, 300)}};
  for (int v = 80; v <= 320; v += 20) t.midline.push_back(onBack(kCx, v));
  t.acupoints_in_view = {{"GV14", t.levels["C7"]}, {"GV9", t.levels["T7"]}, {"GV3", t.levels["L4"]}};
  if (surface)
    t.surface = [](const cv::Point2f& q, Eigen::Vector3d* p) {
      *p = onBack(q.x, q.y);
      return true;
    };
  else
    t.surface = [](const cv::Point2f&, Eigen::Vector3d*) { return false; };
  return t;
}

/// A result whose midline lies `dx` px to the image's right of the true one and whose C7 / L4 rows are `c7_row` /
/// `l4_row`; each point placed at its level's pixel.
cect::LocatedAcupoints result(double dx, double c7_row, double l4_row, bool published) {
  cect::LocatedAcupoints r;
  r.valid = published;
  if (!published) r.reason = "layout not trusted: test";
  cect::BackLandmarks& lm = r.landmarks;
  lm.valid = true;
  for (int y = 60; y <= 360; ++y) {
    lm.midline.emplace_back(static_cast<float>(kCx + dx), static_cast<float>(y));
    lm.lateral.emplace_back(-1.0f, 0.0f);
  }
  lm.c7.body = cv::Point2f(static_cast<float>(kCx + dx), static_cast<float>(c7_row));
  lm.l4.body = cv::Point2f(static_cast<float>(kCx + dx), static_cast<float>(l4_row));
  const cect::AcupointModel m = model();
  for (const cect::AcupointSpec& spec : m.points) {
    cect::LocatedAcupoint a;
    a.name = spec.name;
    a.placed = true;
    a.rectified = cect::levelPixel(lm, m, spec.level);
    a.valid = published;
    r.points.push_back(a);
  }
  return r;
}

const cect::LevelError& level(const cect::PairScore& s, const std::string& name) {
  for (const cect::LevelError& e : s.levels)
    if (e.level == name) return e;
  throw std::runtime_error("no level " + name);
}

TEST(CectEvaluation, LevelsAlongAndAcrossTheBody) {
  // C7 5 px toward the feet, L4 15 px toward the head, so T7 (halfway) 5 px toward the head; the midline 10 px to
  // the image's right, i.e. toward the subject's right (across < 0).
  const cect::PairScore s = cect::scorePair(result(10.0, 105.0, 285.0, true), model(), geometry(), truth());
  ASSERT_EQ(s.levels.size(), 3u);
  EXPECT_TRUE(s.landmarks);
  EXPECT_TRUE(s.published);
  EXPECT_NEAR(level(s, "C7").along_mm, 5 * kMmPerPx, 1e-6);
  EXPECT_NEAR(level(s, "T7").along_mm, -5 * kMmPerPx, 1e-6);
  EXPECT_NEAR(level(s, "L4").along_mm, -15 * kMmPerPx, 1e-6);
  for (const cect::LevelError& e : s.levels) {
    EXPECT_TRUE(e.scored) << e.level;
    EXPECT_NEAR(e.across_mm, -10 * kMmPerPx, 1e-6) << e.level;
  }
  EXPECT_NEAR(s.worst_level_mm, 15 * kMmPerPx, 1e-6);
  EXPECT_NEAR(s.midline_across_mm, 10 * kMmPerPx, 1e-6);
  EXPECT_EQ(s.in_view, 3);
  EXPECT_EQ(s.valid_in_view, 3);
  ASSERT_EQ(s.layout_mm.size(), 3u);
  EXPECT_NEAR(s.layout_mm.at("GV14"), std::hypot(5.0, 10.0) * kMmPerPx, 1e-6);
  EXPECT_FALSE(s.wronglyTrusted());
}

TEST(CectEvaluation, PixelsOffTheSurfaceAreScoredOnTheirRay) {
  const cect::PairScore on = cect::scorePair(result(-4.0, 95.0, 310.0, true), model(), geometry(), truth(true));
  const cect::PairScore off = cect::scorePair(result(-4.0, 95.0, 310.0, true), model(), geometry(), truth(false));
  for (std::size_t i = 0; i < on.levels.size(); ++i) {
    EXPECT_NEAR(on.levels[i].along_mm, off.levels[i].along_mm, 1e-6) << on.levels[i].level;
    EXPECT_NEAR(on.levels[i].across_mm, off.levels[i].across_mm, 1e-6) << on.levels[i].level;
  }
  EXPECT_NEAR(off.midline_across_mm, 4 * kMmPerPx, 1e-6);
}

TEST(CectEvaluation, AFarLevelPublishedIsWronglyTrustedRefusedIsNot) {
  // L4 25 px (50 mm) toward the head.
  const cect::PairScore trusted = cect::scorePair(result(0.0, 100.0, 275.0, true), model(), geometry(), truth());
  const cect::PairScore refused = cect::scorePair(result(0.0, 100.0, 275.0, false), model(), geometry(), truth());
  EXPECT_NEAR(trusted.worst_level_mm, 50.0, 1e-6);
  EXPECT_TRUE(trusted.wronglyTrusted());
  EXPECT_FALSE(refused.wronglyTrusted());
  EXPECT_EQ(refused.valid_in_view, 0);

  const cect::PairScore good = cect::scorePair(result(0.0, 102.0, 298.0, true), model(), geometry(), truth());
  cect::LocatedAcupoints none;
  none.reason = "no landmarks of the back: test";
  const cect::PairScore nothing = cect::scorePair(none, model(), geometry(), truth());
  EXPECT_FALSE(nothing.landmarks);
  EXPECT_TRUE(std::isnan(nothing.worst_level_mm));

  const cect::ScoreSummary sum = cect::summarise({trusted, refused, good, nothing});
  EXPECT_EQ(sum.pairs, 4);
  EXPECT_EQ(sum.published, 2);
  EXPECT_EQ(sum.refused, 2);
  EXPECT_EQ(sum.refused_wrong, 1);  // `refused` was indeed 50 mm off; `nothing` had no landmarks to judge
  EXPECT_EQ(sum.wrongly_trusted, 1);
  EXPECT_EQ(sum.levels.at("L4").count, 2);
  EXPECT_NEAR(sum.levels.at("L4").mean, 0.5 * (50.0 + 4.0), 1e-6);
  EXPECT_NEAR(sum.levels.at("L4").max, 50.0, 1e-6);
  EXPECT_EQ(sum.in_view, 6);
  EXPECT_EQ(sum.valid_in_view, 6);
  EXPECT_DOUBLE_EQ(sum.placedShare(), 1.0);
}

TEST(CectEvaluation, ASpineLineFarAcrossPublishedIsWronglyTrustedRefusedIsRightlyRefused) {
  // The levels at their true rows, the spine line 25 px (50 mm) to the side: no level is off along the body.
  const cect::PairScore trusted = cect::scorePair(result(25.0, 100.0, 300.0, true), model(), geometry(), truth());
  const cect::PairScore refused = cect::scorePair(result(25.0, 100.0, 300.0, false), model(), geometry(), truth());
  EXPECT_NEAR(trusted.worst_level_mm, 0.0, 1e-6);
  EXPECT_NEAR(trusted.midline_across_mm, 50.0, 1e-6);
  EXPECT_TRUE(trusted.farOff());
  EXPECT_TRUE(trusted.wronglyTrusted());
  EXPECT_FALSE(refused.wronglyTrusted());
  // 15 px (30 mm) across is within the limit.
  const cect::PairScore near = cect::scorePair(result(-15.0, 100.0, 300.0, true), model(), geometry(), truth());
  EXPECT_NEAR(near.midline_across_mm, 30.0, 1e-6);
  EXPECT_FALSE(near.wronglyTrusted());

  const cect::ScoreSummary sum = cect::summarise({trusted, refused, near});
  EXPECT_EQ(sum.wrongly_trusted, 1);
  EXPECT_EQ(sum.refused_wrong, 1);
}

TEST(CectEvaluation, SpreadIsOfMagnitudesWithTheNearestRankP95) {
  std::vector<double> v;
  for (int i = 1; i <= 20; ++i) v.push_back(i % 2 ? -i : i);
  v.push_back(std::numeric_limits<double>::quiet_NaN());
  const cect::Spread s = cect::spreadOf(v);
  EXPECT_EQ(s.count, 20);
  EXPECT_DOUBLE_EQ(s.mean, 10.5);
  EXPECT_DOUBLE_EQ(s.p95, 19.0);
  EXPECT_DOUBLE_EQ(s.max, 20.0);
  EXPECT_TRUE(std::isnan(cect::spreadOf({}).mean));
}

}  // namespace

TEST(CectStatistics, OneQuantileWithEachCallersIndexConvention) {
  using cect::detail::quantile;
  using Index = cect::detail::QuantileIndex;
  const std::vector<double> v{5, 1, 4, std::nan(""), 2, 3};  // the NaN is left out: n = 5
  EXPECT_EQ(quantile(v, 0.95, Index::kNearestRank), 5.0);    // ceil(0.95 * 5) - 1 = 4
  EXPECT_EQ(quantile(v, 0.95, Index::kFloorOfSpan), 4.0);    // floor(0.95 * 4) = 3
  EXPECT_EQ(quantile(v, 0.95, Index::kRoundedOfSpan), 5.0);  // floor(3.8 + 0.5) = 4
  EXPECT_EQ(quantile(v, 0.4, Index::kNearestRank), 2.0);     // ceil(2) - 1 = 1
  EXPECT_EQ(quantile(v, 0.4, Index::kRoundedOfSpan), 3.0);   // floor(1.6 + 0.5) = 2
  EXPECT_EQ(quantile(v, 0.0, Index::kNearestRank), 1.0);     // clamped to the first
  EXPECT_EQ(quantile(v, 1.0, Index::kFloorOfSpan), 5.0);
  EXPECT_TRUE(std::isnan(quantile(std::vector<double>{std::nan("")}, 0.5)));
  EXPECT_EQ(cect::detail::median(v), 3.0);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
