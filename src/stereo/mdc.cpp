// MDC, the refinement's disparity calibration (thesis §2.3.2, Eq. 2.11-2.13): every pixel takes the level of
// maximal adaptive-support-weighted vote of the voters in its window.
//
// * MDC: the vote's tables (exp(-Δc/γc) in steps of γc/64, exp(-Δg/γg) per offset) are built once per call and
//   shared by the row stripes. Pixels whose window holds one voter level take it directly. The others are voted four
//   at a time (LaneVote: four adjacent pixels in the SIMD lanes, one window offset per vector step, one accumulator
//   per level of the union of the four windows, found from per-row 64-bit level masks); each lane adds its weight or
//   +0.0, so its sums are WeightedVote's floats added in the same raster order. WeightedVote (a scalar per-pixel
//   histogram whose argmax runs over the voted levels only) takes the pixels within r + 3 columns of the left / right
//   border, unions of more than 24 levels, and the all-zero-score case (underflowed weights), where only it knows
//   which levels were voted for. Both round the colour-table index half to even. test_stereo_refine's
//   FastVoteEqualsTheStraightforwardOneBitForBit checks the result bit for bit against a plain per-pixel vote.
// * Measured (Release, stereo_bench --frame: 640 x 480, 64 levels, median of 3; 2 cores shared with other jobs,
//   load 4-5, so ratios rather than absolute figures; the per-pixel WeightedVote alone, run alternately, in
//   brackets): MDC alone (--refine mdc --no-lr-check) back 290-320 ms (550-810), boxes 250-340 ms (500-530);
//   FFD + MDC, the default with the right view matched beside the left: back 780-1360 ms (1510-1820), boxes
//   820-1400 ms (940-1660). FFD (SLIC dominates) is about 300-600 ms of that.
#include <array>
#include <cstdint>
#include <type_traits>
#include <vector>

#include <opencv2/core/hal/intrin.hpp>

#include "massage_cell/stereo/refine.h"
#include "refine_common.h"

namespace massage_cell::stereo {

using namespace refine_detail;

namespace {

/// MDC's voters: each pixel's level (index from lo; -1: not a voter - invalid or in the fattening mask) and the
/// smallest / largest voter level within the window around every pixel (FLT_MAX / -FLT_MAX: none).
struct Voters {
  cv::Mat level, window_min, window_max;
};

Voters voters(const cv::Mat& levels, int lo, const cv::Mat& fattening_mask, int window) {
  Voters v;
  v.level.create(levels.size(), CV_32S);
  v.window_min.create(levels.size(), CV_32F);
  v.window_max.create(levels.size(), CV_32F);
  for (int y = 0; y < levels.rows; ++y) {
    const int* l = levels.ptr<int>(y);
    const uchar* m = fattening_mask.empty() ? nullptr : fattening_mask.ptr<uchar>(y);
    int* own = v.level.ptr<int>(y);
    float* a = v.window_min.ptr<float>(y);
    float* b = v.window_max.ptr<float>(y);
    for (int x = 0; x < levels.cols; ++x) {
      const bool ok = l[x] != kInvalidLevel && !(m && m[x]);
      own[x] = ok ? l[x] - lo : -1;
      a[x] = ok ? static_cast<float>(own[x]) : std::numeric_limits<float>::max();
      b[x] = ok ? static_cast<float>(own[x]) : -std::numeric_limits<float>::max();
    }
  }
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(window, window));
  cv::erode(v.window_min, v.window_min, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
            cv::Scalar(std::numeric_limits<float>::max()));
  cv::dilate(v.window_max, v.window_max, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
             cv::Scalar(-std::numeric_limits<float>::max()));
  return v;
}

/// The vote's read-only tables, built once per call and shared by the threads: exp(-Δc/γc) in steps of γc/64 up to
/// float underflow, exp(-Δg/γg) per window offset.
struct VoteTables {
  static constexpr float kSteps = 64.0f;
  int r = 0, side = 0;
  float to_index = 0.0f, last = 0.0f;  ///< Δc -> table index; the last index (weight 0)
  std::vector<float> colour_weight, spatial;

