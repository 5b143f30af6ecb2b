// CECT step 5: the acupoint model. Landmarks of the prone back found in the
// (rectified) left view from the segmentation and its contour, the cun scale
// from the body's own proportions, and every acupoint of
// shared/reference/back_acupoints.md placed as (vertebral level, lateral cun)
// -> left-image pixel. The pixels then go through CECT to 3D. ROS-free.
//
// Configuration: config/acupoints.yaml (loadAcupointModel). Image frame of
// the cell's camera: head toward the image top, the subject's left on the
// image left (camera looking down at a prone subject); `head_up: false` in
// the YAML flips the vertical direction.
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/cect/segmentation.h"

namespace massage_cell::cect {

struct AcupointSpec {
  std::string name;          ///< frame-friendly name: "GV14", "BL23_L", "EX_B2_T5_R", "GB21_L"
  std::string level;         ///< vertebral level "C7", "T1".."T12", "L1".."L5"
  double lateral_cun = 0.0;  ///< toward the subject's left (+) or right (-)
  std::string region;        ///< "upper_back", "lower_back", "midline", "shoulder": the arm's press limits key on it
  /// Along the body from the level, a fraction of C7 -> L4 toward L4: a client's correction (client_profile.h; 0 in
  /// the model's file).
  double level_offset = 0.0;
};

struct AcupointModel {
  /// Position of each vertebral level (lower border of its spinous process)
  /// along the midline as a fraction of the C7 -> L4 distance (C7 = 0,
  /// L4 = 1; L5 > 1). Every level an acupoint uses must be listed.
  std::map<std::string, double> level_fraction;
  /// Midline to the medial scapular border = 3 cun; this ratio ties the cun
  /// to a width measurable in the image: cun = cun_per_shoulder_width * shoulder width.
  double cun_per_shoulder_width = 0.0;
  /// C7 lies this fraction of the C7 -> L4 distance below the top of the back's contour at the midline.
  double c7_below_top = 0.0;
  /// The waist (narrowest row between shoulders and hips) lies this fraction
  /// of the C7 -> L4 distance below C7 in the image: with c7_below_top it
  /// fixes C7 and L4 from the top of the back and the waist (see landmarks.cpp).
  double waist_fraction = 0.0;
  /// On the mean subject seen from the cell's centred camera, the spine's
  /// level of the waist lies this fraction of C7 -> L4 below the silhouette's
  /// narrowest row (the flanks' rims are lower than the spine: parallax along
  /// the body). correctWaistParallax measures the subject's own offset in 3D
  /// and moves the waist by the difference. Optional in the YAML (0).
  double waist_rim_offset = 0.0;
  /// Proportions for landmarks out of view (optional in the YAML): the
  /// shoulder line (the upper back's widest row) lies this fraction of
  /// C7 -> L4 below C7 (C7 from it when the neck is out of view), and C7 -> L4
  /// is this many shoulder widths (L4 from C7 when the waist or the hips are
  /// out of view), both in the image's rows.
  double shoulder_below_c7 = 0.15;
  double length_per_shoulder_width = 1.22;
  /// The layout's own uncertainty (one sigma, fractions of the C7 -> L4
  /// length; optional in the YAML): along the body at C7 and at L4 when the
  /// landmark was measured or inferred (a point between them takes the
  /// linear mix by its level), and across the body. layoutCovariance().
  struct LayoutSigma {
    double c7_measured = 0.025, c7_inferred = 0.22;
    double l4_measured = 0.075, l4_inferred = 0.08;
    /// A given landmark (given_landmarks.h): a palpated and clicked C7 or L4, ~5 mm of a ~0.45 m C7 -> L4.
    double c7_given = 0.012, l4_given = 0.012;
    /// A level given between them (T7 palpated at the scapulae's inferior angles, or its marker).
    double level_given = 0.012;
    double across = 0.02;
  } layout_sigma;
  /// Bounds of a believable layout (layout_check.h; optional in the YAML as `plausibility`): adult sizes with a
  /// margin, and how far the proportions may stray from this model's. Sources: config/acupoints.yaml, docs/cect.md.
  struct Plausibility {
    double min_length_m = 0.28, max_length_m = 0.58;                  ///< C7 -> L4 along the body
    double min_shoulder_width_m = 0.28, max_shoulder_width_m = 0.65;  ///< the upper back's widest row
    /// C7 -> L4 over the shoulder width may differ from length_per_shoulder_width by this fraction of it.
    double proportion_tolerance = 0.35;
    /// The shoulder line below C7, as a fraction of C7 -> L4 (when C7 was not taken from the shoulder line).
    double min_shoulder_below_c7 = -0.10, max_shoulder_below_c7 = 0.45;
    /// A level given between C7 and L4 (T7) farther than this (a fraction of C7 -> L4) from the model's fraction
    /// disagrees with the model's proportions: reported (LayoutCheck::notes), the given level used.
    double given_level_tolerance = 0.06;
    /// ... farther than this, beyond the population's spread of that landmark: refused.
    double given_level_limit = 0.20;
    /// A given landmark farther than this (cun) across the back's measured midline is not on the spine: refused.
    double max_given_off_midline_cun = 2.5;
    /// A given landmark the pair also measured (C7 at a neck's base, L4 at the waist) farther from it along the body
    /// than this many of their combined sigmas (layout_sigma) is refused until it is confirmed.
    double given_disagreement_sigmas = 3.0;
  } plausibility;
  bool head_up = true;  ///< head toward the image top
  std::vector<AcupointSpec> points;

