// Graph-cut baselines of optimizers.h: alpha-expansion and alpha-beta swap
// (Boykov, Veksler, Zabih, PAMI 2001) for E(d) = sum_p S(p, d_p)
// + sum_{p,q} u_pq V(d_p, d_q), V(a, b) = min(|a - b|, T) (T <= 0: |a - b|),
// on 4-connected pairs. Every binary move is one MaxFlow (max_flow.h).
//
// Graph convention of both moves: binary variable x_p, x_p = 0 <-> p on the
// source side, x_p = 1 <-> sink side. A node's source capacity is paid when
// x_p = 1 and its sink capacity when x_p = 0; an arc p -> q is paid when
// x_p = 0 and x_q = 1. Per node the unary costs E_p(0), E_p(1) are
// accumulated first, then min(E_p(0), E_p(1)) is subtracted (a constant) and
// addTerminalWeights(p, E_p(1) - m, E_p(0) - m).
//
// alpha-expansion (x_p = 0: keep d_p, x_p = 1: take alpha). Nodes only for
// pixels with d_p != alpha (pixels already at alpha cannot change).
//   unary: E_p(0) = S(p, d_p), E_p(1) = S(p, alpha)
//   pair with q fixed at alpha: E_p(0) += u V(d_p, alpha)   (E_p(1): V = 0)
//   pair of two nodes (Kolmogorov-Zabih 2004 submodular term):
//     A = E(0,0) = u V(d_p, d_q), B = E(0,1) = u V(d_p, alpha),
//     C = E(1,0) = u V(alpha, d_q), D = E(1,1) = 0
//     E(x_p, x_q) = A + (C - A) x_p + (D - C) x_q + (B + C - A - D)(1 - x_p) x_q
//     -> E_p(1) += C - A, E_q(1) += D - C = -C, arc p -> q capacity B + C - A.
//   B + C - A >= 0 is the triangle inequality of the metric V (truncating a
//   metric at T keeps it a metric); it is clamped at 0 against float rounding.
//
// Local expansion (localExpansion, our addition used to polish HBDS): the
// move of alpha only takes the pixels whose label is within `window` levels
// of alpha as nodes; every other pixel keeps its label and enters its
// neighbours' unaries as a fixed label d_q: E_p(0) += u V(d_p, d_q),
// E_p(1) += u V(alpha, d_q) (the general form of the fixed-at-alpha case).
// Each move is still an exact minimisation over its own move space, so the
// energy never rises; the graphs hold ~2 window / levels of the pixels and
// their pairwise capacities are at most u * 2 window, which keeps the cuts
// cheap.
//
// Coarse polish (coarsePolish, our addition: a full-range polish of HBDS at a
// fraction of the cost). The expansion cycles run on B x B blocks with the
// exact energy of block-constant labellings (block unary = sum of the pixel
// costs, block pair = sum of u over the pixel pairs crossing the boundary,
// pairs inside a block cost 0), from each block's median label; then one
// fusion move at full resolution (x_p = 0: keep d_p, x_p = 1: take c_p, the
// block's label; nodes where c_p != d_p):
//   unary E_p(0) = S(p, d_p), E_p(1) = S(p, c_p); a neighbour q outside the
//   move (c_q = d_q): E_p(0) += u V(d_p, d_q), E_p(1) += u V(c_p, d_q)
//   pair of two nodes: A = u V(d_p, d_q), B = u V(d_p, c_q), C = u V(c_p, d_q),
//     D = u V(c_p, c_q); if A + D > B + C, D is lowered to B + C - A
//     (truncation, Rother et al. 2005); E_p(1) += C - A, E_q(1) += D - C,
//     arc p -> q capacity B + C - A - D (Mover::binaryMove, which the
//     expansion move shares with c_p = alpha).
// Truncated pairs make the cut approximate, so the fused labelling is kept
// only when its exact energy is lower (commit): never above the start's.
//
// alpha-beta swap, alpha < beta (x_p = 0: alpha, x_p = 1: beta). Nodes only
// for pixels labelled alpha or beta.
//   unary: E_p(0) = S(p, alpha), E_p(1) = S(p, beta); for each neighbour q
//   outside the move E_p(0) += u V(alpha, d_q), E_p(1) += u V(beta, d_q)
//   pair of two nodes: arcs p -> q and q -> p, both u V(alpha, beta)
//   (E(0,0) = E(1,1) = 0; needs only a semi-metric).
//
// Cycles: labels in increasing order dmin..dmax (swap: pairs (alpha, beta) in
// lexicographic order), deterministic. A move is accepted only when it lowers
// the energy (exact change recomputed from the labelling, tolerance 1e-9
// relative), so the energy never increases even if a cut were inexact. A
// move whose last attempt failed with no accepted move since then is skipped:
// the graph would be identical (the labelling is unchanged), so is the cut.
// The same holds for the move just accepted (the new labelling is optimal
// among its own alpha-expansions / its alpha-beta swaps). Hence the run stops
// as soon as every label (pair) has failed since the last change, possibly in
// the middle of a cycle, or after max_cycles cycles. `cycles` counts the
// cycles begun.
//
// Default initial labelling: winner-takes-all (ties to the smaller d),
// computed locally here.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "massage_cell/stereo/max_flow.h"
#include "massage_cell/stereo/optimizers.h"