  explicit VoteTables(const RefineParams& params) : r(params.window / 2), side(params.window) {
    const int table_size = static_cast<int>(88.0f * kSteps) + 1;
    colour_weight.resize(table_size);
    for (int i = 0; i < table_size; ++i)
      colour_weight[i] = static_cast<float>(std::exp(-i / static_cast<double>(kSteps)));
    colour_weight.back() = 0.0f;
    last = static_cast<float>(table_size - 1);
    to_index = std::min(kSteps / params.gamma_c, std::numeric_limits<float>::max());  // finite: 0 x it is 0
    spatial.resize(static_cast<std::size_t>(side) * side);
    for (int j = -r; j <= r; ++j)
      for (int i = -r; i <= r; ++i)
        spatial[(j + r) * side + (i + r)] =
            static_cast<float>(std::exp(-std::sqrt(double(i * i + j * j)) / params.gamma_g));
  }

  /// The colour-weight table's index for the Lab distance `dc`: dc x to_index clamped to the table, then rounded
  /// half to even (cvRound, as v_round does in the vector code; clamping first keeps a tiny γc from overflowing int).
  int colourIndex(float dc) const { return cvRound(std::min(dc * to_index, last)); }
};

/// MDC's colour-weighted vote over the window (thesis Sec. 2.3) for one pixel: each voter q adds exp(-Δc(p,q)/γc)
/// exp(-Δg/γg) to its level; the level with the most weight wins (ties: the pixel's own level, else the smallest).
/// One per thread. It serves the pixels LaneVote cannot take, and LaneVote must give exactly its sums.
class WeightedVote {
 public:
  WeightedVote(const cv::Mat (&lab)[3], const Voters& voters, int nlevels, const VoteTables& tables)
      : lab_(lab), voters_(voters), t_(tables), score_(nlevels, 0.0f), stamp_(nlevels, -1), index_(t_.side + 8) {
    touched_.reserve(std::min(nlevels, t_.side * t_.side));
  }

  /// The winning level (index from lo) at pixel (x, y) whose own level is `own` (-1: none).
  int winner(int x, int y, int own) {
    const int W = voters_.level.cols, H = voters_.level.rows, r = t_.r;
    const int pixel_id = y * W + x;
    touched_.clear();
    const float Lp = lab_[0].ptr<float>(y)[x], ap = lab_[1].ptr<float>(y)[x], bp = lab_[2].ptr<float>(y)[x];
    const int x0 = std::max(0, x - r), x1 = std::min(W - 1, x + r), n = x1 - x0 + 1;
    const int y0 = std::max(0, y - r), y1 = std::min(H - 1, y + r);
    const float* cw = t_.colour_weight.data();
    for (int yy = y0; yy <= y1; ++yy) {
      colourIndices(yy, x0, n, Lp, ap, bp);
      const int* vq = voters_.level.ptr<int>(yy) + x0;
      const float* sw = t_.spatial.data() + (yy - y + r) * t_.side + (x0 - x + r);
      for (int i = 0; i < n; ++i) {
        const int v = vq[i];
        if (v < 0) continue;
        if (stamp_[v] != pixel_id) {
          stamp_[v] = pixel_id;
          score_[v] = 0.0f;
          touched_.push_back(v);
        }
        score_[v] += cw[index_[i]] * sw[i];
      }
    }
    int winner = -1;
    float best = -1.0f;
    for (const int v : touched_) {
      const float s = score_[v];
      if (s > best || (s == best && v != winner && (winner != own && (v == own || v < winner)))) {
        best = s;
        winner = v;
      }
    }
    return winner;
  }

