// One call from a rectified image pair to a disparity map with any of the
// project's methods, and their one default setting. ROS-free. Evaluation on
// Middlebury scenes: middlebury.h; pictures: colourise.h; the allocator
// setting of programs matching many pairs: memory.h.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"
#include "massage_cell/stereo/energy.h"
#include "massage_cell/stereo/filters.h"
#include "massage_cell/stereo/refine.h"
#include "massage_cell/stereo/subpixel.h"

namespace massage_cell::stereo {

enum class Method { kHbds, kExpansion, kSwap, kWta, kSgbm };
/// Refinement after the method (thesis Sec. 2.3, refine.h): none; Gu's
/// disparity calibration (MDC without fattening detection); FFD + MDC; and
/// the conventional refiners of the thesis's Table 2.5 (filters.h), each
/// alone or blind to FFD's fattening mask.
enum class Refinement { kNone, kMdc, kFfdMdc, kBf2d, kFfdBf2d, kBf3d, kFfdBf3d, kWmf, kFfdWmf };
/// "none" | "mdc" | "ffd-mdc" | "2dbf" | "ffd-2dbf" | "3dbf" | "ffd-3dbf" | "wmf" | "ffd-wmf"
Refinement parseRefinement(const std::string& name);
std::string toString(Refinement refinement);
bool usesFattening(Refinement refinement);    ///< the ffd-* ones
Method parseMethod(const std::string& name);  ///< "hbds" | "expansion" | "swap" | "wta" | "sgbm"
std::string toString(Method method);

/// The data term of the default setting: AD-census (docs/stereo.md "The default setting": with the full-range polish
/// it beats the thesis's term on every real scene measured but Venus).
inline CostParams defaultMatchCost() {
  CostParams cost;
  cost.data_term = DataTerm::kAdCensus;
  return cost;
}

/// Every parameter of match(). Its defaults are the project's one default setting — the library's, the hbds node's
/// (cfg/HBDS.cfg mirrors them; test_hbds_defaults fails when they disagree) and the stereo tools' — and the best
/// measured on real scenes: AD-census, HBDS with overlap 1, then one alpha-expansion cycle over every level on 2x2
/// blocks fused into the HBDS labelling (the coarse full-range polish), FFD + MDC and the left-right check
/// (docs/stereo.md "The default setting": Middlebury 2005 Art / Dolls 18.6 / 13.0 % bad > 1 px against 31.1 / 15.0 %
/// with the thesis's term and no polish, and StereoSGBM + fill's 29.0 / 20.1 %).
struct StereoParams {
  CostParams cost = defaultMatchCost();
  SmoothParams smooth;
  int max_cycles = 20;  ///< expansion / swap
  /// hbds only: levels each child's set reaches across the break point (0:
  /// the thesis's disjoint split; see hbds() in optimizers.h).
  int hbds_overlap = 1;
  /// hbds only: block side of the coarse-to-fine cuts (1: off; see hbds()).
  int hbds_coarse = 1;
  /// hbds only: after the hierarchy, local alpha-expansion moves (labels
  /// within polish_window levels of alpha) lower the Eq. 2.2 energy of the
  /// HBDS labelling; 0 = pure HBDS as in the thesis. The default, 256,
  /// reaches every level of any range up to 256: where a texture-less region
  /// went down the wrong side of a split, its true level can still take it.
  int polish_window = 256;
  int polish_cycles = 1;  ///< cycles of the polish (it stops earlier when a cycle changes nothing)
  /// hbds only, with polish_window > 0: block side of a coarse polish (0 or
  /// 1: off, the polish runs at full resolution). >= 2: the polish's
  /// expansion cycles run on polish_coarse x polish_coarse blocks, then one
  /// fusion move at full resolution picks, per pixel, the HBDS label or its
  /// block's label (coarsePolish() in optimizers.h).
  int polish_coarse = 2;
  Refinement refine = Refinement::kFfdMdc;  ///< after any method (none: the method's own output)
  RefineParams refine_params;               ///< detect_fattening is set from `refine`
  FilterParams filter_params;               ///< the 2dbf / 3dbf / wmf refiners
  /// Last, for the cost-volume methods (SGBM has its own 1/16 pixel): each
  /// integer label moved to the minimum of its cost curve (subpixel.h).
  bool subpixel = false;
  SubpixelParams subpixel_params;
  /// Left-right check (consistency.h; our addition beside the thesis): the
  /// right view's map by the same method on the mirrored pair (twice the
  /// work; with two threads or more the views run concurrently, see
  /// `threads`); left pixels it does not confirm within `lr_tolerance` —
  /// occluded, in the border band, mismatched — are marked in
  /// MatchResult::consistent and filled from the background side along their row.
  bool lr_check = true;
  float lr_tolerance = 1.0f;
  /// Worker threads, 0 = all cores. With lr_check and two or more, the two views run at once and share them (the
  /// right view gets half, rounded down). The result does not depend on it.
  int threads = 0;
};

/// A value of StereoParams that match() refuses.
struct ParamProblem {
  std::string name;     ///< the parameter as the hbds node names it (cfg/HBDS.cfg), e.g. "ncc_window"
  std::string problem;  ///< what is wrong with its value, e.g. "must be odd and >= 1"
};
/// Every problem of `params` (empty when match() accepts them), the one check the node's parameters and the tools'
/// options go through. The disparity range is checked against the images by match() itself.
std::vector<ParamProblem> checkParams(const StereoParams& params);

struct MatchResult {
  cv::Mat disparity;         ///< CV_32F, NaN where the method gives none (SGBM); sub-pixel with `subpixel`
  double cost_ms = 0.0;      ///< matching cost volume (0 for SGBM)
  double optimize_ms = 0.0;  ///< the method itself
  double refine_ms = 0.0;    ///< the refinement (0 without)
  double subpixel_ms = 0.0;  ///< the sub-pixel step (0 without)
  /// With lr_check: the wall time it adds after the left view — the rest of the right view's matching (all of it
  /// with one thread), the check and the filling. The stages above are the left view's (with two threads or more,
  /// timed while the right view runs beside it), so total_ms() is the call's wall time.
  double lr_ms = 0.0;
  double total_ms() const { return cost_ms + optimize_ms + refine_ms + subpixel_ms + lr_ms; }
  /// With lr_check: CV_8U, 255 where the right view confirms the disparity,
  /// 0 where it was filled from the background; else empty.
  cv::Mat consistent;
  Energy energy;  ///< Eq. 2.2 of the (rounded, clamped) result on this pair's cost volume, before lr_check's filling
  cv::Mat fattening;  ///< FFD's mask (CV_8U, 255 = fattening) with the ffd-* refinements, else empty
  int cuts = 0;
};

/// Runs `method` on a rectified pair (CV_8UC1 / CV_8UC3, same size). Throws
/// std::invalid_argument for bad input (see computeCostVolume); an exception of
/// either view leaves only once both have stopped. The result depends on the
/// pair and the parameters alone: not on `threads`, the calling thread or
/// earlier calls (see filterDisparity() for the weighted median's).
MatchResult match(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params);

}  // namespace massage_cell::stereo
