// Dense disparity optimisers on a cost volume: HBDS (thesis Ch. 2) and the
// graph-cut baselines alpha-expansion and alpha-beta swap (Boykov, Veksler,
// Zabih 2001) minimising the energy of energy.h. ROS-free.
#pragma once

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"
#include "massage_cell/stereo/energy.h"

namespace massage_cell::stereo {

struct OptimizerResult {
  cv::Mat disparity;  ///< CV_32F integer disparities
  Energy energy;      ///< under Eq. 2.2 with the run's weights and truncation
  int cuts = 0;       ///< binary graph cuts solved
  int cycles = 0;     ///< expansion / swap cycles (0 for HBDS)
  int layers = 0;     ///< HBDS: depth of the hierarchy
};

/// HBDS: hierarchical bilateral disparity structure. The set [dmin, dmax] is
/// split at its break point (rough WTA histogram of the layer's pixels); one
/// binary graph cut over that layer's active pixels (4-connected pairs inside
/// the layer) with data term Eq. 2.4 (min cost in each subset) and smooth term
/// Eq. 2.5 (u_{p,q} |D*| / 2 when labels differ) assigns each pixel to B or F;
/// recursion until every set holds one level. `threads` parallelises
/// independent sub-problems (0 = all cores). `overlap` (our addition; 0 =
/// the thesis's disjoint split B = [lo, psi], F = [psi + 1, hi]): both
/// children's sets reach `overlap` levels across the break point, B = [lo,
/// psi + overlap], F = [psi + 1 - overlap, hi], so a pixel whose disparity
/// is near psi (a slanted surface crossing the split) can still reach it from
/// the side the cut sent it to. `coarse` (our addition; 1 = off): cuts of
/// large layers are solved coarse to fine, first on coarse x coarse blocks
/// of pixels (unaries and pairs summed), then at full resolution only in a
/// band of one block around the blocks' label boundary (the other pixels take
/// their block's label): an approximation that saves most of the max-flow
/// time on smooth, weakly textured layers. Results do not depend on `threads`.
OptimizerResult hbds(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                     int threads = 0, int overlap = 0, int coarse = 1);

/// alpha-expansion from `initial` (empty: WTA), cycles over all labels until a
/// cycle brings no improvement (or max_cycles).
OptimizerResult alphaExpansion(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                               const cv::Mat& initial = cv::Mat(), int max_cycles = 20);

/// alpha-expansion restricted to local moves: the move of alpha only
/// involves the pixels whose current label lies within `window` (>= 1) levels
/// of alpha; the other pixels keep their labels. Used to polish an HBDS
/// labelling; same stopping rule (a cycle with no accepted move).
OptimizerResult localExpansion(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                               const cv::Mat& initial, int window, int max_cycles = 20);

/// Coarse full-range polish (our addition): the alpha-expansion cycles of
/// localExpansion (labels within `window` of alpha; window >= levels: plain
/// alpha-expansion) run on block x block pixel blocks (block >= 2) with the
/// exact energy of block-constant labellings (block unary = sum of its
/// pixels' costs, block pair = sum of u over the pixel pairs crossing the
/// boundary, times V), started from the median of `initial` in each block;
/// then one fusion move at full resolution: each pixel keeps its `initial`
/// label or takes its block's label, one binary cut on the Eq. 2.2 energy
/// (non-submodular pairs truncated, Rother et al. 2005), accepted only when it
/// lowers the energy (so the result's energy is never above `initial`'s).
OptimizerResult coarsePolish(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                             const cv::Mat& initial, int block, int window, int max_cycles = 1);

/// alpha-beta swap, same stopping rule.
OptimizerResult alphaBetaSwap(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                              const cv::Mat& initial = cv::Mat(), int max_cycles = 20);

}  // namespace massage_cell::stereo