 private:
  /// index_[i]: VoteTables::colourIndex of window row yy's pixel x0 + i against (Lp, ap, bp); four at a time where
  /// SIMD is available (the same operations, the same rounding).
  void colourIndices(int yy, int x0, int n, float Lp, float ap, float bp) {
    const float* Lq = lab_[0].ptr<float>(yy) + x0;
    const float* aq = lab_[1].ptr<float>(yy) + x0;
    const float* bq = lab_[2].ptr<float>(yy) + x0;
    int i = 0;
#if CV_SIMD128
    const cv::v_float32x4 vL = cv::v_setall_f32(Lp), va = cv::v_setall_f32(ap), vb = cv::v_setall_f32(bp);
    const cv::v_float32x4 vscale = cv::v_setall_f32(t_.to_index), vlast = cv::v_setall_f32(t_.last);
    for (; i + 4 <= n; i += 4) {
      const cv::v_float32x4 dL = cv::v_load(Lq + i) - vL, da = cv::v_load(aq + i) - va, db = cv::v_load(bq + i) - vb;
      const cv::v_float32x4 dc = cv::v_sqrt(dL * dL + da * da + db * db);
      cv::v_store(index_.data() + i, cv::v_round(cv::v_min(dc * vscale, vlast)));
    }
#endif
    for (; i < n; ++i) {
      const float dL = Lq[i] - Lp, da = aq[i] - ap, db = bq[i] - bp;
      index_[i] = t_.colourIndex(std::sqrt(dL * dL + da * da + db * db));
    }
  }

  const cv::Mat (&lab_)[3];
  const Voters& voters_;
  const VoteTables& t_;
  std::vector<float> score_;
  std::vector<int> stamp_, touched_, index_;
};

#if CV_SIMD128
/// Calls f(std::integral_constant<int, k>()) for k = min(n, 4): LaneVote's block sizes as template arguments.
template <typename F>
void withBlockSize(int n, F&& f) {
  switch (std::min(n, 4)) {
    case 1:
      f(std::integral_constant<int, 1>());
      break;
    case 2:
      f(std::integral_constant<int, 2>());
      break;
    case 3:
      f(std::integral_constant<int, 3>());
      break;
    default:
      f(std::integral_constant<int, 4>());
      break;
  }
}

/// WeightedVote's sums for four adjacent pixels (x .. x + 3, one per SIMD lane) whose windows lie inside the image's
/// columns: each window offset is one vector step (the four voters are adjacent in memory), and each given level has
/// a vector accumulator that adds the weight where the voter has that level and +0.0 elsewhere. Adding +0.0 to a
/// non-negative float changes nothing, so every lane sums exactly the weights WeightedVote sums, in the same (raster)
/// order: the same floats, the same winner. The levels are accumulated in blocks of up to four (registers).
class LaneVote {
 public:
  static constexpr int kMaxLevels = 24;  ///< more distinct levels in the union of the windows: WeightedVote

  LaneVote(const cv::Mat (&lab)[3], const Voters& voters, const VoteTables& tables)
      : lab_(lab), voters_(voters), t_(tables), w_(tables.side * tables.side), lev_(tables.side * tables.side) {}

  /// Scores of `levels` (count <= kMaxLevels, indices from lo) for the four pixels from (x, y): score[k * 4 + lane].
  void scores(int x, int y, const int* levels, int count, float* score) {
    const int H = voters_.level.rows;
    const int y0 = std::max(0, y - t_.r), y1 = std::min(H - 1, y + t_.r);
    const bool more_blocks = count > 4;
    withBlockSize(count, [&](auto k) { firstBlock<decltype(k)::value>(x, y, y0, y1, levels, score, more_blocks); });
    const int elements = (y1 - y0 + 1) * t_.side;
    for (int k = 4; k < count; k += 4)
      withBlockSize(count - k, [&](auto n) { laterBlock<decltype(n)::value>(elements, levels + k, score + 4 * k); });
  }

