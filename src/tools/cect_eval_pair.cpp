#include "cect_eval_pair.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <tuple>

#include <opencv2/imgproc.hpp>

#include "cect_eval_picture.h"
#include "cect_eval_scoring.h"
#include "cect_scenes.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/ground_truth.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"
#include "sim_rig.h"

namespace massage_cell::tools::cect_eval {
namespace {

using Clock = std::chrono::steady_clock;

/// The set-up of one pair of condition `c`.
tools::Scenario scenarioFor(const Options& o, const Condition& c, int subject) {
  sim::RigParameters rig = cameraRig(o.width, o.height, o.fx, o.baseline, o.camera_height, o.raw);
  if (c.real) return tools::realScenario(c.name, subject, rig);
  tools::Scenario s;
  s.body = sim::BodyParameters::subject(subject);
  rig.shift = c.shift;
  s.rig = rig;
  s.light = c.light;
  s.yaw_deg = o.yaw_deg;
  return s;
}

/// One scenario rendered: the subject's back (turned on the table by its yaw), the rig and the stereo frame.
struct RenderedPair {
  std::unique_ptr<sim::BackModel> back;
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();  ///< the back's turn about the vertical through its centre
  sim::StereoPairModel pair;
  sim::StereoFrame frame;
};

RenderedPair renderPair(const Options& o, const Condition& c, int subject) {
  RenderedPair r;
  tools::Scenario sc = scenarioFor(o, c, subject);
  if (o.markers) {
    for (const cect::SkinMarkerSpec& m : o.markers->markers)
      sc.dressing.stickers.push_back({m.landmark, sim::stickerColour(m.colour), m.diameter_m});
  }
  r.back = std::make_unique<sim::BackModel>(sc.body);
  sim::Scene scene = sim::makeCellScene(*r.back, 1, sc.dressing);
  // The subject turned on the table: the back's mesh and its anatomical
  // acupoints about the vertical through the mesh's centre.
  if (sc.yaw_deg != 0.0) {
    for (sim::Mesh& m : scene.meshes) {
      if (m.label != sim::kLabelBack) continue;
      Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
      for (const auto& v : m.vertices) {
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
      }
      const Eigen::Vector3d centre(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0.0);
      r.turn = Eigen::Translation3d(centre) * Eigen::AngleAxisd(-sc.yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()) *
               Eigen::Translation3d(-centre);
      sim::transform(m, r.turn.linear().cast<float>(), r.turn.translation().cast<float>());
    }
  }
  const sim::Renderer renderer(scene);
  r.pair = sim::makeStereoPair(sc.rig);
  sim::RenderOptions ro;
  ro.noise_seed = static_cast<std::uint32_t>(subject);
  r.frame = sim::renderStereoFrame(renderer, r.pair, sim::Lighting::preset(sc.light), ro);
  if (sc.photo.any()) {
    r.frame.left.image = sim::applyPhotoArtefacts(r.frame.left.image, sc.photo);
    r.frame.right.image = sim::applyPhotoArtefacts(r.frame.right.image, sc.photo);
  }
  return r;
}

/// The depth scorer's queries at the true pixels of the model's acupoints in view (the simulator's truth), in the
/// order of the chain's points.
std::vector<Query> trueAcupointQueries(const cect::LocatedAcupoints& result,
                                       const std::map<std::string, sim::PointTruth>& seen,
                                       const camera::StereoModel& geometry) {
  std::vector<Query> given;
  for (const cect::LocatedAcupoint& a : result.points) {
    const auto t = seen.find(a.name);
    if (t == seen.end() || !t->second.in_view) continue;
    const cv::Point2f raw(static_cast<float>(t->second.left_pixel.x()), static_cast<float>(t->second.left_pixel.y()));
    given.push_back(Query{geometry.toRectified(raw), nullptr, {}});
  }
  return given;
}

/// The rendered back's vertebral levels on the skin (C7, T1..L5), in the left optical frame.
std::map<std::string, Eigen::Vector3d> trueLevels(const RenderedPair& r) {
  auto landmarks = r.back->landmarks();
  for (auto& [name, point] : landmarks) point = r.turn * point;
  std::map<std::string, Eigen::Vector3d> levels;
  for (const auto& [name, point] : sim::toCameraFrame(landmarks, r.pair.left))
    if (name.size() <= 3) levels[name] = point;  // the levels, not the bony landmarks (scapula_..., iliac_crest_...)
  return levels;
}

/// --given-landmarks: C7 and L4 as a therapist clicks them, each up to `mm` from the truth (uniform over a disc
/// facing the camera), as rectified left pixels.
std::vector<cect::GivenLandmark> clickedLandmarks(const RenderedPair& r, const camera::StereoModel& geometry, double mm,
                                                  const std::vector<std::string>& names, int subject) {
  std::mt19937 rng(static_cast<std::uint32_t>(7000 + subject));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<cect::GivenLandmark> out;
  const auto levels = trueLevels(r);
  // Drawn in this order whichever are given, so a subject's C7 and L4 clicks stay the same with T7 added.
  for (const char* name : {"C7", "L4", "T7"}) {
    const double radius = 0.001 * mm * std::sqrt(unit(rng)), angle = 2.0 * M_PI * unit(rng);
    if (std::find(names.begin(), names.end(), name) == names.end()) continue;
    const Eigen::Vector3d p = levels.at(name) + radius * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
    const Eigen::Vector3d q = geometry.project(p);
    out.push_back(
        {name, cv::Point2f(static_cast<float>(q.x()), static_cast<float>(q.y())), cect::LandmarkSource::kGivenClick});
  }
  return out;
}

/// The anatomy of a rendered pair as the scorer wants it: the levels and the spine line on the skin, the in-view
/// acupoints and the surface seen at each pixel, in the left optical frame.
cect::BackTruth backTruth(const RenderedPair& r, const std::map<std::string, sim::PointTruth>& seen,
                          const std::map<std::string, Eigen::Vector3d>& anatomical, const Scorer& scorer) {
  cect::BackTruth truth;
  truth.levels = trueLevels(r);
  const Eigen::Isometry3d left_from_world = r.pair.left.world_from_camera.inverse();
  for (const Eigen::Vector3d& p : r.back->midline()) truth.midline.push_back(left_from_world * (r.turn * p));
  for (const auto& [name, t] : seen)
    if (t.in_view && anatomical.count(name)) truth.acupoints_in_view[name] = anatomical.at(name);
  truth.surface = [&scorer](const cv::Point2f& q, Eigen::Vector3d* p) { return scorer.truth(q, p); };
  return truth;
}

/// CECT's options for pair `subject`: the chain's switches and, with --given-landmarks, the therapist's clicks.
cect::LocateOptions locateOptions(const Options& o, const RenderedPair& r, const camera::StereoModel& geometry,
                                  int subject) {
  cect::LocateOptions lo;
  lo.correct_parallax = o.parallax;
  lo.levels_in_3d = o.levels_3d;
  lo.check_layout = o.layout_check;
  lo.trust.c7_at_neck = !o.trust_c7_at_top;
  lo.trust.l4_measured = !o.trust_inferred_l4;
  if (o.given_mm >= 0.0) lo.given = clickedLandmarks(r, geometry, o.given_mm, o.given_levels, subject);
  for (cect::GivenLandmark& g : lo.given) g.confirmed = o.confirm_given;
  return lo;
}

/// The placed acupoints as queries at their pixels with CECT's points there; on a published pair, the ones not
/// placed as per-point misses.
std::vector<Query> placedAcupointQueries(const cect::LocatedAcupoints& result, PairResult* res) {
  std::vector<Query> acu;
  for (const cect::LocatedAcupoint& a : result.points)
    if (a.placed) {
      acu.push_back(Query{a.rectified, &a.point, a.name});
    } else if (result.valid) {
      Stats& pp = res->per_point[a.name];
      pp.queried = 1;
      pp.misses["placement: " + a.reason] = 1;
    }
  return acu;
}

/// Random back pixels: well inside the back's border, and next to the arms (within 20 px at 640).
struct BackQueries {
  std::vector<Query> inner, near_arms;
};

BackQueries backQueries(const Options& o, const sim::StereoFrame& frame, const camera::StereoModel& geometry,
                        int subject) {
  BackQueries q;
  const cv::Mat visible_back = (frame.left.labels == sim::kLabelBack) & (frame.left_visible > 0);
  cv::Mat inner_back;
  cv::erode(visible_back, inner_back, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(17, 17)));
  q.inner = randomQueries(inner_back, static_cast<std::uint32_t>(1000 + subject), o.random_points, geometry);
  const cv::Mat arms = frame.left.labels == sim::kLabelArm;
  if (cv::countNonZero(arms) > 0) {
    const int radius = std::max(2, cvRound(20.0 * o.width / 640.0));
    cv::Mat near;
    cv::dilate(arms, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
    q.near_arms =
        randomQueries(near & visible_back, static_cast<std::uint32_t>(2000 + subject), o.random_points, geometry);
  }
  return q;
}

}  // namespace

/// --by-border: the bands' lower edges (px at 640 columns) and names.
const std::vector<std::pair<double, std::string>>& borderBands() {
  static const std::vector<std::pair<double, std::string>> b{
      {0.0, "0-8 px"}, {8.0, "8-15 px"}, {15.0, "15-30 px"}, {30.0, "30-45 px"}, {45.0, ">=45 px"}};
  return b;
}

/// A pair's layout error as Stats: every placed acupoint in view (published valid or not), its pixel's surface point
/// against the anatomical acupoint (PairScore::layout_mm), of the acupoints in view.
Stats layoutStats(const cect::PairScore& score) {
  Stats st;
  st.queried = score.in_view;
  for (const auto& [name, mm] : score.layout_mm) st.errors_mm.push_back(mm);
  return st;
}

PairResult evaluatePair(const Options& o, const Condition& c, int subject, const cect::AcupointModel& model,
                        const cect::CectParams& params) {
  PairResult res;
  const RenderedPair r = renderPair(o, c, subject);
  const sim::StereoFrame& frame = r.frame;
  const camera::StereoModel geometry(r.pair.left_info, r.pair.right_info);

  // CECT: segmentation to 3D acupoints, timed; SGBM on the same rectified pair.
  const auto t0 = Clock::now();
  const cect::CectFrame f = cect::CectFrame::analyse(frame.left.image, frame.right.image, geometry, params);
  const cect::LocatedAcupoints result = cect::locateAcupoints(f, model, locateOptions(o, r, geometry, subject));
  if (!result.valid) res.failure = result.reason;
  res.check = result.check;
  res.landmarks = cect::describeLandmarks(result.landmarks);
  res.cect_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const auto t1 = Clock::now();
  const cv::Mat sgbm = sgbmDisparity(geometry, frame, o.width);
  res.sgbm_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count();
  const Scorer scorer(f, geometry, frame, r.pair.left.world_from_camera.inverse(), sgbm, &res);

  // Point sets: the model's acupoints, random back pixels, back pixels next to the arms (within 20 px at 640).
  const std::vector<Query> acu = placedAcupointQueries(result, &res);
  const BackQueries back = backQueries(o, frame, geometry, subject);
  std::tie(res.stats["cect/acupoints"], res.stats["sgbm/acupoints"]) =
      scorer.score(acu, static_cast<int>(model.points.size()));
  std::tie(res.stats["cect/random"], res.stats["sgbm/random"]) =
      scorer.score(back.inner, static_cast<int>(back.inner.size()));
  if (o.by_border) scoreByBorder(o, frame, geometry, scorer, &res);

  // The landmarks and the model's placement against the anatomy; the depth at the true acupoint pixels.
  auto turned = r.back->acupoints();
  for (auto& [name, point] : turned) point = r.turn * point;
  const auto anatomical = sim::toCameraFrame(turned, r.pair.left);
  const auto seen = sim::acupointTruth(turned, r.pair, frame);
  res.score = cect::scorePair(result, model, geometry, backTruth(r, seen, anatomical, scorer));
  const std::vector<Query> given = trueAcupointQueries(result, seen, geometry);
  std::tie(res.stats["cect/given"], res.stats["sgbm/given"]) = scorer.score(given, static_cast<int>(given.size()));
  std::tie(res.stats["cect/near_arms"], res.stats["sgbm/near_arms"]) =
      scorer.score(back.near_arms, static_cast<int>(back.near_arms.size()));
  if (!o.pictures.empty()) {
    writePicture(o, c, subject, f, result, anatomical, geometry,
                 [&](const cv::Point2f& q, Eigen::Vector3d* p) { return scorer.truth(q, p); });
  }
  return res;
}

void ConditionResult::add(int subject, const PairResult& r) {
  for (const auto& [key, st] : r.stats) total[key].add(st);
  layout.add(layoutStats(r.score));
  in_view += r.score.in_view;
  valid_in_view += r.score.valid_in_view;
  valid_out_of_view += r.score.valid_out_of_view;
  for (const auto& [name, st] : r.per_point) per_point[name].add(st);
  for (const auto& [key, st] : r.border) border[key].add(st);
  scores.push_back(r.score);
  cect_ms.push_back(r.cect_ms);
  sgbm_ms.push_back(r.sgbm_ms);
  if (!r.failure.empty()) failures.push_back("subject " + std::to_string(subject) + ": " + r.failure);
}

}  // namespace massage_cell::tools::cect_eval
