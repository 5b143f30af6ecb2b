// cect_locate: the acupoints of a back on a stereo pair (CECT's 3D points
// with their uncertainty), or their layout in pixels on one image. See --help.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <Eigen/Core>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cect_params.h"
#include "cli.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/cect/segmentation.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using tools::require;
using tools::UsageError;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const char* const kUsage =
    R"(Usage: cect_locate --left L.png --right R.png --left-info LEFT.yaml --right-info RIGHT.yaml
                   [--acupoints FILE] [--format yaml|csv] [--output FILE] [--overlay OUT.png]
                   [--min-depth M] [--max-depth M] [--param NAME=VALUE,...]
                   [--no-parallax-correction] [--no-3d-levels] [--landmark NAME=U,V ...]
                   [--trust-c7-at-top] [--trust-inferred-l4]
                   [--profile FILE] [--save-profile FILE [--client NAME]]
       cect_locate --layout-only IMAGE.png [--acupoints FILE] [--format yaml|csv]
                   [--output FILE] [--overlay OUT.png] [--landmark NAME=U,V ...] [--trust-c7-at-top]
                   [--trust-inferred-l4] [--profile FILE]

Finds the acupoints of the acupoint model on a subject lying prone (head toward
the image top unless the model says `head_up: false`).

Stereo mode: CECT analyses the pair (segmentation -> contour correspondences ->
barycentric transfer -> 3D), the model places every acupoint on the left image
from the back's landmarks, and CECT localises it in 3D. The images may be raw
(distorted, unrectified) or rectified, as the camera_info files (ROS
camera_calibration format) say; their sizes must match them.

