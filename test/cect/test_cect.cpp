// CECT core: stereo geometry, foundational correspondences on synthetic
// contours, barycentric transfer under an affine warp, rendered backs (raw and
// rectified), bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numeric>
#include <random>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "massage_cell/cect/cect.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"

using namespace massage_cell;

namespace {

/// A rectified pair's calibration: fx = fy = f, principal point at the centre.
std::pair<camera::CameraCalibration, camera::CameraCalibration> rectifiedInfo(int w, int h, double f, double b) {
  camera::CameraCalibration l;
  l.width = w;
  l.height = h;
  l.D.assign(5, 0.0);
  l.K = {f, 0, (w - 1) / 2.0, 0, f, (h - 1) / 2.0, 0, 0, 1};
  l.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  l.P = {f, 0, (w - 1) / 2.0, 0, 0, f, (h - 1) / 2.0, 0, 0, 0, 1, 0};
  camera::CameraCalibration r = l;
  r.P[3] = -f * b;
  return {l, r};
}

/// Skin-coloured shape with faint texture on a pale bluish sheet; the right
/// view is the left one warped by the affine disparity d(x, y) = a x + b y + c
/// (a plane seen by a rectified pair), so x_r = x - d(x, y).
struct AffineScene {
  cv::Mat left, right;
  double a = 0.02, b = -0.015, c = 30.0;
  double disparity(double x, double y) const { return a * x + b * y + c; }
};

AffineScene makeAffineScene(int w, int h, bool u_shape) {
  AffineScene s;
  cv::Mat mask = cv::Mat::zeros(h, w, CV_8U);
  cv::ellipse(mask, cv::Point(w / 2, h / 2), cv::Size(w / 4, h / 3), 0, 0, 360, cv::Scalar(255), -1);
  if (u_shape) {
    // Two arms reaching up: rows near the top cross the contour four times.
    cv::rectangle(mask, cv::Rect(w / 4 - 10, h / 8, 30, h / 2), cv::Scalar(255), -1);
    cv::rectangle(mask, cv::Rect(3 * w / 4 - 20, h / 8, 30, h / 2), cv::Scalar(255), -1);
  }
  cv::GaussianBlur(mask, mask, cv::Size(0, 0), 1.0);
  cv::Mat noise(h, w, CV_32F);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 12.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.0);
  cv::Mat tex(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float m = mask.at<std::uint8_t>(y, x) / 255.0f;
      const float n = noise.at<float>(y, x);
      const cv::Vec3f skin(110 + n, 140 + n, 195 + n), sheet(225 + 0.3f * n, 220 + 0.3f * n, 212 + 0.3f * n);
      tex.at<cv::Vec3f>(y, x) = m * skin + (1 - m) * sheet;
    }
  tex.convertTo(s.left, CV_8UC3);
  cv::Mat mapx(h, w, CV_32F), mapy(h, w, CV_32F);
  // right(x_r, y) = left(x_l, y) with x_r = x_l - d(x_l, y): solve for x_l.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double xl = (x + s.b * y + s.c) / (1.0 - s.a);
      mapx.at<float>(y, x) = static_cast<float>(xl);
      mapy.at<float>(y, x) = static_cast<float>(y);
    }
  cv::remap(s.left, s.right, mapx, mapy, cv::INTER_CUBIC, cv::BORDER_REPLICATE);
  return s;
}

struct Rendered {
  sim::StereoPairModel pair;
  sim::StereoFrame frame;
};

/// `specular` < 0: the skin's sheen as modelled; otherwise its Blinn-Phong weight.
Rendered renderBack(bool rectified, int subject = 0, int w = 640, int h = 480, double fx = 500, float specular = -1.0f,
                    sim::LightPreset light = sim::LightPreset::kTopCentre) {
  const sim::BackModel back(sim::BodyParameters::subject(subject));
  sim::Scene scene = sim::makeBackScene(back, 1);
  if (specular >= 0.0f)
    for (auto& m : scene.meshes) m.material.specular = specular;
  const sim::Renderer renderer(scene);
  sim::RigParameters rig;
  rig.width = w;
  rig.height = h;
  rig.fx = fx;
  rig.rectified = rectified;
  Rendered r;
  r.pair = sim::makeStereoPair(rig);
  sim::RenderOptions ro;
  ro.supersample = 1;
  r.frame = sim::renderStereoFrame(renderer, r.pair, sim::Lighting::preset(light), ro);
  return r;
}

/// The same pair analysed twice: with `on`, and with `off` (one feature
/// switched off); both frames must be valid.
struct OnOff {
  cect::CectFrame on, off;
};
OnOff analyseOnOff(const Rendered& r, const cect::CectParams& on, const cect::CectParams& off) {
  const camera::StereoModel g(r.pair.left_info, r.pair.right_info);
  OnOff out{cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, on),
            cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, off)};
  EXPECT_TRUE(out.on.valid()) << out.on.reason();
  EXPECT_TRUE(out.off.valid()) << out.off.reason();
  return out;
}

}  // namespace

TEST(StereoModelOnRenderedPairs, RawPairRoundTripsAndFundamentalMatrix) {
  sim::RigParameters rig;
  rig.rectified = false;
  const sim::StereoPairModel pair = sim::makeStereoPair(rig);
  const camera::StereoModel g(pair.left_info, pair.right_info);
  EXPECT_FALSE(g.identity());
  EXPECT_NEAR(g.baseline(), 0.10, 1e-6);
  const Eigen::Matrix3d F = g.fundamental();
  const Eigen::Matrix<double, 3, 4> Pl = pair.left.projectionMatrix(), Pr = pair.right.projectionMatrix();
  const Eigen::Isometry3d left_from_world = pair.left.world_from_camera.inverse();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d pw(-0.27 + u(rng), u(rng), 0.1 + 0.5 * u(rng));
    const Eigen::Vector3d xl = Pl * pw.homogeneous(), xr = Pr * pw.homogeneous();
    EXPECT_NEAR((xr / xr.z()).dot(F * (xl / xl.z())), 0.0, 1e-6) << "epipolar constraint";
    // Distorted raw pixel -> rectified -> triangulate == the point.
    Eigen::Vector2d raw;
    ASSERT_TRUE(pair.left.project(pw, &raw));
    const cv::Point2f rect = g.toRectified(cv::Point2f(static_cast<float>(raw.x()), static_cast<float>(raw.y())));
    const cv::Point2f back = g.toRaw(rect);
    EXPECT_NEAR(back.x, raw.x(), 1e-3);
    EXPECT_NEAR(back.y, raw.y(), 1e-3);
    const Eigen::Vector3d p_left = left_from_world * pw;
    const Eigen::Vector3d proj = g.project(p_left);
    EXPECT_NEAR(proj.x(), rect.x, 1e-3);
    EXPECT_NEAR(proj.y(), rect.y, 1e-3);
    EXPECT_LT((g.triangulate(proj.x(), proj.y(), proj.z()) - p_left).norm(), 1e-6);
  }
}