namespace massage_cell::stereo {

namespace {

/// Validated problem data shared by both optimisers.
struct Problem {
  const CostVolume* volume = nullptr;
  int w = 0, h = 0, n = 0, dmin = 0, dmax = 0;
  std::vector<float> ur, ud;  ///< u of pair (p, p + 1) and (p, p + w); 0 where absent
  std::vector<float> vdist;   ///< V for |a - b| = 0..levels-1

  float cost(int p, int d) const { return volume->slice(d)[p]; }
  float v(int a, int b) const { return vdist[static_cast<std::size_t>(std::abs(a - b))]; }
};

void copyWeights(const cv::Mat& m, std::vector<float>& out, const char* name) {
  out.resize(static_cast<std::size_t>(m.rows) * m.cols);
  for (int y = 0; y < m.rows; ++y) {
    const float* row = m.ptr<float>(y);
    for (int x = 0; x < m.cols; ++x) {
      if (!(row[x] >= 0.0f) || !std::isfinite(row[x]))
        throw std::invalid_argument(std::string("graph cuts: weights.") + name + " must be finite and >= 0");
      out[static_cast<std::size_t>(y) * m.cols + x] = row[x];
    }
  }
}

Problem makeProblem(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                    int max_cycles) {
  Problem pb;
  pb.volume = &volume;
  pb.w = volume.width();
  pb.h = volume.height();
  if (pb.w <= 0 || pb.h <= 0) throw std::invalid_argument("graph cuts: empty cost volume");
  if (max_cycles < 0) throw std::invalid_argument("graph cuts: max_cycles must be >= 0");
  if (std::isnan(smooth.truncation)) throw std::invalid_argument("graph cuts: truncation is NaN");
  const cv::Size size(pb.w, pb.h);
  if (weights.right.type() != CV_32FC1 || weights.right.size() != size || weights.down.type() != CV_32FC1 ||
      weights.down.size() != size)
    throw std::invalid_argument("graph cuts: weights must be CV_32FC1 of the volume's size");
  pb.n = pb.w * pb.h;
  pb.dmin = volume.dmin();
  pb.dmax = volume.dmax();
  copyWeights(weights.right, pb.ur, "right");
  copyWeights(weights.down, pb.ud, "down");
  // Pairs that do not exist must not contribute, whatever the caller stored.
  for (int y = 0; y < pb.h; ++y) pb.ur[static_cast<std::size_t>(y) * pb.w + pb.w - 1] = 0.0f;
  for (int x = 0; x < pb.w; ++x) pb.ud[static_cast<std::size_t>(pb.h - 1) * pb.w + x] = 0.0f;
  pb.vdist.resize(static_cast<std::size_t>(volume.levels()));
  for (int k = 0; k < volume.levels(); ++k)
    pb.vdist[static_cast<std::size_t>(k)] =
        smooth.truncation > 0.0f ? std::min(static_cast<float>(k), smooth.truncation) : static_cast<float>(k);
  return pb;
}

/// Local WTA (ties to the smaller d), so this file does not depend on cost_volume.cpp.
std::vector<int> argminLabels(const Problem& pb) {
  std::vector<int> lab(static_cast<std::size_t>(pb.n), pb.dmin);
  std::vector<float> best(pb.volume->slice(pb.dmin), pb.volume->slice(pb.dmin) + pb.n);
  for (int d = pb.dmin + 1; d <= pb.dmax; ++d) {
    const float* s = pb.volume->slice(d);
    for (int p = 0; p < pb.n; ++p)
      if (s[p] < best[static_cast<std::size_t>(p)]) {
        best[static_cast<std::size_t>(p)] = s[p];
        lab[static_cast<std::size_t>(p)] = d;
      }
  }
  return lab;
}

std::vector<int> initialLabels(const Problem& pb, const cv::Mat& initial) {
  if (initial.empty()) return argminLabels(pb);
  if (initial.type() != CV_32FC1 || initial.size() != cv::Size(pb.w, pb.h))
    throw std::invalid_argument("graph cuts: initial labelling must be CV_32FC1 of the volume's size");
  std::vector<int> lab(static_cast<std::size_t>(pb.n));
  for (int y = 0; y < pb.h; ++y) {
    const float* row = initial.ptr<float>(y);
    for (int x = 0; x < pb.w; ++x) {
      const float v = row[x];
      if (!std::isfinite(v) || v != std::floor(v) || v < pb.dmin || v > pb.dmax)
        throw std::invalid_argument("graph cuts: initial labelling at (" + std::to_string(x) + ", " +
                                    std::to_string(y) + ") is not an integer in [" + std::to_string(pb.dmin) + ", " +
                                    std::to_string(pb.dmax) + "]");
      lab[static_cast<std::size_t>(y) * pb.w + x] = static_cast<int>(v);
    }
  }
  return lab;
}

double energyOf(const Problem& pb, const std::vector<int>& lab) {
  double e = 0.0;
  for (int p = 0; p < pb.n; ++p) {
    const int d = lab[static_cast<std::size_t>(p)];
    e += pb.cost(p, d);
    const int x = p % pb.w;
    if (x + 1 < pb.w) e += static_cast<double>(pb.ur[static_cast<std::size_t>(p)]) * pb.v(d, lab[p + 1]);
    if (p + pb.w < pb.n) e += static_cast<double>(pb.ud[static_cast<std::size_t>(p)]) * pb.v(d, lab[p + pb.w]);
  }
  return e;
}

/// Shared state of a run: current labels, the labels proposed by a cut and
/// buffers reused across moves.
class Mover {
 public:
  explicit Mover(const Problem& pb, std::vector<int> lab)
      : pb_(pb),
        lab_(std::move(lab)),
        next_(lab_),
        target_(static_cast<std::size_t>(pb.n)),
        node_(static_cast<std::size_t>(pb.n), -1) {
    energy_ = energyOf(pb_, lab_);
  }