 private:
  /// Computes the four lanes' weights over the window (kept in w_ / lev_ for the later blocks if `keep`) and
  /// accumulates the first K levels.
  template <int K>
  void firstBlock(int x, int y, int y0, int y1, const int* levels, float* score, bool keep) {
    const int r = t_.r, side = t_.side;
    const cv::v_float32x4 Lc = cv::v_load(lab_[0].ptr<float>(y) + x), ac = cv::v_load(lab_[1].ptr<float>(y) + x),
                          bc = cv::v_load(lab_[2].ptr<float>(y) + x);
    const cv::v_float32x4 vscale = cv::v_setall_f32(t_.to_index), vlast = cv::v_setall_f32(t_.last);
    const float* cw = t_.colour_weight.data();
    Accumulators<K> acc(levels);
    int e = 0;
    for (int yy = y0; yy <= y1; ++yy) {
      const int* vq = voters_.level.ptr<int>(yy) + x - r;
      const float* Lq = lab_[0].ptr<float>(yy) + x - r;
      const float* aq = lab_[1].ptr<float>(yy) + x - r;
      const float* bq = lab_[2].ptr<float>(yy) + x - r;
      const float* sw = t_.spatial.data() + (yy - y + r) * side;
      for (int i = 0; i < side; ++i, ++e) {
        const cv::v_int32x4 lev = cv::v_load(vq + i);
        const cv::v_float32x4 dL = cv::v_load(Lq + i) - Lc, da = cv::v_load(aq + i) - ac, db = cv::v_load(bq + i) - bc;
        const cv::v_float32x4 dc = cv::v_sqrt(dL * dL + da * da + db * db);
        const cv::v_int32x4 index = cv::v_round(cv::v_min(dc * vscale, vlast));  // VoteTables::colourIndex
        const cv::v_float32x4 w = cv::v_lut(cw, index) * cv::v_setall_f32(sw[i]);
        if (keep) {
          cv::v_store(w_[e].data(), w);
          cv::v_store(lev_[e].data(), lev);
        }
        acc.add(w, lev);
      }
    }
    acc.store(score);
  }

  /// Accumulates K more levels from the weights firstBlock kept.
  template <int K>
  void laterBlock(int elements, const int* levels, float* score) const {
    Accumulators<K> acc(levels);
    for (int e = 0; e < elements; ++e) acc.add(cv::v_load(w_[e].data()), cv::v_load(lev_[e].data()));
    acc.store(score);
  }

  /// K levels' per-lane sums.
  template <int K>
  struct Accumulators {
    cv::v_int32x4 level[K];
    cv::v_float32x4 sum[K];

    explicit Accumulators(const int* levels) {
      for (int k = 0; k < K; ++k) {
        level[k] = cv::v_setall_s32(levels[k]);
        sum[k] = cv::v_setzero_f32();
      }
    }
    void add(const cv::v_float32x4& w, const cv::v_int32x4& lev) {
      for (int k = 0; k < K; ++k) sum[k] += w & cv::v_reinterpret_as_f32(lev == level[k]);
    }
    void store(float* score) const {
      for (int k = 0; k < K; ++k) cv::v_store(score + 4 * k, sum[k]);
    }
  };