--layout-only IMAGE: one image, no calibration: the back is segmented, its
landmarks found and the acupoints placed in pixels, without 3D. Lateral offsets
are in cun, 1 cun = cun_per_shoulder_width x the back's shoulder width in
pixels (the model's definition with one scale over the whole image). For
checking the acupoint layout on ordinary photos of backs. The segmentation's
pixel sizes are scaled by the image's width / 640 as in the stereo mode.

Options:
  --left, --right FILE     the stereo pair's images (colour)
  --left-info, --right-info FILE   their camera_info YAML files
  --layout-only IMAGE      one image, pixels only (no stereo options then)
  --acupoints FILE         the acupoint model (default: the package's config/acupoints.yaml)
  --profile FILE           a client's profile (cect/client_profile.h): its per-point
                           corrections move the model's points; its C7 -> L4 (stereo
                           mode) must agree with this pair's within its tolerance, or
                           the layout is "not trusted"
  --save-profile FILE      (stereo mode, C7 and L4 both given) write the client's profile:
                           this pair's C7 -> L4 and the corrections of --profile
  --client NAME            the client's id in the saved profile
  --landmark NAME=U,V[,confirm]  a landmark a therapist palpated, at raw left pixel
                           (U, V) inside the image: C7 (the vertebra prominens), T7 (the
                           scapulae's inferior angles' line) or L4 (the iliac crests'
                           line); it replaces the found one (repeat the option for
                           each). It is checked like a measured one: off the spine, or
                           out of its place between C7 and L4, the layout is "not
                           trusted"; where the pair measured the same landmark (C7 at
                           a neck's base, L4 at the waist) and the two disagree, too,
                           unless `confirm` keeps the given one
  --trust-c7-at-top        trust a C7 taken from the back's top where no neck is in
                           view (by default such a layout is "not trusted": give C7);
                           for backs rendered without a neck
  --trust-inferred-l4      trust an L4 inferred from C7 and the shoulder width where no
                           waist is seen (by default such a layout is "not trusted": give L4)
  --format yaml|csv        output format (default yaml)
  --output FILE            write the output there (default: standard output)
  --overlay OUT.png        picture: the (raw) left image with the back's contour
                           (magenta), the model's midline (yellow), every placed
                           acupoint as a dot with its name (green: valid, red: placed
                           but not localised in 3D) and a status line
  --min-depth, --max-depth M   the depths the back may lie at, metres from the left
                           camera (default 0.25 .. 2.5): the disparities searched
  --param NAME=VALUE,...   CECT parameters by their CectParams names (cect.h), e.g.
                           --param ncc_radius=9,seed_step=12
  --no-parallax-correction place the acupoints from the silhouette's centre line
                           as it is (default: moved onto the skin's midline in 3D)
  --no-3d-levels           the waist and the vertebral levels in image rows only
                           (default: the waist at the spine's height and the
                           levels spaced along the body in 3D)
  -h, --help               print this help

Output, one entry per acupoint of the model in the model's order:
  name, region             as in the model
  valid                    placed, (stereo mode) localised in 3D, and the layout
                           trusted (a layout that fails the plausibility checks
                           - sizes, proportions, the shoulder line - has every
                           point invalid with "layout not trusted: ...")
  reason                   why not valid (empty when valid)
  u, v                     the pixel in the raw left image (pixel centres at
                           integers); NaN (YAML) / empty (CSV) when not placed
                           (a refused layout keeps its pixels, for a look)
Stereo mode only:
  x, y, z                  the 3D point, metres, in the left camera's optical frame
                           (REP 103: x right, y down, z forward)
  sigma_x, sigma_y, sigma_z   standard deviations of x, y, z (metres): the
                           matching's and the layout's (inferred landmarks
                           widen it; acupoints.yaml layout_sigma)
  disparity_sigma          standard deviation of the disparity, pixels
                           (x .. disparity_sigma NaN / empty when not valid)
YAML: a header, then the list `acupoints:`. The header: mode; the inputs;
client_profile (none, or --profile's file with its client, C7 -> L4 and number
of corrections, also said on standard error); frame (CECT's status: valid,
reason, view_scale, disparity_range searched,
timings_ms: CECT's stages and the layout + 3D step on this pair, 2 cores; in
layout-only mode the segmentation's valid and reason); landmarks (valid: found,
trusted: the layout on them passed the checks, reason, used: the landmarks the
layout used with their sources, notes: disagreements that did not refuse it,
body_angle_deg, shoulder_width_px, measured / inferred / given, and c7, l4, shoulder_line, waist_line,
iliac_line: points on the midline, raw left pixels [u, v]); valid / reason
(whether the acupoints could be placed, and why not); acupoints_valid and
acupoints_total.
CSV: a header line, then one line per acupoint.

A pair or image without a (usable) back is not an error: the tool exits 0 with
every acupoint invalid and the reason, the header saying why, and a warning on
standard error. Exit status: 0 done, 2 bad usage (unknown or missing option,
bad value), 1 other errors (unreadable image or file, image size not matching
its camera_info, bad calibration, malformed acupoint model, a --profile that
cannot be read or has an unknown key, a value of the wrong type or a missing
one: docs/cect.md "Client profiles"); all with a one-line
message.

Example:
  cect_locate --left left.png --right right.png --left-info left_camera_info.yaml \
      --right-info right_camera_info.yaml --format csv --output acupoints.csv --overlay acupoints.png
)";

struct Options {
  std::string left, right, left_info, right_info;
  std::string layout_only;  ///< --layout-only IMAGE
  std::string acupoints;
  std::string format = "yaml";
  std::string output;   ///< empty: stdout
  std::string overlay;  ///< empty: none
  double min_depth = kNaN, max_depth = kNaN;
  std::vector<std::pair<std::string, double>> params;  ///< --param
  bool parallax = true;
  bool levels_3d = true;
  std::vector<cect::GivenLandmark> landmarks;  ///< --landmark, raw left pixels
  bool trust_c7_at_top = false;                ///< --trust-c7-at-top
  bool trust_inferred_l4 = false;              ///< --trust-inferred-l4
  std::string profile;                         ///< --profile FILE: a client's profile applied
  std::string save_profile;                    ///< --save-profile FILE
  std::string client;                          ///< --client NAME (with --save-profile)
  bool stereo() const { return layout_only.empty(); }
};

// ---------------------------------------------------------------------------
// What the tool reports, the same for both modes.

struct PointRow {
  std::string name, region, reason;
  bool valid = false;
  cv::Point2f pixel{static_cast<float>(kNaN), static_cast<float>(kNaN)};  ///< raw left image
  Eigen::Vector3d position = Eigen::Vector3d::Constant(kNaN);
  Eigen::Vector3d sigma = Eigen::Vector3d::Constant(kNaN);
  double disparity_sigma = kNaN;
};

struct LandmarkSummary {
  bool valid = false;    ///< found in the view
  bool trusted = false;  ///< ... and the layout built on them passed the checks (cect::checkLayout)
  std::string reason;
  std::vector<std::string> used;   ///< the layout's landmarks with their sources: "C7 given (clicked)", ...
  std::vector<std::string> notes;  ///< disagreements that did not refuse the layout
  double body_angle_deg = kNaN, shoulder_width_px = kNaN;
  std::vector<std::string> measured, inferred, given;  ///< which landmarks this view measured / inferred / was given
  std::string trunk;                                   ///< what the segmentation cut away (arms, cloth)
  std::string background;                              ///< what the depth gate called far background
  /// C7, L4 and the midline at the shoulder, waist and iliac lines, raw left pixels.
  std::vector<std::pair<std::string, cv::Point2f>> points;
};

struct Report {
  bool stereo = true;
  std::vector<std::pair<std::string, std::string>> inputs;  ///< (key, path)
  std::string client_profile = "none";                      ///< --profile's file and what it holds
  bool frame_valid = false;
  std::string frame_reason;
  double view_scale = kNaN;
  cv::Vec2d disparity_range{kNaN, kNaN};
  cect::CectTimings timings;  ///< CECT's stages on this pair (stereo mode)
  double locate_ms = kNaN;    ///< the model's layout and the acupoints to 3D
  LandmarkSummary landmarks;
  bool valid = false;  ///< the acupoints could be placed
  std::string reason;
  std::vector<PointRow> points;
  /// For the overlay, raw left pixels.
  std::vector<cv::Point2f> contour, midline;
  int validCount() const {
    return static_cast<int>(std::count_if(points.begin(), points.end(), [](const PointRow& p) { return p.valid; }));
  }
};

/// Maps a rectified left pixel to the raw left image (identity in layout-only mode).
using ToRaw = std::function<cv::Point2f(const cv::Point2f&)>;

/// The midline's point at `row` of the body's frame (linear between its points).
cv::Point2f midlinePoint(const cect::BackLandmarks& lm, double row) {
  const auto& m = lm.midline;
  const double t = std::clamp(row - m.front().y, 0.0, static_cast<double>(m.size() - 1));
  const std::size_t i = std::min(static_cast<std::size_t>(t), m.size() - 1);
  const std::size_t j = std::min(i + 1, m.size() - 1);
  const float f = static_cast<float>(t - static_cast<double>(i));
  return m[i] + f * (m[j] - m[i]);
}

LandmarkSummary summarise(const cect::LocatedAcupoints& located, const ToRaw& to_raw) {
  const cect::BackLandmarks& lm = located.landmarks;
  LandmarkSummary s;
  s.valid = lm.valid;
  s.reason = lm.reason;
  if (!lm.valid || lm.midline.empty()) return s;
  s.trusted = located.check.trusted;
  if (!s.trusted) s.reason = located.check.reason();
  s.notes = located.check.notes;
  for (const cect::LayoutLandmark& l : cect::layoutLandmarks(lm)) s.used.push_back(cect::describeLandmark(l));
  s.body_angle_deg = lm.body_angle_deg;
  s.shoulder_width_px = lm.shoulder_width;
  s.measured = lm.measured;
  s.inferred = lm.inferred;
  s.given = lm.given;
  auto image = [&](const cv::Point2f& body) { return to_raw(cect::toImage(lm, body)); };
  s.points = {{"c7", image(lm.c7.body)},
              {"l4", image(lm.l4.body)},
              {"shoulder_line", image(midlinePoint(lm, lm.shoulder_row))},
              {"waist_line", image(midlinePoint(lm, lm.waist_row))},
              {"iliac_line", image(midlinePoint(lm, lm.iliac_row))}};
  return s;
}

/// The overlay's contour and midline in raw left pixels.
void addOutlines(Report* r, const cect::Segmentation& seg, const cect::BackLandmarks& lm, const ToRaw& to_raw) {
  for (const cv::Point2f& p : seg.contour) r->contour.push_back(to_raw(p));
  if (!lm.valid) return;
  for (const cv::Point2f& p : lm.midline) r->midline.push_back(to_raw(cect::toImage(lm, p)));
}

// ---------------------------------------------------------------------------
// Inputs.

cv::Mat readImage(const std::string& path, const std::string& option) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(option + ": no such image file '" + path + "'");
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    img.release();
  }
  if (img.empty()) throw std::runtime_error(option + ": cannot read '" + path + "' as an image");
  return img;
}