  /// Names of every point, in file order.
  std::vector<std::string> names() const;
  const AcupointSpec* find(const std::string& name) const;
  /// Throws std::invalid_argument naming the first problem (unknown level, duplicate name, ...).
  void validate() const;
};

/// Reads config/acupoints.yaml (yaml-cpp). Throws std::runtime_error naming
/// the file and the problem.
AcupointModel loadAcupointModel(const std::string& path);

/// Where a landmark of the layout came from.
enum class LandmarkSource {
  kMeasured,      ///< found in the view: C7 at the neck's base or the back's top, L4 from the waist
  kInferred,      ///< from other landmarks by the model's proportions: C7 from the shoulder line, L4 from C7 and the
                  ///< shoulder width
  kGiven,         ///< given from outside (given_landmarks.h), how not said
  kGivenService,  ///< given through the cect node's ~set_landmark / ~set_landmark_pixel
  kGivenClick,    ///< given by a click (rviz's Publish Point, a click on the debug image)
  kGivenMarker,   ///< given by a skin marker found in the view (skin_markers.h)
  kGivenOption,   ///< given on a tool's command line (cect_locate's --landmark)
};
/// Given from outside (any of the kGiven... values): it overrides a measured or inferred one.
inline bool isGiven(LandmarkSource source) {
  return source != LandmarkSource::kMeasured && source != LandmarkSource::kInferred;
}
/// What BackLandmark.msg's `source` carries: "measured", "inferred" or "given".
std::string sourceName(LandmarkSource source);
/// How a given landmark was given, as the descriptions say it: "service", "clicked", "marker", "--landmark"; empty for
/// a landmark not given or given without saying how (kGiven).
std::string givenHowName(LandmarkSource source);

/// What a measured or inferred landmark was taken from (Landmark::detail).
inline constexpr const char* kFromNeckBase = "the neck's base";
inline constexpr const char* kFromBackTop = "the back's top";
inline constexpr const char* kFromShoulderLine = "the shoulder line";
inline constexpr const char* kFromWaist = "the waist";
inline constexpr const char* kFromShoulderWidth = "C7 and the shoulder width";

/// One landmark of the layout (C7, a given level between such as T7, L4): where it is and what fixed it. The one
/// record the layout (placement, layoutCovariance), the checks (layout_check.h), the descriptions and the messages
/// read.
struct Landmark {
  Landmark(std::string level_ = {}, LandmarkSource source_ = LandmarkSource::kMeasured, std::string detail_ = {})
      : level(std::move(level_)), source(source_), detail(std::move(detail_)) {}
  std::string level;  ///< "C7", "T7", "L4"
  LandmarkSource source = LandmarkSource::kMeasured;
  std::string
      detail;        ///< measured / inferred: from what (kFromNeckBase, ...); empty when given (givenHowName says how)
  cv::Point2f body;  ///< on the midline, the body frame's pixel (BackLandmarks)
  /// The camera's raw left pixel where known (a given landmark kept by GivenLandmarkSet), else NaN.
  cv::Point2f raw_pixel{std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN()};
  /// 3D, the left optical frame, metres, where known (a given landmark applied with the back's 3D), else NaN.
  cv::Point3f point{std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN(),
                    std::numeric_limits<float>::quiet_NaN()};

