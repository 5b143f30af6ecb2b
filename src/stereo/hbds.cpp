// HBDS: Hierarchical Bilateral Disparity Structure (thesis Ch. 2, Sec. 2.2).
//
// The disparity set [dmin, dmax] of the cost volume is split recursively into
// a background subset B = [lo, psi] and a foreground subset F = [psi + 1, hi]
// (psi: the break point of Eq. 2.9-2.10 computed by breakPoint() on the
// histogram of a rough winner-takes-all map). For every split one binary graph
// cut (MaxFlow) over the pixels still "active" in that set assigns each pixel
// to B or F by minimising the bilateral energy of Eq. 2.3:
//   data term   Eq. 2.4: D_p(B) = min_{d in B} S(p, d), D_p(F) = min_{d in F} S(p, d)
//   smooth term Eq. 2.5: V_pq = u_pq * |D*| / 2 when the labels differ,
//                        |D*| = hi - lo + 1 (size of the current set), u_pq
//                        from PairwiseWeights, 4-connected pairs whose two
//                        pixels are both active in the node; a pair whose
//                        other pixel already left the node charges
//                        u_pq |D*| / 2 to the label away from that pixel's
//                        set (our choice, see below).
// The recursion stops when a set holds one level: its pixels get that
// disparity. Nodes with no pixels are dropped.
//
// Implementation choices (not fixed by the thesis; what each was measured against: docs/stereo.md, "HBDS
// implementation notes"):
//  * Source side of the cut = B (background, smaller disparities).
//  * The break point histogram of a node is built from the within-set WTA (argmin of S over [lo, hi], ties to the
//    smaller d) of the node's active pixels - the thesis's rough disparity map restricted to the node - counted from
//    the per-pixel argmins the data term computes anyway.
//  * Per-node work is O(active pixels x set size): every node inherits its pixels' set minimum and argmin from its
//    parent (the root computes them); after psi is known only the side without the argmin needs a pass (d outer,
//    pixels inner, in ascending memory order) and records its argmin for the child.
//  * Whether a neighbour is in the node, or which way it went, is kept per pixel as 2 bits per neighbour
//    (Context::relation): "same node" until the cut that separates the two pixels, which records "above" for the one
//    sent to B and "below" for the one sent to F. Only the node owning both pixels writes them, so the boundary term
//    needs no other node's state and the results do not depend on the schedule.
//  * A node alone at its depth (the root) splits its data-term passes over the thread pool; the max-flow is
//    sequential. Nodes are independent once their parent is cut, so a small pool cuts every queued node as soon as
//    a worker is free, largest first, with no barrier between depths; each worker reuses one MaxFlow.
//  * Overlapping subsets (optional, `overlap` = m levels; 0 = the thesis's disjoint split): B = [lo, psi + m],
//    F = [psi + 1 - m, hi], each kept strictly smaller than [lo, hi], so a pixel whose disparity lies next to the
//    break point can still reach it from either side.
//  * Pairs crossing the layer boundary: a pair {p, q} whose q already left the node charges u_pq |D*| / 2 to the
//    label of p away from q's set (a unary term; |D*| / 2 is the distance between the centres of B and F).
//  * Coarse-to-fine cuts (optional, `coarse` = C): a layer of >= kCoarseMinPixels pixels is cut over C x C blocks,
//    then at full resolution in a one-block band around the blocks' label boundary.
//  * The Eq. 2.5 penalty is not truncated by SmoothParams::truncation (the thesis's V has none); truncation only
//    enters the reported energy, Eq. 2.2 via labellingEnergy(), comparable with alpha-expansion's.
//  * layers = number of hierarchy depths at which at least one cut was solved (ceil(log2(levels)) for a balanced
//    split; 0 when dmin == dmax).
#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"
#include "massage_cell/stereo/energy.h"
#include "massage_cell/stereo/max_flow.h"
#include "massage_cell/stereo/optimizers.h"