TEST(StereoModelOnRenderedPairs, RejectsBadCalibrations) {
  auto [l, r] = rectifiedInfo(320, 240, 250, 0.1);
  camera::CameraCalibration none = l;
  none.K = {};
  EXPECT_THROW(camera::StereoModel(none, r), std::invalid_argument);
  camera::CameraCalibration wrong = r;
  wrong.P[3] = 25.0;  // right camera on the left
  EXPECT_THROW(camera::StereoModel(l, wrong), std::invalid_argument);
  camera::CameraCalibration small = r;
  small.width = 160;
  EXPECT_THROW(camera::StereoModel(l, small), std::invalid_argument);
  const camera::StereoModel ok(l, r);
  cv::Mat img(240, 320, CV_8UC3, cv::Scalar(200, 200, 200)), other(200, 320, CV_8UC3);
  EXPECT_THROW(cect::CectFrame::analyse(img, other, ok, {}), std::invalid_argument);
  EXPECT_THROW(cect::CectFrame::analyse(cv::Mat(), img, ok, {}), std::invalid_argument);
  cv::Mat grey(240, 320, CV_8U, cv::Scalar(100));
  EXPECT_THROW(cect::CectFrame::analyse(grey, grey, ok, {}), std::invalid_argument);
  EXPECT_THROW(cect::CectFrame::analyse(img, img, camera::StereoModel(), {}), std::invalid_argument);
}

TEST(Cect, FoundationalCorrespondencesPickTheRightCrossing) {
  // U-shaped region: rows through the arms cross the right contour four
  // times; every foundational correspondence must take the crossing of its
  // own border (a wrong one is off by tens of pixels).
  // (The shape, not a back: the segmentation keeps it whole, arms included.)
  const AffineScene s = makeAffineScene(480, 360, true);
  auto [l, r] = rectifiedInfo(480, 360, 400, 0.1);
  cect::CectParams p;
  p.seed_step = 0;
  p.query_search = 0;
  p.segmentation.trunk.separate_arms = false;
  const cect::CectFrame f = cect::CectFrame::analyse(s.left, s.right, camera::StereoModel(l, r), p);
  ASSERT_TRUE(f.valid()) << f.reason();
  ASSERT_GT(f.foundationalCount(), 80u);
  double worst = 0.0;
  std::vector<double> errors;
  int four_crossing_rows = 0;
  for (const auto& v : f.vertices()) {
    errors.push_back(std::abs(v.disparity - s.disparity(v.left.x, v.left.y)));
    worst = std::max(worst, errors.back());
    if (cect::rowCrossings(f.right().score, v.left.y).size() == 4) ++four_crossing_rows;
  }
  std::sort(errors.begin(), errors.end());
  std::cout << "foundational: " << errors.size() << ", on four-crossing rows " << four_crossing_rows
            << ", median error " << errors[errors.size() / 2] << " px, worst " << worst << " px\n";
  EXPECT_GT(four_crossing_rows, 10) << "the scene must exercise several crossings per row";
  // A wrong crossing is off by an arm's width (>= 30 px); near the arms'
  // rounded corners the border runs at a shallow angle to the rows and the
  // crossing is less precise.
  EXPECT_LT(worst, 2.0) << "foundational disparity error, px: a wrong crossing was taken";
  EXPECT_LT(errors[errors.size() / 2], 0.2) << "sub-pixel crossings";
}

TEST(Cect, BarycentricTransferIsExactUnderAnAffineWarp) {
  const AffineScene s = makeAffineScene(480, 360, false);
  auto [l, r] = rectifiedInfo(480, 360, 400, 0.1);
  cect::CectParams p;
  p.auto_scale = false;  // a flat synthetic shape, not a back: the reference view's pixels as they are
  p.seed_step = 0;       // contour only: the thesis's plain transfer
  p.query_search = 0;    // no matching: transfer alone
  const camera::StereoModel g(l, r);
  const cect::CectFrame f = cect::CectFrame::analyse(s.left, s.right, g, p);
  ASSERT_TRUE(f.valid()) << f.reason();
  double worst = 0.0;
  int n = 0;
  for (int y = 100; y < 260; y += 7)
    for (int x = 160; x < 320; x += 7) {
      const cect::LocalizedPoint q = f.localizeRectified(cv::Point2f(static_cast<float>(x), static_cast<float>(y)));
      if (!q.valid) continue;
      ++n;
      worst = std::max(worst, std::abs(q.disparity - s.disparity(x, y)));
      EXPECT_LT(q.spread, 0.5);
    }
  EXPECT_GT(n, 400);
  EXPECT_LT(worst, 0.25) << "transfer error, px (an affine map is reproduced exactly by barycentric coordinates)";
}

TEST(Cect, BlankSceneAndOffBackPixelsAreReported) {
  auto [l, r] = rectifiedInfo(320, 240, 250, 0.1);
  const camera::StereoModel g(l, r);
  const cv::Mat sheet(240, 320, CV_8UC3, cv::Scalar(225, 220, 212));
  const cect::CectFrame f = cect::CectFrame::analyse(sheet, sheet, g, {});
  EXPECT_FALSE(f.valid());
  EXPECT_FALSE(f.reason().empty());
  const cect::LocalizedPoint q = f.localize(cv::Point2f(160, 120));
  EXPECT_FALSE(q.valid);
  EXPECT_NE(q.reason.find("no valid frame"), std::string::npos) << q.reason;

  const AffineScene s = makeAffineScene(320, 240, false);
  const cect::CectFrame ok = cect::CectFrame::analyse(s.left, s.right, g, {});
  ASSERT_TRUE(ok.valid()) << ok.reason();
  const cect::LocalizedPoint off = ok.localize(cv::Point2f(5, 5));
  EXPECT_FALSE(off.valid);
  EXPECT_NE(off.reason.find("not on the back"), std::string::npos) << off.reason;
  EXPECT_FALSE(ok.localize(cv::Point2f(-3, 5)).valid);
  EXPECT_FALSE(ok.localize(cv::Point2f(1000, 5)).valid);
  EXPECT_FALSE(ok.drawDebug().empty());
}

