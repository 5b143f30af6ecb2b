// cect_eval: the thesis's three CECT experiments on rendered subjects
// (ideal conditions over 28 subjects, three light directions, four camera
// shifts), with CECT and dense StereoSGBM at the same pixels against the
// simulator's exact ground truth.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cect_params.h"
#include "cect_scenes.h"
#include "cli.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/evaluation.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/ground_truth.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"
#include "massage_cell/stereo/memory.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using tools::UsageError;
using Clock = std::chrono::steady_clock;

const char* kUsage = R"(Usage: cect_eval [--experiments ideal,lighting,shift] [--subjects N] [--condition-subjects K]
                 [--random-points N] [--width W --height H --fx F --baseline B --camera-height Z]
                 [--yaw DEG] [--raw] [--acupoints FILE] [--seed-step N] [--query-search PX]
                 [--param NAME=VALUE,...] [--csv] [--per-point] [--no-parallax-correction]
                 [--no-3d-levels] [--pictures DIR] [--by-border] [--given-landmarks MM] [--given-levels LIST]
                 [--confirm-given] [--conditions LIST] [--first-subject N] [--no-layout-check] [--trust-c7-at-top]
                 [--trust-inferred-l4]

Renders prone subjects with the scene simulator and localises points on their
backs with CECT (segmentation -> contour correspondences -> barycentric
transfer -> constraints -> 3D) and, at the same left pixels, with dense
StereoSGBM on the same rectified pair. Errors are 3D distances to the exact
surface point seen at that pixel (the simulator's ground truth), in mm.
Experiments (the thesis's Sec. 3.3):
  ideal      subjects 1..N (default 28), light top-centre, no camera shift
  lighting   subjects 1..K (default 8) under lights top-left / top-centre / top-right
  shift      subjects 1..K with the camera shifted 0 / 4 / 7 / 14 cm along the table
  real       the cell as it is (not in the default set): subjects 1..K of a wide
             population (BodyParameters::varied: both sexes, BMI 18-38, six skin
             types) with arms, head in a face cradle, hair, buttocks, sheets of
             several colours, the neck and hips framed in or out of view, under
             the conditions arms_touching, arms_apart (8-20 degrees), arms_raised,
             neck_cut (the image's top edge 1-5 cm above C7), hips_cut (the view
             ending between L2 and mid-buttocks), towel (over the buttocks, many
             colours and weaves), dark_skin (Fitzpatrick V-VI), toe_in (raw
             toe-in rigs, 1-4 degrees, baselines 6-12 cm), mixed (all drawn
             at random), skin_marks (paper tags on acupoints, a strap or a seam
             across the back, tattoos, moles; printed sheets) and photo (colour
             casts, vignetting, motion blur, JPEG; src/tools/cect_scenes.cpp)
Point sets: `acupoints` (every point of the acupoint model, placed by the model
from the left view) and `random` (N random back pixels seen by both cameras,
at least 8 px inside the back's border; default 100 per pair).
p95: the 95th percentile of the localised points' errors.
acc_rate: share of the queried points localised with an error < 10 mm (a point
a method cannot localise counts as a miss). `model` reports how far the model's
placed acupoints lie from the anatomical ones (independent of the matching).
CECT ms: segmentation to 3D acupoints per pair (2 cores).
  --yaw DEG    the subject lies turned by DEG degrees on the table (about the
               vertical through the back's centre; + turns the head toward the
               image right, clockwise on screen): every condition, the ground
               truth turned with it
  --param      set CECT parameters by their CectParams names, e.g.
               --param ncc_radius=9,smooth_radius=2 (see cect.h)
  --csv        print CSV: condition,subject,method,points,mean_mm,max_mm,acc_rate
               (method "model", points "layout": the placed acupoints' layout error)
  --pictures DIR  write every pair's picture to DIR/<condition>_s<subject>.png:
               the rectified left view, the back's contour (magenta), the model's
               midline (yellow), each placed acupoint coloured by CECT's 3D error
               there (green < 5 mm, orange < 10 mm, red >= 10 mm or not
               localised) and the anatomical acupoints (white crosses)
  --no-3d-levels  the waist and the vertebral levels in image rows only (the
               default moves the waist to the spine's height and spaces the
               levels along the body's axis in CECT's 3D: correctWaistParallax,
               measureLevelsIn3D)
  --no-parallax-correction  place the acupoints from the silhouette's centre
               line as it is (the default moves it onto the skin's midline in 3D:
               correctMidlineParallax)
  --given-landmarks MM  the therapist's landmarks: C7 and L4 given to the
               chain as a palpating therapist would click them, each up to MM mm
               (uniform over a disc on the skin, seeded per subject) from the
               simulator's true C7 and iliac-crest line (cect/given_landmarks.h)
  --given-levels LIST  which landmarks --given-landmarks gives, of C7, T7
               (the scapulae's inferior angles' line), L4 (default C7,L4)
  --confirm-given  the clicks confirmed (~set_landmark's confirm): a pair whose
               own C7 or L4 disagrees with them is not refused for it
  --skin-markers  the kit's coloured skin markers (config/skin_markers.yaml, or
               --marker-kit FILE) stuck on each subject's landmarks, rendered, and
               found by the chain in both views (cect/skin_markers.h)
  --marker-kit FILE  the skin-marker kit for --skin-markers
  --no-layout-check  publish every layout the chain finds (the default refuses
               one that fails the plausibility checks: cect/layout_check.h)
  --trust-c7-at-top  trust a C7 taken from the back's top where no neck is in
               view (the default refuses it: the thesis's armless torso, the
               ideal / lighting / shift experiments, has no neck, its back ends
               at the neck's base)
  --trust-inferred-l4  trust an L4 inferred from C7 and the shoulder width where
               no waist is seen (the default refuses it)
  --conditions LIST  the realistic conditions to run, comma-separated (default:
               all of them, in the order above)
  --first-subject N  the realistic conditions' subjects start at N (default 1;
               the figures of docs/ were tuned on 1..28: 29.. are unseen)
  --per-point  also print, per condition, every acupoint's CECT figures over the
               subjects and the commonest reason it was not localised
  --by-border  also print, per condition, both methods' figures on every 4th
               back pixel (seen by both cameras) by its distance to the back's
               border in the left view (bands 0-8, 8-15, 15-30, 30-45, >= 45 px,
               scaled by the width / 640): what a caller of ~localize_pixels
               gets near the flanks and the shoulders' top, and how well CECT's
               uncertainty covers it (median disparity sigma; share of the
               disparity errors within 2 sigma, 95 % when calibrated)
)";

struct Options {
  std::vector<std::string> experiments{"ideal", "lighting", "shift"};
  std::vector<std::string> conditions;  ///< --conditions: the realistic ones to run (empty: all)
  int subjects = 28;
  int condition_subjects = 8;
  int random_points = 100;
  int width = 640, height = 480;
  double fx = 500.0, baseline = 0.10, camera_height = 0.95;
  double yaw_deg = 0.0;  ///< the subject turned on the table
  bool raw = false;
  bool csv = false;
  bool per_point = false;
  bool by_border = false;  ///< --by-border
  double given_mm = -1.0;  ///< --given-landmarks: C7 and L4 clicked within this many mm (< 0: none given)
  std::vector<std::string> given_levels{"C7", "L4"};  ///< --given-levels: which ones are clicked
  bool confirm_given = false;      ///< --confirm-given: the clicks confirmed over the pair's own landmarks
  int first_subject = 1;           ///< --first-subject (the realistic conditions)
  bool layout_check = true;        ///< --no-layout-check: false
  bool trust_c7_at_top = false;    ///< --trust-c7-at-top
  bool trust_inferred_l4 = false;  ///< --trust-inferred-l4
  std::string marker_kit;          ///< --marker-kit (empty: the package's config/skin_markers.yaml)
  std::optional<cect::SkinMarkerOptions> markers;  ///< --skin-markers: the kit, rendered and looked for
  bool parallax = true;                            ///< the model's midline corrected for the silhouette's parallax (3D)
  bool levels_3d = true;                           ///< the levels spaced along the body's axis in 3D
  std::string acupoints;
  std::string pictures;  ///< --pictures: a folder for every pair's picture
  int seed_step = -1;
  double query_search = -1.0;
  std::vector<std::pair<std::string, double>> params;  ///< --param
};

struct Condition {
  std::string name;
  sim::LightPreset light = sim::LightPreset::kTopCentre;
  double shift = 0.0;
  std::vector<int> subjects;
  bool real = false;  ///< a realistic condition (cect_scenes.h: realScenario(name, ...))
};

/// The set-up of one pair of condition `c`.
tools::Scenario scenarioFor(const Options& o, const Condition& c, int subject) {
  sim::RigParameters rig;
  rig.width = o.width;
  rig.height = o.height;
  rig.fx = o.fx;
  rig.baseline = o.baseline;
  rig.centre.z() = o.camera_height;
  rig.rectified = !o.raw;
  if (c.real) return tools::realScenario(c.name, subject, rig);
  tools::Scenario s;
  s.body = sim::BodyParameters::subject(subject);
  rig.shift = c.shift;
  s.rig = rig;
  s.light = c.light;
  s.yaw_deg = o.yaw_deg;
  return s;
}

/// Errors of one method on one point set of one pair.
struct Stats {
  int queried = 0;
  std::vector<double> errors_mm;  ///< localised points only
  /// Mean, p95 (nearest rank) and max of the errors (cect/evaluation.h); NaN each when none.
  cect::Spread spread() const { return cect::spreadOf(errors_mm); }
  double accRate() const {
    if (queried == 0) return std::nan("");
    return static_cast<double>(std::count_if(errors_mm.begin(), errors_mm.end(), [](double e) { return e < 10.0; })) /
           queried;
  }
  std::map<std::string, int> misses;  ///< why queried points were not localised
  /// CECT's uncertainty: per localised point its disparity sigma (px) and
  /// |disparity error| / sigma.
  std::vector<double> sigma_px, z;
  /// Share of the localised points whose disparity error is within 2 sigma
  /// (95 % for a calibrated Gaussian sigma).
  double within2Sigma() const {
    if (z.empty()) return std::nan("");
    return static_cast<double>(std::count_if(z.begin(), z.end(), [](double v) { return v <= 2.0; })) / z.size();
  }
  void add(const Stats& o) {
    queried += o.queried;
    errors_mm.insert(errors_mm.end(), o.errors_mm.begin(), o.errors_mm.end());
    sigma_px.insert(sigma_px.end(), o.sigma_px.begin(), o.sigma_px.end());
    z.insert(z.end(), o.z.begin(), o.z.end());
    for (const auto& [why, n] : o.misses) misses[why] += n;
  }
  std::string commonestMiss() const {
    const auto it = std::max_element(misses.begin(), misses.end(),
                                     [](const auto& a, const auto& b) { return a.second < b.second; });
    return it == misses.end() ? std::string() : it->first + " (" + std::to_string(it->second) + ")";
  }
};

/// Bilinear sample of a CV_32FC3 / CV_32F map where all four neighbours are finite.
bool sampleMap(const cv::Mat& m, double x, double y, Eigen::Vector3d* out) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return false;
  const double fx = x - x0, fy = y - y0;
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (int dy = 0; dy <= 1; ++dy)
    for (int dx = 0; dx <= 1; ++dx) {
      Eigen::Vector3d v;
      if (m.type() == CV_32FC3) {
        const cv::Vec3f p = m.at<cv::Vec3f>(y0 + dy, x0 + dx);
        v = Eigen::Vector3d(p[0], p[1], p[2]);
      } else {
        v = Eigen::Vector3d::Constant(m.at<float>(y0 + dy, x0 + dx));
      }
      if (!v.allFinite()) return false;
      acc += (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * v;
    }
  *out = acc;
  return true;
}

/// --by-border: the bands' lower edges (px at 640 columns) and names.
const std::vector<std::pair<double, std::string>>& borderBands() {
  static const std::vector<std::pair<double, std::string>> b{
      {0.0, "0-8 px"}, {8.0, "8-15 px"}, {15.0, "15-30 px"}, {30.0, "30-45 px"}, {45.0, ">=45 px"}};
  return b;
}

struct PairResult {
  std::map<std::string, Stats> stats;      ///< "cect/acupoints", "sgbm/random", ...
  std::map<std::string, Stats> per_point;  ///< CECT on each acupoint (by name)
  std::map<std::string, Stats> border;     ///< --by-border: "cect/<band>", "sgbm/<band>"
  double cect_ms = 0.0, sgbm_ms = 0.0;
  std::string failure;  ///< CECT's reason when the frame was not usable
  /// The landmarks, the layout (placed vs anatomical acupoints) and the acupoints in view against the anatomy
  /// (cect/evaluation.h)
  cect::PairScore score;
  cect::LayoutCheck check;  ///< the layout's plausibility as the chain judged it
  std::string landmarks;    ///< describeLandmarks
};

/// A pair's layout error as Stats: every placed acupoint in view (published valid or not), its pixel's surface point
/// against the anatomical acupoint (PairScore::layout_mm), of the acupoints in view.
Stats layoutStats(const cect::PairScore& score) {
  Stats st;
  st.queried = score.in_view;
  for (const auto& [name, mm] : score.layout_mm) st.errors_mm.push_back(mm);
  return st;
}

/// --pictures: one pair's picture (see the usage).
void writePicture(const Options& o, const Condition& c, int subject, const cect::CectFrame& f,
                  const cect::LocatedAcupoints& result, const std::map<std::string, Eigen::Vector3d>& anatomical,
                  const camera::StereoModel& geometry,
                  const std::function<bool(const cv::Point2f&, Eigen::Vector3d*)>& truth) {
  const cect::BackLandmarks& lm = result.landmarks;
  cv::Mat img;
  if (!f.leftRectified().empty()) {
    img = f.leftRectified().clone();
  } else {
    img = cv::Mat(o.height, o.width, CV_8UC3, cv::Scalar::all(0));
  }
  if (!f.left().contour.empty()) {
    std::vector<cv::Point> contour;
    for (const auto& p : f.left().contour) contour.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, contour, true, cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  }
  if (lm.valid && lm.midline.size() > 1) {
    std::vector<cv::Point> mid;
    for (const auto& p : lm.midline) {
      const cv::Point2f q = cect::toImage(lm, p);
      mid.emplace_back(cvRound(q.x), cvRound(q.y));
    }
    cv::polylines(img, mid, false, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  for (const auto& [name, p] : anatomical) {
    const Eigen::Vector3d q = geometry.project(p);
    cv::drawMarker(img, cv::Point(cvRound(q.x()), cvRound(q.y())), cv::Scalar(255, 255, 255), cv::MARKER_CROSS, 5, 1);
  }
  for (const cect::LocatedAcupoint& a : result.points) {
    if (!a.placed) continue;
    Eigen::Vector3d gt;
    double err = std::numeric_limits<double>::infinity();
    if (a.valid && truth(a.rectified, &gt)) err = 1000.0 * (a.point.position - gt).norm();
    const cv::Scalar colour = err < 5.0    ? cv::Scalar(0, 220, 0)
                              : err < 10.0 ? cv::Scalar(0, 165, 255)
                                           : cv::Scalar(0, 0, 255);
    cv::circle(img, cv::Point(cvRound(a.rectified.x), cvRound(a.rectified.y)), 2, colour, -1, cv::LINE_AA);
  }
  std::ostringstream text;
  text << c.name << ", subject " << subject;
  if (lm.valid && lm.body_angle_deg != 0.0)
    text << ", turned " << std::fixed << std::setprecision(1) << lm.body_angle_deg << " deg";
  if (!result.valid) text << ": " << result.reason;
  cv::putText(img, f.left().trunk.summary(), cv::Point(8, 36), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 255, 255),
              1, cv::LINE_AA);
  cv::putText(img, text.str(), cv::Point(8, 18), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  std::ostringstream name;
  name << o.pictures << "/" << c.name << "_s" << std::setw(2) << std::setfill('0') << subject << ".png";
  if (!cv::imwrite(name.str(), img)) throw std::runtime_error("cannot write '" + name.str() + "'");
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

/// StereoSGBM (3-way) on the rectified pair: disparities, NaN where it gives none.
cv::Mat sgbmDisparity(const camera::StereoModel& geometry, const sim::StereoFrame& frame, int width) {
  cv::Mat left_rect, right_rect, disp16, disp;
  geometry.rectify(frame.left.image, frame.right.image, &left_rect, &right_rect);
  const int block = 5, num = 16 * static_cast<int>(std::ceil(width / 5.0 / 16.0));
  auto sgbm = cv::StereoSGBM::create(0, num, block, 8 * 3 * block * block, 32 * 3 * block * block, 1, 63, 10, 100, 1,
                                     cv::StereoSGBM::MODE_SGBM_3WAY);
  sgbm->compute(left_rect, right_rect, disp16);
  disp16.convertTo(disp, CV_32F, 1.0 / 16.0);
  disp.setTo(std::numeric_limits<float>::quiet_NaN(), disp16 < 0);
  return disp;
}

/// A rectified left pixel to score, and CECT's point there when it is already known (the placed acupoints).
struct Query {
  cv::Point2f rect;
  const cect::LocalizedPoint* cect = nullptr;
  std::string name;  ///< acupoints
};

/// Up to `count` of the mask's pixels in a shuffled order (seeded), as rectified queries.
std::vector<Query> randomQueries(const cv::Mat& mask, std::uint32_t seed, int count,
                                 const camera::StereoModel& geometry) {
  std::vector<cv::Point> pts;
  cv::findNonZero(mask, pts);
  std::mt19937 rng(seed);
  std::shuffle(pts.begin(), pts.end(), rng);
  std::vector<Query> out;
  for (int i = 0; i < count && i < static_cast<int>(pts.size()); ++i)
    out.push_back(Query{geometry.toRectified(cv::Point2f(pts[static_cast<std::size_t>(i)])), nullptr, {}});
  return out;
}

/// CECT's and StereoSGBM's 3D errors at query pixels against the rendered surface.
class Scorer {
 public:
  Scorer(const cect::CectFrame& f, const camera::StereoModel& geometry, const sim::StereoFrame& frame,
         const Eigen::Isometry3d& left_from_world, const cv::Mat& sgbm, PairResult* res)
      : f_(f), geometry_(geometry), frame_(frame), left_from_world_(left_from_world), sgbm_(sgbm), res_(res) {}

  /// The surface point seen at a rectified left pixel.
  bool truth(const cv::Point2f& rect, Eigen::Vector3d* p) const {
    const cv::Point2f raw = geometry_.toRaw(rect);
    Eigen::Vector3d w;
    if (!sampleMap(frame_.left.points, raw.x, raw.y, &w)) return false;
    *p = left_from_world_ * w;
    return true;
  }

  /// CECT's and SGBM's figures on a point set (`queried`: the set's nominal size; queries without ground truth
  /// are not counted). Named queries also fill the per-point figures.
  std::pair<Stats, Stats> score(const std::vector<Query>& qs, int queried) const {
    Stats sc, ss;
    sc.queried = ss.queried = queried;
    for (const Query& q : qs) {
      Eigen::Vector3d gt;
      if (!truth(q.rect, &gt)) {  // off the surface: not a fair query for either method
        --sc.queried;
        --ss.queried;
        continue;
      }
      const cect::LocalizedPoint lp = q.cect ? *q.cect : f_.localizeRectified(q.rect);
      if (lp.valid) {
        sc.errors_mm.push_back(1000.0 * (lp.position - gt).norm());
        sc.sigma_px.push_back(lp.disparity_sigma);
        sc.z.push_back(std::abs(lp.disparity - geometry_.project(gt).z()) / std::max(lp.disparity_sigma, 1e-9));
      }
      if (!q.name.empty()) {
        Stats& pp = res_->per_point[q.name];
        pp.queried = 1;
        if (lp.valid)
          pp.errors_mm.push_back(sc.errors_mm.back());
        else
          pp.misses[lp.reason.substr(0, lp.reason.find(" by "))] = 1;
      }
      Eigen::Vector3d ps;
      if (sgbmPoint(q.rect, &ps)) ss.errors_mm.push_back(1000.0 * (ps - gt).norm());
    }
    return std::make_pair(sc, ss);
  }

 private:
  bool sgbmPoint(const cv::Point2f& q, Eigen::Vector3d* p) const {
    Eigen::Vector3d d;
    if (!sampleMap(sgbm_, q.x, q.y, &d) || !(d.x() > 0)) return false;
    *p = geometry_.triangulate(q.x, q.y, d.x());
    return true;
  }

  const cect::CectFrame& f_;
  const camera::StereoModel& geometry_;
  const sim::StereoFrame& frame_;
  const Eigen::Isometry3d left_from_world_;
  const cv::Mat& sgbm_;
  PairResult* res_;
};

/// --by-border: every 4th back pixel, by its distance to the back's border, scored per band.
void scoreByBorder(const Options& o, const sim::StereoFrame& frame, const camera::StereoModel& geometry,
                   const Scorer& scorer, PairResult* res) {
  cv::Mat back_mask = (frame.left.labels == sim::kLabelBack) & (frame.left_visible > 0);
  cv::Mat dist;
  cv::distanceTransform(back_mask, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const double k = o.width / 640.0;
  std::map<std::string, std::vector<Query>> bands;
  for (int y = 2; y < back_mask.rows; y += 4)
    for (int x = 2; x < back_mask.cols; x += 4) {
      if (!back_mask.at<std::uint8_t>(y, x)) continue;
      const double dpx = dist.at<float>(y, x) / k;
      std::size_t b = 0;
      while (b + 1 < borderBands().size() && dpx >= borderBands()[b + 1].first) ++b;
      const cv::Point2f raw(static_cast<float>(x), static_cast<float>(y));
      bands[borderBands()[b].second].push_back(Query{geometry.toRectified(raw), nullptr, {}});
    }
  for (const auto& [band, qs] : bands)
    std::tie(res->border["cect/" + band], res->border["sgbm/" + band]) = scorer.score(qs, static_cast<int>(qs.size()));
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

PairResult evaluatePair(const Options& o, const Condition& c, int subject, const cect::AcupointModel& model,
                        const cect::CectParams& params) {
  PairResult res;
  const RenderedPair r = renderPair(o, c, subject);
  const sim::StereoFrame& frame = r.frame;
  const camera::StereoModel geometry(r.pair.left_info, r.pair.right_info);

  // CECT: segmentation to 3D acupoints, timed; SGBM on the same rectified pair.
  const auto t0 = Clock::now();
  const cect::CectFrame f = cect::CectFrame::analyse(frame.left.image, frame.right.image, geometry, params);
  cect::LocateOptions lo;
  lo.correct_parallax = o.parallax;
  lo.levels_in_3d = o.levels_3d;
  lo.check_layout = o.layout_check;
  lo.trust.c7_at_neck = !o.trust_c7_at_top;
  lo.trust.l4_measured = !o.trust_inferred_l4;
  if (o.given_mm >= 0.0) lo.given = clickedLandmarks(r, geometry, o.given_mm, o.given_levels, subject);
  for (cect::GivenLandmark& g : lo.given) g.confirmed = o.confirm_given;
  const cect::LocatedAcupoints result = cect::locateAcupoints(f, model, lo);
  if (!result.valid) res.failure = result.reason;
  res.check = result.check;
  res.landmarks = cect::describeLandmarks(result.landmarks);
  res.cect_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const auto t1 = Clock::now();
  const cv::Mat sgbm = sgbmDisparity(geometry, frame, o.width);
  res.sgbm_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count();
  const Scorer scorer(f, geometry, frame, r.pair.left.world_from_camera.inverse(), sgbm, &res);

  // Point sets: the model's acupoints, random back pixels, back pixels next to the arms (within 20 px at 640).
  std::vector<Query> acu;
  for (const cect::LocatedAcupoint& a : result.points)
    if (a.placed) {
      acu.push_back(Query{a.rectified, &a.point, a.name});
    } else if (result.valid) {
      Stats& pp = res.per_point[a.name];
      pp.queried = 1;
      pp.misses["placement: " + a.reason] = 1;
    }
  const cv::Mat visible_back = (frame.left.labels == sim::kLabelBack) & (frame.left_visible > 0);
  cv::Mat inner_back;
  cv::erode(visible_back, inner_back, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(17, 17)));
  const std::vector<Query> rnd =
      randomQueries(inner_back, static_cast<std::uint32_t>(1000 + subject), o.random_points, geometry);
  std::vector<Query> near_arms;
  const cv::Mat arms = frame.left.labels == sim::kLabelArm;
  if (cv::countNonZero(arms) > 0) {
    const int radius = std::max(2, cvRound(20.0 * o.width / 640.0));
    cv::Mat near;
    cv::dilate(arms, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
    near_arms =
        randomQueries(near & visible_back, static_cast<std::uint32_t>(2000 + subject), o.random_points, geometry);
  }
  std::tie(res.stats["cect/acupoints"], res.stats["sgbm/acupoints"]) =
      scorer.score(acu, static_cast<int>(model.points.size()));
  std::tie(res.stats["cect/random"], res.stats["sgbm/random"]) = scorer.score(rnd, static_cast<int>(rnd.size()));
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
      scorer.score(near_arms, static_cast<int>(near_arms.size()));
  if (!o.pictures.empty()) {
    writePicture(o, c, subject, f, result, anatomical, geometry,
                 [&](const cv::Point2f& q, Eigen::Vector3d* p) { return scorer.truth(q, p); });
  }
  return res;
}

std::string fmt(double v, int prec = 2) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(prec) << v;
  return s.str();
}

/// One condition's line of the closing table.
struct SummaryRow {
  std::string condition;
  int in_view = 0, valid_in_view = 0, valid_out_of_view = 0;  ///< over every pair (published or not)
  Stats layout, given, sgbm_given, near_arms;
  double cect_ms = 0.0;
  cect::ScoreSummary landmarks;
  double placedShare() const { return in_view ? 100.0 * valid_in_view / in_view : std::nan(""); }
};

/// The closing table: per condition, the acupoints in view and placed, the
/// layout's error, and the 3D error at the true acupoint pixels.
void printSummary(const std::vector<SummaryRow>& rows) {
  std::cout << "Summary (acupoints in view = the simulator's truth; layout = the placed pixel's surface point vs the\n"
               "anatomical acupoint; given = CECT at the true acupoint pixels; near arms = back pixels within 20 px of "
               "an arm)\n"
            << std::left << std::setw(18) << "condition" << std::right << std::setw(8) << "in view" << std::setw(9)
            << "placed%" << std::setw(8) << "extra" << std::setw(12) << "layout mm" << std::setw(10) << "lay p95"
            << std::setw(11) << "given mm" << std::setw(10) << "giv p95" << std::setw(9) << "giv<1cm" << std::setw(10)
            << "sgbm<1cm" << std::setw(10) << "arms mm" << std::setw(10) << "arms<1cm" << std::setw(8) << "ms"
            << "\n";
  for (const SummaryRow& r : rows) {
    const cect::Spread layout = r.layout.spread(), given = r.given.spread();
    std::cout << std::left << std::setw(18) << r.condition << std::right << std::setw(8) << r.in_view << std::setw(9)
              << fmt(r.placedShare(), 1) << std::setw(8) << r.valid_out_of_view << std::setw(12) << fmt(layout.mean, 1)
              << std::setw(10) << fmt(layout.p95, 1) << std::setw(11) << fmt(given.mean) << std::setw(10)
              << fmt(given.p95) << std::setw(8) << fmt(100.0 * r.given.accRate(), 1) << "%" << std::setw(9)
              << fmt(100.0 * r.sgbm_given.accRate(), 1) << "%" << std::setw(10) << fmt(r.near_arms.spread().mean)
              << std::setw(9) << fmt(100.0 * r.near_arms.accRate(), 1) << "%" << std::setw(8) << fmt(r.cect_ms, 1)
              << "\n";
  }
}

/// The closing landmark table: per condition, the levels along the body, the spine line across, refusals and the
/// pairs wrongly trusted.
void printLandmarkSummary(const std::vector<SummaryRow>& rows) {
  std::cout
      << "\nLandmarks against the anatomy (published pairs; mean / p95 mm along the body; spine line mean mm across;\n"
         "layout = their acupoints against the anatomical ones, mean / p95 mm; refused = pairs not published;\n"
         "wrong = published with a level along the body or the spine line across it more than "
      << fmt(cect::PairScore::kWrongLevelMm, 0) << " mm off)\n"
      << std::left << std::setw(18) << "condition" << std::right << std::setw(14) << "C7" << std::setw(14) << "T7"
      << std::setw(14) << "L4" << std::setw(8) << "spine" << std::setw(14) << "layout" << std::setw(10) << "refused"
      << std::setw(8) << "wrong" << std::setw(9) << "placed%"
      << "\n";
  for (const SummaryRow& r : rows) {
    const cect::ScoreSummary& l = r.landmarks;
    auto level = [&](const char* name) {
      const cect::Spread& s = l.levels.at(name);
      return fmt(s.mean, 1) + " / " + fmt(s.p95, 1);
    };
    std::cout << std::left << std::setw(18) << r.condition << std::right << std::setw(14) << level("C7")
              << std::setw(14) << level("T7") << std::setw(14) << level("L4") << std::setw(8)
              << fmt(l.midline_across.mean, 1) << std::setw(14)
              << (fmt(l.layout.mean, 1) + " / " + fmt(l.layout.p95, 1)) << std::setw(10)
              << (std::to_string(l.refused) + "/" + std::to_string(l.pairs)) << std::setw(8) << l.wrongly_trusted
              << std::setw(9) << fmt(100.0 * l.placedShare(), 1) << "\n";
  }
}

/// The experiments' conditions, each with its subjects.
std::vector<Condition> conditionsOf(const Options& o) {
  std::vector<Condition> conditions;
  auto range = [](int n, int first = 1) {
    std::vector<int> v;
    for (int i = first; i < first + n; ++i) v.push_back(i);
    return v;
  };
  for (const std::string& e : o.experiments) {
    if (e == "ideal") {
      conditions.push_back({"ideal", sim::LightPreset::kTopCentre, 0.0, range(o.subjects)});
    } else if (e == "lighting") {
      conditions.push_back({"light_top_left", sim::LightPreset::kTopLeft, 0.0, range(o.condition_subjects)});
      conditions.push_back({"light_top_centre", sim::LightPreset::kTopCentre, 0.0, range(o.condition_subjects)});
      conditions.push_back({"light_top_right", sim::LightPreset::kTopRight, 0.0, range(o.condition_subjects)});
    } else if (e == "real") {
      for (const std::string& name : o.conditions.empty() ? tools::realConditions() : o.conditions)
        conditions.push_back(
            {name, sim::LightPreset::kTopCentre, 0.0, range(o.condition_subjects, o.first_subject), true});
    } else if (e == "shift") {
      for (int cm : {0, 4, 7, 14})
        conditions.push_back({"shift_" + std::to_string(cm) + "cm", sim::LightPreset::kTopCentre, cm / 100.0,
                              range(o.condition_subjects)});
    }
  }
  return conditions;
}

/// One condition's pairs added up.
struct ConditionResult {
  std::map<std::string, Stats> total, per_point, border;
  /// The layout and the acupoints in view over every pair, published or not (the pairs' PairScores added up;
  /// ScoreSummary's are over the published pairs)
  Stats layout;
  int in_view = 0, valid_in_view = 0, valid_out_of_view = 0;
  std::vector<double> cect_ms, sgbm_ms;
  std::vector<std::string> failures;
  std::vector<cect::PairScore> scores;  ///< per pair: landmarks, layout, trust
};

/// Every subject of the condition (--csv: a row per subject and figure as they come).
ConditionResult evaluateCondition(const Options& o, const Condition& c, const cect::AcupointModel& model,
                                  const cect::CectParams& params) {
  ConditionResult cr;
  for (int s : c.subjects) {
    const PairResult r = evaluatePair(o, c, s, model, params);
    for (const auto& [key, st] : r.stats) {
      cr.total[key].add(st);
      if (o.csv) {
        const auto slash = key.find('/');
        std::cout << c.name << "," << s << "," << key.substr(0, slash) << "," << key.substr(slash + 1) << ","
                  << fmt(st.spread().mean, 3) << "," << fmt(st.spread().max, 3) << "," << fmt(st.accRate(), 4) << "\n";
      }
    }
    const Stats layout = layoutStats(r.score);
    cr.layout.add(layout);
    if (o.csv)
      std::cout << c.name << "," << s << ",model,layout," << fmt(layout.spread().mean, 3) << ","
                << fmt(layout.spread().max, 3) << "," << fmt(layout.accRate(), 4) << "\n";
    cr.in_view += r.score.in_view;
    cr.valid_in_view += r.score.valid_in_view;
    cr.valid_out_of_view += r.score.valid_out_of_view;
    for (const auto& [name, st] : r.per_point) cr.per_point[name].add(st);
    for (const auto& [key, st] : r.border) cr.border[key].add(st);
    cr.scores.push_back(r.score);
    if (o.csv) {
      const cect::PairScore& ps = r.score;
      std::cout << c.name << "," << s << ",landmarks," << (ps.published ? "published" : "refused");
      for (const cect::LevelError& e : ps.levels) std::cout << "," << e.level << "=" << fmt(e.along_mm, 1);
      const cect::LayoutCheck& k = r.check;
      std::cout << ",midline=" << fmt(ps.midline_across_mm, 1) << ",length_m=" << fmt(k.length_m, 3)
                << ",shoulder_m=" << fmt(k.shoulder_width_m, 3) << ",ratio=" << fmt(k.length_per_shoulder_width, 3)
                << ",shoulder_below_c7=" << fmt(k.shoulder_below_c7, 3) << ",\"" << r.landmarks << "\"\n";
    }
    cr.cect_ms.push_back(r.cect_ms);
    cr.sgbm_ms.push_back(r.sgbm_ms);
    if (!r.failure.empty()) cr.failures.push_back("subject " + std::to_string(s) + ": " + r.failure);
  }
  return cr;
}

std::string validShare(const Stats& st) {
  return fmt(st.queried ? 100.0 * st.errors_mm.size() / st.queried : std::nan(""), 1);
}

/// mean / p95 / max of a spread, one decimal.
std::string spreadText(const cect::Spread& s) { return fmt(s.mean, 1) + " / " + fmt(s.p95, 1) + " / " + fmt(s.max, 1); }

/// The condition's landmarks against the anatomy and how often the layout was trusted when it should not have been.
void printLandmarks(const std::string& condition, const cect::ScoreSummary& l) {
  std::cout << std::left << std::setw(18) << condition << "landmarks of the " << l.published
            << " published pairs (mean / p95 / max mm along the body):";
  for (const std::string& level : cect::scoredLevels())
    std::cout << " " << level << " " << spreadText(l.levels.at(level)) << ";";
  std::cout << " spine line across " << spreadText(l.midline_across) << "\n"
            << std::setw(18) << ""
            << "refused " << l.refused << " of " << l.pairs << " pairs (" << l.refused_wrong << " of them > "
            << fmt(cect::PairScore::kWrongLevelMm, 0)
            << " mm off); wrongly trusted (published, a level along the body or the spine line across it > "
            << fmt(cect::PairScore::kWrongLevelMm, 0) << " mm off) " << l.wrongly_trusted << "\n";
}

/// The condition's table rows, the placement and timing line, the acupoints in view, the failures and the sigmas;
/// returns its summary row.
SummaryRow printCondition(const Condition& c, ConditionResult& cr) {
  for (const auto& [key, st] : cr.total) {
    const auto slash = key.find('/');
    const cect::Spread e = st.spread();
    std::cout << std::left << std::setw(18) << c.name << std::setw(8) << key.substr(0, slash) << std::setw(11)
              << key.substr(slash + 1) << std::right << std::setw(8) << st.queried << std::setw(8) << validShare(st)
              << std::setw(9) << fmt(e.mean) << std::setw(9) << fmt(e.max) << std::setw(9) << fmt(e.p95) << std::setw(8)
              << fmt(100.0 * st.accRate(), 1) << "%\n";
  }
  const cect::Spread layout = cr.layout.spread(), cect_ms = cect::spreadOf(cr.cect_ms),
                     sgbm_ms = cect::spreadOf(cr.sgbm_ms);
  std::cout << std::left << std::setw(18) << c.name << "model placement vs anatomical acupoints: mean "
            << fmt(layout.mean, 1) << " mm, max " << fmt(layout.max, 1) << " mm; CECT " << fmt(cect_ms.median, 1)
            << " ms median (max " << fmt(cect_ms.max, 1) << "), SGBM " << fmt(sgbm_ms.median, 1) << " ms; "
            << c.subjects.size() << " subjects\n";
  const Stats& g = cr.total["cect/given"];
  const Stats& sg = cr.total["sgbm/given"];
  const cect::Spread ge = g.spread();
  SummaryRow row{c.name, cr.in_view, cr.valid_in_view,           cr.valid_out_of_view, cr.layout,
                 g,      sg,         cr.total["cect/near_arms"], cect_ms.median,       cect::summarise(cr.scores)};
  printLandmarks(c.name, row.landmarks);
  std::cout << std::left << std::setw(18) << c.name << "acupoints in view " << cr.in_view << ": "
            << fmt(row.placedShare(), 1) << " % placed (" << cr.valid_out_of_view
            << " placed though out of view); layout vs anatomical mean " << fmt(layout.mean, 1) << " mm, p95 "
            << fmt(layout.p95, 1) << " mm\n"
            << std::setw(18) << ""
            << "at the true acupoint pixels: CECT mean " << fmt(ge.mean) << " mm, p95 " << fmt(ge.p95) << ", "
            << fmt(100.0 * g.accRate(), 1) << " % within 1 cm; SGBM mean " << fmt(sg.spread().mean) << " mm, "
            << fmt(100.0 * sg.accRate(), 1) << " % within 1 cm\n";
  for (const auto& f : cr.failures) std::cout << "  CECT failed on " << f << "\n";
  const Stats& a = cr.total["cect/acupoints"];
  const Stats& r = cr.total["cect/random"];
  std::cout << std::left << std::setw(18) << c.name << "CECT's disparity sigma: acupoints median "
            << fmt(cect::spreadOf(a.sigma_px).median) << " px, " << fmt(100.0 * a.within2Sigma(), 1)
            << " % of their errors within 2 sigma; random points " << fmt(cect::spreadOf(r.sigma_px).median) << " px, "
            << fmt(100.0 * r.within2Sigma(), 1) << " %\n";
  return row;
}

/// --by-border: the back's pixels by their distance to the border, per band and method.
void printBorderBands(const std::map<std::string, Stats>& border) {
  std::cout << "  back pixels by distance to the border (every 4th pixel, both views):\n"
            << "  " << std::left << std::setw(10) << "band" << std::setw(8) << "method" << std::right << std::setw(8)
            << "queried" << std::setw(8) << "valid%" << std::setw(9) << "mean mm" << std::setw(9) << "max mm"
            << std::setw(9) << "acc<1cm" << std::setw(10) << "sigma px" << std::setw(9) << "in 2sig"
            << "\n";
  for (const auto& [edge, band] : borderBands())
    for (const char* method : {"cect", "sgbm"}) {
      const auto it = border.find(std::string(method) + "/" + band);
      if (it == border.end()) continue;
      const Stats& st = it->second;
      std::cout << "  " << std::left << std::setw(10) << band << std::setw(8) << method << std::right << std::setw(8)
                << st.queried << std::setw(8) << validShare(st) << std::setw(9) << fmt(st.spread().mean) << std::setw(9)
                << fmt(st.spread().max) << std::setw(8) << fmt(100.0 * st.accRate(), 1) << "%" << std::setw(10)
                << fmt(cect::spreadOf(st.sigma_px).median) << std::setw(8) << fmt(100.0 * st.within2Sigma(), 1)
                << (st.z.empty() ? " " : "%") << "\n";
    }
}

/// --per-point: every acupoint of the model.
void printPerPoint(const std::map<std::string, Stats>& per_point, const cect::AcupointModel& model) {
  std::cout << "  " << std::left << std::setw(14) << "acupoint" << std::right << std::setw(8) << "queried"
            << std::setw(8) << "valid%" << std::setw(9) << "mean mm" << std::setw(9) << "max mm" << std::setw(9)
            << "acc<1cm"
            << "  commonest miss\n";
  for (const std::string& name : model.names()) {
    const auto it = per_point.find(name);
    if (it == per_point.end()) continue;
    const Stats& st = it->second;
    std::cout << "  " << std::left << std::setw(14) << name << std::right << std::setw(8) << st.queried << std::setw(8)
              << validShare(st) << std::setw(9) << fmt(st.spread().mean) << std::setw(9) << fmt(st.spread().max)
              << std::setw(8) << fmt(100.0 * st.accRate(), 1) << "%  " << st.commonestMiss() << "\n";
  }
}

/// --skin-markers: the kit, every sticker in a colour the simulator has.
cect::SkinMarkerOptions loadKit(const std::string& path) {
  const std::string file = path.empty() ? tools::packageFile("config/skin_markers.yaml") : path;
  cect::SkinMarkerOptions kit;
  try {
    kit = cect::loadSkinMarkerOptions(file);
    for (const cect::SkinMarkerSpec& m : kit.markers) (void)sim::stickerColour(m.colour);
  } catch (const std::exception& e) {
    tools::require(false, std::string("--skin-markers: ") + e.what());
  }
  return kit;
}

void run(const Options& o) {
  stereo::retainFreedMemory();  // page faults would otherwise dominate the per-pair timings
  const cect::AcupointModel model =
      cect::loadAcupointModel(o.acupoints.empty() ? tools::packageFile("config/acupoints.yaml") : o.acupoints);
  cect::CectParams params;
  if (o.seed_step >= 0) params.seed_step = o.seed_step;
  if (o.query_search >= 0) params.query_search = o.query_search;
  tools::applyParams(params, o.params);
  params.skin_markers = o.markers;

  if (o.csv)
    std::cout << "condition,subject,method,points,mean_mm,max_mm,acc_rate\n";
  else
    std::cout << "CECT vs StereoSGBM at the same left pixels; " << o.width << "x" << o.height << ", fx " << o.fx
              << " px, baseline " << o.baseline << " m, camera " << o.camera_height << " m above the table"
              << (o.yaw_deg != 0.0 ? ", subject turned " + fmt(o.yaw_deg, 1) + " deg" : std::string())
              << (o.raw ? ", raw (distorted, unrectified) pairs" : ", rectified pairs") << "\n\n"
              << std::left << std::setw(18) << "condition" << std::setw(8) << "method" << std::setw(11) << "points"
              << std::right << std::setw(8) << "queried" << std::setw(8) << "valid%" << std::setw(9) << "mean mm"
              << std::setw(9) << "max mm" << std::setw(9) << "p95 mm" << std::setw(9) << "acc<1cm"
              << "\n";
  std::vector<SummaryRow> summary;
  for (const Condition& c : conditionsOf(o)) {
    ConditionResult cr = evaluateCondition(o, c, model, params);
    if (o.csv) continue;
    summary.push_back(printCondition(c, cr));
    if (o.by_border) printBorderBands(cr.border);
    if (o.per_point) printPerPoint(cr.per_point, model);
    std::cout << "\n";
  }
  if (!o.csv) {
    printSummary(summary);
    printLandmarkSummary(summary);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return tools::runTool(
      "cect_eval",
      [&] {
        tools::OptionTable t;
        t.values["--experiments"] = [&](const std::string& opt, const std::string& v) {
          o.experiments = tools::splitList(v);
          tools::require(!o.experiments.empty(), opt + ": empty list");
          for (const auto& e : o.experiments)
            tools::require(e == "ideal" || e == "lighting" || e == "shift" || e == "real",
                           opt + ": unknown experiment '" + e + "' (ideal, lighting, shift, real)");
        };
        t.values["--conditions"] = [&](const std::string& opt, const std::string& v) {
          o.conditions = tools::splitList(v);
          const auto& known = tools::realConditions();
          for (const auto& c : o.conditions)
            tools::require(std::find(known.begin(), known.end(), c) != known.end(),
                           opt + ": unknown realistic condition '" + c + "'");
          tools::require(!o.conditions.empty(), opt + ": empty list");
        };
        t.values["--subjects"] = [&](const std::string& opt, const std::string& v) {
          o.subjects = tools::parseInt(opt, v);
          tools::require(o.subjects >= 1 && o.subjects <= 28, opt + " must be in 1..28");
        };
        t.values["--condition-subjects"] = [&](const std::string& opt, const std::string& v) {
          o.condition_subjects = tools::parseInt(opt, v);
          tools::require(o.condition_subjects >= 1 && o.condition_subjects <= 28, opt + " must be in 1..28");
        };
        t.values["--random-points"] = [&](const std::string& opt, const std::string& v) {
          o.random_points = tools::parseInt(opt, v);
          tools::require(o.random_points >= 0, opt + " must be >= 0");
        };
        t.values["--width"] = [&](const std::string& opt, const std::string& v) { o.width = tools::parseInt(opt, v); };
        t.values["--height"] = [&](const std::string& opt, const std::string& v) {
          o.height = tools::parseInt(opt, v);
        };
        t.values["--fx"] = [&](const std::string& opt, const std::string& v) { o.fx = tools::parseDouble(opt, v); };
        t.values["--baseline"] = [&](const std::string& opt, const std::string& v) {
          o.baseline = tools::parseDouble(opt, v);
        };
        t.values["--camera-height"] = [&](const std::string& opt, const std::string& v) {
          o.camera_height = tools::parseDouble(opt, v);
        };
        t.values["--yaw"] = [&](const std::string& opt, const std::string& v) {
          o.yaw_deg = tools::parseDouble(opt, v);
          tools::require(std::abs(o.yaw_deg) <= 45.0, opt + " must be within +-45 degrees");
        };
        t.values["--acupoints"] = [&](const std::string&, const std::string& v) { o.acupoints = v; };
        t.values["--seed-step"] = [&](const std::string& opt, const std::string& v) {
          o.seed_step = tools::parseInt(opt, v);
          tools::require(o.seed_step >= 0, opt + " must be >= 0");
        };
        t.values["--query-search"] = [&](const std::string& opt, const std::string& v) {
          o.query_search = tools::parseDouble(opt, v);
          tools::require(o.query_search >= 0, opt + " must be >= 0");
        };
        t.values["--param"] = [&](const std::string& opt, const std::string& v) {
          for (const std::string& kv : tools::splitList(v)) {
            const auto eq = kv.find('=');
            tools::require(eq != std::string::npos, opt + ": expected NAME=VALUE, got '" + kv + "'");
            const std::string name = kv.substr(0, eq);
            tools::require(tools::paramSetters().count(name) > 0, opt + ": unknown CECT parameter '" + name + "'");
            o.params.emplace_back(name, tools::parseDouble(opt + " " + name, kv.substr(eq + 1)));
          }
        };
        t.values["--given-landmarks"] = [&](const std::string& opt, const std::string& v) {
          o.given_mm = tools::parseDouble(opt, v);
          tools::require(o.given_mm >= 0.0 && o.given_mm <= 100.0, opt + " must be in 0..100 mm");
        };
        t.values["--given-levels"] = [&](const std::string& opt, const std::string& v) {
          o.given_levels = tools::splitList(v);
          tools::require(!o.given_levels.empty(), opt + ": empty list");
          for (const auto& n : o.given_levels)
            tools::require(n == "C7" || n == "T7" || n == "L4", opt + ": unknown landmark '" + n + "' (C7, T7, L4)");
        };
        t.values["--first-subject"] = [&](const std::string& opt, const std::string& v) {
          o.first_subject = tools::parseInt(opt, v);
          tools::require(o.first_subject >= 1 && o.first_subject <= 10000, opt + " must be in 1..10000");
        };
        t.flags["--raw"] = [&] { o.raw = true; };
        t.flags["--no-layout-check"] = [&] { o.layout_check = false; };
        t.flags["--trust-c7-at-top"] = [&] { o.trust_c7_at_top = true; };
        t.flags["--trust-inferred-l4"] = [&] { o.trust_inferred_l4 = true; };
        t.flags["--confirm-given"] = [&] { o.confirm_given = true; };
        bool skin_markers = false;
        t.flags["--skin-markers"] = [&] { skin_markers = true; };
        t.values["--marker-kit"] = [&](const std::string&, const std::string& v) { o.marker_kit = v; };
        t.flags["--csv"] = [&] { o.csv = true; };
        t.flags["--per-point"] = [&] { o.per_point = true; };
        t.flags["--by-border"] = [&] { o.by_border = true; };
        t.flags["--no-parallax-correction"] = [&] { o.parallax = false; };
        t.flags["--no-3d-levels"] = [&] { o.levels_3d = false; };
        t.values["--pictures"] = [&](const std::string& opt, const std::string& v) {
          tools::require(!v.empty(), opt + " needs a folder");
          std::error_code ec;
          std::filesystem::create_directories(v, ec);
          tools::require(!ec && std::filesystem::is_directory(v), opt + ": cannot create the folder '" + v + "'");
          o.pictures = v;
        };
        if (!tools::parseArguments(argc, argv, t, kUsage)) return false;
        tools::require(o.width >= 64 && o.height >= 48, "--width/--height too small");
        tools::require(o.fx > 0 && o.baseline > 0 && o.camera_height > 0.3,
                       "--fx, --baseline must be > 0 and --camera-height > 0.3 m");
        tools::require(skin_markers || o.marker_kit.empty(), "--marker-kit needs --skin-markers");
        if (skin_markers) o.markers = loadKit(o.marker_kit);
        return true;
      },
      [&] { run(o); });
}
