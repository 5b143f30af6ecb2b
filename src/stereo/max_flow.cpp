// MaxFlow over OpenCV's cv::detail::GCGraph (Boykov-Kolmogorov augmenting
// paths; permissively licensed as part of OpenCV). No max-flow code of our own.
//
// Capacity type: GCGraph<double>. Measured on a 450 x 375 4-connected grid
// with image-like unaries (float costs in [0, 1], smoothness 0.01..0.06 times
// lambda = 1 / 10 / 50; median of two runs, solve() only):
//   double       3.7 / 11.1 / 45.8 ms, flow exact
//   float        3.8 / 11.1 / 46.9 ms, flow off by ~3 in 22186 (the running
//                flow total accumulates in float; the cut itself was right)
//   int (x 1e4)  3.3 / 10.4 / 44.3 ms, flow off by the rounding (~2e-5);
//                needs a fixed scale in a generic API, and the 32-bit flow
//                total overflows past ~2.1e5 cost units (this cut: 2.2e4)
//   int64 (x1e4) 4.0 / 10.7 / 44.5 ms
// i.e. all within ~5 %, so the exact, scale-free type wins.
//
// GCGraph semantics relied upon:
//  * addTermWeights(i, s, t) accumulates: it keeps only the residual s - t in
//    the node (sign = which terminal) and adds min(s, t) to the flow, so a
//    node with both terminal capacities positive is handled, and repeated
//    calls add up.
//  * addEdges(i, j, w, revw) adds the arc i -> j (w) and j -> i (revw);
//    parallel arcs are allowed.
//  * maxFlow() asserts that at least one edge exists; a graph without edges
//    gets a zero-capacity dummy edge (and, with a single node, a dummy node).
//  * reset() replaces the GCGraph by a new one (GCGraph offers no clear());
//    the freed blocks are usually handed back by malloc to the next graph.
//  * inSourceSegment(i) reports the tree a node was last assigned to.
#include "massage_cell/stereo/max_flow.h"

#include <limits>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc/detail/gcgraph.hpp>

namespace massage_cell::stereo {

struct MaxFlow::Impl {
  cv::detail::GCGraph<double> graph;
  int nodes = 0;
  bool has_edges = false;
  bool solved = false;
  double flow = 0.0;
};

namespace {

[[noreturn]] __attribute__((noinline, cold)) void badCapacity(double c, const char* what) {
  throw std::invalid_argument(std::string("MaxFlow: ") + what + " must be finite and >= 0, got " + std::to_string(c));
}

inline void checkCapacity(double c, const char* what) {
  if (!(c >= 0.0 && c <= std::numeric_limits<double>::max())) badCapacity(c, what);  // also rejects NaN, inf
}

}  // namespace

MaxFlow::MaxFlow(int node_hint, int edge_hint) : impl_(std::make_unique<Impl>()) {
  if (node_hint < 0 || edge_hint < 0) throw std::invalid_argument("MaxFlow: negative size hint");
  // Each addEdge() stores two arcs; GCGraph reserves two extra slots itself.
  impl_->graph.create(static_cast<unsigned>(node_hint), 2u * static_cast<unsigned>(edge_hint));
}

MaxFlow::~MaxFlow() = default;

void MaxFlow::reset(int node_hint, int edge_hint) {
  if (node_hint < 0 || edge_hint < 0) throw std::invalid_argument("MaxFlow: negative size hint");
  impl_->graph = cv::detail::GCGraph<double>();
  impl_->nodes = 0;
  impl_->has_edges = false;
  impl_->solved = false;
  impl_->flow = 0.0;
  impl_->graph.create(static_cast<unsigned>(node_hint), 2u * static_cast<unsigned>(edge_hint));
}

int MaxFlow::addNodes(int count) {
  if (count < 0) throw std::invalid_argument("MaxFlow::addNodes: negative count");
  if (impl_->solved) throw std::logic_error("MaxFlow::addNodes: graph already solved");
  const int first = impl_->nodes;
  for (int i = 0; i < count; ++i) impl_->graph.addVtx();
  impl_->nodes += count;
  return first;
}

void MaxFlow::addTerminalWeights(int node, double source, double sink) {
  if (node < 0 || node >= impl_->nodes)
    throw std::invalid_argument("MaxFlow::addTerminalWeights: node id " + std::to_string(node) + " out of range");
  checkCapacity(source, "source capacity");
  checkCapacity(sink, "sink capacity");
  if (impl_->solved) throw std::logic_error("MaxFlow::addTerminalWeights: graph already solved");
  impl_->graph.addTermWeights(node, source, sink);
}

void MaxFlow::addEdge(int a, int b, double ab, double ba) {
  if (a < 0 || a >= impl_->nodes || b < 0 || b >= impl_->nodes)
    throw std::invalid_argument("MaxFlow::addEdge: node id out of range (" + std::to_string(a) + ", " +
                                std::to_string(b) + ")");
  if (a == b) throw std::invalid_argument("MaxFlow::addEdge: self loop");
  checkCapacity(ab, "edge capacity");
  checkCapacity(ba, "reverse edge capacity");
  if (impl_->solved) throw std::logic_error("MaxFlow::addEdge: graph already solved");
  if (ab == 0.0 && ba == 0.0) return;  // never part of a path; saves memory
  impl_->graph.addEdges(a, b, ab, ba);
  impl_->has_edges = true;
}

double MaxFlow::solve() {
  if (impl_->solved) return impl_->flow;
  if (impl_->nodes == 0) {
    impl_->solved = true;
    impl_->flow = 0.0;
    return 0.0;
  }
  if (!impl_->has_edges) {
    // GCGraph::maxFlow() requires an edge; a zero-capacity one changes nothing.
    const int other = impl_->nodes >= 2 ? 1 : impl_->graph.addVtx();
    impl_->graph.addEdges(0, other, 0.0, 0.0);
    impl_->has_edges = true;
  }
  impl_->flow = impl_->graph.maxFlow();
  impl_->solved = true;
  return impl_->flow;
}

bool MaxFlow::isSource(int node) const {
  if (node < 0 || node >= impl_->nodes)
    throw std::invalid_argument("MaxFlow::isSource: node id " + std::to_string(node) + " out of range");
  if (!impl_->solved) throw std::logic_error("MaxFlow::isSource: call solve() first");
  return impl_->graph.inSourceSegment(node);
}

}  // namespace massage_cell::stereo