namespace {

/// Localises random back pixels of a rendered pair; returns errors in mm
/// against the exact surface point and the share of valid answers.
std::vector<double> renderedErrors(const Rendered& r, double* valid_share, const cect::CectParams& params = {},
                                   double* scale = nullptr) {
  const camera::StereoModel g(r.pair.left_info, r.pair.right_info);
  const cect::CectFrame f = cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, params);
  if (scale) *scale = f.scale();
  EXPECT_TRUE(f.valid()) << f.reason();
  std::cout << "CECT " << f.timings().total_ms << " ms, " << f.foundationalCount() << " foundational, "
            << f.vertices().size() << " vertices\n";
  cv::Mat inner = (r.frame.left.labels == sim::kLabelBack) & (r.frame.left_visible > 0);
  cv::erode(inner, inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(17, 17)));
  std::vector<cv::Point> pts;
  cv::findNonZero(inner, pts);
  std::mt19937 rng(11);
  std::shuffle(pts.begin(), pts.end(), rng);
  const Eigen::Isometry3d left_from_world = r.pair.left.world_from_camera.inverse();
  std::vector<double> err;
  int valid = 0, asked = 0;
  for (int i = 0; i < 200 && i < static_cast<int>(pts.size()); ++i) {
    const cv::Point p = pts[static_cast<std::size_t>(i)];
    const cv::Vec3f w = r.frame.left.points.at<cv::Vec3f>(p.y, p.x);
    const Eigen::Vector3d gt = left_from_world * Eigen::Vector3d(w[0], w[1], w[2]);
    ++asked;
    const cect::LocalizedPoint q = f.localize(cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y)));
    if (!q.valid) continue;
    ++valid;
    err.push_back(1000.0 * (q.position - gt).norm());
    EXPECT_GT(q.covariance(2, 2), 0.0);
  }
  *valid_share = asked ? static_cast<double>(valid) / asked : 0.0;
  return err;
}

double medianOf(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? NAN : v[v.size() / 2];
}

double meanOf(const std::vector<double>& v) {
  return v.empty() ? NAN : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

}  // namespace

TEST(Cect, RenderedBackRectifiedPair) {
  const Rendered r = renderBack(true);
  double share = 0;
  const auto err = renderedErrors(r, &share);
  std::cout << "rectified: valid " << share << ", median " << medianOf(err) << " mm\n";
  // Accuracy targets are cect_eval's; here: it works on skin (the contour
  // alone is off by ~15 cm inside the back, which rises above its contour).
  EXPECT_GT(share, 0.75);
  EXPECT_LT(medianOf(err), 8.0);
}

TEST(Cect, InteriorSeedsOnRenderedSkinAreSubPixelAndAccountedFor) {
  const Rendered r = renderBack(true);
  const camera::StereoModel g(r.pair.left_info, r.pair.right_info);
  const cect::CectFrame f = cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, {});
  ASSERT_TRUE(f.valid()) << f.reason();
  // Every grid point tried ends in exactly one outcome.
  const cect::SeedStats& s = f.seedStats();
  EXPECT_EQ(s.tried, s.no_peak + s.weak + s.left_right + s.continuity + s.accepted);
  const auto seeds = std::count_if(f.vertices().begin(), f.vertices().end(), [](const cect::Correspondence& v) {
    return v.source == cect::Correspondence::Source::kSeed;
  });
  EXPECT_EQ(static_cast<int>(seeds), s.accepted - s.smoothing - s.rim_outliers);
  EXPECT_GT(s.accepted, s.tried / 2);
  // Seeds against the renderer's exact disparity. Matched in grey band-passed
  // across the background step, or in fronto-parallel windows too small for
  // skin, they were 0.5-0.9 px off with a -0.3..-0.9 px bias.
  std::vector<double> err, signed_err;
  for (const cect::Correspondence& v : f.vertices()) {
    if (v.source != cect::Correspondence::Source::kSeed) continue;
    const float truth = r.frame.left_disparity.at<float>(cvRound(v.left.y), cvRound(v.left.x));
    if (!std::isfinite(truth)) continue;
    signed_err.push_back(v.disparity - truth);
    err.push_back(std::abs(v.disparity - truth));
  }
  ASSERT_GT(err.size(), 100u);
  std::cout << "seeds: median |error| " << medianOf(err) << " px, median error " << medianOf(signed_err) << " px\n";
  EXPECT_LT(medianOf(err), 0.3);
  EXPECT_LT(std::abs(medianOf(signed_err)), 0.2);
}

namespace {

/// localizeRectified at every 2nd back pixel (with a true disparity) whose
/// distance to the left contour lies in [lo, hi) px: visit(point, truth).
template <typename Visit>
void forBandPixels(const Rendered& r, const cect::CectFrame& f, double lo, double hi, Visit visit) {
  cv::Mat dist;
  cv::distanceTransform(f.left().mask, dist, cv::DIST_L2, 5);
  for (int y = 0; y < dist.rows; y += 2)
    for (int x = 0; x < dist.cols; x += 2) {
      const float d = dist.at<float>(y, x);
      const float truth = r.frame.left_disparity.at<float>(y, x);
      if (d < lo || d >= hi || !std::isfinite(truth) || r.frame.left.labels.at<std::uint8_t>(y, x) != sim::kLabelBack)
        continue;
      visit(f.localizeRectified(cv::Point2f(static_cast<float>(x), static_cast<float>(y))), truth);
    }
}

/// Signed disparity errors (px) of the valid points of forBandPixels.
std::vector<double> bandErrors(const Rendered& r, const cect::CectFrame& f, double lo, double hi, int* asked) {
  std::vector<double> err;
  *asked = 0;
  forBandPixels(r, f, lo, hi, [&](const cect::LocalizedPoint& q, float truth) {
    ++*asked;
    if (q.valid) err.push_back(q.disparity - truth);
  });
  return err;
}

std::vector<double> absOf(std::vector<double> v) {
  for (double& e : v) e = std::abs(e);
  return v;
}

/// The pair analysed with `on` and with `off`: the mean |disparity error|
/// of each over the back's pixels at least `inside` px in from its contour
/// (more than 1000 of them each, or the test fails).
std::pair<double, double> interiorMeanOnOff(const Rendered& r, const cect::CectParams& on, const cect::CectParams& off,
                                            double inside) {
  const OnOff both = analyseOnOff(r, on, off);
  int asked = 0;
  const auto e = absOf(bandErrors(r, both.on, inside, 1000.0, &asked));
  const auto e0 = absOf(bandErrors(r, both.off, inside, 1000.0, &asked));
  EXPECT_GT(e.size(), 1000u);
  EXPECT_GT(e0.size(), 1000u);
  return {meanOf(e), meanOf(e0)};
}

}  // namespace