camera::CameraCalibration readInfo(const std::string& path, const cv::Mat& image, const std::string& image_path) {
  const camera::CameraCalibration c = camera::readCameraInfoYaml(path);
  if (c.width != image.cols || c.height != image.rows) {
    std::ostringstream s;
    s << "image size mismatch: '" << image_path << "' is " << image.cols << "x" << image.rows << " but '" << path
      << "' says " << c.width << "x" << c.height;
    throw std::runtime_error(s.str());
  }
  return c;
}

cect::AcupointModel loadModel(const Options& o, const cect::ClientProfile& profile) {
  const std::string path = o.acupoints.empty() ? tools::packageFile("config/acupoints.yaml") : o.acupoints;
  return cect::withCorrections(cect::loadAcupointModel(path), profile);
}

std::string oneLine(std::string s);

/// The client's profile (--profile), or an empty one. One that cannot be read (or has an unknown key, a value of the
/// wrong type, ...) is an error: exit 1, before any image is read.
cect::ClientProfile loadProfile(const Options& o) {
  cect::ClientProfile p;
  if (!o.profile.empty()) p = cect::loadClientProfile(o.profile);
  return p;
}

/// --save-profile: the client's C7 -> L4 from this pair (both landmarks given, the layout trusted) with the
/// corrections of --profile carried over.
void saveProfile(const Options& o, const cect::ClientProfile& profile, const cect::LocatedAcupoints& located) {
  // What the pair gave, not the options: errors of content (exit 1).
  cect::ClientProfile measured;
  try {
    measured = cect::measuredProfile(profile, located, o.client);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("--save-profile: " + oneLine(e.what()));
  }
  cect::saveClientProfile(measured, o.save_profile);
}

