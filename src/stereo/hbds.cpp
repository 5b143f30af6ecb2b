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
// Implementation choices (not fixed by the thesis):
//  * Source side of the cut = B (background, smaller disparities).
//  * The break point histogram of a node is built from the within-set WTA
//    (argmin of S over [lo, hi], ties to the smaller d, as winnerTakesAll())
//    of the node's active pixels, i.e. the thesis' "rough disparity map"
//    restricted to the node. It is counted directly from the per-pixel argmins
//    computed for the data term (same result as disparityHistogram() of that
//    rough map masked to the node, without an image-sized pass per node).
//    Evaluated alternative (not kept): histograms of the whole-volume WTA
//    restricted to [lo, hi]. Over a 69-setting (u_max, u_min, tau) sweep on
//    Tsukuba/Venus/Teddy/Cones the mean bad>1px moved from 12.59 % to
//    12.38 % and the best setting from 9.18 % to 9.16 %: no real gain, so
//    the thesis' within-layer rough map stays.
//  * Per-node work is O(active pixels x set size): the set minimum and its
//    argmin of every pixel are known (the root computes them in one pass over
//    d in [lo, hi]; every other node inherits them from its parent, for which
//    they were the minimum and argmin of one side); after psi is known the side
//    holding the argmin already has its minimum, so one pass only visits the
//    other side (d outer, pixels inner, so each slice is read in ascending
//    memory order; pixel lists are kept sorted) and records its argmin for the
//    child. Compared with recomputing each node's pass: same results (ties go
//    to the smaller d either way), a third less work over the volume.
//  * Active pixels are mapped to compact graph ids with a reusable index
//    image. Per-pixel set_lo / set_hi images hold every pixel's current
//    disparity set (its node's set, or [d, d] once finished); they are written
//    in a separate phase after all nodes of a depth are cut, so a node only
//    reads stable values. A neighbour belongs to the node iff its set overlaps
//    [lo, hi] (sets of one depth are disjoint intervals).
//  * A node alone at its depth (the root) splits its two data-term passes
//    over pixel chunks on the thread pool; the max-flow is sequential.
//  * Nodes are independent once their parent is cut (disjoint pixels and
//    disjoint disparity sets; a neighbour outside the node is above or below
//    the node's set whatever refinement it has reached), so a small
//    std::thread pool cuts every queued node as soon as a worker is free,
//    largest first, with no barrier between depths. Each worker reuses one
//    MaxFlow (MaxFlow::reset keeps its memory). Results are independent of
//    the thread count and the schedule (every node is processed identically).
//  * Our choice — pairs crossing the layer boundary (evaluated, kept). The
//    thesis's Eq. 2.3 sums V over the pairs of the layer P^B / P^F being
//    split and says nothing about a pair {p, q} whose q was already sent to
//    another layer (q's set lies entirely above hi or below lo). Ignoring such
//    pairs (the previous implementation) lets the cut move p away from q for
//    free although Eq. 2.2 will charge u_pq |d_p - d_q|. We keep Eq. 2.5 and
//    treat q as a pixel whose bilateral label is fixed to the side nearer its
//    set: the label away from q pays u_pq |D*| / 2 (a unary term; q above:
//    added to D_p(B), q below: added to D_p(F)). |D*| / 2 is exactly the
//    distance between the centres of B = [lo, psi] and F = [psi + 1, hi]
//    for every psi, i.e. the change of u_pq |d_p - d_q| in Eq. 2.2 between
//    the two labels when d_p sits at its subset's centre. Measured (defaults,
//    bad>1px nonocc Tsukuba / Venus / Teddy / Cones; energy / alpha-expansion's):
//    without 3.36 / 1.86 / 10.24 / 5.40 (mean 5.22), energy 1.040 / 1.020 /
//    1.069 / 1.071; with 3.38 / 1.67 / 9.92 / 5.38 (mean 5.09), energy
//    1.029 / 1.013 / 1.048 / 1.050. Cost: two more neighbour reads per pixel.
//  * Evaluated, not kept (noise-level or mixed; all with the boundary term
//    above, mean bad>1px of the four scenes; baseline 5.09, energy ratio
//    1.035): break point histogram counts weighted by confidence 1 - min S
//    (5.09, 1.035); histogram smoothed by a 3- / 5-level box before Otsu and
//    the valley search (5.36 / 5.01, 1.038 / 1.034; Tsukuba 4.72 with the
//    3-level box, Teddy worse with the 5-level one); rough map = WTA of the
//    box-aggregated (3x3 .. 11x11) cost volume, restricted to the node's
//    pixels whose aggregated WTA falls in [lo, hi] with or without the
//    within-set WTA as fallback (4.90 .. 5.22 depending on the box, no
//    consistent winner, energy 1.036 .. 1.037, +20 ms); the thesis's literal
//    split B = [lo, psi - 1], F = [psi, hi] (valley level to F): 5.24, 1.038.
//  * Evaluated, not kept (2026-11): a smooth term from the jump the two
//    subset argmins imply (the Eq. 2.2 cost of the labels Eq. 2.4 assumes):
//    a pair cut with p in B and q in F pays u_pq (f_q - b_p), b / f the
//    argmins of S over B / F (asymmetric arcs, always submodular). Pure HBDS
//    energy / alpha-expansion's fell from 1.048 / 1.050 to 1.022 / 1.022
//    (Teddy / Cones); clamped at |D*| / 2: 1.020 / 1.019; but bad>1px moved
//    3.38 / 1.67 / 9.92 / 5.38 -> 3.42 / 2.34 / 9.38 / 5.68 (clamped 3.23 /
//    2.45 / 9.35 / 5.63): Venus's texture-poor slanted planes get noisy
//    argmins and too weak a coupling. Eq. 2.5 stays; the energy gap is
//    closed instead by the optional local-expansion polish (pipeline.h).
//  * The Eq. 2.5 penalty is not truncated by SmoothParams::truncation (the
//    thesis' V has no truncation); truncation only enters the reported
//    energy, which is Eq. 2.2 via labellingEnergy() so it is comparable with
//    alpha-expansion.
//  * layers = number of hierarchy depths at which at least one cut was
//    solved (ceil(log2(levels)) for a balanced split; 0 when dmin == dmax).
#include <algorithm>
#include <atomic>
#include <condition_variable>
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
  std::vector<float> best;   // min over the whole set, then D(B) / D(F)
  std::vector<float> other;  // min over the side not holding the argmin
  std::vector<int> other_arg;  // its argmin (ties: smaller d)
  std::vector<int> arg;      // within-set WTA argmin
  std::vector<int> pending;  // node-local indices needing the other side
  std::vector<double> hist;
  MaxFlow graph;  // reused across the worker's nodes (keeps its memory)
};

