// Coplanarity in pixels (see coplanarity.h).
#include "massage_cell/planar/coplanarity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace massage_cell::planar {

CoplanarityTest::CoplanarityTest(const std::vector<View>& views, double pixels) : views_(views), pixels_(pixels) {
  if (!(std::isfinite(pixels) && pixels > 0.0)) {
    throw std::invalid_argument("coplanarity tolerance = " + std::to_string(pixels) + " px: expected > 0");
  }
}

double CoplanarityTest::tolerance(const Eigen::Vector3d& X, const Eigen::Vector3d& n, int reference_view) const {
  const Projection& P = views_.at(static_cast<std::size_t>(reference_view)).P;
  const Eigen::Vector3d ray = (X - cameraCentre(P)).normalized();
  // Parallax per world unit along the reference ray: the most any other view's image moves.
  const double step = 1e-3 * (X - cameraCentre(P)).norm();
  double parallax = 0.0;
  for (std::size_t v = 0; v < views_.size(); ++v) {
    if (static_cast<int>(v) == reference_view) continue;
    Eigen::Vector2d a, b;
    if (!project(views_[v].P, X, &a) || !project(views_[v].P, X + step * ray, &b)) continue;
    parallax = std::max(parallax, (b - a).norm() / step);
  }
  const double along = parallax > 0.0 ? std::abs(n.dot(ray)) / parallax : std::numeric_limits<double>::infinity();
  return pixels_ * (along + 1.0 / pixelsPerUnit(P, X));
}

double CoplanarityTest::normalisedDistance(const Eigen::Vector3d& X, const Plane& plane, int reference_view) const {
  return std::abs(plane.distance(X)) / tolerance(X, plane.n, reference_view);
}

}  // namespace massage_cell::planar