cect::CectParams cectParams(const Options& o) {
  cect::CectParams p;
  if (std::isfinite(o.min_depth)) p.min_depth = o.min_depth;
  if (std::isfinite(o.max_depth)) p.max_depth = o.max_depth;
  tools::applyParams(p, o.params);
  return p;
}

// ---------------------------------------------------------------------------
// Stereo mode.

PointRow stereoRow(const cect::LocatedAcupoint& a) {
  PointRow r;
  r.name = a.name;
  r.region = a.region;
  r.valid = a.valid;
  r.reason = a.reason;
  if (a.placed) r.pixel = a.raw;
  if (a.valid) {
    r.position = a.point.position;
    r.sigma = a.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();  // matching and layout
    r.disparity_sigma = a.point.disparity_sigma;
  }
  return r;
}

struct StereoInput {
  cv::Mat left, right;
  camera::StereoModel geometry;
};

/// The images, checked against their calibrations, and the pair's geometry.
StereoInput readPair(const Options& o) {
  StereoInput in;
  in.left = readImage(o.left, "--left");
  in.right = readImage(o.right, "--right");
  const camera::CameraCalibration left_info = readInfo(o.left_info, in.left, o.left);
  const camera::CameraCalibration right_info = readInfo(o.right_info, in.right, o.right);
  try {
    in.geometry = camera::StereoModel(left_info, right_info);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("calibration '" + o.left_info + "' / '" + o.right_info + "': " + e.what());
  }
  return in;
}

Report stereoReport(const Options& o, const cect::CectFrame& frame, const cect::LocatedAcupoints& located) {
  const camera::StereoModel& geometry = frame.geometry();
  Report r;
  r.inputs = {{"left", o.left}, {"right", o.right}, {"left_info", o.left_info}, {"right_info", o.right_info}};
  r.frame_valid = frame.valid();
  r.frame_reason = frame.reason();
  r.view_scale = frame.scale();
  r.disparity_range = frame.disparityRange();
  r.timings = frame.timings();
  r.valid = located.valid;
  r.reason = located.reason;
  const ToRaw to_raw = [&geometry](const cv::Point2f& p) { return geometry.toRaw(p); };
  r.landmarks = summarise(located, to_raw);
  r.landmarks.trunk = frame.left().valid ? frame.left().trunk.summary() : std::string();
  r.landmarks.background = frame.background().summary();
  if (!located.valid && located.landmarks.reason.empty()) r.landmarks.reason = located.reason;
  for (const cect::LocatedAcupoint& a : located.points) r.points.push_back(stereoRow(a));
  addOutlines(&r, frame.left(), located.landmarks, to_raw);
  return r;
}

/// --landmark's pixels, each checked against the raw left image's size as the node checks a click (GivenLandmarkSet);
/// throws UsageError naming the one outside.
std::vector<cect::GivenLandmark> givenInImage(const std::vector<cect::GivenLandmark>& given, cv::Size size) {
  cect::GivenLandmarkSet set;
  for (const cect::GivenLandmark& g : given) {
    const std::string problem = set.set(g.name, g.pixel, g.source, size, g.confirmed);
    if (!problem.empty()) throw UsageError("--landmark: " + problem);
  }
  return given;
}

Report locateStereo(const Options& o, const cect::AcupointModel& model, const cect::ClientProfile& profile) {
  const StereoInput in = readPair(o);
  const cect::CectFrame frame = cect::CectFrame::analyse(in.left, in.right, in.geometry, cectParams(o));
  cect::LocateOptions lo;
  lo.correct_parallax = o.parallax;
  lo.levels_in_3d = o.levels_3d;
  lo.trust.c7_at_neck = !o.trust_c7_at_top;
  lo.trust.l4_measured = !o.trust_inferred_l4;
  lo.trust.client_length_m = profile.c7_to_l4_m;
  lo.trust.length_tolerance_m = profile.length_tolerance_m;
  for (const cect::GivenLandmark& g : givenInImage(o.landmarks, in.left.size()))
    lo.given.push_back({g.name, in.geometry.toRectified(g.pixel), g.source, g.confirmed});
  const auto t0 = std::chrono::steady_clock::now();
  const cect::LocatedAcupoints located = cect::locateAcupoints(frame, model, lo);
  const double locate_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!o.save_profile.empty()) saveProfile(o, profile, located);
  Report r = stereoReport(o, frame, located);
  r.locate_ms = locate_ms;
  return r;
}

