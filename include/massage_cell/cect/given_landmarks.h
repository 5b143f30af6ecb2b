// Landmarks given from outside the image analysis: a therapist palpates C7,
// the iliac crests (L4) and the scapulae's inferior angles (T7) in seconds,
// and clicks them (rviz's Publish Point, a click on the debug image, the cect
// node's ~set_landmark service) or sticks markers on them. Given landmarks
// replace the measured or inferred ones of the same name; the levels between
// two of them follow from the model's level fractions between those two.
// ROS-free.
#pragma once

#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"

namespace massage_cell::cect {

/// A pair's back as given landmarks follow it: its rectified left view in grey and the back's mask (copies: they
/// outlive the pair's images), its geometry and decimation (to and from the camera's pixels), and the metres per
/// pixel at the back's centre. backView() makes one (not valid, with the reason, when the pair has no back); a default
/// one (not valid, no reason) is none: landmarks given on it are not followed.
struct BackView {
  bool valid = false;
  std::string reason;  ///< why not valid (no back in view)
  cv::Mat grey, mask;
  camera::StereoModel geometry;
  camera::Decimation decimation;
  cv::Point2f centre;                                                  ///< the back's centroid, rectified pixels
  double metres_per_pixel = std::numeric_limits<double>::quiet_NaN();  ///< at the centre (NaN: no depth there)
};
BackView backView(const CectFrame& frame, const camera::Decimation& decimation);

/// How the back moved from one pair to another: the skin's texture tracked from the first view's back to the second
/// (Lucas-Kanade, forward and back), a similarity fitted to the tracks with RANSAC.
struct BackMotion {
  bool valid = false;
  std::string reason;     ///< why not (no back, too little texture, too few tracks agree)
  cv::Matx23d transform;  ///< the first view's rectified pixels -> the second's
  double move_m = 0.0;    ///< how far the back's centre moved (metres, at the skin)
  double turn_deg = 0.0;  ///< how far it turned in the image (+: clockwise on screen)
  int tracks = 0, agreeing = 0;
};
BackMotion backMotion(const BackView& from, const BackView& to);

/// How far a back may move from where it lay when its landmarks were given before they are stale: breathing moves
/// the back 2-5 mm (mostly in depth), the tracking's noise is ~1 px; a client who slides or turns moves it
/// centimetres. The landmarks follow within these; beyond, a therapist confirms them.
struct FollowLimits {
  double max_move_m = 0.02;
  double max_turn_deg = 5.0;
};

struct GivenLandmark {
  GivenLandmark() = default;
  GivenLandmark(std::string name_, const cv::Point2f& pixel_, LandmarkSource source_, bool confirmed_ = false)
      : name(std::move(name_)), pixel(pixel_), source(source_), confirmed(confirmed_) {}
  std::string name;   ///< givenLandmarkNames(): "C7" (the vertebra prominens), "T7" (the scapulae's inferior angles'
                      ///< line), "L4" (the iliac crests' line)
  cv::Point2f pixel;  ///< on the midline at that level, rectified left image
  /// How it was given (one of the given sources): said in the landmarks' description and messages.
  LandmarkSource source = LandmarkSource::kGiven;
  /// The camera's raw left pixel where known (GivenLandmarkSet::forPair), else NaN: carried into Landmark::raw_pixel.
  cv::Point2f raw_pixel{std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN()};
  /// Confirmed over the pair's own measurement of the same landmark (a neck's base, a waist) where the two disagree:
  /// without it such a layout is not trusted (checkLayout).
  bool confirmed = false;
  /// Non-empty: why the landmark no longer holds (the back moved or was lost since it was given, GivenLandmarkSet::
  /// follow): the layout is not trusted until it is confirmed again.
  std::string stale;
};

/// The names a landmark can be given by: "C7", "T7", "L4".
const std::vector<std::string>& givenLandmarkNames();

/// An empty string when `name` can be given, else why not (naming the names that can).
std::string checkGivenLandmarkName(const std::string& name);

/// Puts `given` into `landmarks` (as findLandmarks and the parallax corrections left them): each level at its
/// pixel's row of the body's frame, the midline moved across to pass through the given pixels (with one, shifted by
/// a constant; with more, the straight lines through them in order between the first and the last, the lateral
/// directions perpendicular to each, and beyond them the midline shifted to join it), `c7` / `l4` given (their
/// source, raw pixel and, with `point`, 3D), a given T7 in `given_levels` (placeAcupoints then spaces the levels C7..T7
/// and T7..L4 by the model's fractions between them), the description's "given" list filled, and `given_checks`
/// recording each given pixel against the back as measured before (across its midline; the pair's own C7 / L4 where it
/// measured them) for checkLayout. Clears `along` (measured from the old C7: call measureLevelsIn3D again). Returns an
/// empty string when applied; else the problem (an unknown name, a name twice, a pixel not finite or not on the back's
/// rows, L4 not below C7, T7 not between them), leaving the landmarks as they were. `point`: the back's 3D
/// (framePoints), which places the spine across each given row for the checks (the middle of the back's top there);
/// without it the silhouette's midline does.
std::string applyGivenLandmarks(BackLandmarks* landmarks, const std::vector<GivenLandmark>& given,
                                const PointLookup& point = {});

/// The landmarks a node was given, each kept as a pixel of the camera's raw left image (what a click on the image,
/// a service call's pixel or a 3D point projected into the camera all come to), turned into each pair's processed
/// rectified pixels. Not thread-safe: the node guards it.
class GivenLandmarkSet {
 public:
  /// Sets (or replaces) `name` at `raw_pixel` of an image of `image_size` (`confirmed`: GivenLandmark::confirmed), on
  /// the back of `view` (the pair it was given on; no frame: not followed). Returns an empty string, else the problem
  /// (an unknown name, a pixel not finite or outside the image) and changes nothing.
  std::string set(const std::string& name, const cv::Point2f& raw_pixel, LandmarkSource source, cv::Size image_size,
                  bool confirmed = false, const BackView& view = {});
  void clear() { landmarks_.clear(); }
  bool empty() const { return landmarks_.empty(); }
  /// Carries each landmark with the back from the view it was given (or confirmed) on to `now` (backMotion): moved
  /// and turned with it; beyond `limits` it is stale (GivenLandmark::stale says why) though carried (shown where the
  /// back took it, for a therapist to confirm), and when the back cannot be followed it keeps its last place, stale.
  void follow(const BackView& now, const FollowLimits& limits = {});
  /// The therapist checked the landmarks where they are now (carried with the back): each is given again there, on
  /// the back of `now`, and no longer stale. Returns an empty string, else the problem (no back in `now`) and changes
  /// nothing.
  std::string confirm(const BackView& now);
  /// The landmarks in a pair's rectified left pixels (`geometry` of the processed images, `decimation` from the
  /// camera's to them), each with its raw pixel (GivenLandmark::raw_pixel).
  std::vector<GivenLandmark> forPair(const camera::StereoModel& geometry, const camera::Decimation& decimation) const;
  /// "C7 (clicked) at raw (412.0, 96.5), L4 (service) at raw (...)", or "none".
  std::string describe() const;

 private:
  struct Kept {
    GivenLandmark given;       ///< pixel: where it is now (carried), the camera's raw left image
    cv::Point2f anchor_pixel;  ///< where it was given or last confirmed ...
    BackView anchor;           ///< ... on this pair's back
  };
  std::map<std::string, Kept> landmarks_;
};

/// A camera pixel (raw left, full resolution) of a rectified pixel of the processed images.
cv::Point2f cameraPixel(const cv::Point2f& rect_pixel, const camera::StereoModel& geometry,
                        const camera::Decimation& decimation);

/// Which landmark a click at `rect_pixel` names when the click does not say: the one of givenLandmarkNames() whose
/// level in `landmarks` lies nearest to it (a click at the neck's base is C7, one at the hips L4), only when that is
/// unambiguous: at most kClickNameRatio as far as the next nearest level. Else `name` is empty and `problem` says
/// why (no layout, or the two nearest levels with their distances).
struct ClickName {
  std::string name;
  std::string problem;
};
constexpr double kClickNameRatio = 0.5;
ClickName nameClick(const BackLandmarks& landmarks, const AcupointModel& model, const cv::Point2f& rect_pixel);

}  // namespace massage_cell::cect
