// Unit tests of the acupoint tracker and the pixel queries (massage_cell/cect/tracker.h). main() is in
// test_temporal_filter.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "massage_cell/cect/tracker.h"

namespace cect = massage_cell::cect;
namespace camera = massage_cell::camera;

namespace {

cect::AcupointModel model() {
  return cect::loadAcupointModel(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/acupoints.yaml");
}

/// Every point of the model placed at pixel (10 + i, 20) and, for those in `measured`, localised at `z`.
cect::LocatedAcupoints located(const cect::AcupointModel& m, const std::vector<std::size_t>& measured, double z) {
  cect::LocatedAcupoints l;
  l.valid = true;
  l.points.resize(m.points.size());
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    cect::LocatedAcupoint& p = l.points[i];
    p.name = m.points[i].name;
    p.region = m.points[i].region;
    p.placed = true;
    p.rectified = p.raw = cv::Point2f(10.0f + static_cast<float>(i), 20.0f);
    p.reason = "not localised: no seed near it";
  }
  for (std::size_t i : measured) {
    cect::LocatedAcupoint& p = l.points[i];
    p.valid = true;
    p.reason.clear();
    p.point.valid = true;
    p.point.position = Eigen::Vector3d(0.01 * static_cast<double>(i), 0.0, z);
    p.point.covariance = Eigen::Matrix3d::Identity() * 1e-6;
    p.layout_covariance = Eigen::Matrix3d::Identity() * 4e-6;
  }
  return l;
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST(AcupointTracker, MeasuredPointsAreValidWithTheirWholeUncertainty) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  const camera::Decimation half(cv::Size(640, 480), 2);
  const cect::TrackerUpdate& u = tracker.update(located(m, {0, 3}, 0.9), 100.0, half);
  ASSERT_EQ(u.points.size(), m.points.size());
  EXPECT_TRUE(u.problem.empty());
  EXPECT_EQ(u.measured, 2);
  EXPECT_EQ(u.valid, 2);
  const cect::TrackedAcupoint& p = u.points[3];
  EXPECT_EQ(p.name, m.points[3].name);
  EXPECT_TRUE(p.valid && p.measured && p.accepted);
  EXPECT_TRUE(p.reason.empty()) << p.reason;
  EXPECT_NEAR((p.position - Eigen::Vector3d(0.03, 0.0, 0.9)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(p.covariance(0, 0), 5e-6, 1e-12);            // the matching's and the layout's
  EXPECT_FLOAT_EQ(p.raw.x, (13.0f + 0.5f) * 2.0f - 0.5f);  // the camera's pixel
  EXPECT_FLOAT_EQ(p.rectified.x, 13.0f);                   // the processed image's
  EXPECT_FALSE(u.points[1].valid);
  EXPECT_EQ(u.points[1].reason, "not localised: no seed near it");
}

TEST(AcupointTracker, AnUnmeasuredPointIsHeldForMaxAgeWithTheReason) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  cect::TemporalFilterParams params;
  params.max_age = 1.0;
  tracker.setParams(params);
  tracker.update(located(m, {5}, 0.9), 10.0, {});
  const cect::TrackerUpdate& held = tracker.update(located(m, {}, 0.9), 10.5, {});
  EXPECT_TRUE(held.points[5].valid);
  EXPECT_FALSE(held.points[5].measured);
  EXPECT_TRUE(contains(held.points[5].reason, "no seed near it; estimate from 0.5 s before")) << held.points[5].reason;
  EXPECT_TRUE(tracker.estimate(m.points[5].name, 10.6).valid);
  const cect::TrackerUpdate& gone = tracker.update(located(m, {}, 0.9), 11.2, {});
  EXPECT_FALSE(gone.points[5].valid);
  const cect::TrackedAcupoint old = tracker.estimate(m.points[5].name, 11.2);
  EXPECT_FALSE(old.valid);
  EXPECT_TRUE(contains(old.reason, "no valid estimate of " + m.points[5].name)) << old.reason;
}

TEST(AcupointTracker, APairWithoutABackInvalidatesEveryPoint) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  tracker.update(located(m, {0, 1, 2}, 0.9), 1.0, {});
  cect::LocatedAcupoints none;
  none.reason = "no usable view of the back: the skin region is too small";
  const cect::TrackerUpdate& u = tracker.update(none, 1.1, {});
  EXPECT_EQ(u.problem, none.reason);
  EXPECT_EQ(u.valid, 0);
  for (const auto& p : u.points) {
    EXPECT_FALSE(p.valid) << p.name;
    EXPECT_EQ(p.reason, none.reason) << p.name;
  }
}

TEST(AcupointTracker, AnOutlierIsRejectedAndSaysHowFar) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  tracker.update(located(m, {2}, 0.9), 1.0, {});
  const cect::TrackerUpdate& u = tracker.update(located(m, {2}, 0.95), 1.1, {});  // 5 cm away: beyond the 1 cm gate
  EXPECT_TRUE(u.points[2].measured);
  EXPECT_FALSE(u.points[2].accepted);
  EXPECT_TRUE(u.points[2].valid);  // the estimate stands
  EXPECT_NEAR(u.points[2].position.z(), 0.9, 1e-12);
  EXPECT_TRUE(contains(u.points[2].reason, "rejected as an outlier (5 cm from the estimate)")) << u.points[2].reason;
  EXPECT_EQ(tracker.rejectedOutliers(), 1);
}