// ---------------------------------------------------------------------------
// Layout-only mode.

/// The segmentation the stereo mode uses on a view of this width (CectFrame::
/// analyse with auto_scale: CECT's default parameters scaled by the width /
/// 640 in quarter octaves, the contour sampled every sample_spacing).
cect::SegmentationParams segmentationFor(int width) {
  cect::CectParams p;
  p.segmentation.contour_spacing = p.sample_spacing;
  // viewScale quantises (d / B) / kReferencePixelsPerMetre: with B = 1 it
  // quantises width / 640.
  const double scale = cect::viewScale(width / 640.0 * cect::kReferencePixelsPerMetre, 1.0);
  return cect::scaledParams(p, scale).segmentation;
}

Report locateLayout(const Options& o, const cect::AcupointModel& model) {
  const cv::Mat image = readImage(o.layout_only, "--layout-only");
  const cect::Segmentation seg = cect::segmentBack(image, segmentationFor(image.cols));
  cect::LocateOptions lo;
  lo.given = givenInImage(o.landmarks, image.size());
  lo.trust.c7_at_neck = !o.trust_c7_at_top;
  lo.trust.l4_measured = !o.trust_inferred_l4;
  const cect::LocatedAcupoints located = cect::locateLayout(seg, model, lo);

  Report r;
  r.stereo = false;
  r.inputs = {{"image", o.layout_only}};
  r.frame_valid = seg.valid;
  r.frame_reason = seg.reason;
  r.valid = located.valid;
  r.reason = located.reason;
  const ToRaw identity = [](const cv::Point2f& p) { return p; };
  r.landmarks = summarise(located, identity);
  r.landmarks.trunk = seg.valid ? seg.trunk.summary() : std::string();
  for (const cect::LocatedAcupoint& a : located.points) {
    PointRow row;
    row.name = a.name;
    row.region = a.region;
    row.valid = a.valid;
    row.reason = a.reason;
    if (a.placed) row.pixel = a.rectified;
    r.points.push_back(row);
  }
  addOutlines(&r, seg, located.landmarks, identity);
  return r;
}

// ---------------------------------------------------------------------------
// Output.

void emitPixel(YAML::Emitter& y, const std::string& key, const cv::Point2f& p) {
  y << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq << static_cast<double>(p.x)
    << static_cast<double>(p.y) << YAML::EndSeq;
}

