// Coloured adhesive skin markers (a kit of stickers a therapist puts on the palpated C7 and on the iliac crests'
// line, L4, and optionally on T7) found in both views of a rectified stereo pair: per sticker, the pixels of its colour
// (HSV), opened and split into blobs, the round ones of a dot's size kept; the one on the back in the left view is
// matched along its row in the right view. Never guesses: none or several candidates are a problem, not a pick. What is
// found is meant to become a GivenLandmark (given_landmarks.h) with source "marker". ROS-free.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace massage_cell::cect {

/// One sticker of the kit: which landmark it marks and its colour.
struct SkinMarkerSpec {
  std::string landmark;  ///< "C7", "T7" or "L4" (must pass checkGivenLandmarkName from given_landmarks.h)
  std::string colour;    ///< its everyday name ("green"): what to buy, what the simulator renders (empty: from the hue)
  double hue_deg = 0;    ///< the sticker's hue, degrees 0..360 (HSV of the sRGB image)
  double hue_tolerance_deg = 22;  ///< accepted |hue - hue_deg| (wrapping at 360)
  double min_saturation = 0.40;   ///< 0..1
  double min_value = 0.12;        ///< 0..1 (dark pixels have no reliable hue)
  double diameter_m = 0.025;      ///< printed size, metres (used with the pixel scale when known)
  /// Stuck only on some backs (T7's dot): no candidate of its colour on the back is no problem (SkinMarkers::absent).
  bool optional = false;
};

/// The kit and the limits of the search (pixels of the rectified images).
struct SkinMarkerOptions {
  std::vector<SkinMarkerSpec> markers;
  double min_diameter_px = 3.0;  ///< smaller blobs are noise
  double max_diameter_px = 60.0;
  double min_fill = 0.55;              ///< blob area / area of its minimum enclosing circle (a round dot)
  double max_row_difference_px = 2.0;  ///< rectified: the dot's centre row in the left and right views
  double max_area_ratio = 2.5;         ///< left vs right blob area
  double mask_margin_px =
      6.0;  ///< the back's mask is dilated by this much (a dot is not skin: it may cut the mask's edge)
  /// With a pixel scale: a blob whose diameter differs from diameter_m / scale by more than this factor (either way)
  /// is not the sticker.
  double max_size_ratio = 1.6;
};

/// One sticker found in both views.
struct SkinMarkerDetection {
  std::string landmark;
  cv::Point2f left, right;  ///< sub-pixel centres (intensity-weighted centroid of the blob), rectified images
  float disparity = 0;      ///< left.x - right.x
  double diameter_px = 0;   ///< equivalent diameter in the left view
};

/// What detectSkinMarkers found, and why the others were not.
struct SkinMarkers {
  std::vector<SkinMarkerDetection> found;  ///< at most one per landmark, in the kit's order
  /// Per missing/refused marker, e.g. "L4 (blue dot): not found in the left view", "C7 (green dot): 2 candidates in
  /// the left view, none taken (at ...)", "C7 (green dot): no match in the right view on rows 101..105 with
  /// disparity 8..40".
  std::vector<std::string> problems;
  /// The optional markers with no candidate on the back ("T7 (magenta dot)"): not stuck on this subject.
  std::vector<std::string> absent;
  /// One line: the found ones, then the problems, then the optional ones absent: "C7 at (160.2, 41.0) d 23.1; L4
  /// (blue dot): not found in the left view; T7 (magenta dot): optional, not on the back"; "no markers" when there
  /// is none of these.
  std::string describe() const;
};

/// Empty string when usable, else the first problem (no markers, an unknown landmark, a landmark twice, hue out of
/// 0..360, tolerance <= 0 or >= 90, two stickers whose hue ranges overlap, saturation/value out of 0..1, non-positive
/// sizes, min >= max, a fill out of (0, 1], an area or size ratio below 1, ...).
std::string checkSkinMarkerOptions(const SkinMarkerOptions& options);

/// Loads a kit from YAML (yaml-cpp; keys as the fields, all but `markers` optional; `markers:` a list whose items
/// need `landmark` and `hue_deg`). Throws std::runtime_error naming the file and the problem (missing file, bad YAML,
/// an unknown key, a wrong type, checkSkinMarkerOptions' problem).
SkinMarkerOptions loadSkinMarkerOptions(const std::string& path);

/// Metres per pixel at a rectified left pixel (the same type as acupoint_model.h's PixelScale).
using SkinMarkerScale = std::function<double(const cv::Point2f& rect_pixel)>;

/// Finds each sticker in the rectified pair (BGR CV_8UC3, same size). `left_mask` (CV_8U, non-zero on the back; may
/// be empty = whole image) restricts the left-view search, dilated by mask_margin_px: a blob is on the back when at
/// least half of the 2 px ring around it lies in the dilated mask (so a dot the segmentation cut out of the mask, as
/// a hole or a notch at its edge, still counts). `disparity_range` = {min, max} disparities searched in the right
/// view. `metres_per_pixel`, when given, refuses left-view blobs of the wrong size for the printed diameter (a scale
/// that is not finite and positive at a blob skips the check). Throws std::invalid_argument for images of the wrong
/// type/size, a mask of the wrong type/size, a range not finite or min > max, and options checkSkinMarkerOptions
/// refuses; content problems go to `problems`. Deterministic.
SkinMarkers detectSkinMarkers(const cv::Mat& left_bgr, const cv::Mat& right_bgr, const cv::Mat& left_mask,
                              cv::Vec2d disparity_range, const SkinMarkerOptions& options,
                              const SkinMarkerScale& metres_per_pixel = {});

/// The pixels of the kit's dots in `bgr` (CV_8UC3), whatever they lie on: each colour's components of a dot's size
/// (min_diameter_px .. max_diameter_px across, so a sheet or a gown of that colour is not one), grown by their
/// anti-aliased rim (2 px). CV_8U, 255 on them. The segmentation counts them as skin (a sticker on the back is the
/// back). Throws std::invalid_argument for an image that is not CV_8UC3 or options checkSkinMarkerOptions refuses.
cv::Mat skinMarkerPixels(const cv::Mat& bgr, const SkinMarkerOptions& options);

}  // namespace massage_cell::cect