namespace massage_cell::stereo {
// PROBE-BEGIN (temporary instrumentation)
struct HbdsProbeCut {
  int depth, lo, hi, psi, b_hi, f_lo, n;
  const int* pixels;
  const float *min_b, *min_f;
  const double *cost_b, *cost_f;
  const std::uint8_t* side;
  const int *arg, *arg_b, *arg_f;
  const double* hist;
};
void (*g_hbds_probe)(const HbdsProbeCut&) = nullptr;
thread_local int g_hbds_depth = 0;
// PROBE-END
namespace {

struct Node {
  int lo = 0, hi = 0;       // disparity set [lo, hi], hi > lo
  std::vector<int> pixels;  // linear indices y * W + x, ascending
  // min of S over [lo, hi] and its argmin (ties: smaller d) per pixel,
  // aligned with `pixels`; inherited from the parent's data-term passes
  // (empty for the root, which computes them).
  std::vector<float> best;
  std::vector<int> arg;
};

// What processing one node produces: the non-trivial children (sets with more
// than one level) in the order B, F. Single-level children are written to the
// disparity map directly.
struct NodeOutput {
  std::vector<Node> children;  // all non-empty children (B, F), incl. single-level ones
};

// Per-worker buffers reused across nodes.
struct Scratch {
  std::vector<float> best;          // min over the whole set [lo, hi]
  std::vector<int> arg;             // its argmin (ties: smaller d): the within-set WTA
  std::vector<float> min_b, min_f;  // D(B), D(F) of Eq. 2.4: min over [lo, b_hi] / [f_lo, hi]
  std::vector<int> arg_b, arg_f;    // their argmins (ties: smaller d)
  std::vector<int> pending;         // node-local indices needing a pass over B, then over F
  std::vector<double> hist;
  std::vector<double> cost_b, cost_f;  // unary of each label: Eq. 2.4 plus the boundary pairs
  std::vector<std::uint8_t> side;      // the cut's answer per node pixel: 1 = B (source)
  std::vector<int> graph_id;           // node pixel -> id in the fine graph, -1: fixed by the coarse cut
  // Coarse cut (Context::coarse > 1): blocks of coarse x coarse pixels.
  std::vector<int> block_of;     // node pixel -> compact block id
  std::vector<int> block_index;  // block grid cell -> compact block id, -1 (all -1 between nodes)
  std::vector<int> block_cell;   // compact block id -> grid cell
  std::vector<double> block_b, block_f, block_right, block_down;
  std::vector<std::uint8_t> block_side, block_band;
  MaxFlow graph;  // reused across the worker's nodes (keeps its memory)
};

struct Context {
  const CostVolume* volume = nullptr;
  const float* u_right = nullptr;  // continuous CV_32F H x W
  const float* u_down = nullptr;
  int width = 0, height = 0;
  int overlap = 0;  // levels each child's set reaches across the break point
  int coarse = 1;   // block side of the coarse cut (1: none)
  int blocks_x = 0, blocks_y = 0;
  // Per pixel, 2 bits per neighbour (kRight, kDown, kLeft, kUp): kSame while
  // both are in one node; at the cut that separates them, the pixel sent to
  // B records its neighbour as kAbove and the one sent to F records kBelow.
  // Written only by the node owning both pixels, read only by a node owning
  // the pixel: no races, and independent of the schedule.
  std::vector<std::uint8_t> relation;
  std::vector<int> index;  // compact graph id of the pixel in its node
  float* disparity = nullptr;
};

// Runs fn(task, worker) for task in [0, count) on up to `threads` threads.
// Tasks are handed out by an atomic counter; the first exception is rethrown.
template <class Fn>
void runParallel(int count, int threads, Fn&& fn) {
  const int workers = std::max(1, std::min(threads, count));
  if (workers == 1) {
    for (int t = 0; t < count; ++t) fn(t, 0);
    return;
  }
  std::atomic<int> next{0};
  std::vector<std::exception_ptr> errors(workers);
  auto body = [&](int worker) {
    try {
      for (int t = next.fetch_add(1); t < count; t = next.fetch_add(1)) fn(t, worker);
    } catch (...) {
      errors[worker] = std::current_exception();
      next.store(count);  // stop handing out work
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  for (int w = 1; w < workers; ++w) pool.emplace_back(body, w);
  body(0);
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
}

enum : unsigned { kSame = 0, kAbove = 1, kBelow = 2 };
enum Direction { kRight = 0, kDown = 1, kLeft = 2, kUp = 3 };
inline unsigned relationOf(const Context& ctx, int p, Direction dir) {
  return (ctx.relation[static_cast<std::size_t>(p)] >> (2 * dir)) & 3u;
}
inline void setRelation(Context& ctx, int p, Direction dir, unsigned value) {
  std::uint8_t& r = ctx.relation[static_cast<std::size_t>(p)];
  r = static_cast<std::uint8_t>((r & ~(3u << (2 * dir))) | (value << (2 * dir)));
}

void assignLevel(Context& ctx, const std::vector<int>& pixels, int d) {
  const float value = static_cast<float>(d);
  for (int p : pixels) ctx.disparity[p] = value;
}

// Calls fn(q, dir, u_pq, forward) for each 4-neighbour q of pixel p inside
// the image; forward: q is p's right or lower neighbour (each pair once).
template <class Fn>
inline void forEachNeighbour(const Context& ctx, int p, Fn&& fn) {
  const int W = ctx.width, N = ctx.width * ctx.height, x = p % W;
  if (x + 1 < W) fn(p + 1, kRight, ctx.u_right[p], true);
  if (p + W < N) fn(p + W, kDown, ctx.u_down[p], true);
  if (x > 0) fn(p - 1, kLeft, ctx.u_right[p - 1], false);
  if (p >= W) fn(p - W, kUp, ctx.u_down[p - W], false);
}

// The two labels' unaries of each node pixel: Eq. 2.4's D(B), D(F) plus, for
// a pair whose other pixel already left the node, u_pq |D*| / 2 on the label
// away from that pixel's set.
void unaries(const Context& ctx, const Node& node, double half, Scratch& s) {
  const int n = static_cast<int>(node.pixels.size());
  s.cost_b.resize(n);
  s.cost_f.resize(n);
  for (int i = 0; i < n; ++i) {
    const int p = node.pixels[i];
    double uB = 0.0, uF = 0.0;
    forEachNeighbour(ctx, p, [&](int, Direction dir, float u, bool) {
      const unsigned rel = relationOf(ctx, p, dir);
      if (rel == kAbove)
        uB += u;
      else if (rel == kBelow)
        uF += u;
    });
    s.cost_b[i] = s.min_b[i] + half * uB;
    s.cost_f[i] = s.min_f[i] + half * uF;
  }
}

// One binary cut over the node pixels with graph_id >= 0; the others keep
// their s.side and charge each free neighbour u_pq |D*| / 2 for the other
// label. Source side = B: a pixel on the source side cuts its sink edge, so
// the sink capacity is its B unary and the source capacity its F unary.
void cutPixels(const Context& ctx, const Node& node, double half, int free_count, Scratch& s) {
  const int n = static_cast<int>(node.pixels.size());
  MaxFlow& graph = s.graph;
  graph.reset(free_count, 2 * free_count);
  graph.addNodes(free_count);
  for (int i = 0; i < n; ++i) {
    const int id = s.graph_id[i];
    if (id < 0) continue;
    double cb = s.cost_b[i], cf = s.cost_f[i];
    const int p = node.pixels[i];
    forEachNeighbour(ctx, p, [&](int q, Direction dir, float u, bool forward) {
      if (u <= 0.0f || relationOf(ctx, p, dir) != kSame) return;  // not in the node, or no pair term
      const int j = ctx.index[q];
      const int jd = s.graph_id[j];
      if (jd >= 0) {
        if (forward) graph.addEdge(id, jd, u * half, u * half);
      } else if (s.side[j]) {
        cf += u * half;  // q fixed in B: F pays the pair
      } else {
        cb += u * half;
      }
    });
    const double m = std::min(cb, cf);
    graph.addTerminalWeights(id, cf - m, cb - m);
  }
  graph.solve();
  for (int i = 0; i < n; ++i)
    if (s.graph_id[i] >= 0) s.side[i] = graph.isSource(s.graph_id[i]) ? 1 : 0;
}

// Coarse to fine (Context::coarse = c > 1): the node's pixels are grouped in
// c x c blocks and one cut over the blocks (each block's unaries summed, and
// the pairs between two blocks summed into one edge) labels every block; the
// pixels of blocks more than one block away from a block of the other label
// take their block's label, and the rest (the band around the boundary) are
// left to the fine cut: their graph_id is set, and the count is returned.
int coarseCut(const Context& ctx, const Node& node, double half, Scratch& s) {
  const int n = static_cast<int>(node.pixels.size());
  const int c = ctx.coarse, W = ctx.width, BW = ctx.blocks_x, BH = ctx.blocks_y;
  if (s.block_index.empty()) s.block_index.assign(static_cast<std::size_t>(BW) * BH, -1);
  s.block_cell.clear();
  s.block_of.resize(n);
  for (int i = 0; i < n; ++i) {
    const int p = node.pixels[i];
    const int cell = (p / W / c) * BW + (p % W) / c;
    int& b = s.block_index[cell];
    if (b < 0) {
      b = static_cast<int>(s.block_cell.size());
      s.block_cell.push_back(cell);
    }
    s.block_of[i] = b;
  }
  const int nb = static_cast<int>(s.block_cell.size());
  s.block_b.assign(nb, 0.0);
  s.block_f.assign(nb, 0.0);
  s.block_right.assign(nb, 0.0);
  s.block_down.assign(nb, 0.0);
  for (int i = 0; i < n; ++i) {
    const int b = s.block_of[i], p = node.pixels[i];
    s.block_b[b] += s.cost_b[i];
    s.block_f[b] += s.cost_f[i];
    forEachNeighbour(ctx, p, [&](int q, Direction dir, float u, bool forward) {
      if (!forward || u <= 0.0f || relationOf(ctx, p, dir) != kSame) return;
      if (s.block_of[ctx.index[q]] == b) return;  // inside the block
      (dir == kRight ? s.block_right : s.block_down)[b] += u * half;
    });
  }
  MaxFlow& graph = s.graph;
  graph.reset(nb, 2 * nb);
  graph.addNodes(nb);
  for (int b = 0; b < nb; ++b) {
    const int cell = s.block_cell[b];
    if (s.block_right[b] > 0.0) graph.addEdge(b, s.block_index[cell + 1], s.block_right[b], s.block_right[b]);
    if (s.block_down[b] > 0.0) graph.addEdge(b, s.block_index[cell + BW], s.block_down[b], s.block_down[b]);
    const double m = std::min(s.block_b[b], s.block_f[b]);
    graph.addTerminalWeights(b, s.block_f[b] - m, s.block_b[b] - m);
  }
  graph.solve();
  s.block_side.resize(nb);
  for (int b = 0; b < nb; ++b) s.block_side[b] = graph.isSource(b) ? 1 : 0;

  // The band: blocks with a 4-neighbour block of the other label, grown by
  // one block (8-neighbourhood).
  auto blockAt = [&](int bx, int by) {
    return bx < 0 || by < 0 || bx >= BW || by >= BH ? -1 : s.block_index[by * BW + bx];
  };
  s.block_band.assign(nb, 0);
  for (int b = 0; b < nb; ++b) {
    const int bx = s.block_cell[b] % BW, by = s.block_cell[b] / BW;
    bool edge = false;
    for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
      const int o = blockAt(bx + dx, by + dy);
      edge = edge || (o >= 0 && s.block_side[o] != s.block_side[b]);
    }
    if (!edge) continue;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int o = blockAt(bx + dx, by + dy);
        if (o >= 0) s.block_band[o] = 1;
      }
  }
  int free_count = 0;
  for (int i = 0; i < n; ++i) {
    const int b = s.block_of[i];
    if (s.block_band[b]) {
      s.graph_id[i] = free_count++;
    } else {
      s.graph_id[i] = -1;
      s.side[i] = s.block_side[b];
    }
  }
  for (int cell : s.block_cell) s.block_index[cell] = -1;  // clean for the worker's next node
  return free_count;
}

// Smallest pixel chunk worth a thread of its own in the data-term passes.
constexpr int kMinChunk = 16384;
// Smallest node cut coarse to fine (Context::coarse > 1): smaller cuts are fast.
constexpr int kCoarseMinPixels = 8192;

/// Start of chunk c of `chunks` equal chunks of `total` items.
std::size_t chunkBegin(int c, int chunks, std::size_t total) { return total * static_cast<std::size_t>(c) / chunks; }

// Pass 1: min over [lo, hi] and its argmin (ties: smaller d), per pixel. Children inherit them from their
// parent's passes (the minimum over a subset and its argmin are what the parent computed for that side), so only
// the root runs this pass. Pixel chunks are independent: `chunks` of them in parallel.
void setMinima(const Context& ctx, const Node& node, int chunks, Scratch& s) {
  const int n = static_cast<int>(node.pixels.size());
  if (!node.best.empty()) {
    s.best.assign(node.best.begin(), node.best.end());
    s.arg.assign(node.arg.begin(), node.arg.end());
    return;
  }
  const CostVolume& vol = *ctx.volume;
  s.best.resize(n);
  s.arg.resize(n);
  runParallel(chunks, chunks, [&](int c, int) {
    const int i0 = static_cast<int>(chunkBegin(c, chunks, n)), i1 = static_cast<int>(chunkBegin(c + 1, chunks, n));
    const int* px = node.pixels.data();
    float* best = s.best.data();
    int* arg = s.arg.data();
    const float* sl = vol.slice(node.lo);
    for (int i = i0; i < i1; ++i) {
      best[i] = sl[px[i]];
      arg[i] = node.lo;
    }
    for (int d = node.lo + 1; d <= node.hi; ++d) {
      sl = vol.slice(d);
      for (int i = i0; i < i1; ++i) {
        const float cost = sl[px[i]];
        if (cost < best[i]) {
          best[i] = cost;
          arg[i] = d;
        }
      }
    }
  });
}

// Pass 2 (Eq. 2.4): each pixel's minimum over B = [lo, b_hi] and over F = [f_lo, hi]. A side holding the set's
// argmin has min = best and the same argmin; the other side's minimum is computed only for the pixels that need it
// (with overlap, a pixel whose argmin lies in both sets needs no pass at all).
void setSideMinima(const Context& ctx, const Node& node, int b_hi, int f_lo, int chunks, Scratch& s) {
  const CostVolume& vol = *ctx.volume;
  const int n = static_cast<int>(node.pixels.size());
  s.min_b.resize(n);
  s.arg_b.resize(n);
  s.min_f.resize(n);
  s.arg_f.resize(n);
  s.pending.clear();
  for (int i = 0; i < n; ++i) {
    if (s.arg[i] <= b_hi) {
      s.min_b[i] = s.best[i];
      s.arg_b[i] = s.arg[i];
    } else {
      s.pending.push_back(i);  // needs min over B
    }
  }
  const std::size_t needB = s.pending.size();
  for (int i = 0; i < n; ++i) {
    if (s.arg[i] >= f_lo) {
      s.min_f[i] = s.best[i];
      s.arg_f[i] = s.arg[i];
    } else {
      s.pending.push_back(i);  // needs min over F
    }
  }
  auto sideMin = [&](std::size_t begin, std::size_t end, int d0, int d1, float* out, int* out_arg) {
    const int* pend = s.pending.data();
    const int* px = node.pixels.data();
    const float* sl = vol.slice(d0);
    for (std::size_t k = begin; k < end; ++k) {
      out[pend[k]] = sl[px[pend[k]]];
      out_arg[pend[k]] = d0;
    }
    for (int d = d0 + 1; d <= d1; ++d) {
      sl = vol.slice(d);
      for (std::size_t k = begin; k < end; ++k) {
        const int i = pend[k];
        const float cost = sl[px[i]];
        if (cost < out[i]) {
          out[i] = cost;
          out_arg[i] = d;
        }
      }
    }
  };
  runParallel(chunks, chunks, [&](int c, int) {
    sideMin(chunkBegin(c, chunks, needB), chunkBegin(c + 1, chunks, needB), node.lo, b_hi, s.min_b.data(),
            s.arg_b.data());
    const std::size_t needF = s.pending.size() - needB;
    sideMin(needB + chunkBegin(c, chunks, needF), needB + chunkBegin(c + 1, chunks, needF), f_lo, node.hi,
            s.min_f.data(), s.arg_f.data());
  });
}

// The two children of a cut node (source side = B), each inheriting its side's minimum and argmin (pass 1 of the
// child); and the relation bits of every pair the cut separates (both pixels are the node's).
void splitNode(Context& ctx, const Node& node, int b_hi, int f_lo, const Scratch& s, NodeOutput& out) {
  const std::vector<int>& pix = node.pixels;
  const int n = static_cast<int>(pix.size());
  Node back, fore;
  back.pixels.reserve(n);
  fore.pixels.reserve(n);
  for (Node* child : {&back, &fore}) {
    child->best.reserve(n);
    child->arg.reserve(n);
  }
  back.lo = node.lo;
  back.hi = b_hi;
  fore.lo = f_lo;
  fore.hi = node.hi;
  const bool inherit_back = b_hi > node.lo, inherit_fore = node.hi > f_lo;  // single-level children need none
  for (int i = 0; i < n; ++i) {
    const bool to_back = s.side[i] != 0;
    Node& child = to_back ? back : fore;
    child.pixels.push_back(pix[i]);
    if (to_back ? !inherit_back : !inherit_fore) continue;
    child.best.push_back(to_back ? s.min_b[i] : s.min_f[i]);
    child.arg.push_back(to_back ? s.arg_b[i] : s.arg_f[i]);
  }
  const int W = ctx.width, N = ctx.width * ctx.height;
  for (int i = 0; i < n; ++i) {
    const int p = pix[i];
    const bool p_back = s.side[i] != 0;
    auto separate = [&](int q, Direction dir, Direction back_dir) {
      if (relationOf(ctx, p, dir) != kSame) return;
      const bool q_back = s.side[ctx.index[q]] != 0;
      if (q_back == p_back) return;
      setRelation(ctx, p, dir, p_back ? kAbove : kBelow);
      setRelation(ctx, q, back_dir, p_back ? kBelow : kAbove);
    };
    if (p % W + 1 < W) separate(p + 1, kRight, kLeft);
    if (p + W < N) separate(p + W, kDown, kUp);
  }
  out.children.clear();
  for (Node* child : {&back, &fore})
    if (!child->pixels.empty()) out.children.push_back(std::move(*child));
}

// One bilateral disparity estimation (Eq. 2.3) on `node`; the compact index of
// the node's pixels must already be set and their relation bits must be those
// left by the node's ancestors. `helpers`: threads available to this node's
// data-term passes (the graph cut itself is sequential).
void processNode(Context& ctx, const Node& node, int helpers, Scratch& s, NodeOutput& out) {
  const int n = static_cast<int>(node.pixels.size());
  const int lo = node.lo, hi = node.hi;
  // A node solved alone at its depth (the root) splits its pixel chunks over `helpers` threads.
  const int chunks = std::max(1, std::min(helpers, n / kMinChunk));
  setMinima(ctx, node, chunks, s);

  // Break point (Eq. 2.9-2.10) on the rough within-set WTA histogram.
  s.hist.assign(static_cast<std::size_t>(hi - lo + 1), 0.0);
  for (int i = 0; i < n; ++i) s.hist[s.arg[i] - lo] += 1.0;
  const int psi = breakPoint(s.hist, lo, hi);
  if (psi < lo || psi >= hi) throw std::logic_error("hbds: breakPoint returned psi outside [lo, hi)");

  // The children's sets: B = [lo, b_hi], F = [f_lo, hi]. Without overlap
  // they split [lo, hi] at psi (the thesis); with overlap m they both reach m
  // levels across it (b_hi = psi + m, f_lo = psi + 1 - m), each kept strictly
  // smaller than [lo, hi] so that the recursion ends.
  const int b_hi = std::min(psi + ctx.overlap, hi - 1);
  const int f_lo = std::max(psi + 1 - ctx.overlap, lo + 1);
  setSideMinima(ctx, node, b_hi, f_lo, chunks, s);

  // The cut (source side = B), on every pixel or coarse to fine.
  const double half = 0.5 * static_cast<double>(hi - lo + 1);  // |D*| / 2 of Eq. 2.5
  unaries(ctx, node, half, s);
  s.side.resize(n);
  s.graph_id.resize(n);
  int free_count = n;
  if (ctx.coarse > 1 && n >= kCoarseMinPixels) {
    free_count = coarseCut(ctx, node, half, s);
  } else {
    for (int i = 0; i < n; ++i) s.graph_id[i] = i;
  }
  if (free_count > 0) cutPixels(ctx, node, half, free_count, s);
  if (g_hbds_probe)  // PROBE
    g_hbds_probe({g_hbds_depth, lo, hi, psi, b_hi, f_lo, n, node.pixels.data(), s.min_b.data(), s.min_f.data(),
                  s.cost_b.data(), s.cost_f.data(), s.side.data(), s.arg.data(), s.arg_b.data(), s.arg_f.data(),
                  s.hist.data()});  // PROBE
  splitNode(ctx, node, b_hi, f_lo, s, out);
}

// Cuts the whole hierarchy from the root [dmin, dmax] down to single levels, writing ctx.disparity. Nodes of any
// depth run as soon as their parent is cut (no barrier per depth), largest first, on `threads` workers (this thread
// is worker 0); the schedule does not influence the results.
void cutHierarchy(Context& ctx, int threads, OptimizerResult& result) {
  const CostVolume& volume = *ctx.volume;
  const std::size_t N = static_cast<std::size_t>(ctx.width) * ctx.height;
  struct Task {
    Node node;
    int depth = 0;
  };
  // Nodes waiting to be cut, largest first (ties: the order of arrival;
  // the schedule does not influence the results).
  std::vector<Task> queue;
  std::mutex mutex;
  std::condition_variable wake;
  int busy = 0;        // nodes being processed
  int max_depth = -1;  // deepest node cut so far
  bool failed = false;
  std::exception_ptr error;
  std::vector<Scratch> scratch(threads);

  Task root;
  root.node.lo = volume.dmin();
  root.node.hi = volume.dmax();
  root.node.pixels.resize(N);
  for (std::size_t p = 0; p < N; ++p) root.node.pixels[p] = static_cast<int>(p);
  queue.push_back(std::move(root));

  // Cuts one node, then writes the final disparity of single-level
  // children and queues the others. Correctness of running nodes
  // concurrently: a node reads and writes only data of its own pixels (their
  // compact index, their relation bits, their inherited minima); a
  // neighbour outside the node is known through the relation bits the
  // ancestor that separated them wrote before this node was queued.
  auto runTask = [&](Task& task, int worker, int helpers, std::vector<Task>& children) {
    const Node& node = task.node;
    for (std::size_t i = 0; i < node.pixels.size(); ++i) ctx.index[node.pixels[i]] = static_cast<int>(i);
    NodeOutput out;
    g_hbds_depth = task.depth;  // PROBE
    processNode(ctx, node, helpers, scratch[worker], out);
    for (Node& child : out.children) {
      if (child.lo == child.hi) {
        assignLevel(ctx, child.pixels, child.lo);
      } else {
        Task t;
        t.node = std::move(child);
        t.depth = task.depth + 1;
        children.push_back(std::move(t));
      }
    }
  };
  auto bySize = [](const Task& a, const Task& b) { return a.node.pixels.size() < b.node.pixels.size(); };
  auto body = [&](int worker) {
    std::vector<Task> children;
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      wake.wait(lock, [&] { return failed || !queue.empty() || busy == 0; });
      if (failed || queue.empty()) break;  // error, or nothing queued and nothing running: done
      // Largest waiting node; stable among equal sizes (first queued).
      auto it = queue.begin();
      for (auto j = queue.begin(); j != queue.end(); ++j)
        if (bySize(*it, *j)) it = j;
      Task task = std::move(*it);
      queue.erase(it);
      ++busy;
      // A node started while nothing else can run (the root) shares its
      // data-term passes with the idle threads.
      const int helpers = (busy == 1 && queue.empty()) ? threads : 1;
      lock.unlock();
      children.clear();
      try {
        runTask(task, worker, helpers, children);
      } catch (...) {
        lock.lock();
        if (!failed) error = std::current_exception();
        failed = true;
        --busy;
        wake.notify_all();
        break;
      }
      lock.lock();
      --busy;
      ++result.cuts;
      max_depth = std::max(max_depth, task.depth);
      for (Task& c : children) queue.push_back(std::move(c));
      wake.notify_all();
    }
  };
  // Nodes of any depth run as soon as their parent is cut (no barrier per
  // depth), on `threads` workers (this thread is worker 0).
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int w = 1; w < threads; ++w) pool.emplace_back(body, w);
  body(0);
  for (auto& th : pool) th.join();
  result.layers = max_depth + 1;
  if (error) std::rethrow_exception(error);
}

}  // namespace

