// Landmarks given from outside the image analysis: a therapist palpates C7,
// the iliac crests (L4) and the scapulae's inferior angles (T7) in seconds,
// and clicks them (rviz's Publish Point, a click on the debug image, the cect
// node's ~set_landmark service) or sticks markers on them. Given landmarks
// replace the measured or inferred ones of the same name; the levels between
// two of them follow from the model's level fractions between those two.
// ROS-free.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"

namespace massage_cell::cect {

struct GivenLandmark {
  std::string name;    ///< givenLandmarkNames(): "C7" (the vertebra prominens), "T7" (the scapulae's inferior angles'
                       ///< line), "L4" (the iliac crests' line)
  cv::Point2f pixel;   ///< on the midline at that level, rectified left image
  std::string source;  ///< how it was given ("clicked", "service", "marker"): said in the landmarks' description
};

/// The names a landmark can be given by: "C7", "T7", "L4".
const std::vector<std::string>& givenLandmarkNames();

/// An empty string when `name` can be given, else why not (naming the names that can).
std::string checkGivenLandmarkName(const std::string& name);

/// Puts `given` into `landmarks` (as findLandmarks and the parallax corrections left them): each level at its
/// pixel's row of the body's frame, the midline moved across to pass through the given pixels (with one, shifted by
/// a constant; with more, the straight lines through them in order between the first and the last, the lateral
/// directions perpendicular to each, and beyond them the midline shifted to join it), `c7_given` / `l4_given` set,
/// a given T7 in `given_levels` (placeAcupoints then spaces the levels C7..T7 and T7..L4 by the model's fractions
/// between them) and the description's "given" list filled. Clears `along` (measured from the old C7: call
/// measureLevelsIn3D again). Returns an empty string when applied; else the problem (an unknown name, a name twice,
/// a pixel not finite or not on the back's rows, L4 not below C7, T7 not between them), leaving the landmarks as
/// they were.
std::string applyGivenLandmarks(BackLandmarks* landmarks, const std::vector<GivenLandmark>& given);

/// The landmarks a node was given, each kept as a pixel of the camera's raw left image (what a click on the image,
/// a service call's pixel or a 3D point projected into the camera all come to), turned into each pair's processed
/// rectified pixels. Not thread-safe: the node guards it.
class GivenLandmarkSet {
 public:
  /// Sets (or replaces) `name` at `raw_pixel` of an image of `image_size`. Returns an empty string, else the problem
  /// (an unknown name, a pixel not finite or outside the image) and changes nothing.
  std::string set(const std::string& name, const cv::Point2f& raw_pixel, const std::string& source,
                  cv::Size image_size);
  void clear() { landmarks_.clear(); }
  bool empty() const { return landmarks_.empty(); }
  /// The landmarks in a pair's rectified left pixels (`geometry` of the processed images, `decimation` from the
  /// camera's to them).
  std::vector<GivenLandmark> forPair(const camera::StereoModel& geometry, const camera::Decimation& decimation) const;
  /// "C7 (clicked) at raw (412.0, 96.5), L4 (service) at raw (...)", or "none".
  std::string describe() const;

 private:
  std::map<std::string, GivenLandmark> landmarks_;  ///< pixel: the camera's raw left image
};

/// A camera pixel (raw left, full resolution) of a rectified pixel of the processed images.
cv::Point2f cameraPixel(const cv::Point2f& rect_pixel, const camera::StereoModel& geometry,
                        const camera::Decimation& decimation);

/// Which landmark a click at `rect_pixel` gives: the one of givenLandmarkNames() whose level in `landmarks` lies
/// nearest to it (a click at the neck's base is C7, one at the hips L4); empty when the landmarks are not valid.
std::string nearestGivenLandmark(const BackLandmarks& landmarks, const AcupointModel& model,
                                 const cv::Point2f& rect_pixel);

}  // namespace massage_cell::cect