  const std::vector<int>& labels() const { return lab_; }
  double energy() const { return energy_; }
  int cuts() const { return cuts_; }

  /// One alpha-expansion move; true when accepted (energy decreased).
  /// window > 0 restricts the move to the pixels whose label is within
  /// `window` levels of alpha (the others stay fixed).
  bool expand(int alpha, int window = 0) {
    return binaryMove([&](int p) {
      const int d = lab_[static_cast<std::size_t>(p)];
      return window <= 0 || std::abs(d - alpha) <= window ? alpha : d;
    });
  }

  /// One fusion move (Lempitsky et al. 2010): each pixel keeps its label or
  /// takes proposal[p]; true when accepted (energy decreased).
  bool fuse(const std::vector<int>& proposal) {
    return binaryMove([&](int p) { return proposal[static_cast<std::size_t>(p)]; });
  }

  /// One alpha-beta swap move over the pixels currently labelled alpha or beta.
  bool swap(int alpha, int beta, const std::vector<int>& members) {
    const int n = pb_.n, w = pb_.w;
    const int m = static_cast<int>(members.size());
    if (m == 0) return false;
    for (int i = 0; i < m; ++i) node_[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])] = i;
    e0_.assign(static_cast<std::size_t>(m), 0.0);
    e1_.assign(static_cast<std::size_t>(m), 0.0);
    MaxFlow mf(m, 2 * m);
    mf.addNodes(m);
    const double vab = pb_.v(alpha, beta);
    auto neighbour = [&](int i, int q, float u) {
      if (u == 0.0f) return;
      const int nq = node_[static_cast<std::size_t>(q)];
      if (nq < 0) {
        const int dq = lab_[static_cast<std::size_t>(q)];
        e0_[static_cast<std::size_t>(i)] += static_cast<double>(u) * pb_.v(alpha, dq);
        e1_[static_cast<std::size_t>(i)] += static_cast<double>(u) * pb_.v(beta, dq);
      } else if (nq > i) {
        const double c = static_cast<double>(u) * vab;
        mf.addEdge(i, nq, c, c);
      }
    };
    for (int i = 0; i < m; ++i) {
      const int p = members[static_cast<std::size_t>(i)];
      e0_[static_cast<std::size_t>(i)] += pb_.cost(p, alpha);
      e1_[static_cast<std::size_t>(i)] += pb_.cost(p, beta);
      const int x = p % w;
      if (x + 1 < w) neighbour(i, p + 1, pb_.ur[static_cast<std::size_t>(p)]);
      if (x > 0) neighbour(i, p - 1, pb_.ur[static_cast<std::size_t>(p - 1)]);
      if (p + w < n) neighbour(i, p + w, pb_.ud[static_cast<std::size_t>(p)]);
      if (p >= w) neighbour(i, p - w, pb_.ud[static_cast<std::size_t>(p - w)]);
    }
    addTerminals(mf, m);
    mf.solve();
    ++cuts_;
    changed_.clear();
    for (int i = 0; i < m; ++i) {
      const int p = members[static_cast<std::size_t>(i)];
      const int d = mf.isSource(i) ? alpha : beta;
      if (d != lab_[static_cast<std::size_t>(p)]) {
        next_[static_cast<std::size_t>(p)] = d;
        changed_.push_back(p);
      }
    }
    for (int i = 0; i < m; ++i) node_[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])] = -1;
    return commit();
  }

 private:
  /// The binary move both expand() and fuse() are: each pixel p keeps its
  /// label d_p (x_p = 0) or takes target(p) = c_p (x_p = 1), one cut on the
  /// exact Eq. 2.2 energy; nodes only where c_p != d_p. A neighbour q outside
  /// the move keeps d_q: E_p(0) += u V(d_p, d_q), E_p(1) += u V(c_p, d_q). A
  /// pair of two nodes, A = u V(d_p, d_q), B = u V(d_p, c_q), C = u V(c_p, d_q),
  /// D = u V(c_p, c_q): E_p(1) += C - A, E_q(1) += D - C, arc p -> q with
  /// B + C - A - D. An expansion's pairs are submodular (D = 0, V a metric);
  /// a fusion's that are not (A + D > B + C) have D lowered to B + C - A
  /// (truncation, Rother et al. 2005), so its cut is approximate; commit()
  /// keeps the result only when the exact energy drops.
  template <typename Target>
  bool binaryMove(const Target& target) {
    const int n = pb_.n, w = pb_.w;
    nodes_.clear();
    for (int p = 0; p < n; ++p) {
      target_[static_cast<std::size_t>(p)] = target(p);
      if (target_[static_cast<std::size_t>(p)] != lab_[static_cast<std::size_t>(p)]) {
        node_[static_cast<std::size_t>(p)] = static_cast<int>(nodes_.size());
        nodes_.push_back(p);
      } else {
        node_[static_cast<std::size_t>(p)] = -1;
      }
    }
    const int m = static_cast<int>(nodes_.size());
    if (m == 0) return false;
    e0_.assign(static_cast<std::size_t>(m), 0.0);
    e1_.assign(static_cast<std::size_t>(m), 0.0);
    MaxFlow mf(m, 2 * m);
    mf.addNodes(m);
    for (int i = 0; i < m; ++i) {
      const int p = nodes_[static_cast<std::size_t>(i)];
      e0_[static_cast<std::size_t>(i)] = pb_.cost(p, lab_[static_cast<std::size_t>(p)]);
      e1_[static_cast<std::size_t>(i)] = pb_.cost(p, target_[static_cast<std::size_t>(p)]);
    }
    auto pair = [&](int p, int q, float u) {
      if (u == 0.0f) return;
      const int np = node_[static_cast<std::size_t>(p)], nq = node_[static_cast<std::size_t>(q)];
      if (np < 0 && nq < 0) return;
      const int dp = lab_[static_cast<std::size_t>(p)], dq = lab_[static_cast<std::size_t>(q)];
      const int cp = target_[static_cast<std::size_t>(p)], cq = target_[static_cast<std::size_t>(q)];
      const double uu = static_cast<double>(u);
      if (np < 0) {  // p keeps d_p (= c_p)
        e0_[static_cast<std::size_t>(nq)] += uu * pb_.v(dp, dq);
        e1_[static_cast<std::size_t>(nq)] += uu * pb_.v(dp, cq);
        return;
      }
      if (nq < 0) {
        e0_[static_cast<std::size_t>(np)] += uu * pb_.v(dp, dq);
        e1_[static_cast<std::size_t>(np)] += uu * pb_.v(cp, dq);
        return;
      }
      const double a = uu * pb_.v(dp, dq), b = uu * pb_.v(dp, cq), c = uu * pb_.v(cp, dq);
      const double slack = b + c - a - uu * pb_.v(cp, cq);  // < 0: not submodular
      const double d = uu * pb_.v(cp, cq) + std::min(0.0, slack);
      e1_[static_cast<std::size_t>(np)] += c - a;
      e1_[static_cast<std::size_t>(nq)] += d - c;
      mf.addEdge(np, nq, std::max(0.0, slack), 0.0);
    };
    for (int i = 0; i < m; ++i) {
      const int p = nodes_[static_cast<std::size_t>(i)];
      const int x = p % w;
      // Each pair once, from its first member if that is a node, else from
      // the second (the first is then outside the move).
      if (x + 1 < w) pair(p, p + 1, pb_.ur[static_cast<std::size_t>(p)]);
      if (p + w < n) pair(p, p + w, pb_.ud[static_cast<std::size_t>(p)]);
      if (x > 0 && node_[static_cast<std::size_t>(p - 1)] < 0) pair(p - 1, p, pb_.ur[static_cast<std::size_t>(p - 1)]);
      if (p >= w && node_[static_cast<std::size_t>(p - w)] < 0) pair(p - w, p, pb_.ud[static_cast<std::size_t>(p - w)]);
    }
    addTerminals(mf, m);
    mf.solve();
    ++cuts_;
    changed_.clear();
    for (int i = 0; i < m; ++i)
      if (!mf.isSource(i)) {
        const int p = nodes_[static_cast<std::size_t>(i)];
        next_[static_cast<std::size_t>(p)] = target_[static_cast<std::size_t>(p)];
        changed_.push_back(p);
      }
    return commit();
  }

  void addTerminals(MaxFlow& mf, int m) const {
    for (int i = 0; i < m; ++i) {
      const double a = e0_[static_cast<std::size_t>(i)], b = e1_[static_cast<std::size_t>(i)];
      const double lo = std::min(a, b);
      mf.addTerminalWeights(i, b - lo, a - lo);
    }
  }

  /// Exact energy change of next_ against lab_ (they differ on changed_);
  /// applies it when negative, reverts next_ otherwise.
  bool commit() {
    if (changed_.empty()) return false;
    const int n = pb_.n, w = pb_.w;
    double delta = 0.0;
    auto edge = [&](int p, int q, float u) {
      delta += static_cast<double>(u) * (pb_.v(next_[static_cast<std::size_t>(p)], next_[static_cast<std::size_t>(q)]) -
                                         pb_.v(lab_[static_cast<std::size_t>(p)], lab_[static_cast<std::size_t>(q)]));
    };
    auto isChanged = [&](int q) { return next_[static_cast<std::size_t>(q)] != lab_[static_cast<std::size_t>(q)]; };
    for (int p : changed_) {
      delta += static_cast<double>(pb_.cost(p, next_[static_cast<std::size_t>(p)])) -
               static_cast<double>(pb_.cost(p, lab_[static_cast<std::size_t>(p)]));
      const int x = p % w;
      // A pair with both ends changed is counted from its first member only.
      if (x + 1 < w) edge(p, p + 1, pb_.ur[static_cast<std::size_t>(p)]);
      if (p + w < n) edge(p, p + w, pb_.ud[static_cast<std::size_t>(p)]);
      if (x > 0 && !isChanged(p - 1)) edge(p - 1, p, pb_.ur[static_cast<std::size_t>(p - 1)]);
      if (p >= w && !isChanged(p - w)) edge(p - w, p, pb_.ud[static_cast<std::size_t>(p - w)]);
    }
    const bool accept = delta < -1e-9 * std::max(1.0, std::abs(energy_));
    for (int p : changed_) {
      if (accept)
        lab_[static_cast<std::size_t>(p)] = next_[static_cast<std::size_t>(p)];
      else
        next_[static_cast<std::size_t>(p)] = lab_[static_cast<std::size_t>(p)];
    }
    if (accept) energy_ += delta;
    return accept;
  }

  const Problem& pb_;
  std::vector<int> lab_, next_;
  std::vector<int> target_;   ///< pixel -> the label x_p = 1 gives it in the current move
  std::vector<int> node_;     ///< pixel -> graph node of the current move, -1 if none
  std::vector<int> nodes_;    ///< graph node -> pixel (expansion)
  std::vector<int> changed_;  ///< pixels whose label the current cut changes
  std::vector<double> e0_, e1_;
  double energy_ = 0.0;
  int cuts_ = 0;
};