OptimizerResult hbds(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth, int threads,
                     int overlap, int coarse) {
  const int W = volume.width(), H = volume.height();
  if (W <= 0 || H <= 0) throw std::invalid_argument("hbds: empty cost volume");
  const cv::Size size(W, H);
  if (weights.right.size() != size || weights.down.size() != size || weights.right.type() != CV_32F ||
      weights.down.type() != CV_32F)
    throw std::invalid_argument("hbds: pairwise weights must be CV_32F of the cost volume's size");
  if (threads < 0) throw std::invalid_argument("hbds: threads must be >= 0");
  if (overlap < 0) throw std::invalid_argument("hbds: overlap must be >= 0");
  if (coarse < 1 || coarse > 8) throw std::invalid_argument("hbds: coarse must be in 1..8");
  if (threads == 0) threads = std::max(1, cv::getNumberOfCPUs());

  // Continuous copies only if needed (ROIs).
  const cv::Mat u_right = weights.right.isContinuous() ? weights.right : weights.right.clone();
  const cv::Mat u_down = weights.down.isContinuous() ? weights.down : weights.down.clone();

  OptimizerResult result;
  result.disparity = cv::Mat(H, W, CV_32F, cv::Scalar(static_cast<float>(volume.dmin())));

  Context ctx;
  ctx.volume = &volume;
  ctx.u_right = u_right.ptr<float>();
  ctx.u_down = u_down.ptr<float>();
  ctx.width = W;
  ctx.height = H;
  const std::size_t N = static_cast<std::size_t>(W) * H;
  ctx.overlap = overlap;
  ctx.coarse = coarse;
  ctx.blocks_x = (W + coarse - 1) / coarse;
  ctx.blocks_y = (H + coarse - 1) / coarse;
  ctx.relation.assign(N, 0);
  ctx.index.assign(N, 0);
  ctx.disparity = result.disparity.ptr<float>();

  if (volume.dmin() < volume.dmax()) cutHierarchy(ctx, threads, result);

  result.energy = labellingEnergy(volume, weights, result.disparity, smooth.truncation);
  return result;
}

}  // namespace massage_cell::stereo