TEST(Cect, RimProfileFollowsTheFlankBetweenContourAndSeeds) {
  // Across the occluding contour depth varies with the square root of the
  // distance to it; linear interpolation between the contour and the first
  // seeds ~30 px inside undershoots by up to ~4 px there.
  const Rendered r = renderBack(true);
  cect::CectParams with, without;
  without.rim_profile = false;
  // Every triangle kept, so that the band is interpolated either way.
  with.max_triangle_edge = without.max_triangle_edge = 0.0;
  const OnOff both = analyseOnOff(r, with, without);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cect::CectFrame &f = both.on, &f0 = both.off;
  const auto rim = std::count_if(f.vertices().begin(), f.vertices().end(), [](const cect::Correspondence& v) {
    return v.source == cect::Correspondence::Source::kRimProfile;
  });
  EXPECT_GT(rim, 100);
  int asked = 0, asked0 = 0;
  const auto e = absOf(bandErrors(r, f, 2.0, 24.0, &asked));
  const auto e0 = absOf(bandErrors(r, f0, 2.0, 24.0, &asked0));
  std::cout << "2-24 px from the contour: rim profile median |error| " << medianOf(e) << " px, valid " << e.size()
            << "/" << asked << "; linear " << medianOf(e0) << " px, valid " << e0.size() << "/" << asked0 << "\n";
  EXPECT_LT(medianOf(e), 0.7);
  EXPECT_LT(medianOf(e), 0.5 * medianOf(e0));
  EXPECT_GT(e.size(), e0.size());
}

TEST(Cect, RimProfileStaysBetweenTheRimAndTheSeedsWhereTheImageCutsTheBack) {
  // With the camera 14 cm along the table the image's bottom edge cuts
  // subject 4's hips: next to the corner between a flank and that edge the
  // seeds lie to one side of the rim's normal, and the profile fitted to
  // them ran off (27-46 px too far at 10-27 px from the rim, points 0.2-0.7 m
  // off). Its values must stay within the rim's and the seeds' range.
  const sim::BackModel back(sim::BodyParameters::subject(4));
  const sim::Renderer renderer(sim::makeBackScene(back, 1));
  sim::RigParameters rig;
  rig.shift = 0.14;
  Rendered r;
  r.pair = sim::makeStereoPair(rig);
  sim::RenderOptions ro;
  ro.supersample = 1;
  r.frame = sim::renderStereoFrame(renderer, r.pair, sim::Lighting::preset(sim::LightPreset::kTopCentre), ro);
  const camera::StereoModel g(r.pair.left_info, r.pair.right_info);
  const auto f = cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, cect::CectParams{});
  ASSERT_TRUE(f.valid()) << f.reason();
  int rim = 0, near_bottom = 0;
  double worst = 0.0;
  for (const auto& v : f.vertices()) {
    if (v.source != cect::Correspondence::Source::kRimProfile) continue;
    const float gt = r.frame.left_disparity.at<float>(cvRound(v.left.y), cvRound(v.left.x));
    if (!std::isfinite(gt)) continue;
    ++rim;
    near_bottom += v.left.y > r.frame.left.image.rows - 24;
    worst = std::max(worst, static_cast<double>(std::abs(v.disparity - gt)));
  }
  std::cout << rim << " rim-profile vertices (" << near_bottom << " within 24 px of the bottom edge), worst |error| "
            << worst << " px\n";
  EXPECT_GT(rim, 100);
  EXPECT_GT(near_bottom, 0);
  EXPECT_LT(worst, 4.0);
  // ... and no pixel near the cut is localised that far off.
  for (int x = 200; x < 300; x += 2) {
    const auto q = f.localize(cv::Point2f(static_cast<float>(x), 474.0f));
    const float gt = r.frame.left_disparity.at<float>(474, x);
    if (q.valid && std::isfinite(gt)) {
      EXPECT_LT(std::abs(q.disparity - gt), 4.0) << "at x " << x;
    }
  }
}

namespace {

/// A pair analysed with slanted windows (the defaults) and without them.
OnOff slantedOnOff(const Rendered& r) {
  // Without the rim profiles, which drop the seeds they disagree with:
  // the seeds' own windows are what is compared.
  cect::CectParams with;
  with.rim_profile = false;
  cect::CectParams without = with;
  without.slanted_windows = false;
  return analyseOnOff(r, with, without);
}

}  // namespace

TEST(Cect, SlantedWindowsTakeTheBiasOffTheSlopesTowardTheRim) {
  // Toward the rim (the flanks, the shoulders' top) the disparity changes by
  // more than a pixel across a fronto-parallel window, whose peak then
  // follows the window's strongest texture rather than its centre. Matte
  // skin (no sheen), so that the windows' geometry is what is measured:
  // the mean subject's band 8-40 px inside the contour (~5 % better
  // there, every 8 px wide band alike).
  const Rendered r = renderBack(true, 0, 640, 480, 500, 0.0f);
  const OnOff both = slantedOnOff(r);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  int asked = 0, asked0 = 0;
  const auto e = absOf(bandErrors(r, both.on, 8.0, 40.0, &asked));
  const auto e0 = absOf(bandErrors(r, both.off, 8.0, 40.0, &asked0));
  ASSERT_GT(e.size(), 1000u);
  std::cout << "8-40 px inside the contour: slanted windows mean |error| " << meanOf(e) << " px (" << e.size() << "/"
            << asked << " valid); fronto-parallel " << meanOf(e0) << " px (" << e0.size() << "/" << asked0 << ")\n";
  EXPECT_LT(meanOf(e), 0.97 * meanOf(e0));
  EXPECT_GE(e.size(), e0.size() - 10);
}

TEST(Cect, SeedsBelowTheShouldersTopAreMatchedWithSlantedWindows) {
  // Below the shoulders' top (a border along the rows 6-32 px above, the
  // back continuing 32 px to either side) the skin rolls over toward the
  // head more steeply than the seeds' quadratic, fitted from one side only,
  // says: those seeds are re-matched with slanted windows whatever their
  // estimated slant. Subject 11, matte.
  const Rendered r = renderBack(true, 11, 640, 480, 500, 0.0f);
  const OnOff both = slantedOnOff(r);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cv::Mat& mask = both.on.left().mask;
  auto on = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < mask.cols && y < mask.rows && mask.at<std::uint8_t>(y, x) != 0;
  };
  double sum = 0.0, sum0 = 0.0;
  int n = 0;
  for (int y = 0; y < mask.rows; y += 2)
    for (int x = 0; x < mask.cols; x += 2) {
      const float t = r.frame.left_disparity.at<float>(y, x);
      if (!on(x, y) || !on(x - 32, y) || !on(x + 32, y) || !on(x, y - 6) || on(x, y - 32) || !std::isfinite(t))
        continue;
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      const cect::LocalizedPoint a = both.on.localizeRectified(q), b = both.off.localizeRectified(q);
      if (!a.valid || !b.valid) continue;
      sum += std::abs(a.disparity - t);
      sum0 += std::abs(b.disparity - t);
      ++n;
    }
  ASSERT_GT(n, 500);
  std::cout << "below the shoulders' top (" << n << " px): slanted windows mean |error| " << sum / n
            << " px, fronto-parallel " << sum0 / n << " px\n";
  EXPECT_LT(sum, 0.9 * sum0);
}