void emitHeader(YAML::Emitter& y, const Report& r) {
  y << YAML::Key << "mode" << YAML::Value << (r.stereo ? "stereo" : "layout_only");
  for (const auto& [key, path] : r.inputs) y << YAML::Key << key << YAML::Value << path;
  y << YAML::Key << "client_profile" << YAML::Value << r.client_profile;
  y << YAML::Key << "frame" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "valid" << YAML::Value << r.frame_valid;
  y << YAML::Key << "reason" << YAML::Value << r.frame_reason;
  if (r.stereo) {
    y << YAML::Key << "view_scale" << YAML::Value << r.view_scale;
    y << YAML::Key << "disparity_range" << YAML::Value << YAML::Flow << YAML::BeginSeq << r.disparity_range[0]
      << r.disparity_range[1] << YAML::EndSeq;
    const cect::CectTimings& t = r.timings;
    y << YAML::Key << "timings_ms" << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (const auto& [key, ms] : {std::pair<const char*, double>{"rectify", t.rectify_ms},
                                  {"segment", t.segment_ms},
                                  {"foundational", t.foundational_ms},
                                  {"interior", t.interior_ms},
                                  {"cect_total", t.total_ms},
                                  {"locate", r.locate_ms}})
      y << YAML::Key << key << YAML::Value << std::round(10.0 * ms) / 10.0;
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
  const LandmarkSummary& l = r.landmarks;
  y << YAML::Key << "landmarks" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "valid" << YAML::Value << l.valid;
  y << YAML::Key << "trusted" << YAML::Value << l.trusted;
  y << YAML::Key << "reason" << YAML::Value << l.reason;
  y << YAML::Key << "used" << YAML::Value << YAML::Flow << l.used;
  if (!l.notes.empty()) y << YAML::Key << "notes" << YAML::Value << l.notes;
  y << YAML::Key << "body_angle_deg" << YAML::Value << l.body_angle_deg;
  y << YAML::Key << "shoulder_width_px" << YAML::Value << l.shoulder_width_px;
  y << YAML::Key << "measured" << YAML::Value << YAML::Flow << l.measured;
  y << YAML::Key << "inferred" << YAML::Value << YAML::Flow << l.inferred;
  y << YAML::Key << "given" << YAML::Value << YAML::Flow << l.given;
  y << YAML::Key << "trunk" << YAML::Value << l.trunk;
  if (!l.background.empty()) y << YAML::Key << "background" << YAML::Value << l.background;
  for (const auto& [name, p] : l.points) emitPixel(y, name, p);
  y << YAML::EndMap;
  y << YAML::Key << "valid" << YAML::Value << r.valid;
  y << YAML::Key << "reason" << YAML::Value << r.reason;
  y << YAML::Key << "acupoints_valid" << YAML::Value << r.validCount();
  y << YAML::Key << "acupoints_total" << YAML::Value << static_cast<int>(r.points.size());
}

void emitPoint(YAML::Emitter& y, const PointRow& p, bool stereo) {
  y << YAML::BeginMap;
  y << YAML::Key << "name" << YAML::Value << p.name;
  y << YAML::Key << "region" << YAML::Value << p.region;
  y << YAML::Key << "valid" << YAML::Value << p.valid;
  y << YAML::Key << "reason" << YAML::Value << p.reason;
  y << YAML::Key << "u" << YAML::Value << static_cast<double>(p.pixel.x);
  y << YAML::Key << "v" << YAML::Value << static_cast<double>(p.pixel.y);
  if (stereo) {
    const char* axes[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i) y << YAML::Key << axes[i] << YAML::Value << p.position[i];
    const char* sigmas[3] = {"sigma_x", "sigma_y", "sigma_z"};
    for (int i = 0; i < 3; ++i) y << YAML::Key << sigmas[i] << YAML::Value << p.sigma[i];
    y << YAML::Key << "disparity_sigma" << YAML::Value << p.disparity_sigma;
  }
  y << YAML::EndMap;
}

std::string toYaml(const Report& r) {
  YAML::Emitter y;
  y.SetDoublePrecision(7);
  y << YAML::BeginMap;
  emitHeader(y, r);
  y << YAML::Key << "acupoints" << YAML::Value << YAML::BeginSeq;
  for (const PointRow& p : r.points) emitPoint(y, p, r.stereo);
  y << YAML::EndSeq << YAML::EndMap;
  if (!y.good()) throw std::runtime_error("YAML output: " + y.GetLastError());
  return std::string(y.c_str()) + "\n";
}

/// A CSV field (RFC 4180): quoted when it holds a comma, a quote or a line break.
std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

/// A number for CSV; empty when unknown.
std::string csvNumber(double v) {
  if (!std::isfinite(v)) return "";
  std::ostringstream s;
  s << std::setprecision(7) << v;
  return s.str();
}

std::string toCsv(const Report& r) {
  std::ostringstream out;
  out << "name,region,valid,reason,u,v";
  if (r.stereo) out << ",x,y,z,sigma_x,sigma_y,sigma_z,disparity_sigma";
  out << "\n";
  for (const PointRow& p : r.points) {
    out << csvField(p.name) << "," << csvField(p.region) << "," << (p.valid ? "true" : "false") << ","
        << csvField(p.reason) << "," << csvNumber(p.pixel.x) << "," << csvNumber(p.pixel.y);
    if (r.stereo) {
      for (int i = 0; i < 3; ++i) out << "," << csvNumber(p.position[i]);
      for (int i = 0; i < 3; ++i) out << "," << csvNumber(p.sigma[i]);
      out << "," << csvNumber(p.disparity_sigma);
    }
    out << "\n";
  }
  return out.str();
}

void writeText(const Options& o, const std::string& text) {
  if (o.output.empty()) {
    std::cout << text << std::flush;
    return;
  }
  std::ofstream f(o.output);
  f << text;
  f.close();
  if (!f) throw std::runtime_error("--output: cannot write '" + o.output + "'");
}

// ---------------------------------------------------------------------------
// Overlay.

std::vector<cv::Point> polyline(const std::vector<cv::Point2f>& pts) {
  std::vector<cv::Point> out;
  for (const cv::Point2f& p : pts)
    if (std::isfinite(p.x) && std::isfinite(p.y)) out.emplace_back(cvRound(p.x), cvRound(p.y));
  return out;
}

std::string statusLine(const Report& r) {
  std::ostringstream s;
  s << (r.stereo ? "stereo: " : "layout only: ");
  if (!r.valid) return s.str() + "no acupoints: " + r.reason;
  s << r.validCount() << "/" << r.points.size() << (r.stereo ? " acupoints localised" : " acupoints placed");
  if (r.stereo) s << ", view scale " << std::fixed << std::setprecision(2) << r.view_scale;
  if (r.landmarks.body_angle_deg != 0.0)
    s << ", body turned " << std::fixed << std::setprecision(1) << r.landmarks.body_angle_deg << " deg";
  return s.str();
}

void drawStatus(cv::Mat& img, const std::string& text, double k) {
  const double scale = 0.45 * k;
  const int thickness = std::max(1, cvRound(k));
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline);
  const int pad = std::max(2, cvRound(4 * k));
  cv::rectangle(img, cv::Rect(0, 0, std::min(img.cols, size.width + 2 * pad), size.height + baseline + 2 * pad),
                cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(img, text, cv::Point(pad, pad + size.height), cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255),
              thickness, cv::LINE_AA);
}

