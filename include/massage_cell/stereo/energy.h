// The multi-label energy of Eq. 2.2 shared by HBDS and the graph-cut
// baselines: E(d) = sum_p S(p, d_p) + sum_{p,q} V(d_p, d_q) over 4-connected
// pairs, V = u_{p,q} min(|d_p - d_q|, truncation). ROS-free.
#pragma once

#include <opencv2/core.hpp>

#include "massage_cell/stereo/cost_volume.h"

namespace massage_cell::stereo {

struct SmoothParams {
  float tau = 30.0f;     ///< intensity difference (grey levels) at which u reaches u_min
  float u_min = 0.01f;   ///< penalty per disparity level across a strong edge
  float u_max = 0.08f;   ///< penalty per disparity level in a uniform region
  float truncation = 0;  ///< 0: V = u |dp - dq|; > 0: V = u min(|dp - dq|, truncation)
};

/// u_{p,q} = (u_min - u_max) min(|I_p - I_q|, tau) / tau + u_max for every
/// right neighbour pair ((x, y), (x + 1, y)) and down pair ((x, y), (x, y + 1))
/// of the left image (|I_p - I_q| = largest channel difference for colour).
/// CV_32F; the last column of `right` and last row of `down` are 0.
struct PairwiseWeights {
  cv::Mat right;
  cv::Mat down;
};
PairwiseWeights pairwiseWeights(const cv::Mat& left, const SmoothParams& params);

struct Energy {
  double data = 0.0;
  double smooth = 0.0;
  double total() const { return data + smooth; }
};

/// Energy of an integer labelling (CV_32F holding integers in the volume's
/// range; other values throw std::invalid_argument).
Energy labellingEnergy(const CostVolume& volume, const PairwiseWeights& weights, const cv::Mat& disparity,
                       float truncation);

}  // namespace massage_cell::stereo