  const cv::Mat (&lab_)[3];
  const Voters& voters_;
  const VoteTables& t_;
  std::vector<std::array<float, 4>> w_;
  std::vector<std::array<int, 4>> lev_;
};
#endif

int lowestBit(std::uint64_t m) {
  int b = 0;
  while (!(m & 1)) {
    m >>= 1;
    ++b;
  }
  return b;
}

/// Per pixel, the voter levels (bit l) in its row at the column span [x - r, x + r + 3] (the union of four adjacent
/// windows' columns); for maps of at most 64 levels.
cv::Mat rowLevelMasks(const Voters& v, int r, int threads) {
  const int W = v.level.cols;
  cv::Mat masks(v.level.size(), CV_64F);  // uint64 storage
  cv::parallel_for_(
      cv::Range(0, v.level.rows),
      [&](const cv::Range& rows) {
        std::vector<std::uint64_t> bit(W);
        for (int y = rows.start; y < rows.end; ++y) {
          const int* l = v.level.ptr<int>(y);
          for (int x = 0; x < W; ++x) bit[x] = l[x] < 0 ? 0 : std::uint64_t{1} << l[x];
          std::uint64_t* m = reinterpret_cast<std::uint64_t*>(masks.ptr(y));
          for (int x = 0; x < W; ++x) {
            std::uint64_t acc = 0;
            for (int c = std::max(0, x - r); c <= std::min(W - 1, x + r + 3); ++c) acc |= bit[c];
            m[x] = acc;
          }
        }
      },
      stripes(threads, v.level.rows));
  return masks;
}

/// What recoverDisparity's row stripes share.
struct MdcInput {
  const cv::Mat& levels;  ///< the rounded map (kInvalidLevel: NaN)
  int lo, nlevels;
  const Voters& voters;
  const cv::Mat (&lab)[3];
  const VoteTables& tables;
  cv::Mat row_masks;  ///< rowLevelMasks, when LaneVote runs and the map has at most 64 levels
  bool lanes;         ///< LaneVote runs: SIMD, and the image is wide enough for four windows side by side
};

/// MDC over rows of the map, written into `result` where the winner differs from the pixel's own level. Pixels
/// whose window holds one voter level take it; the others are voted four at a time by LaneVote where their windows
/// lie inside the columns and their union holds at most LaneVote::kMaxLevels levels, else one by one by WeightedVote.
class MdcRows {
 public:
  MdcRows(const MdcInput& in, cv::Mat& result)
      : in_(in),
        result_(result),
        vote_(in.lab, in.voters, in.nlevels, in.tables)
#if CV_SIMD128
        ,
        lane_vote_(in.lab, in.voters, in.tables)
#endif
  {
  }

  void row(int y) {
    window_min_ = in_.voters.window_min.ptr<float>(y);
    window_max_ = in_.voters.window_max.ptr<float>(y);
    own_row_ = in_.levels.ptr<int>(y);
    out_ = result_.ptr<float>(y);
    for (int x = 0; x < result_.cols;) {
      const int winner = obviousWinner(x);
      if (winner == kVote) {
#if CV_SIMD128
        if (voteFour(x, y)) {
          x += 4;
          continue;
        }
#endif
        set(x, vote_.winner(x, y, own(x)));
      } else if (winner != kNoVoter) {
        set(x, winner);
      }
      ++x;
    }
  }

 private:
  static constexpr int kNoVoter = -1, kVote = -2;

  /// The winner at x of the current row when no vote is needed: kNoVoter (keep d(p)), the one level in the window;
  /// else kVote.
  int obviousWinner(int x) const {
    if (window_min_[x] == std::numeric_limits<float>::max()) return kNoVoter;
    if (window_min_[x] == window_max_[x]) return static_cast<int>(window_min_[x]);
    return kVote;
  }

  int own(int x) const { return own_row_[x] == kInvalidLevel ? -1 : own_row_[x] - in_.lo; }

  void set(int x, int winner) {
    if (winner != own(x)) out_[x] = static_cast<float>(winner + in_.lo);
  }

#if CV_SIMD128
  /// Votes pixels x .. x + 3 of row y with LaneVote; false (nothing done) when it cannot take them.
  bool voteFour(int x, int y) {
    const int r = in_.tables.r;
    if (!in_.lanes || x < r || x + 3 + r > result_.cols - 1) return false;
    const int count = unionLevels(x, y);
    if (count > LaneVote::kMaxLevels) return false;
    lane_vote_.scores(x, y, levels_, count, score_);
    for (int lane = 0; lane < 4; ++lane) {
      int winner = obviousWinner(x + lane);
      if (winner == kNoVoter) continue;
      if (winner == kVote) winner = laneWinner(lane, count, own(x + lane));
      if (winner < 0) winner = vote_.winner(x + lane, y, own(x + lane));
      set(x + lane, winner);
    }
    return true;
  }