void writeOverlay(const Options& o, const Report& r) {
  cv::Mat img = readImage(r.stereo ? o.left : o.layout_only, r.stereo ? "--left" : "--layout-only");
  const double k = std::max(1.0, img.cols / 640.0);  // line and text sizes for large images
  const int line = std::max(1, cvRound(k));
  const std::vector<cv::Point> contour = polyline(r.contour), midline = polyline(r.midline);
  if (contour.size() > 1) cv::polylines(img, contour, true, cv::Scalar(255, 0, 255), line, cv::LINE_AA);
  if (midline.size() > 1) cv::polylines(img, midline, false, cv::Scalar(0, 255, 255), line, cv::LINE_AA);
  for (const PointRow& p : r.points) {
    if (!std::isfinite(p.pixel.x) || !std::isfinite(p.pixel.y)) continue;
    const cv::Point c(cvRound(p.pixel.x), cvRound(p.pixel.y));
    const cv::Scalar colour = p.valid ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 0, 255);
    cv::circle(img, c, cvRound(2 * k), colour, cv::FILLED, cv::LINE_AA);
    cv::putText(img, p.name, c + cv::Point(cvRound(3 * k), cvRound(-2 * k)), cv::FONT_HERSHEY_PLAIN, 0.6 * k, colour, 1,
                cv::LINE_AA);
  }
  drawStatus(img, statusLine(r), k);
  bool ok = false;
  try {
    ok = cv::imwrite(o.overlay, img);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("--overlay: cannot write '" + o.overlay + "'");
}

// ---------------------------------------------------------------------------

/// Messages stay on one line.
std::string oneLine(std::string s) {
  std::replace(s.begin(), s.end(), '\n', ' ');
  std::replace(s.begin(), s.end(), '\r', ' ');
  return s;
}

void run(const Options& o) {
  // The tool reports its own errors, one line each.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  const cect::ClientProfile profile = loadProfile(o);
  const cect::AcupointModel model = loadModel(o, profile);
  Report r = o.stereo() ? locateStereo(o, model, profile) : locateLayout(o, model);
  if (!o.profile.empty()) {
    r.client_profile = o.profile + " (" + cect::describeClientProfile(profile) + ")";
    std::cerr << "cect_locate: client profile: " << r.client_profile << "\n";
  }
  writeText(o, o.format == "csv" ? toCsv(r) : toYaml(r));
  if (!o.overlay.empty()) writeOverlay(o, r);
  if (!r.valid) std::cerr << "cect_locate: warning: no acupoints: " << oneLine(r.reason) << "\n";
}

// ---------------------------------------------------------------------------
// Options.

void addParamOption(tools::OptionTable& t, Options& o) {
  t.values["--param"] = [&o](const std::string& opt, const std::string& v) {
    const std::vector<std::string> items = tools::splitList(v);
    require(!items.empty(), opt + ": expected NAME=VALUE,...");
    for (const std::string& kv : items) {
      const auto eq = kv.find('=');
      require(eq != std::string::npos, opt + ": expected NAME=VALUE, got '" + kv + "'");
      const std::string name = kv.substr(0, eq);
      require(tools::paramSetters().count(name) > 0, opt + ": unknown CECT parameter '" + name + "'");
      o.params.emplace_back(name, tools::parseDouble(opt + " " + name, kv.substr(eq + 1)));
    }
  };
}

void addDepthOptions(tools::OptionTable& t, Options& o) {
  t.values["--min-depth"] = [&o](const std::string& opt, const std::string& v) {
    o.min_depth = tools::parseDouble(opt, v);
    require(o.min_depth > 0.0, opt + " must be > 0");
  };
  t.values["--max-depth"] = [&o](const std::string& opt, const std::string& v) {
    o.max_depth = tools::parseDouble(opt, v);
    require(o.max_depth > 0.0, opt + " must be > 0");
  };
}

