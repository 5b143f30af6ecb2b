// Photo-consistency of a plane: grey levels sampled in a reference view are
// carried into every other view by the homography the plane induces
// (computed from the P matrices: X = [(pi^T C) I - C pi^T] P^+ x), and the
// normalised cross-correlation of the two sets of samples scores the plane.
// Shared by the half-plane searches (a strip beside a line) and the
// extension (a grown region). ROS-free.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

/// The homogeneous world point on `plane` seen at pixel x of the camera P is
/// X = M x (a 4x3 matrix); the plane-induced homography into a view Pv is Pv M.
Eigen::Matrix<double, 4, 3> planeBackProjection(const Projection& P, const Plane& plane);

class PhotoConsistency {
 public:
  /// Grey samples of a region of the reference view.
  struct Samples {
    int reference_view = -1;
    std::vector<Eigen::Vector3d> pixels;   ///< homogeneous reference pixels
    std::vector<float> values;             ///< their grey levels
    std::vector<Eigen::Vector3d> corners;  ///< homogeneous corners of the region (must lie on the plane in front)
    bool textured = false;                 ///< enough samples with a grey-level spread to be scored
  };

  /// Converts every view to grey once; keeps a reference to `views`.
  explicit PhotoConsistency(const std::vector<View>& views);

  /// The samples at `pixels` (those inside the image) of `reference_view`.
  Samples sample(int reference_view, const std::vector<Eigen::Vector2d>& pixels,
                 const std::vector<Eigen::Vector2d>& corners) const;

  /// Mean NCC over the other views that see at least 80 % of the samples,
  /// with every corner in front of both cameras; -1 when none does or the
  /// samples have no texture.
  double score(const Samples& samples, const Plane& plane) const;

  /// The grey levels (CV_32F, 0..255) of view `v`.
  const cv::Mat& grey(int v) const { return grey_.at(static_cast<std::size_t>(v)); }

 private:
  const std::vector<View>& views_;
  std::vector<cv::Mat> grey_;  ///< CV_32F per view
};

}  // namespace massage_cell::planar