  /// levels_: the voter levels of the union of the windows of pixels x .. x + 3 of row y, ascending (a superset
  /// without row_masks: every level between their windows' extremes). Returns their count, LaneVote::kMaxLevels + 1
  /// when there are more.
  int unionLevels(int x, int y) {
    constexpr int kTooMany = LaneVote::kMaxLevels + 1;
    int count = 0;
    if (!in_.row_masks.empty()) {
      const int r = in_.tables.r, H = result_.rows;
      std::uint64_t mask = 0;
      for (int yy = std::max(0, y - r); yy <= std::min(H - 1, y + r); ++yy)
        mask |= reinterpret_cast<const std::uint64_t*>(in_.row_masks.ptr(yy))[x];
      for (; mask && count < kTooMany; mask &= mask - 1) levels_[count++] = lowestBit(mask);
      return count;
    }
    float lmin = window_min_[x], lmax = window_max_[x];
    for (int j = 1; j < 4; ++j) {
      lmin = std::min(lmin, window_min_[x + j]);
      lmax = std::max(lmax, window_max_[x + j]);
    }
    if (lmax - lmin >= LaneVote::kMaxLevels) return kTooMany;
    for (int l = static_cast<int>(lmin); l <= static_cast<int>(lmax); ++l) levels_[count++] = l;
    return count;
  }

  /// The level with the largest score in `lane` (ties: `own`, else the smallest), or -1 when every score is 0:
  /// levels absent from the lane's window score +0.0 and cannot reach a positive best, but a best of 0 (all weights
  /// underflowed) is WeightedVote's, which knows which levels were voted for.
  int laneWinner(int lane, int count, int own) const {
    float best = 0.0f;
    int winner = -1;
    for (int k = 0; k < count; ++k) {
      const float s = score_[4 * k + lane];
      if (s > best || (s == best && s > 0.0f && levels_[k] == own)) {
        best = s;
        winner = levels_[k];
      }
    }
    return winner;
  }
#endif

  const MdcInput& in_;
  cv::Mat& result_;
  WeightedVote vote_;
  const float *window_min_ = nullptr, *window_max_ = nullptr;
  const int* own_row_ = nullptr;
  float* out_ = nullptr;
#if CV_SIMD128
  LaneVote lane_vote_;
  int levels_[LaneVote::kMaxLevels + 1];
  float score_[4 * LaneVote::kMaxLevels];
#endif
};

}  // namespace

cv::Mat recoverDisparity(const cv::Mat& left, const cv::Mat& disparity, const cv::Mat& fattening_mask,
                         const RefineParams& params, int threads) {
  checkImage("recoverDisparity", left, disparity);
  if (!fattening_mask.empty()) {
    if (fattening_mask.type() != CV_8UC1) fail("recoverDisparity", "fattening mask must be CV_8UC1");
    if (fattening_mask.size() != disparity.size())
      fail("recoverDisparity", "fattening mask and disparity map sizes differ");
  }
  validate(params);
  int lo, hi;
  const cv::Mat levels = roundedLevels(disparity, lo, hi);
  cv::Mat result = disparity.clone();
  if (lo > hi) return result;  // no voter anywhere
  if (static_cast<long long>(hi) - lo > 1 << 24) fail("recoverDisparity", "disparity range too wide");
  const int nlevels = hi - lo + 1;
  const Voters v = voters(levels, lo, fattening_mask, params.window);
  cv::Mat lab[3];
  labPlanes(left, lab);
  const VoteTables tables(params);
  MdcInput in{levels, lo, nlevels, v, lab, tables, cv::Mat(), false};
#if CV_SIMD128
  in.lanes = disparity.cols >= tables.side + 3;
  if (in.lanes && nlevels <= 64) in.row_masks = rowLevelMasks(v, tables.r, threads);
#endif
  cv::parallel_for_(
      cv::Range(0, disparity.rows),
      [&](const cv::Range& rows) {
        MdcRows mdc(in, result);
        for (int y = rows.start; y < rows.end; ++y) mdc.row(y);
      },
      stripes(threads, disparity.rows));
  return result;
}

}  // namespace massage_cell::stereo
