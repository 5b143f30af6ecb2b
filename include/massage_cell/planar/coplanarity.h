// When a triangulated point lies on a plane, in the views' own terms: the
// point may be moved onto the plane (along the reference camera's ray) without
// its image moving by more than `pixels` in any other view, nor its
// reference pixel by more than `pixels`. Triangulation is least certain along
// the ray and with short baselines; this tolerance follows that, in any world
// units. ROS-free.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

class CoplanarityTest {
 public:
  /// Keeps a reference to `views`. Throws std::invalid_argument for pixels <= 0.
  CoplanarityTest(const std::vector<View>& views, double pixels);

  /// The largest distance from X to a plane of unit normal n on which X still
  /// counts as lying, seen from `reference_view`.
  double tolerance(const Eigen::Vector3d& X, const Eigen::Vector3d& n, int reference_view) const;
  /// |plane.distance(X)| / tolerance(X, plane.n, reference_view): <= 1 on the plane.
  double normalisedDistance(const Eigen::Vector3d& X, const Plane& plane, int reference_view) const;
  bool onPlane(const Eigen::Vector3d& X, const Plane& plane, int reference_view) const {
    return normalisedDistance(X, plane, reference_view) <= 1.0;
  }

 private:
  const std::vector<View>& views_;
  double pixels_;
};

}  // namespace massage_cell::planar