OptimizerResult finish(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                       const Problem& pb, const Mover& mover, int cycles) {
  OptimizerResult r;
  r.disparity.create(pb.h, pb.w, CV_32F);
  for (int y = 0; y < pb.h; ++y) {
    float* row = r.disparity.ptr<float>(y);
    for (int x = 0; x < pb.w; ++x) row[x] = static_cast<float>(mover.labels()[static_cast<std::size_t>(y) * pb.w + x]);
  }
  r.energy = labellingEnergy(volume, weights, r.disparity, smooth.truncation);
  r.cuts = mover.cuts();
  r.cycles = cycles;
  return r;
}

}  // namespace

namespace {

/// Expansion cycles of `mover` (see the header comment); returns the cycles begun.
int expansionCycles(const Problem& pb, Mover& mover, int max_cycles, int window) {
  const int levels = pb.dmax - pb.dmin + 1;
  // failed_at[a]: value of `accepted` when alpha = dmin + a last failed (or
  // succeeded); -1: never tried. Equal to `accepted` -> the move cannot help.
  std::vector<std::int64_t> failed_at(static_cast<std::size_t>(levels), -1);
  std::int64_t accepted = 0;
  int streak = 0;  // consecutive labels that cannot improve the current labelling
  int cycles = 0;
  bool converged = levels < 2;
  while (!converged && cycles < max_cycles) {
    ++cycles;
    for (int a = 0; a < levels && !converged; ++a) {
      if (failed_at[static_cast<std::size_t>(a)] != accepted) {
        if (mover.expand(pb.dmin + a, window)) {
          ++accepted;
          streak = 0;
        }
        failed_at[static_cast<std::size_t>(a)] = accepted;
      }
      converged = ++streak >= levels;
    }
  }
  return cycles;
}

OptimizerResult runExpansion(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                             const cv::Mat& initial, int max_cycles, int window) {
  const Problem pb = makeProblem(volume, weights, smooth, max_cycles);
  Mover mover(pb, initialLabels(pb, initial));
  const int cycles = expansionCycles(pb, mover, max_cycles, window);
  return finish(volume, weights, smooth, pb, mover, cycles);
}

}  // namespace