TEST(Cect, SmoothingFollowsTheSpinesGrooveAcrossTheBody) {
  // Across the body the back is a dome with two paraspinal ridges and the
  // spine's groove between them (~0.5 px deep, ~40 px ridge to ridge here):
  // a quadratic over the (wide) smoothing radius cannot follow that
  // cross-section; the quartic across the body follows it better.
  // The mean subject, matte: the fit's shape is what is measured.
  const Rendered r = renderBack(true, 0, 640, 480, 500, 0.0f);
  cect::CectParams with, without;
  without.quartic_across = false;
  const auto [e, e0] = interiorMeanOnOff(r, with, without, 48.0);
  std::cout << "interior (>= 48 px inside the contour): quartic across mean |error| " << e << " px, quadratic " << e0
            << " px\n";
  EXPECT_LT(e, 0.9 * e0);
}

TEST(Cect, SheenIsTakenOffBeforeMatching) {
  // The highlight, a virtual image behind the convex back, pulls plain grey
  // matches farther (subject 3: -0.6 px in the interior, -0.2 px without
  // any sheen); taking the estimated sheen off removes about half of that.
  const Rendered r = renderBack(true, 3);
  cect::CectParams with, without;
  without.sheen_sigma = 0.0;
  int asked = 0;
  const OnOff both = analyseOnOff(r, with, without);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cect::CectFrame &f = both.on, &f0 = both.off;
  const auto e = bandErrors(r, f, 32.0, 1000.0, &asked);
  const auto e0 = bandErrors(r, f0, 32.0, 1000.0, &asked);
  std::cout << "interior: sheen removed median error " << medianOf(e) << " px, |error| " << medianOf(absOf(e))
            << "; plain grey " << medianOf(e0) << " px, |error| " << medianOf(absOf(e0)) << "\n";
  EXPECT_LT(std::abs(medianOf(e)), 0.8 * std::abs(medianOf(e0)));
  EXPECT_LT(medianOf(absOf(e)), medianOf(absOf(e0)));
}

/// The pair moved `k` px to the right in both views (a camera whose
/// principal point lies k px farther right): the same scene, the body at
/// another place relative to the seed grid.
Rendered shiftedRight(const Rendered& r, int k) {
  Rendered s = r;
  const cv::Mat t = (cv::Mat_<double>(2, 3) << 1, 0, k, 0, 1, 0);
  auto shift = [&](const cv::Mat& in, int interp, const cv::Scalar& fill) {
    cv::Mat out;
    cv::warpAffine(in, out, t, in.size(), interp, cv::BORDER_CONSTANT, fill);
    return out;
  };
  s.frame.left.image = shift(r.frame.left.image, cv::INTER_NEAREST, cv::Scalar(0, 0, 0));
  s.frame.right.image = shift(r.frame.right.image, cv::INTER_NEAREST, cv::Scalar(0, 0, 0));
  s.frame.left.labels = shift(r.frame.left.labels, cv::INTER_NEAREST, cv::Scalar(0));
  s.frame.left_disparity = shift(r.frame.left_disparity, cv::INTER_NEAREST, cv::Scalar(NAN));
  for (auto* c : {&s.pair.left_info, &s.pair.right_info}) {
    c->K[2] += k;
    c->P[2] += k;
  }
  return s;
}

TEST(Cect, SeedColumnsAtHalfStepsMakeTheReliefIndependentOfTheBodysPlace) {
  // With a column every seed step, the spine's groove and the paraspinal
  // ridges are reconstructed differently depending on where the columns
  // fall: the same pair (the mean subject) moved by 0 / 4 / 8 / 12 px.
  // Half-step columns make the interior's error nearly independent of that
  // (0.193-0.197 px against 0.201-0.221 px), and lower everywhere.
  const Rendered r0 = renderBack(true);
  cect::CectParams half, whole;
  whole.seed_column_step = whole.seed_step;
  ASSERT_EQ(half.seed_column_step * 2, half.seed_step);
  std::vector<double> e_half, e_whole;
  for (int k : {0, 4, 8, 12}) {
    const auto [e, e0] = interiorMeanOnOff(shiftedRight(r0, k), half, whole, 32.0);
    e_half.push_back(e);
    e_whole.push_back(e0);
    std::cout << "moved " << k << " px: interior mean |error| " << e_half.back() << " px with half-step columns, "
              << e_whole.back() << " px with whole-step columns\n";
  }
  auto range = [](const std::vector<double>& v) {
    return *std::max_element(v.begin(), v.end()) - *std::min_element(v.begin(), v.end());
  };
  EXPECT_LT(range(e_half), 0.5 * range(e_whole));
  EXPECT_LT(*std::max_element(e_half.begin(), e_half.end()), *std::min_element(e_whole.begin(), e_whole.end()));
}

TEST(Cect, SheenTwicingKeepsTheHighlightsOffTheRidges) {
  // A side light lays a highlight along the paraspinal ridge facing it; a
  // single Gaussian flattens that highlight's peak, and the residual, which
  // moves with the viewpoint, pulls the ridge's matches farther. Twicing
  // the smoothing keeps the peak. Dark subject 5 (faint texture), light
  // top-right: the interior's mean |error| drops by a fifth (by ~6 % with
  // seed columns a whole step apart, and on subject 3 under the top-left light).
  const Rendered r = renderBack(true, 5, 640, 480, 500, -1.0f, sim::LightPreset::kTopRight);
  cect::CectParams with, without;
  without.sheen_twicing = false;
  const auto [e, e0] = interiorMeanOnOff(r, with, without, 32.0);
  std::cout << "interior, light top-right: twicing mean |error| " << e << " px, one Gaussian " << e0 << " px\n";
  EXPECT_LT(e, 0.9 * e0);
}