  bool given() const { return isGiven(source); }
  /// Measured at the base of a neck in view (not the back's top taken for it, nor the shoulder line).
  bool atNeckBase() const { return source == LandmarkSource::kMeasured && detail == kFromNeckBase; }
};

/// The layout's sigma along the body (AcupointModel::layout_sigma, a fraction of C7 -> L4) of `level` ("C7", "L4" or a
/// level given between them) fixed by `source`.
double layoutSigma(const AcupointModel& model, const std::string& level, LandmarkSource source);
inline double layoutSigma(const AcupointModel& model, const Landmark& landmark) {
  return layoutSigma(model, landmark.level, landmark.source);
}

/// Landmarks of the back, in pixels of the body's frame: the rectified left
/// image turned (about the back) so that the body lies along the columns with
/// the head up, rows running across the body. For a subject lying along the
/// image's columns head up (within 1 degree) that frame is the image itself;
/// a subject lying turned on the table, or head down (`head_up: false`), has
/// its landmarks in the turned frame, and `to_image` (toImage()) maps them
/// into the image. levelPixel() and placeAcupoints() return image pixels.
struct BackLandmarks {
  bool valid = false;
  std::string reason;
  /// The spine's midline, one point per row of the body's frame from the top
  /// of the back to its bottom (x = middle of the back's extent on that row,
  /// smoothed).
  std::vector<cv::Point2f> midline;
  /// C7 and L4 on the midline (body: rows and columns of the body's frame), with what fixed them: C7 measured (at
  /// the neck's base or the back's top) or inferred from the shoulder line, L4 measured (the waist) or inferred from
  /// C7 and the shoulder width, either given from outside (given_landmarks.h: a therapist's click, a skin marker),
  /// which overrides the others. `measured` / `inferred` / `given` below say it in words.
  Landmark c7{"C7", LandmarkSource::kMeasured, kFromBackTop}, l4{"L4", LandmarkSource::kMeasured, kFromWaist};
  double shoulder_row = 0.0;    ///< the shoulder line (widest row of the upper back)
  double shoulder_width = 0.0;  ///< pixels, across the back at the shoulder line
  double waist_row = 0.0;       ///< narrowest row between shoulders and hips
  double iliac_row = 0.0;       ///< iliac-crest line (~L4)
  double top_row = 0.0;         ///< where the midline leaves the back at the head end (the neck base)
  /// Unit direction toward the subject's left, perpendicular to the midline (per midline row).
  std::vector<cv::Point2f> lateral;
  /// With the back's 3D (measureLevelsIn3D): per midline point, metres along
  /// the body's axis in 3D (the chord from C7 to L4) from C7; NaN where
  /// unknown. Empty: the levels are spaced in the frame's rows.
  std::vector<double> along;
  /// The body's frame -> the rectified left image (a rotation and a shift).
  cv::Matx23d to_image = cv::Matx23d(1, 0, 0, 0, 1, 0);
  /// Levels given between C7 and L4 (given_landmarks.h: T7, the scapulae's inferior angles), head to feet, each at
  /// its row of the body's frame (body.y): the levels between two of C7, these and L4 are spaced by the model's
  /// fractions between them.
  std::vector<Landmark> given_levels;
  /// What the checks need to know of each given landmark (applyGivenLandmarks; checkLayout): where it was given
  /// against the back as measured before it was applied.
  struct GivenCheck {
    std::string level;                               ///< "C7", "T7", "L4"
    LandmarkSource source = LandmarkSource::kGiven;  ///< how it was given
    cv::Point2f body;                                ///< the given pixel in the body's frame
    double off_midline = 0.0;  ///< pixels of the body's frame across the measured midline (+: the body frame's right,
                               ///< the subject's right in a head-up view), at the given row
    /// The same landmark as the pair measured it (C7 at a neck's base, L4 from the waist), body frame row; NaN when
    /// the pair did not measure it.
    double measured_row = std::numeric_limits<double>::quiet_NaN();
    std::string measured_from;  ///< "the neck's base", "the waist"
    bool confirmed = false;     ///< the given one confirmed over a measured one that disagrees with it
    std::string stale;          ///< non-empty: why it no longer holds (the back moved since it was given)
  };
  std::vector<GivenCheck> given_checks;
  /// In words: what the pair measured and inferred ("C7 at the neck's base", "the waist", "L4 from C7 and the
  /// shoulder width (...)"), and the given landmarks ("C7 (clicked)"): printed, never read back (c7, l4 and
  /// given_levels say it).
  std::vector<std::string> measured, inferred, given;
  /// How far the body is turned against the image's columns, degrees
  /// (+: the head toward the image right of a head-up view, clockwise on screen); 0 within
  /// 1 degree.
  double body_angle_deg = 0.0;
};

/// One line: the landmarks the layout used with their sources (layoutLandmarks), then what the pair itself measured
/// and inferred (a given landmark replaces its measured one), e.g. "used: C7 given (clicked), L4 measured (the
/// waist); measured: C7 at the neck's base, the waist; inferred: -".
std::string describeLandmarks(const BackLandmarks& landmarks);

/// One of the layout's landmarks (C7, a given T7, L4) with its rectified left pixel.
struct LayoutLandmark {
  Landmark landmark;
  cv::Point2f pixel;  ///< rectified left image
};

/// C7, the given levels between (T7) and L4 of `landmarks`, head to feet (empty when they are not valid).
std::vector<LayoutLandmark> layoutLandmarks(const BackLandmarks& landmarks);

/// From what a landmark was fixed, in words: Landmark::detail ("the neck's base", "C7 and the shoulder width"), or
/// for a given one how it was given (givenHowName: "clicked", "marker", ...). BackLandmark.msg's `detail`.
std::string landmarkDetail(const Landmark& landmark);

/// "C7 given (clicked)", "L4 measured (the waist)": the level, sourceName and landmarkDetail.
std::string describeLandmark(const Landmark& landmark);
inline std::string describeLandmark(const LayoutLandmark& landmark) { return describeLandmark(landmark.landmark); }

/// A point of the body's frame (BackLandmarks) in the rectified left image.
cv::Point2f toImage(const BackLandmarks& landmarks, const cv::Point2f& body_pixel);

/// Finds the landmarks from the left view's segmentation. The body's frame:
/// the axis of the midline between C7 and L4 (fitted row by row) is turned
/// onto the columns and the landmarks found again, until it stays within
/// 0.1 degree (at most a few turns; a body turned by more than 45 degrees is
/// refused). Never throws for image content (valid = false with a reason).
/// `l4_given`: L4 will be given (a click, a skin marker; applyGivenLandmarks), so an L4 inferred below the back's
/// bottom (a towel over the hips, a short trunk) does not fail the search.
BackLandmarks findLandmarks(const Segmentation& left, const AcupointModel& model, bool l4_given = false);

/// Metres per pixel at a rectified left pixel (depth / fx), NaN if unknown.
using PixelScale = std::function<double(const cv::Point2f& rect_pixel)>;

/// 3D point (left camera frame, metres) of a rectified left pixel; false if unknown.
using PointLookup = std::function<bool(const cv::Point2f& rect_pixel, cv::Point3d* point)>;

/// The silhouette's centre line is not the skin's midline: the flanks' rims
/// lie ~0.1 m below the spine, so a camera off the body's symmetry plane
/// (the left camera of a pair is half a baseline off) sees them shifted
/// against the spine by the parallax (~8 mm in the cell). With the back in
/// 3D this moves the midline (and C7, L4 on it) onto the skin point of each
/// row that lies on the plane halfway between the two rims (normal from rim
/// to rim parallel to the image plane: the camera looks down at the table;
/// rolled against the body is fine): per row the 3D points of the outermost
/// back pixels, Newton steps along the row, then a robust line
/// fitted to the shifts over the torso's rows (rows of the body's frame;
/// `left` and `point` are the image's). Returns the mean shift in pixels
/// (toward the body frame's right: +); leaves the landmarks as they are and
/// returns NaN when fewer than 10 rows have the 3D points.
double correctMidlineParallax(BackLandmarks* landmarks, const Segmentation& left, const PointLookup& point);

/// The waist is the silhouette's narrowest row, read from the flanks' rims,
/// which lie ~0.1 m below the spine: seen from a camera off the waist the
/// rims' row and the spine's row at the same place along the body differ by
/// the parallax (~10 px at 640x480 for the cell's centred camera, calibrated
/// into waist_fraction with `waist_rim_offset`), and a camera moved along the
/// table changes it (the waist, and L4 with it, lagged the body by 3 px at
/// 4 cm and ~15 px at 14 cm). With the back in 3D this finds the midline row
/// at the same position along the body's axis as the waist's rims, moves the
/// waist by that offset less the calibrated one, and places C7 and L4 again
/// from the top and the waist. Call after correctMidlineParallax and before
/// measureLevelsIn3D (it clears `along`, which is measured from C7). Returns the waist's move in rows of the body
/// frame; leaves the landmarks as they are and returns NaN without the 3D points.
double correctWaistParallax(BackLandmarks* landmarks, const AcupointModel& model, const Segmentation& left,
                            const PointLookup& point);

/// The levels between C7 and L4 are fractions of the spine's length, but the
/// image's rows are not proportional to length along the body: the upper
/// back rises toward the camera (magnified) and a camera off the back's
/// centre sees it in perspective; spaced in rows, T6-T12 came out 4-8 px
/// (6-12 mm) toward the head with the camera centred and 12-21 px with it
/// 4-14 cm along the table. With the back in 3D this measures every midline
/// point's position along the body's axis (the chord C7 -> L4; a robust cubic
/// in the row fitted to the 3D points, so depth noise does not add length),
/// and levelPixel() / placeAcupoints() then space the levels along it. C7 and
/// L4 stay where the silhouette put them. Returns C7 -> L4 in metres; leaves
/// the landmarks as they are and returns NaN when too few midline points
/// between C7 and L4 have 3D points or the fit is not monotonic.
double measureLevelsIn3D(BackLandmarks* landmarks, const PointLookup& point);

class CectFrame;
/// A CECT frame's surface as the model wants it: metres per pixel (depth / fx)
/// and 3D points at rectified left pixels (the frame must outlive them).
PixelScale frameScale(const CectFrame& frame);
PointLookup framePoints(const CectFrame& frame);

struct AcupointPixel {
  std::string name;
  cv::Point2f pixel;  ///< rectified left image
  bool valid = false;
  std::string reason;
};

/// The layout's uncertainty of a point at `level` (AcupointModel::
/// layout_sigma by the sources of BackLandmarks::c7 / l4 / given_levels: layoutSigma), 3x3 in
/// metres^2 in the left optical frame, lying in the image plane's directions
/// (along the body's axis on the image and across it; the camera looks down
/// on the back). `metres_per_pixel` at the point turns the C7 -> L4 length
/// on the image into metres. Zero for an unknown level or scale.
Eigen::Matrix3d layoutCovariance(const BackLandmarks& landmarks, const AcupointModel& model, const std::string& level,
                                 double metres_per_pixel);

/// Midline pixel of `level` in the image (interpolated along the midline with level_fraction).
cv::Point2f levelPixel(const BackLandmarks& landmarks, const AcupointModel& model, const std::string& level);
/// cun in metres from the shoulder width (scale gives metres per pixel on the shoulder line).
double cunMetres(const BackLandmarks& landmarks, const AcupointModel& model, const PixelScale& scale);
/// Every acupoint of the model as a left-image pixel (lateral offsets in
/// metres converted with `scale` at the midline point of its level).
std::vector<AcupointPixel> placeAcupoints(const BackLandmarks& landmarks, const AcupointModel& model,
                                          const PixelScale& scale);

}  // namespace massage_cell::cect
