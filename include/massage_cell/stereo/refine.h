// Disparity refinement with fattening foreground region detection (thesis
// Ch. 2 §2.3): FFD (§2.3.1) finds the foreground-fattening regions of a
// disparity map by comparing its edges with a superpixel segmentation of the
// reference image; MDC (§2.3.2, Eq. 2.11-2.13) recomputes every disparity as
// the adaptive-support-weighted vote of the reliable (non-fattening) pixels of
// a window around it. ROS-free (OpenCV core / imgproc / ximgproc).
//
// Conventions as in cost_volume.h: the left image is the reference view;
// disparities are CV_32F pixels, NaN = invalid (no disparity).
//
// Our choices where the thesis is silent (measured on Middlebury 2003 with
// HBDS input; numbers in src/stereo/refine.cpp):
//
// FFD (detectFattening)
// * Disparity edges: cv::Canny on the integer (rounded) disparity map, with
//   the 3 x 3 Sobel derivatives of that map passed in directly, so the two
//   hysteresis thresholds are disparity jumps in pixels (a step of h pixels has
//   L2 Sobel magnitude 4 h). NaN pixels take, for edge detection only, the
//   smaller of the nearest valid disparities to their left and right on their
//   row (the background, as an occlusion fill does).
// * Superpixels of the reference image: OpenCV ximgproc SLIC (default: plain
//   SLIC on CIELab, region_size 12, ruler 15, 10 iterations, connectivity
//   enforced); SLICO and SEEDS are selectable. Measured FFD+MDC on the four
//   scenes (same other parameters): SLIC < SLICO < SEEDS in bad pixels (mean
//   disc 17.5 / 18.5 / 21.7 % with an early, looser parameter set); SEEDS
//   segments straddle object boundaries more often (under-segmentation, which
//   the thesis's segmentation is meant to avoid); region_size 20 was far worse.
// * Segment boundary: the pixels whose 4-neighbour carries another label
//   (both sides of the border) AND whose two segments' mean CIELab colours
//   differ by at least `boundary_contrast` (ΔE): SLIC often leaves a thin
//   sliver of background along an object edge, and the boundary between that
//   sliver and the rest of the background is no image edge. A disparity-edge
//   pixel farther than `edge_tolerance` pixels (Euclidean) from every such
//   boundary pixel is an interior edge pixel of its segment.
// * Per segment S with at least `min_edge_pixels` interior edge pixels: the
//   region split is S plus the segments found within ceil(edge_tolerance) + 1
//   pixels of its interior edge pixels (one hop, no chaining). The integer
//   disparities of its valid pixels are split in two classes at the largest
//   gap between consecutive significant disparity levels (levels holding at
//   least max(2, `min_class_fraction` x valid pixels); the rest join the side
//   of the gap's middle they fall on). The larger-disparity class is marked as
//   fattening if (a) the gap is at least `min_jump`, (b) at least
//   `min_edge_pixels` interior edge pixels see both classes in their 3 x 3
//   neighbourhood inside the region (the split runs along the interior edge),
//   and (c) the two classes' mean CIELab colours differ by less than
//   `max_fattening_contrast` (a fattening band wears the background's colour;
//   a high class of another colour is a real object the segmentation missed;
//   without (c) FFD marked 10-24 k pixels per scene, 75-85 % of them correct,
//   and made MDC clearly worse).
//
// MDC (recoverDisparity)
// * Colour distance Δc: Euclidean in CIELab (L in 0..100, as Yoon & Kweon),
//   computed in float; grey images use L = 100 grey / 255 with a = b = 0.
//   Spatial distance Δg: Euclidean pixel distance. The window is the
//   `window` x `window` square around p clipped to the image (no padding).
// * exp(-Δc / γc) comes from a table in steps of γc / 64 (relative error of the
//   weight <= 0.8 %); exp(-Δg / γg) is precomputed per window offset.
// * Voters (C(q, d) = 1) are the pixels with a finite disparity outside the
//   fattening mask, voting for round(d(q)). Candidates are the levels voted
//   for in the window (other d have Ω = 0 and cannot win).
// * d'(p) = argmax Ω(p, d); ties: p's own rounded disparity if it is among the
//   tied maxima, else the smallest tied d. No voter in the window: d(p) is kept
//   (NaN stays NaN). If d'(p) equals round(d(p)), the input value is kept
//   (sub-pixel input is not quantised where it wins; integer maps: the same).
//   Otherwise the output is the integer d'(p). Every pixel, fattening or NaN
//   included, is recomputed when it has voters.
// * Exact shortcut: where every voter of the window has the same level (min ==
//   max of the voters' levels, separable min/max filters), that level is the
//   answer without summing.
// * Defaults window 21, γc 7, γg 10.5 (Yoon & Kweon: 35, 5, 17.5): Gu's
//   calibration on HBDS maps is as good or better with 21-25 (mean bad > 1
//   nonocc 3.96 % vs 4.15 % at 35) and 21 meets ~120 ms on 450 x 375 with 2
//   threads (35: ~320 ms, 25: ~165 ms).
// * Complexity: O(W H w^2) time for the pixels whose window holds more than
//   one level (w = window), O(W H) for the others, independent of the
//   disparity range; memory O(W H) plus O(levels) per thread. Rows are
//   distributed over threads with cv::parallel_for_.
#pragma once