tools::OptionTable optionTable(Options& o) {
  tools::OptionTable t;
  auto path = [](std::string* target) {
    return [target](const std::string& opt, const std::string& v) {
      require(!v.empty(), opt + ": empty file name");
      *target = v;
    };
  };
  t.values["--left"] = path(&o.left);
  t.values["--right"] = path(&o.right);
  t.values["--left-info"] = path(&o.left_info);
  t.values["--right-info"] = path(&o.right_info);
  t.values["--layout-only"] = path(&o.layout_only);
  t.values["--acupoints"] = path(&o.acupoints);
  t.values["--profile"] = path(&o.profile);
  t.values["--save-profile"] = path(&o.save_profile);
  t.values["--client"] = [&o](const std::string& opt, const std::string& v) {
    require(!v.empty(), opt + ": empty name");
    o.client = v;
  };
  t.values["--output"] = path(&o.output);
  t.values["--overlay"] = [&o](const std::string& opt, const std::string& v) {
    require(!v.empty(), opt + ": empty file name");
    require(cv::haveImageWriter(v), opt + ": cannot write images of that type: '" + v + "' (use .png)");
    o.overlay = v;
  };
  t.values["--format"] = [&o](const std::string& opt, const std::string& v) {
    require(v == "yaml" || v == "csv", opt + ": unknown format '" + v + "' (yaml or csv)");
    o.format = v;
  };
  addDepthOptions(t, o);
  addParamOption(t, o);
  t.flags["--no-parallax-correction"] = [&o] { o.parallax = false; };
  t.flags["--no-3d-levels"] = [&o] { o.levels_3d = false; };
  t.flags["--trust-c7-at-top"] = [&o] { o.trust_c7_at_top = true; };
  t.flags["--trust-inferred-l4"] = [&o] { o.trust_inferred_l4 = true; };
  t.values["--landmark"] = [&o](const std::string& opt, const std::string& v) {
    const auto eq = v.find('=');
    require(eq != std::string::npos, opt + ": expected NAME=U,V, got '" + v + "'");
    const std::string name = v.substr(0, eq);
    const std::string problem = cect::checkGivenLandmarkName(name);
    require(problem.empty(), opt + ": " + problem);
    const std::vector<std::string> uv = tools::splitList(v.substr(eq + 1));
    require(uv.size() == 2 || (uv.size() == 3 && uv[2] == "confirm"),
            opt + " " + name + ": expected the pixel as U,V or U,V,confirm, got '" + v.substr(eq + 1) + "'");
    for (const cect::GivenLandmark& g : o.landmarks) require(g.name != name, opt + ": " + name + " given twice");
    o.landmarks.push_back({name,
                           cv::Point2f(static_cast<float>(tools::parseDouble(opt + " " + name, uv[0])),
                                       static_cast<float>(tools::parseDouble(opt + " " + name, uv[1]))),
                           cect::LandmarkSource::kGivenOption, uv.size() == 3});
  };
  return t;
}

/// The combination of options: one of the two modes, complete.
void checkOptions(const Options& o) {
  require(o.client.empty() || !o.save_profile.empty(), "--client names the client in --save-profile's file: give both");
  if (!o.stereo()) {
    require(o.left.empty() && o.right.empty() && o.left_info.empty() && o.right_info.empty(),
            "--layout-only takes one image: no --left / --right / --left-info / --right-info");
    require(o.save_profile.empty(), "--save-profile needs a stereo pair (the client's C7 -> L4 in metres)");
    require(o.params.empty() && std::isnan(o.min_depth) && std::isnan(o.max_depth) && o.parallax && o.levels_3d,
            "--param, --min-depth, --max-depth, --no-parallax-correction and --no-3d-levels need a stereo pair "
            "(not --layout-only)");
    return;
  }
  std::vector<std::string> missing;
  if (o.left.empty()) missing.push_back("--left");
  if (o.right.empty()) missing.push_back("--right");
  if (o.left_info.empty()) missing.push_back("--left-info");
  if (o.right_info.empty()) missing.push_back("--right-info");
  std::string list;
  for (const std::string& m : missing) list += (list.empty() ? "" : ", ") + m;
  require(missing.empty(), "missing " + list +
                               " (a stereo pair needs --left, --right, --left-info and "
                               "--right-info; one image: --layout-only IMAGE)");
  cect::CectParams depths;
  if (std::isfinite(o.min_depth)) depths.min_depth = o.min_depth;
  if (std::isfinite(o.max_depth)) depths.max_depth = o.max_depth;
  require(depths.min_depth < depths.max_depth,
          "--min-depth must be less than --max-depth (the defaults are 0.25 and 2.5 m)");
  try {
    cectParams(o);  // --param values checked with the rest
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return tools::runTool(
      "cect_locate",
      [&] {
        if (!tools::parseArguments(argc, argv, optionTable(o), kUsage)) return false;
        checkOptions(o);
        return true;
      },
      [&] {
        try {
          run(o);
        } catch (const std::exception& e) {
          throw std::runtime_error(oneLine(e.what()));
        }
      });
}