TEST(AcupointTracker, StampsGoingBackResetTheEstimates) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  tracker.update(located(m, {0}, 0.9), 50.0, {});
  const cect::TrackerUpdate& u = tracker.update(located(m, {1}, 0.8), 2.0, {});
  EXPECT_TRUE(u.reset);
  EXPECT_FALSE(u.points[0].valid);
  EXPECT_TRUE(u.points[1].valid);
  EXPECT_FALSE(tracker.update(located(m, {1}, 0.8), 2.1, {}).reset);
}

TEST(AcupointTracker, EstimatesAreQueriedByName) {
  const cect::AcupointModel m = model();
  cect::AcupointTracker tracker(m);
  EXPECT_TRUE(contains(tracker.estimate(m.points[0].name, 0.0).reason, "no stereo pair analysed yet"));
  const cect::TrackedAcupoint unknown = tracker.estimate("XX99", 0.0);
  EXPECT_FALSE(unknown.valid);
  EXPECT_TRUE(contains(unknown.reason, "unknown acupoint 'XX99' (known: " + m.points[0].name)) << unknown.reason;
  tracker.update(located(m, {4}, 0.9), 7.0, {});
  const cect::TrackedAcupoint e = tracker.estimate(m.points[4].name, 7.5);
  ASSERT_TRUE(e.valid) << e.reason;
  EXPECT_DOUBLE_EQ(e.stamp, 7.0);
  const cect::TrackedAcupoint stale = tracker.estimate(m.points[4].name, 9.5);  // max_age 2 s by default
  EXPECT_FALSE(stale.valid);
  EXPECT_TRUE(contains(stale.reason, "s old (max_age 2 s)")) << stale.reason;
  EXPECT_THROW(cect::AcupointTracker(cect::AcupointModel{}), std::invalid_argument);
  cect::TemporalFilterParams bad;
  bad.alpha = 0.0;
  EXPECT_THROW(tracker.setParams(bad), std::invalid_argument);
  EXPECT_DOUBLE_EQ(tracker.params().alpha, cect::TemporalFilterParams{}.alpha);
}

TEST(LocalizePixels, WithoutAnAnalysedPairEveryPixelSaysSo) {
  const cect::PixelPoints none = cect::localizePixels(nullptr, {}, {{1.0, 2.0}, {NAN, 3.0}});
  EXPECT_FALSE(none.success);
  EXPECT_EQ(none.message, "no stereo pair analysed yet");
  ASSERT_EQ(none.points.size(), 2u);
  for (const auto& p : none.points) {
    EXPECT_FALSE(p.valid);
    EXPECT_EQ(p.reason, none.message);
  }
}

TEST(DrawAcupoints, TheLayoutsLandmarksAreDrawnWithTheirSources) {
  // A grey pair (no back: the plain left view is drawn) and the layout's landmarks: a given C7 in magenta, a measured
  // L4 in cyan, each a cross with its name and source to its left; the view scaled by 3 to 960 px.
  camera::CameraCalibration c;
  c.width = 320;
  c.height = 240;
  c.D = {0, 0, 0, 0, 0};
  c.K = {250, 0, 160, 0, 250, 120, 0, 0, 1};
  c.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.P = {250, 0, 160, 0, 0, 250, 120, 0, 0, 0, 1, 0};
  camera::CameraCalibration r = c;
  r.P[3] = -25.0;
  const cv::Mat grey(240, 320, CV_8UC3, cv::Scalar(90, 90, 90));
  const cect::CectFrame frame = cect::CectFrame::analyse(grey, grey, camera::StereoModel(c, r), {});
  const std::vector<cect::LayoutLandmark> landmarks{
      {{"C7", cect::LandmarkSource::kGivenClick}, {200.0f, 40.0f}},
      {{"L4", cect::LandmarkSource::kMeasured, cect::kFromWaist}, {200.0f, 200.0f}}};
  const cv::Mat image = cect::drawAcupoints(frame, {}, 960, landmarks);
  ASSERT_EQ(image.cols, 960);
  // Magenta-ish (blue and red, no green) and cyan-ish (blue and green, no red) pixels around a point; anti-aliased
  // text and lines blend into the grey, so by their hue.
  auto count = [](const cv::Mat& img, const cv::Point& at, int radius, bool magenta) {
    int n = 0;
    for (int y = at.y - radius; y <= at.y + radius; ++y)
      for (int x = at.x - radius; x <= at.x + radius; ++x) {
        const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
        const int other = magenta ? p[1] : p[2], shared = magenta ? p[2] : p[1];
        n += p[0] > 140 && shared > 140 && other < 110;
      }
    return n;
  };
  EXPECT_GT(count(image, {601, 121}, 6, true), 10) << "C7's cross";
  EXPECT_GT(count(image, {601, 601}, 6, false), 10) << "L4's cross";
  EXPECT_EQ(count(image, {601, 601}, 6, true), 0) << "L4 is not drawn as given";
  // The name to the left of the cross ("C7 given (clicked)", ~150 px wide at this size), none to its right.
  EXPECT_GT(count(image, {520, 121}, 20, true), 20) << "C7's name";
  EXPECT_EQ(count(image, {700, 121}, 20, true), 0) << "nothing to the right";
  const cv::Mat none = cect::drawAcupoints(frame, {}, 960);
  EXPECT_EQ(count(none, {601, 121}, 6, true) + count(none, {520, 121}, 20, true), 0) << "no landmarks, none drawn";
}
