#include "massage_cell/cect/trunk.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "stats_detail.h"

namespace massage_cell::cect {

std::string TrunkReport::summary() const {
  std::ostringstream s;
  if (arm_left || arm_right) {
    s << "arms cut at creases:" << (arm_left ? " image left" : "") << (arm_left && arm_right ? "," : "")
      << (arm_right ? " image right" : "");
  } else {
    s << "no arm along the trunk";
  }
  if (side_run_pixels > 0) s << "; " << side_run_pixels << " px of skin beside the trunk removed";
  if (cloth_pixels > 0) s << "; " << cloth_pixels << " px of skin-coloured cloth removed";
  return s.str();
}

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr double kNoiseFloor = 20.0;      // grey levels added to the local brightness (cloth test)
constexpr double kMeanCreaseDepth = 2.0;  // an arm's crease is on average this many times crease_strength deep
constexpr double kBodyWidth = 290.0;      // px: the body's median row width the pixel sizes are given for

/// One run of mask pixels on a row: [a, b] inclusive; a > b when none.
struct Run {
  int a = 0, b = -1;
  bool empty() const { return a > b; }
  int width() const { return b - a + 1; }
};

cv::Mat logGrey(const cv::Mat& bgr) {
  cv::Mat grey, out;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(out, CV_32F);
  out += static_cast<float>(kNoiseFloor);  // dark skin's sensor noise stays small in the log
  cv::log(out, out);
  return out;
}

/// Removes cloth (fine texture) from the mask; returns the pixels removed.
int removeCloth(const cv::Mat& bgr, cv::Mat* mask, const TrunkParams& p) {
  cv::Mat grey, fine, coarse, mean, energy;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(grey, CV_32F);
  const double sigma = std::max(0.3, p.cloth_sigma);
  cv::GaussianBlur(grey, fine, cv::Size(0, 0), sigma);
  cv::GaussianBlur(grey, coarse, cv::Size(0, 0), 2.0 * sigma);
  cv::GaussianBlur(grey, mean, cv::Size(0, 0), 4.0);
  // Band-pass relative to the local brightness; the floor keeps the sensor
  // noise of dark skin from reading as texture.
  cv::Mat band = (fine - coarse) / (mean + kNoiseFloor);
  cv::GaussianBlur(band.mul(band), energy, cv::Size(0, 0), std::max(0.5, p.cloth_window));
  // Away from the mask's border (the silhouette's edge is a strong contrast
  // too), in patches that survive an opening and cover some area; then grown
  // back out to the border.
  const int reach = static_cast<int>(std::ceil(3.0 * p.cloth_window));
  auto disk = [](int r) { return cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * r + 1, 2 * r + 1}); };
  cv::Mat inner;
  cv::erode(*mask, inner, disk(reach));
  cv::Mat cloth = (energy > p.cloth_contrast * p.cloth_contrast) & inner;
  cv::morphologyEx(cloth, cloth, cv::MORPH_OPEN, disk(std::max(1, p.cloth_open_radius)));
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(cloth, labels, stats, centroids, 8, CV_32S);
  const double min_area = p.cloth_min_area * static_cast<double>(mask->total());
  cloth.setTo(0);
  for (int k = 1; k < n; ++k)
    if (stats.at<int>(k, cv::CC_STAT_AREA) >= min_area) cloth.setTo(255, labels == k);
  cv::dilate(cloth, cloth, disk(reach));
  cloth &= *mask;
  const int removed = cv::countNonZero(cloth);
  mask->setTo(0, cloth);
  return removed;
}

std::vector<Run> runsOf(const cv::Mat& mask, int y) {
  std::vector<Run> runs;
  const unsigned char* m = mask.ptr<unsigned char>(y);
  for (int x = 0; x < mask.cols; ++x) {
    if (!m[x]) continue;
    Run r{x, x};
    while (r.b + 1 < mask.cols && m[r.b + 1]) ++r.b;
    runs.push_back(r);
    x = r.b;
  }
  return runs;
}