struct Context {
  const CostVolume* volume = nullptr;
  const float* u_right = nullptr;  // continuous CV_32F H x W
  const float* u_down = nullptr;
  int width = 0, height = 0;
  // Current disparity set of every pixel. Atomic (relaxed) because a node
  // reads its neighbours' sets while other nodes may be refining theirs.
  std::unique_ptr<std::atomic<int>[]> set_lo, set_hi;
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

void assignLevel(Context& ctx, const std::vector<int>& pixels, int d) {
  const float value = static_cast<float>(d);
  for (int p : pixels) ctx.disparity[p] = value;
}

// One bilateral disparity estimation (Eq. 2.3) on `node`; the compact index of
// the node's pixels must already be set and set_lo / set_hi must hold every
// pixel's current disparity set. `helpers`: threads available to this
// node's data-term passes (the graph cut itself is sequential).
// Smallest pixel chunk worth a thread of its own in the data-term passes.
constexpr int kMinChunk = 16384;

void processNode(Context& ctx, const Node& node, int helpers, Scratch& s, NodeOutput& out) {
  const CostVolume& vol = *ctx.volume;
  const std::vector<int>& pix = node.pixels;
  const int n = static_cast<int>(pix.size());
  const int lo = node.lo, hi = node.hi;

  // Pass 1: min over [lo, hi] and its argmin (ties: smaller d), per pixel.
  // Children inherit them from their parent's passes (the minimum over a
  // subset and its argmin are what the parent computed for that side), so
  // only the root runs this pass. Pixel chunks are independent; a node solved
  // alone at its depth (the root) splits them over `helpers` threads.
  const int chunks = std::max(1, std::min(helpers, n / kMinChunk));
  auto chunkBegin = [&](int c, std::size_t total) { return total * static_cast<std::size_t>(c) / chunks; };
  if (!node.best.empty()) {
    s.best.assign(node.best.begin(), node.best.end());
    s.arg.assign(node.arg.begin(), node.arg.end());
  } else {
    s.best.resize(n);
    s.arg.resize(n);
    runParallel(chunks, chunks, [&](int c, int) {
      const int i0 = static_cast<int>(chunkBegin(c, n)), i1 = static_cast<int>(chunkBegin(c + 1, n));
      const int* px = pix.data();
      float* best = s.best.data();
      int* arg = s.arg.data();
      const float* sl = vol.slice(lo);
      for (int i = i0; i < i1; ++i) {
        best[i] = sl[px[i]];
        arg[i] = lo;
      }
      for (int d = lo + 1; d <= hi; ++d) {
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

  // Break point (Eq. 2.9-2.10) on the rough within-set WTA histogram.
  s.hist.assign(static_cast<std::size_t>(hi - lo + 1), 0.0);
  for (int i = 0; i < n; ++i) s.hist[s.arg[i] - lo] += 1.0;
  const int psi = breakPoint(s.hist, lo, hi);
  if (psi < lo || psi >= hi) throw std::logic_error("hbds: breakPoint returned psi outside [lo, hi)");

  // Pass 2 (Eq. 2.4): the side holding the argmin has min = best; the other
  // side's minimum is computed only for the pixels that need it.
  s.other.resize(n);
  s.other_arg.resize(n);
  s.pending.clear();
  for (int i = 0; i < n; ++i)
    if (s.arg[i] <= psi) s.pending.push_back(i);  // needs min over F
  const std::size_t needF = s.pending.size();
  for (int i = 0; i < n; ++i)
    if (s.arg[i] > psi) s.pending.push_back(i);  // needs min over B
  auto sideMin = [&](std::size_t begin, std::size_t end, int d0, int d1) {
    const int* pend = s.pending.data();
    const int* px = pix.data();
    float* other = s.other.data();
    int* other_arg = s.other_arg.data();
    const float* sl = vol.slice(d0);
    for (std::size_t k = begin; k < end; ++k) {
      other[pend[k]] = sl[px[pend[k]]];
      other_arg[pend[k]] = d0;
    }
    for (int d = d0 + 1; d <= d1; ++d) {
      sl = vol.slice(d);
      for (std::size_t k = begin; k < end; ++k) {
        const int i = pend[k];
        const float cost = sl[px[i]];
        if (cost < other[i]) {
          other[i] = cost;
          other_arg[i] = d;
        }
      }
    }
  };
  runParallel(chunks, chunks, [&](int c, int) {
    sideMin(chunkBegin(c, needF), chunkBegin(c + 1, needF), psi + 1, hi);
    const std::size_t needB = s.pending.size() - needF;
    sideMin(needF + chunkBegin(c, needB), needF + chunkBegin(c + 1, needB), lo, psi);
  });

  // Graph: source side = B. A node on the source side cuts its sink edge, so
  // the sink capacity is D(B) and the source capacity D(F).
  const double half = 0.5 * static_cast<double>(hi - lo + 1);  // |D*| / 2 of Eq. 2.5
  const int W = ctx.width;
  const int N = ctx.width * ctx.height;
  MaxFlow& graph = s.graph;
  graph.reset(n, 2 * n);
  graph.addNodes(n);
  const std::atomic<int>* setLo = ctx.set_lo.get();
  const std::atomic<int>* setHi = ctx.set_hi.get();
  for (int i = 0; i < n; ++i) {
    const bool inB = s.arg[i] <= psi;
    double dB = inB ? s.best[i] : s.other[i];
    double dF = inB ? s.other[i] : s.best[i];
    const int p = pix[i];
    const int x = p % W;
    double uB = 0.0, uF = 0.0;  // boundary pairs: penalty of the side away from q
    auto neighbour = [&](int q, float u, bool forward) {
      if (setLo[q].load(std::memory_order_relaxed) > hi) uB += u;
      else if (setHi[q].load(std::memory_order_relaxed) < lo) uF += u;
      else if (forward && u > 0) graph.addEdge(i, ctx.index[q], u * half, u * half);
    };
    if (x + 1 < W) neighbour(p + 1, ctx.u_right[p], true);
    if (p + W < N) neighbour(p + W, ctx.u_down[p], true);
    if (x > 0) neighbour(p - 1, ctx.u_right[p - 1], false);
    if (p >= W) neighbour(p - W, ctx.u_down[p - W], false);
    dB += half * uB;
    dF += half * uF;
    const double m = std::min(dB, dF);
    graph.addTerminalWeights(i, dF - m, dB - m);
  }
  graph.solve();

  Node back, fore;
  back.pixels.reserve(n);
  fore.pixels.reserve(n);
  for (Node* child : {&back, &fore}) {
    child->best.reserve(n);
    child->arg.reserve(n);
  }
  back.lo = lo;
  back.hi = psi;
  fore.lo = psi + 1;
  fore.hi = hi;
  // Each child inherits its side's minimum and argmin (pass 1 of the child).
  const bool inherit_back = psi > lo, inherit_fore = hi > psi + 1;  // single-level children need none
  for (int i = 0; i < n; ++i) {
    const bool to_back = graph.isSource(i);
    Node& child = to_back ? back : fore;
    child.pixels.push_back(pix[i]);
    if (to_back ? !inherit_back : !inherit_fore) continue;
    const bool arg_in_back = s.arg[i] <= psi;  // the side holding the set's argmin has it as its own
    const bool own = arg_in_back == to_back;
    child.best.push_back(own ? s.best[i] : s.other[i]);
    child.arg.push_back(own ? s.arg[i] : s.other_arg[i]);
  }

  out.children.clear();
  for (Node* child : {&back, &fore})
    if (!child->pixels.empty()) out.children.push_back(std::move(*child));
}

}  // namespace

OptimizerResult hbds(const CostVolume& volume, const PairwiseWeights& weights, const SmoothParams& smooth,
                     int threads) {
  const int W = volume.width(), H = volume.height();
  if (W <= 0 || H <= 0) throw std::invalid_argument("hbds: empty cost volume");
  const cv::Size size(W, H);
  if (weights.right.size() != size || weights.down.size() != size || weights.right.type() != CV_32F ||
      weights.down.type() != CV_32F)
    throw std::invalid_argument("hbds: pairwise weights must be CV_32F of the cost volume's size");
  if (threads < 0) throw std::invalid_argument("hbds: threads must be >= 0");
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
  ctx.set_lo.reset(new std::atomic<int>[N]);
  ctx.set_hi.reset(new std::atomic<int>[N]);
  for (std::size_t p = 0; p < N; ++p) {
    ctx.set_lo[p].store(volume.dmin(), std::memory_order_relaxed);
    ctx.set_hi[p].store(volume.dmax(), std::memory_order_relaxed);
  }
  ctx.index.assign(N, 0);
  ctx.disparity = result.disparity.ptr<float>();

  if (volume.dmin() < volume.dmax()) {
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

    // Cuts one node, then publishes its children's sets (and the final
    // disparity of single-level children) before queueing the non-trivial
    // ones. Correctness of running nodes concurrently: a node only reads the
    // compact index of its own pixels, and the sets of its neighbours; a
    // neighbour outside the node lies in a set disjoint from the node's
    // parent's set, so every version of its set (it may be refined at any
    // time) is entirely above or entirely below the node's set, which is all
    // the boundary term looks at. Pixels of the node itself got their sets
    // from the parent before the node was queued.
    auto runTask = [&](Task& task, int worker, int helpers, std::vector<Task>& children) {
      const Node& node = task.node;
      for (std::size_t i = 0; i < node.pixels.size(); ++i) ctx.index[node.pixels[i]] = static_cast<int>(i);
      NodeOutput out;
      processNode(ctx, node, helpers, scratch[worker], out);
      for (Node& child : out.children) {
        for (int p : child.pixels) {
          ctx.set_lo[p].store(child.lo, std::memory_order_relaxed);
          ctx.set_hi[p].store(child.hi, std::memory_order_relaxed);
        }
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

  result.energy = labellingEnergy(volume, weights, result.disparity, smooth.truncation);
  return result;
}

}  // namespace massage_cell::stereo
