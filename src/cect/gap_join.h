// CECT segmentation, private step: pieces of one back split by a thin band
// across it — a bra strap, a seam, a row of paper tags, a tattoo's line — are
// joined again. Used by segmentation.cpp between the mask's cleaning and the
// trunk's cut.
//
// The body lies along the image's columns (trunk.h), so a band across it
// separates the two pieces within columns: per column, the free rows between
// a pixel of one piece above and one of the other below. Two pieces are one
// back cut across when, in the columns where that gap is about its typical
// (median) width, the band is thin (at most kReachShare of the larger
// piece's size, sqrt(area), and kMaxBandShare of its length), runs across the
// body (slope within kMaxBandSlope) and spans kMinCutShare of the narrower
// piece's width at the cut (the other may hold the shoulders and upper arms).
// Those columns' gaps become skin. Run after the trunk's cut, so arms held
// away are gone. A towel over the back or the hair over the nape leave a
// wider band; an arm beside the flank leaves no gap within columns.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace massage_cell::cect::detail {

struct GapJoinReport {
  int joined = 0;               ///< pieces joined to another
  int widest_gap = 0;           ///< the widest band bridged, pixels
  std::string summary() const;  ///< "" when none, else e.g. "1 piece joined across a 14 px band"
};

/// Joins, in place, the pieces of `mask` (CV_8U, 255 skin) that are one back
/// cut across by a thin band: the band's pixels between them become skin.
/// Pieces smaller than `min_piece_area` pixels take no part.
GapJoinReport joinAcrossThinBands(cv::Mat* mask, double min_piece_area);

}  // namespace massage_cell::cect::detail
