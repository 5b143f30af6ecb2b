// The project's one max-flow interface. Implemented with OpenCV's
// cv::detail::GCGraph (Boykov-Kolmogorov, Apache-2.0); no GPL code, no
// hand-written max-flow.
#pragma once

#include <memory>

namespace massage_cell::stereo {

class MaxFlow {
 public:
  MaxFlow(int node_hint = 0, int edge_hint = 0);
  ~MaxFlow();
  MaxFlow(const MaxFlow&) = delete;
  MaxFlow& operator=(const MaxFlow&) = delete;

  /// Empties the graph (no nodes, no edges, not solved) and makes room for the
  /// given numbers of nodes and edges, so one object can serve many graphs.
  /// The next graph behaves exactly like one built in a new object.
  void reset(int node_hint = 0, int edge_hint = 0);
  /// Adds `count` nodes; returns the index of the first.
  int addNodes(int count);
  /// Capacities from the source to `node` and from `node` to the sink (>= 0).
  void addTerminalWeights(int node, double source, double sink);
  /// Edge a -> b with capacity `ab` and b -> a with capacity `ba` (>= 0).
  void addEdge(int a, int b, double ab, double ba);
  /// Computes the maximum flow (= the minimum cut's cost).
  double solve();
  /// After solve(): true when `node` is on the source side of the minimum cut.
  bool isSource(int node) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace massage_cell::stereo