OptimizerResult alphaExpansion(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                               const cv::Mat& initial, int max_cycles) {
  return runExpansion(volume, weights, smooth, initial, max_cycles, 0);
}

OptimizerResult localExpansion(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                               const cv::Mat& initial, int window, int max_cycles) {
  if (window < 1) throw std::invalid_argument("localExpansion: window must be >= 1");
  return runExpansion(volume, weights, smooth, initial, max_cycles, window);
}

OptimizerResult coarsePolish(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                             const cv::Mat& initial, int block, int window, int max_cycles) {
  if (block < 2) throw std::invalid_argument("coarsePolish: block must be >= 2");
  if (window < 1) throw std::invalid_argument("coarsePolish: window must be >= 1");
  const Problem pb = makeProblem(volume, weights, smooth, max_cycles);
  if (initial.empty()) throw std::invalid_argument("coarsePolish: needs an initial labelling");
  const std::vector<int> lab = initialLabels(pb, initial);
  const int w = pb.w, h = pb.h, n = pb.n;
  const int bw = (w + block - 1) / block, bh = (h + block - 1) / block;
  std::vector<int> block_of(static_cast<std::size_t>(n));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) block_of[static_cast<std::size_t>(y) * w + x] = (y / block) * bw + x / block;
  // Block unaries: the sum of the block's pixel costs at each label.
  CostVolume coarse(bw, bh, pb.dmin, pb.dmax, 0.0f);
  for (int d = pb.dmin; d <= pb.dmax; ++d) {
    const float* s = volume.slice(d);
    float* cs = coarse.slice(d);
    for (int p = 0; p < n; ++p) cs[block_of[static_cast<std::size_t>(p)]] += s[p];
  }
  // Block pairs: the sum of u over the pixel pairs crossing the boundary
  // (pairs inside a block cost nothing for a block-constant labelling).
  PairwiseWeights cw{cv::Mat::zeros(bh, bw, CV_32F), cv::Mat::zeros(bh, bw, CV_32F)};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * w + x;
      const int bx = x / block, by = y / block;
      if (x + 1 < w && (x + 1) / block != bx) cw.right.at<float>(by, bx) += pb.ur[p];
      if (y + 1 < h && (y + 1) / block != by) cw.down.at<float>(by, bx) += pb.ud[p];
    }
  // Initial block labels: the (lower) median of the block's labels.
  cv::Mat binit(bh, bw, CV_32F);
  std::vector<int> members;
  for (int by = 0; by < bh; ++by)
    for (int bx = 0; bx < bw; ++bx) {
      members.clear();
      for (int y = by * block; y < std::min(h, (by + 1) * block); ++y)
        for (int x = bx * block; x < std::min(w, (bx + 1) * block); ++x)
          members.push_back(lab[static_cast<std::size_t>(y) * w + x]);
      const auto mid = members.begin() + static_cast<std::ptrdiff_t>((members.size() - 1) / 2);
      std::nth_element(members.begin(), mid, members.end());
      binit.at<float>(by, bx) = static_cast<float>(*mid);
    }
  const Problem cpb = makeProblem(coarse, cw, smooth, max_cycles);
  Mover cmover(cpb, initialLabels(cpb, binit));
  const int cycles = expansionCycles(cpb, cmover, max_cycles, window);
  // Fusion at full resolution of the initial labelling with the blocks' labels.
  std::vector<int> proposal(static_cast<std::size_t>(n));
  for (int p = 0; p < n; ++p)
    proposal[static_cast<std::size_t>(p)] =
        cmover.labels()[static_cast<std::size_t>(block_of[static_cast<std::size_t>(p)])];
  Mover mover(pb, lab);
  mover.fuse(proposal);
  OptimizerResult r = finish(volume, weights, smooth, pb, mover, cycles);
  r.cuts += cmover.cuts();
  return r;
}