TEST(Cect, PixelsAtTheNeckBaseAreExtrapolatedWithAWiderSigma) {
  // The neck base runs along the epipolar lines: no contour correspondences
  // there, so its band lies outside the triangulation.
  const Rendered r = renderBack(true);
  cect::CectParams on, off;
  off.max_extrapolation = 0.0;
  const OnOff both = analyseOnOff(r, on, off);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cect::CectFrame &f = both.on, &f0 = both.off;
  // The topmost back rows, away from the sides.
  const cv::Rect box = cv::boundingRect(f.left().mask);
  int extrapolated = 0, refused = 0;
  std::vector<double> err;
  for (int y = box.y + 3; y < box.y + 12; y += 2)
    for (int x = box.x + box.width / 3; x < box.x + 2 * box.width / 3; x += 4) {
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      const float truth = r.frame.left_disparity.at<float>(y, x);
      if (!f.left().mask.at<std::uint8_t>(y, x) || !std::isfinite(truth)) continue;
      const cect::LocalizedPoint p = f.localizeRectified(q), p0 = f0.localizeRectified(q);
      if (!p.extrapolated) continue;
      ++extrapolated;
      EXPECT_TRUE(p.valid);
      EXPECT_GT(p.disparity_sigma, on.pixel_sigma);
      err.push_back(std::abs(p.disparity - truth));
      EXPECT_FALSE(p0.valid);
      refused += p0.reason.find("outside the triangulated back") != std::string::npos;
    }
  ASSERT_GT(extrapolated, 10);
  EXPECT_EQ(refused, extrapolated);
  std::cout << "neck base: " << extrapolated << " extrapolated, median |error| " << medianOf(err) << " px\n";
  EXPECT_LT(medianOf(err), 1.0);

  // Seeds that scatter around their quadratic beyond 3 pixel_sigma do not
  // describe a smooth surface: with a (pretended) matching noise of
  // 0.02 px, the same band is refused with that reason.
  cect::CectParams strict;
  strict.pixel_sigma = 0.02;
  const camera::StereoModel g(r.pair.left_info, r.pair.right_info);
  const cect::CectFrame fs = cect::CectFrame::analyse(r.frame.left.image, r.frame.right.image, g, strict);
  ASSERT_TRUE(fs.valid()) << fs.reason();
  int rough = 0;
  for (int y = box.y + 3; y < box.y + 12; y += 2)
    for (int x = box.x + box.width / 3; x < box.x + 2 * box.width / 3; x += 4) {
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      if (!f.localizeRectified(q).extrapolated) continue;
      const cect::LocalizedPoint p = fs.localizeRectified(q);
      rough += !p.valid && p.reason.find("do not fit a smooth surface") != std::string::npos;
    }
  EXPECT_GT(rough, extrapolated / 2);
}

namespace {

/// The mean subject analysed with the direct matches in the border band
/// (the defaults) and without them; rendered once for the two tests below.
struct DirectMatchCase {
  Rendered r;
  OnOff both;
};
const DirectMatchCase& directMatchCase() {
  static const DirectMatchCase c = [] {
    Rendered r = renderBack(true);
    cect::CectParams off;
    off.direct_min_sharpness = 0.0;
    OnOff both = analyseOnOff(r, cect::CectParams{}, off);
    return DirectMatchCase{std::move(r), std::move(both)};
  }();
  return c;
}

}  // namespace

TEST(Cect, TexturedPixelsInTheBorderBandAreMatchedDirectly) {
  // The band along the neck base where no seed window fits: the surface
  // rolls off there (and the vertebra prominens stands out), which the
  // seeds' quadratic cannot see. Where a pixel's own window (restricted to
  // the back) holds texture, a direct match replaces the extrapolation.
  const DirectMatchCase& c = directMatchCase();
  const Rendered& r = c.r;
  ASSERT_TRUE(c.both.on.valid() && c.both.off.valid());
  const cect::CectFrame &f = c.both.on, &f0 = c.both.off;
  const cv::Rect box = cv::boundingRect(f.left().mask);
  std::vector<double> e, e0, sigma;
  int extrapolated = 0;
  for (int y = box.y + 2; y < box.y + 14; ++y)
    for (int x = box.x + box.width / 3; x < box.x + 2 * box.width / 3; x += 2) {
      const float truth = r.frame.left_disparity.at<float>(y, x);
      if (!f.left().mask.at<std::uint8_t>(y, x) || !std::isfinite(truth)) continue;
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      const cect::LocalizedPoint p = f.localizeRectified(q), p0 = f0.localizeRectified(q);
      if (!p0.valid || !p0.extrapolated) continue;
      ++extrapolated;
      ASSERT_TRUE(p.valid) << q;
      if (p.extrapolated) {
        EXPECT_DOUBLE_EQ(p.disparity, p0.disparity) << q;  // untextured: the same extrapolation
        continue;
      }
      // Its own measurement: the matching noise and the slope's part, not
      // the border band's (interpolation) part the extrapolation carries.
      EXPECT_GE(p.disparity_sigma, cect::CectParams{}.pixel_sigma);
      EXPECT_LT(p.disparity_sigma, p0.disparity_sigma) << q;
      sigma.push_back(p.disparity_sigma);
      e.push_back(std::abs(p.disparity - truth));
      e0.push_back(std::abs(p0.disparity - truth));
    }
  std::cout << "neck-base band: " << e.size() << " of " << extrapolated
            << " extrapolated pixels matched directly, median |error| " << medianOf(e) << " px (extrapolated "
            << medianOf(e0) << " px); median sigma " << medianOf(sigma) << " px\n";
  ASSERT_GE(e.size(), 10u);
  // (~0.25 against ~0.4 px; the direct match's share of the gain shrank when
  // the sheen's smoothing was twiced, which made the seeds, and so the
  // extrapolation, better: 0.24 against 0.43 px before.)
  EXPECT_LT(medianOf(e), 0.75 * medianOf(e0));
  EXPECT_LT(medianOf(e), 0.4);
}