#include <stdexcept>

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

enum class Superpixels { kSlic, kSlico, kSeeds };

struct RefineParams {
  // --- FFD (§2.3.1)
  Superpixels superpixels = Superpixels::kSlic;
  int region_size = 12;         ///< average superpixel side (pixels), >= 4
  float ruler = 15.0f;          ///< SLIC compactness (ignored by SLICO / SEEDS)
  int slic_iterations = 10;     ///< SLIC / SEEDS iterations, >= 1
  float canny_low = 2.0f;       ///< Canny hysteresis low threshold, disparity jump (px) > 0
  float canny_high = 3.0f;      ///< Canny high threshold, disparity jump (px) >= canny_low
  float edge_tolerance = 1.5f;  ///< max distance (px) of a disparity edge to a segment boundary to coincide, >= 0
  /// A segment boundary counts only between segments whose mean CIELab
  /// colours differ by at least this (ΔE); 0 = every boundary (thesis literal).
  float boundary_contrast = 8.0f;
  /// A split region's larger-disparity class is fattening only if its mean
  /// CIELab colour is within this ΔE of the smaller-disparity class's; 0 = no check.
  float max_fattening_contrast = 5.0f;
  int min_edge_pixels = 8;           ///< interior edge pixels needed to split a segment, >= 1
  float min_jump = 2.0f;             ///< least disparity gap between the two classes of a split segment (px) > 0
  float min_class_fraction = 0.03f;  ///< significant disparity level: this share of the segment's pixels, [0, 0.5)
  // --- MDC (§2.3.2)
  int window = 21;        ///< odd side of the support window W, >= 1
  float gamma_c = 7.0f;   ///< γc of the adaptive support weight (CIELab units) > 0
  float gamma_g = 10.5f;  ///< γg (pixels) > 0
  // --- refineDisparity
  bool detect_fattening = true;  ///< false: plain calibration (Gu) without FFD
};

/// Throws std::invalid_argument naming the first bad parameter.
void validate(const RefineParams& params);

/// FFD: mask of the foreground-fattening regions of `disparity` (CV_32F, NaN
/// = invalid, otherwise finite) given the reference image `left` (CV_8UC3
/// BGR or CV_8UC1, same size). CV_8U, 255 = fattening, 0 elsewhere (NaN
/// pixels are never fattening). Throws std::invalid_argument naming the
/// problem (empty, sizes differ, wrong types, infinite disparities, bad
/// parameters).
cv::Mat detectFattening(const cv::Mat& left, const cv::Mat& disparity, const RefineParams& params);

/// MDC (Eq. 2.11-2.13): every pixel takes the level of maximal adaptive-
/// support-weighted vote of the voters of its window (finite disparity and
/// not in `fattening_mask`, CV_8U non-zero = excluded; empty = no exclusion,
/// i.e. Gu's original calibration). Returns CV_32F. Throws
/// std::invalid_argument as detectFattening (plus a mask of the wrong size /
/// type). `threads`: worker stripes over rows, 0 = all cores (the result does not depend on it).
cv::Mat recoverDisparity(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& fattening_mask,
                         const RefineParams& params, int threads = 0);

/// FFD (if params.detect_fattening) then MDC. `fattening` (optional) receives
/// the mask used (empty without FFD). FFD is single-threaded, MDC uses `threads` (as recoverDisparity).
cv::Mat refineDisparity(const cv::Mat& left, const cv::Mat& disparity, const RefineParams& params,
                        cv::Mat* fattening = nullptr, int threads = 0);

}  // namespace massage_cell::stereo