/// The body's centre line x = c0 + c1 y: a robust line through the middles of
/// each row's longest run (a trimmed fit: three refits, each without the rows
/// beyond 3 times the median residual, at least 3 px). NaN coefficients when
/// fewer than 8 rows hold skin.
cv::Vec2d centreLine(const cv::Mat& mask) {
  std::vector<double> ys, xs;
  for (int y = 0; y < mask.rows; ++y) {
    const std::vector<Run> runs = runsOf(mask, y);
    if (runs.empty()) continue;
    const Run& r =
        *std::max_element(runs.begin(), runs.end(), [](const Run& u, const Run& v) { return u.width() < v.width(); });
    ys.push_back(y);
    xs.push_back(0.5 * (r.a + r.b));
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (ys.size() < 8) return {nan, nan};
  const Eigen::Index n = static_cast<Eigen::Index>(ys.size());
  Eigen::MatrixXd A(n, 2), B(n, 1);
  for (Eigen::Index i = 0; i < n; ++i) {
    A.row(i) << 1.0, ys[static_cast<std::size_t>(i)];
    B(i, 0) = xs[static_cast<std::size_t>(i)];
  }
  auto trimmed = [](double r, double median) { return r <= std::max(3.0, 3.0 * median) ? 1.0 : 0.0; };
  Eigen::Vector2d c;
  if (!detail::robustFit(A, B, 3, trimmed, &c)) return {nan, nan};
  return {c(0), c(1)};
}

/// Per row, the run holding the centre line; the other runs leave the mask
/// (rows where no run holds it stay as they are). Returns the pixels removed; `central` gets each row's run.
int keepCentralRuns(cv::Mat* mask, const cv::Vec2d& line, std::vector<Run>* central) {
  central->assign(static_cast<std::size_t>(mask->rows), Run{});
  int removed = 0;
  for (int y = 0; y < mask->rows; ++y) {
    const std::vector<Run> runs = runsOf(*mask, y);
    if (runs.empty()) continue;
    const double c = line[0] + line[1] * y;
    auto distance = [c](const Run& r) { return c < r.a ? r.a - c : c > r.b ? c - r.b : 0.0; };
    const Run keep = *std::min_element(runs.begin(), runs.end(),
                                       [&](const Run& u, const Run& v) { return distance(u) < distance(v); });
    // A row whose skin misses the centre line (the shoulders' tops either
    // side of the neck) is left as it is.
    if (distance(keep) > 2.0) continue;
    unsigned char* m = mask->ptr<unsigned char>(y);
    for (const Run& r : runs) {
      if (r.a == keep.a) continue;
      std::fill(m + r.a, m + r.b + 1, static_cast<unsigned char>(0));
      removed += r.width();
    }
    (*central)[static_cast<std::size_t>(y)] = keep;
  }
  return removed;
}

/// Valley depth of the smoothed log grey at (x, y) within run r: how far it
/// lies below the lower of the two crests within `reach` either side. The
/// outer side (toward the run's end: r.a when `left`) leaves out the `margin`
/// pixels next to the end, where the border blends with the background.
float valleyDepth(const cv::Mat& smooth, int y, int x, const Run& r, int reach, int margin, bool left) {
  const float* s = smooth.ptr<float>(y);
  const int lo = std::max(left ? r.a + margin : r.a, x - reach);
  const int hi = std::min(left ? r.b : r.b - margin, x + reach);
  if (lo >= x || hi <= x) return 0.0f;
  float before = -kInf, after = -kInf;
  for (int k = lo; k < x; ++k) before = std::max(before, s[k]);
  for (int k = x + 1; k <= hi; ++k) after = std::max(after, s[k]);
  return std::min(before, after) - s[x];
}

/// Pixels next to a run's end left out of the valley test (the border's blend).
int creaseMargin(const TrunkParams& p) { return static_cast<int>(std::ceil(3.0 * p.crease_sigma)) + 2; }

/// One row of the crease's Viterbi path: the band searched (absolute
/// columns [lo, hi]), the cheapest total cost of each state (0: no crease,
/// 1 + x - lo: the crease at x) and the previous row's state it came from.
struct RowStates {
  int lo = 0, hi = -1;
  std::vector<float> total;
  std::vector<int> from;
};

/// The band of run r where the crease is looked for on one side.
void creaseBand(const Run& r, bool left, const TrunkParams& p, RowStates* s) {
  if (r.empty()) return;
  const int w = r.width();
  const int d0 = static_cast<int>(std::ceil(p.crease_min * w)), d1 = static_cast<int>(std::floor(p.crease_max * w));
  s->lo = left ? r.a + d0 : r.b - d1;
  s->hi = left ? r.a + d1 : r.b - d0;
}

/// Fills row y's states from the previous row's (nullptr for the first row).
void relaxRow(const cv::Mat& smooth, int y, const Run& r, bool left, const TrunkParams& p, const RowStates* prev,
              RowStates* s) {
  constexpr float kSwitch = 4.0f, kMove = 0.1f;  // costs of a crease starting or ending, and of its moving a pixel
  const int reach = std::max(2, static_cast<int>(std::lround(p.crease_reach)));
  const int jump = std::max(1, static_cast<int>(std::lround(p.crease_jump)));
  const float strength = static_cast<float>(p.crease_strength);
  const int n = std::max(0, s->hi - s->lo + 1);
  s->total.assign(static_cast<std::size_t>(1 + n), 0.0f);
  s->from.assign(static_cast<std::size_t>(1 + n), 0);
  for (int k = 0; k <= n; ++k) {
    const int x = s->lo + k - 1;
    // A valley as deep as `strength` costs nothing; deeper ones pay off.
    const float cost =
        k == 0 ? 0.0f
               : std::clamp((strength - valleyDepth(smooth, y, x, r, reach, creaseMargin(p), left)) / strength, -2.0f,
                            1.0f);
    float best = 0.0f;
    int arg = 0;
    if (prev) {
      best = prev->total[0] + (k > 0 ? kSwitch : 0.0f);  // from none
      // From a crease in the previous row: any, to none; within the jump, to a crease.
      const int pn = static_cast<int>(prev->total.size()) - 1;
      const int j0 = k == 0 ? 1 : std::max(1, x - jump - prev->lo + 1);
      const int j1 = k == 0 ? pn : std::min(pn, x + jump - prev->lo + 1);
      for (int j = j0; j <= j1; ++j) {
        const float t = prev->total[static_cast<std::size_t>(j)] +
                        (k == 0 ? kSwitch : kMove * static_cast<float>(std::abs(x - (prev->lo + j - 1))));
        if (t < best) best = t, arg = j;
      }
    }
    s->total[static_cast<std::size_t>(k)] = best + cost;
    s->from[static_cast<std::size_t>(k)] = arg;
  }
}

/// The crease on one side (`left`: the image's left end of each run), by a
/// Viterbi path over the rows: per row a column in the band or none.
/// Returns per row the crease column, -1 for none.
std::vector<int> creasePath(const cv::Mat& smooth, const std::vector<Run>& central, bool left, const TrunkParams& p) {
  const int rows = static_cast<int>(central.size());
  std::vector<RowStates> st(static_cast<std::size_t>(rows));
  for (int y = 0; y < rows; ++y) {
    RowStates& s = st[static_cast<std::size_t>(y)];
    creaseBand(central[static_cast<std::size_t>(y)], left, p, &s);
    relaxRow(smooth, y, central[static_cast<std::size_t>(y)], left, p,
             y > 0 ? &st[static_cast<std::size_t>(y - 1)] : nullptr, &s);
  }
  // Backtrack from the cheapest final state.
  std::vector<int> path(static_cast<std::size_t>(rows), -1);
  if (rows == 0) return path;
  const RowStates& last = st.back();
  int k = static_cast<int>(std::min_element(last.total.begin(), last.total.end()) - last.total.begin());
  for (int y = rows - 1; y >= 0; --y) {
    const RowStates& s = st[static_cast<std::size_t>(y)];
    path[static_cast<std::size_t>(y)] = k > 0 ? s.lo + k - 1 : -1;
    k = s.from[static_cast<std::size_t>(k)];
  }
  return path;
}

/// Keeps the longest stretch of consecutive crease rows (>= 0) of `path`.
void keepLongestRun(std::vector<int>* path) {
  int best_start = 0, best_len = 0;
  for (int i = 0; i < static_cast<int>(path->size());) {
    if ((*path)[static_cast<std::size_t>(i)] < 0) {
      ++i;
      continue;
    }
    int j = i;
    while (j < static_cast<int>(path->size()) && (*path)[static_cast<std::size_t>(j)] >= 0) ++j;
    if (j - i > best_len) best_start = i, best_len = j - i;
    i = j;
  }
  for (int i = 0; i < static_cast<int>(path->size()); ++i)
    if (i < best_start || i >= best_start + best_len) (*path)[static_cast<std::size_t>(i)] = -1;
}

/// Cuts the arms off at their creases (see the header).
void cutArms(const cv::Mat& log_grey, cv::Mat* mask, const std::vector<Run>& central, const TrunkParams& p,
             TrunkReport* report) {
  cv::Mat smooth;
  cv::GaussianBlur(log_grey, smooth, cv::Size(0, 0), std::max(0.3, p.crease_sigma));
  int body_rows = 0;
  for (const Run& r : central) body_rows += r.empty() ? 0 : 1;
  for (const bool left : {true, false}) {
    std::vector<int> path = creasePath(smooth, central, left, p);
    keepLongestRun(&path);
    const int n = static_cast<int>(std::count_if(path.begin(), path.end(), [](int x) { return x >= 0; }));
    (left ? report->crease_rows_left : report->crease_rows_right) = n;
    if (n < p.min_arm_fraction * body_rows) continue;
    // A crease all along an arm, not a patch of shading: its mean depth.
    const int margin = creaseMargin(p);
    const int reach = std::max(2, static_cast<int>(std::lround(p.crease_reach)));
    double depth = 0.0;
    for (int y = 0; y < mask->rows; ++y)
      if (path[static_cast<std::size_t>(y)] >= 0)
        depth += valleyDepth(smooth, y, path[static_cast<std::size_t>(y)], central[static_cast<std::size_t>(y)], reach,
                             margin, left);
    if (depth / n < kMeanCreaseDepth * p.crease_strength) continue;
    (left ? report->arm_left : report->arm_right) = true;
    for (int y = 0; y < mask->rows; ++y) {
      const int x = path[static_cast<std::size_t>(y)];
      if (x < 0) continue;
      const Run& r = central[static_cast<std::size_t>(y)];
      unsigned char* m = mask->ptr<unsigned char>(y);
      if (left)
        std::fill(m + r.a, m + x, static_cast<unsigned char>(0));
      else
        std::fill(m + x + 1, m + r.b + 1, static_cast<unsigned char>(0));
    }
  }
}

/// The pixel sizes of `p` (given for a body kBodyWidth px wide) scaled to the
/// body in `mask`: the median width of the rows' longest runs of skin.
TrunkParams scaledToBody(const TrunkParams& p, const cv::Mat& mask) {
  std::vector<int> widths;
  for (int y = 0; y < mask.rows; ++y) {
    int best = 0;
    for (const Run& r : runsOf(mask, y)) best = std::max(best, r.width());
    if (best > 0) widths.push_back(best);
  }
  if (widths.empty()) return p;
  const double s = std::clamp(detail::median(widths, detail::EvenCount::kUpperMiddle) / kBodyWidth, 0.2, 5.0);
  TrunkParams q = p;
  q.cloth_sigma = p.cloth_sigma * s;
  q.cloth_window = p.cloth_window * s;
  q.cloth_open_radius = std::max(1, static_cast<int>(std::lround(p.cloth_open_radius * s)));
  q.crease_sigma = p.crease_sigma * s;
  q.crease_reach = p.crease_reach * s;
  q.crease_jump = std::max(1.0, p.crease_jump * s);
  return q;
}

}  // namespace

TrunkReport cutToTrunk(const cv::Mat& bgr, cv::Mat* mask, const TrunkParams& given) {
  if (!mask || mask->type() != CV_8UC1 || mask->size() != bgr.size() || bgr.type() != CV_8UC3)
    throw std::invalid_argument("cutToTrunk: expected a BGR image and a CV_8U mask of its size");
  TrunkReport report;
  if (bgr.empty()) return report;
  const TrunkParams params = scaledToBody(given, *mask);
  const cv::Mat lg = logGrey(bgr);
  if (params.reject_cloth) report.cloth_pixels = removeCloth(bgr, mask, params);
  if (!params.separate_arms) return report;
  const cv::Vec2d line = centreLine(*mask);
  if (!std::isfinite(line[0])) return report;
  std::vector<Run> central;
  report.side_run_pixels = keepCentralRuns(mask, line, &central);
  cutArms(lg, mask, central, params, &report);
  return report;
}

}  // namespace massage_cell::cect