TEST(Cect, TheBandAlongARowBorderAveragesTheTransferWithADirectMatch) {
  // Next to a border running along the rows (the shoulders' top, the neck
  // base) the transfer leans on the first seeds, whose windows reach across
  // the band's steep relief; a pixel there takes the mean of the transfer and
  // its own window's match. Everywhere else the transfer is unchanged.
  const DirectMatchCase& c = directMatchCase();
  const Rendered& r = c.r;
  ASSERT_TRUE(c.both.on.valid() && c.both.off.valid());
  const cect::CectFrame &f = c.both.on, &f0 = c.both.off;
  const cv::Rect box = cv::boundingRect(f.left().mask);
  std::vector<double> e, e0;
  int unchanged_inside = 0;
  for (int y = box.y; y < box.y + box.height; y += 2)
    for (int x = box.x; x < box.x + box.width; x += 2) {
      const float truth = r.frame.left_disparity.at<float>(y, x);
      if (!f.left().mask.at<std::uint8_t>(y, x) || !std::isfinite(truth)) continue;
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      const cect::LocalizedPoint p = f.localizeRectified(q), p0 = f0.localizeRectified(q);
      if (!p0.valid || p0.extrapolated) continue;
      ASSERT_TRUE(p.valid) << q;
      if (p.disparity == p0.disparity) {
        if (x > box.x + box.width / 4 && x < box.x + 3 * box.width / 4 && y > box.y + box.height / 4 &&
            y < box.y + 3 * box.height / 4)
          ++unchanged_inside;
        continue;
      }
      // Only pixels of a band along a row border change: near the top or
      // bottom of the back, never in its middle.
      EXPECT_TRUE(y < box.y + box.height / 4 || y > box.y + 3 * box.height / 4) << q;
      e.push_back(std::abs(p.disparity - truth));
      e0.push_back(std::abs(p0.disparity - truth));
    }
  std::cout << "row-border band: " << e.size() << " pixels with a direct match, median |error| " << medianOf(e)
            << " px (transfer alone " << medianOf(e0) << " px); " << unchanged_inside
            << " pixels of the back's middle unchanged\n";
  ASSERT_GE(e.size(), 20u);
  EXPECT_GT(unchanged_inside, 1000);
  // 0.31 against 0.34 px on this subject (0.24 against 0.36 px with seed
  // columns a whole step apart, whose transfer leaned on fewer, more biased
  // seeds); over 28 subjects it keeps GB21 at 6.0-6.4 mm instead of 7.0-7.9.
  EXPECT_LT(medianOf(e), 0.95 * medianOf(e0));
}

TEST(Cect, EdgesAlongTheRowsAreMatchedByTheirShape) {
  // The neck base runs along the rows: no row crossings. Its shape y(x),
  // where it bends, fixes its shift between the views.
  const Rendered r = renderBack(true);
  cect::CectParams on, off;
  off.edge_window = 0.0;
  const OnOff both = analyseOnOff(r, on, off);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cect::CectFrame &f = both.on, &f0 = both.off;
  auto isEdge = [](const cect::Correspondence& v) { return v.source == cect::Correspondence::Source::kEdge; };
  EXPECT_EQ(std::count_if(f0.vertices().begin(), f0.vertices().end(), isEdge), 0);
  const cv::Rect box = cv::boundingRect(f.left().mask);
  int n = 0;
  for (const auto& v : f.vertices()) {
    if (!isEdge(v)) continue;
    ++n;
    EXPECT_TRUE(v.foundational());
    // On the top edge, within 20 deg of the rows, and matched to the rim's
    // own disparity (the truth one pixel inside, where the rim falls away
    // steeply, is a little nearer).
    EXPECT_LT(v.left.y, box.y + 0.2 * box.height);
    const int x = cvRound(v.left.x), y = cvRound(v.left.y) + 1;
    const float truth = r.frame.left_disparity.at<float>(y, x);
    ASSERT_TRUE(std::isfinite(truth)) << v.left;
    EXPECT_LT(std::abs(v.disparity - truth), 1.0) << v.left;
  }
  EXPECT_GE(n, 2);
  std::cout << n << " edge correspondences on the neck base\n";
}

TEST(Cect, LongTrianglesAreDroppedAndTheirPixelsExtrapolated) {
  // Triangles bridging the unmatched neck base span several seed steps;
  // the final triangulation drops them and extrapolates their pixels.
  const Rendered r = renderBack(true);
  cect::CectParams on, off;
  off.max_triangle_edge = 0.0;
  const OnOff both = analyseOnOff(r, on, off);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const cect::CectFrame &f = both.on, &f0 = both.off;
  auto longest = [](const cect::CectFrame& fr) {
    double m = 0.0;
    for (const auto& t : fr.triangles())
      for (int k = 0; k < 3; ++k)
        m = std::max(m, static_cast<double>(cv::norm(fr.vertices()[static_cast<std::size_t>(t[k])].left -
                                                     fr.vertices()[static_cast<std::size_t>(t[(k + 1) % 3])].left)));
    return m;
  };
  const double limit = on.max_triangle_edge * on.seed_step;
  EXPECT_LE(longest(f), limit);
  EXPECT_GT(longest(f0), limit);
  // The pixels the dropped triangles covered: now extrapolated, and better.
  std::vector<double> e, e0;
  for (int y = 0; y < f.left().mask.rows; y += 2)
    for (int x = 0; x < f.left().mask.cols; x += 2) {
      const float truth = r.frame.left_disparity.at<float>(y, x);
      if (!std::isfinite(truth) || r.frame.left.labels.at<std::uint8_t>(y, x) != sim::kLabelBack) continue;
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      const cect::LocalizedPoint p = f.localizeRectified(q), p0 = f0.localizeRectified(q);
      if (!p.valid || !p.extrapolated || !p0.valid || p0.extrapolated) continue;
      e.push_back(std::abs(p.disparity - truth));
      e0.push_back(std::abs(p0.disparity - truth));
    }
  std::cout << "longest edge " << longest(f) << " / " << longest(f0) << " px; " << e.size()
            << " pixels of dropped triangles: median |error| " << medianOf(e) << " px extrapolated, " << medianOf(e0)
            << " px in the long triangles\n";
  ASSERT_GT(e.size(), 20u);
  EXPECT_LT(medianOf(e), 0.8 * medianOf(e0));
}

