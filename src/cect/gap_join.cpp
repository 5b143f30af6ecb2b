// Pieces of one back cut across by a thin band (gap_join.h).
#include "gap_join.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "stats_detail.h"

namespace massage_cell::cect::detail {

namespace {

/// The widest band looked at, as a share of the larger piece's size
/// (sqrt(area)): half a back (0.45 m wide, 0.3 m long) reaches ~6 cm across
/// a band, more than a bra strap (1-3 cm), a seam or a row of paper tags; a
/// towel over the back or hair over the nape leave more.
constexpr double kReachShare = 0.16;
/// The band's width at most this share of its length (the back's width at
/// the cut): a 3 cm strap across a 35 cm waist is 0.09.
constexpr double kMaxBandShare = 0.12;
/// Columns whose gap is at most this times the band's (median) width, plus
/// kWidthSlack px, are the band's (a strap seen tilted or in perspective).
constexpr double kWidthSpread = 1.3;
constexpr double kWidthSlack = 2.0;
/// The band must run across this share of the narrower piece's width beside
/// it (a cut across the back runs across all of it: ~1).
constexpr double kMinCutShare = 0.8;
/// The band runs across the body, which lies along the image's columns
/// turned by up to ~20 degrees (trunk.h); a strap may sag or tilt more.
constexpr double kMaxBandSlope = 0.84;  // tan(40 degrees)
/// Pieces considered, largest first: the back's pieces and a few others.
constexpr int kMaxPieces = 8;

struct Piece {
  int label = 0;
  cv::Rect box;
  double area = 0.0;
};

std::vector<Piece> largePieces(const cv::Mat& mask, double min_area, cv::Mat* labels) {
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, *labels, stats, centroids, 8, CV_32S);
  std::vector<Piece> pieces;
  for (int i = 1; i < n; ++i) {
    const double area = stats.at<int>(i, cv::CC_STAT_AREA);
    if (area < min_area) continue;
    pieces.push_back({i,
                      cv::Rect(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                               stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT)),
                      area});
  }
  std::sort(pieces.begin(), pieces.end(), [](const Piece& a, const Piece& b) { return a.area > b.area; });
  if (pieces.size() > static_cast<std::size_t>(kMaxPieces)) pieces.resize(kMaxPieces);
  return pieces;
}

cv::Rect grown(const cv::Rect& r, int by, const cv::Size& size) {
  return cv::Rect(r.x - by, r.y - by, r.width + 2 * by, r.height + 2 * by) & cv::Rect(cv::Point(0, 0), size);
}

/// In one column, the rows [top, bottom) between a pixel of one piece above
/// and one of the other below.
struct ColumnGap {
  int x = 0, top = 0, bottom = 0;
  int width() const { return bottom - top; }
};

/// Per column of `labels` (a region of interest), the narrowest gap between
/// pieces la and lb, when it is at most `reach` rows.
std::vector<ColumnGap> columnGaps(const cv::Mat& labels, int la, int lb, int reach) {
  std::vector<ColumnGap> gaps;
  for (int x = 0; x < labels.cols; ++x) {
    int last_label = 0, last_row = -1;
    ColumnGap best{x, 0, reach + 1};
    for (int y = 0; y < labels.rows; ++y) {
      const int l = labels.at<int>(y, x);
      if (l == la || l == lb) {
        if (last_label != 0 && l != last_label && y - last_row - 1 < best.width()) best = {x, last_row + 1, y};
        last_label = l;
        last_row = y;
      }  // other labels (specks on a strap's edge) count as the gap's
    }
    if (best.width() <= reach && best.width() > 0) gaps.push_back(best);
  }
  return gaps;
}

/// Columns where the piece has a pixel in rows [y0, y1).
int columnsIn(const cv::Mat& labels, int label, int y0, int y1) {
  int n = 0;
  for (int x = 0; x < labels.cols; ++x) {
    for (int y = std::max(0, y0); y < std::min(labels.rows, y1); ++y) {
      if (labels.at<int>(y, x) == label) {
        ++n;
        break;
      }
    }
  }
  return n;
}