OptimizerResult alphaBetaSwap(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                              const cv::Mat& initial, int max_cycles) {
  const Problem pb = makeProblem(volume, weights, smooth, max_cycles);
  Mover mover(pb, initialLabels(pb, initial));
  const int levels = volume.levels();
  // Pixels per label, kept up to date after every accepted swap.
  std::vector<std::vector<int>> bucket(static_cast<std::size_t>(levels));
  for (int p = 0; p < pb.n; ++p)
    bucket[static_cast<std::size_t>(mover.labels()[static_cast<std::size_t>(p)] - pb.dmin)].push_back(p);
  const int pairs = levels * (levels - 1) / 2;
  std::vector<std::int64_t> failed_at(static_cast<std::size_t>(pairs), -1);
  std::int64_t accepted = 0;
  int streak = 0;
  int cycles = 0;
  bool converged = pairs == 0;
  std::vector<int> members;
  while (!converged && cycles < max_cycles) {
    ++cycles;
    int k = 0;
    for (int a = 0; a < levels && !converged; ++a) {
      for (int b = a + 1; b < levels && !converged; ++b, ++k) {
        auto& ba = bucket[static_cast<std::size_t>(a)];
        auto& bb = bucket[static_cast<std::size_t>(b)];
        if (failed_at[static_cast<std::size_t>(k)] != accepted && !(ba.empty() && bb.empty())) {
          members.clear();
          members.insert(members.end(), ba.begin(), ba.end());
          members.insert(members.end(), bb.begin(), bb.end());
          if (mover.swap(pb.dmin + a, pb.dmin + b, members)) {
            ++accepted;
            streak = 0;
            ba.clear();
            bb.clear();
            for (int p : members) (mover.labels()[static_cast<std::size_t>(p)] == pb.dmin + a ? ba : bb).push_back(p);
          }
        }
        failed_at[static_cast<std::size_t>(k)] = accepted;
        converged = ++streak >= pairs;
      }
    }
  }
  return finish(volume, weights, smooth, pb, mover, cycles);
}

}  // namespace massage_cell::stereo