TEST(Cect, PixelParametersScaleToTheView) {
  // The scale: the contour's disparity over the baseline against the
  // reference view's 550 px per metre, in steps of 2^(1/4).
  EXPECT_DOUBLE_EQ(cect::viewScale(55.0, 0.1), 1.0);
  EXPECT_DOUBLE_EQ(cect::viewScale(51.0, 0.1), 1.0);  // bodies differ: the reference rig stays at 1
  EXPECT_DOUBLE_EQ(cect::viewScale(59.0, 0.1), 1.0);
  EXPECT_NEAR(cect::viewScale(62.0, 0.1), std::exp2(0.25), 1e-12);
  EXPECT_DOUBLE_EQ(cect::viewScale(27.5, 0.1), 0.5);
  EXPECT_DOUBLE_EQ(cect::viewScale(66.0, 0.06), 2.0);
  EXPECT_DOUBLE_EQ(cect::viewScale(0.0, 0.1), 1.0);
  EXPECT_DOUBLE_EQ(cect::viewScale(55.0, 0.0), 1.0);
  const cect::CectParams p;
  const cect::CectParams h = cect::scaledParams(p, 0.5), d = cect::scaledParams(p, 2.0);
  EXPECT_EQ(h.ncc_radius, 5);  // the window's extent: 23 px -> 11
  EXPECT_EQ(d.ncc_radius, 23);
  EXPECT_EQ(h.seed_step, 8);
  EXPECT_EQ(h.seed_column_step, 4);
  EXPECT_DOUBLE_EQ(h.bandpass_high, 3.0);
  EXPECT_DOUBLE_EQ(h.continuity_margin, 1.5);
  EXPECT_DOUBLE_EQ(h.direct_min_sharpness, 4.0 * p.direct_min_sharpness);
  EXPECT_DOUBLE_EQ(h.segmentation.blur_sigma, 0.75);
  EXPECT_DOUBLE_EQ(h.border_sigma, 0.5 * p.border_sigma);  // disparities, like the tolerances
  EXPECT_DOUBLE_EQ(d.slope_sigma, 2.0 * p.slope_sigma);
  EXPECT_DOUBLE_EQ(h.border_sigma_reach, p.border_sigma_reach);  // seed steps
  EXPECT_DOUBLE_EQ(h.lr_tolerance, p.lr_tolerance);              // sub-pixel, scale-free and absolute ones stay
  EXPECT_DOUBLE_EQ(h.smooth_radius, p.smooth_radius);
  EXPECT_DOUBLE_EQ(h.min_disparity, p.min_disparity);
  EXPECT_EQ(cect::scaledParams(p, 1.0).ncc_radius, p.ncc_radius);

  // A half-size camera (320x240, fx 250): the reference parameters as given
  // are too coarse for it; scaled, they mean the same on the skin.
  const Rendered r = renderBack(true, 0, 320, 240, 250);
  cect::CectParams fixed;
  fixed.auto_scale = false;
  double on_share = 0, off_share = 0, scale = 0, fixed_scale = 0;
  const auto on = renderedErrors(r, &on_share, {}, &scale);
  const auto off = renderedErrors(r, &off_share, fixed, &fixed_scale);
  std::cout << "320x240: scaled " << meanOf(on) << " mm (valid " << on_share << "), as given " << meanOf(off)
            << " mm (valid " << off_share << ")\n";
  EXPECT_DOUBLE_EQ(scale, 0.5);
  EXPECT_DOUBLE_EQ(fixed_scale, 1.0);
  EXPECT_GT(on_share, 0.75);
  EXPECT_LT(meanOf(on), 0.8 * meanOf(off));
}

namespace {

/// Over forBandPixels: the share of the localised ones whose |disparity
/// error| is within 2 disparity_sigma, and their median sigma.
struct Coverage {
  double within2 = 0.0, median_sigma = 0.0;
  std::size_t count = 0;
};
Coverage coverage(const Rendered& r, const cect::CectFrame& f, double lo, double hi) {
  std::vector<double> sigma;
  int within = 0;
  forBandPixels(r, f, lo, hi, [&](const cect::LocalizedPoint& q, float truth) {
    if (!q.valid) return;
    sigma.push_back(q.disparity_sigma);
    within += std::abs(q.disparity - truth) <= 2.0 * q.disparity_sigma;
  });
  Coverage c;
  c.count = sigma.size();
  c.within2 = sigma.empty() ? 0.0 : static_cast<double>(within) / sigma.size();
  c.median_sigma = medianOf(sigma);
  return c;
}

}  // namespace

TEST(Cect, DisparitySigmaCoversTheBorderBandsLargerErrors) {
  // Next to the back's border the disparity is interpolated from the rim
  // profile and the first seeds and errs ~1 px, against ~0.3 px inside:
  // the reported sigma grows toward the border (and with the slope), so
  // that ~95 % of the errors lie within 2 sigma in the band as inside.
  const Rendered r = renderBack(true);
  cect::CectParams with, without;
  without.border_sigma = without.slope_sigma = 0.0;
  const OnOff both = analyseOnOff(r, with, without);
  ASSERT_TRUE(both.on.valid() && both.off.valid());
  const Coverage band = coverage(r, both.on, 0.0, 15.0), band0 = coverage(r, both.off, 0.0, 15.0);
  const Coverage mid = coverage(r, both.on, 15.0, 45.0), inner = coverage(r, both.on, 45.0, 1e9);
  const Coverage inner0 = coverage(r, both.off, 45.0, 1e9);
  std::cout << "within 2 sigma (median sigma): 0-15 px " << band.within2 << " (" << band.median_sigma
            << " px), without the structural parts " << band0.within2 << " (" << band0.median_sigma << " px); 15-45 px "
            << mid.within2 << " (" << mid.median_sigma << " px); >= 45 px " << inner.within2 << " ("
            << inner.median_sigma << " px), without " << inner0.within2 << "\n";
  ASSERT_GT(band.count, 500u);
  ASSERT_GT(inner.count, 2000u);
  EXPECT_GT(band.within2, 0.9);
  EXPECT_GT(mid.within2, 0.9);
  EXPECT_GT(inner.within2, 0.9);
  EXPECT_LT(band0.within2, band.within2 - 0.1);  // the matching noise alone does not cover the band
  // Sigma falls from the border inward, and inside stays near the matching noise.
  EXPECT_GT(band.median_sigma, 2.0 * with.pixel_sigma);
  EXPECT_GT(band.median_sigma, mid.median_sigma);
  EXPECT_GT(mid.median_sigma, inner.median_sigma);
  EXPECT_LT(inner.median_sigma, 1.25 * with.pixel_sigma);
  // Only the uncertainty changes: the same disparities.
  for (const cv::Point2f q : {cv::Point2f(320, 240), cv::Point2f(300, 120), cv::Point2f(250, 300)}) {
    const cect::LocalizedPoint a = both.on.localizeRectified(q), b = both.off.localizeRectified(q);
    ASSERT_EQ(a.valid, b.valid);
    if (a.valid) {
      EXPECT_DOUBLE_EQ(a.disparity, b.disparity);
    }
  }
}

TEST(Cect, RenderedBackRawPair) {
  const Rendered r = renderBack(false);
  double share = 0;
  const auto err = renderedErrors(r, &share);
  std::cout << "raw: valid " << share << ", median " << medianOf(err) << " mm\n";
  EXPECT_GT(share, 0.75);
  EXPECT_LT(medianOf(err), 8.0);
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