/// The least-squares slope of the gaps' centre rows against their columns.
double slopeOf(const std::vector<ColumnGap>& band) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const ColumnGap& g : band) {
    const double y = 0.5 * (g.top + g.bottom);
    sx += g.x;
    sy += y;
    sxx += double(g.x) * g.x;
    sxy += g.x * y;
  }
  const double n = static_cast<double>(band.size()), d = n * sxx - sx * sx;
  return d > 0.0 ? (n * sxy - sx * sy) / d : 0.0;
}

/// Joins b to a when they are one back cut across; true when joined.
bool joinPair(const cv::Mat& labels, const Piece& a, const Piece& b, cv::Mat* mask, GapJoinReport* report) {
  const int reach = static_cast<int>(std::ceil(kReachShare * std::sqrt(std::max(a.area, b.area))));
  if ((grown(a.box, reach, mask->size()) & b.box).empty()) return false;
  const cv::Rect roi = grown(a.box | b.box, 1, mask->size());
  const cv::Mat l = labels(roi);
  std::vector<ColumnGap> gaps = columnGaps(l, a.label, b.label, reach);
  if (gaps.size() < 3) return false;
  // The band: the columns whose gap is about the typical (median) one; the flanks, where the outlines part, left out.
  std::vector<int> widths;
  for (const ColumnGap& g : gaps) widths.push_back(g.width());
  const double width = median(widths, EvenCount::kUpperMiddle);
  std::vector<ColumnGap> band;
  for (const ColumnGap& g : gaps)
    if (g.width() <= kWidthSpread * width + kWidthSlack) band.push_back(g);
  const double length = static_cast<double>(band.size());
  if (width > kMaxBandShare * length) return false;
  if (std::abs(slopeOf(band)) > kMaxBandSlope) return false;
  // It spans the narrower piece's width at the cut (its columns within the band's width of it); the other
  // may hold the shoulders and upper arms beside it.
  int top = l.rows, bottom = 0;
  for (const ColumnGap& g : band) {
    top = std::min(top, g.top);
    bottom = std::max(bottom, g.bottom);
  }
  const int beside = static_cast<int>(std::ceil(std::max(3.0, 1.5 * width)));
  const int wa = columnsIn(l, a.label, top - beside, bottom + beside);
  const int wb = columnsIn(l, b.label, top - beside, bottom + beside);
  if (length < kMinCutShare * std::min(wa, wb)) return false;
  cv::Mat m = (*mask)(roi);
  for (const ColumnGap& g : band) m.col(g.x).rowRange(g.top, g.bottom).setTo(255);
  ++report->joined;
  report->widest_gap = std::max(report->widest_gap, static_cast<int>(std::lround(width)));
  return true;
}

}  // namespace

std::string GapJoinReport::summary() const {
  if (joined == 0) return "";
  return std::to_string(joined) + (joined == 1 ? " piece" : " pieces") + " joined across a band of up to " +
         std::to_string(widest_gap) + " px (a strap, a seam, tags)";
}

GapJoinReport joinAcrossThinBands(cv::Mat* mask, double min_piece_area) {
  if (mask->empty() || mask->type() != CV_8UC1)
    throw std::invalid_argument("joinAcrossThinBands: expected a non-empty CV_8U mask");
  GapJoinReport report;
  // Each join makes one piece of two: at most kMaxPieces - 1 rounds.
  for (int round = 0; round < kMaxPieces - 1; ++round) {
    cv::Mat labels;
    const std::vector<Piece> pieces = largePieces(*mask, min_piece_area, &labels);
    bool joined = false;
    for (std::size_t i = 0; i < pieces.size() && !joined; ++i) {
      for (std::size_t j = i + 1; j < pieces.size() && !joined; ++j) {
        joined = joinPair(labels, pieces[i], pieces[j], mask, &report);
      }
    }
    if (!joined) break;
  }
  return report;
}

}  // namespace massage_cell::cect::detail
