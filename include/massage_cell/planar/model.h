// The piecewise-planar model: planes with convex polygons on them, the
// triangle mesh they make, its OBJ / PLY export, and overlay pictures of the
// planes on a view. ROS-free.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

/// Plane n . X + d = 0 with |n| = 1.
struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  double distance(const Eigen::Vector3d& X) const { return n.dot(X) + d; }
  /// Angle between the two planes' normals, degrees in [0, 90].
  double angleTo(const Plane& other) const;
  /// The plane through three points; false when they are (nearly) collinear.
  static bool through(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, Plane* plane);
  /// Least-squares plane of >= 3 points (Eigen's SVD of the centred points); false when degenerate.
  static bool fit(const std::vector<Eigen::Vector3d>& points, Plane* plane);
};

struct Facet {
  Plane plane;
  /// Convex polygons on the plane (each counter-clockwise seen from the
  /// side n points to, >= 3 vertices); a merged facet may hold several.
  std::vector<std::vector<Eigen::Vector3d>> polygons;
  cv::Vec3b colour{200, 200, 200};  ///< BGR: mean colour of the facet in the views
  int support_points = 0;           ///< feature points on it
  double score = 0.0;               ///< photo-consistency (NCC) of its verification
};

struct PlanarModel {
  std::vector<Facet> facets;
  double area() const;  ///< total polygon area, world units squared
};

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<cv::Vec3b> colours;   ///< per vertex, BGR
  std::vector<Eigen::Vector2f> uv;  ///< per vertex texture coordinates in [0,1]^2 of texture_view (empty: none)
  std::vector<std::array<int, 3>> triangles;  ///< vertex indices, counter-clockwise seen from the facet's normal side
  std::vector<int> triangle_facet;            ///< per triangle: index of its facet
};

/// Triangle mesh of the model's polygons (a fan per convex polygon). With
/// `texture_view` >= 0 each vertex gets its texture coordinates in that view
/// (u = (x + 0.5) / width, v = 1 - (y + 0.5) / height: the OBJ convention,
/// (0, 0) at the image's bottom-left corner, pixel centres half a pixel
/// inside; a vertex behind that camera gets (0, 0)). Throws
/// std::invalid_argument for a texture_view out of range and a polygon with
/// < 3 vertices or a non-finite one.
TriangleMesh toMesh(const PlanarModel& model, const std::vector<View>& views = {}, int texture_view = -1);

/// Wavefront OBJ (+ a .mtl naming texture_image when given and the mesh has
/// uv); PLY ascii with per-vertex colours. Throw std::runtime_error naming
/// the file when it cannot be written.
void writeObj(const TriangleMesh& mesh, const std::string& path, const std::string& texture_image = "");
void writePly(const TriangleMesh& mesh, const std::string& path);

/// The view with each facet's visible polygons filled translucently in a
/// colour of its own and outlined, numbered by facet index. Throws
/// std::invalid_argument for an empty image, a degenerate P or an invalid
/// polygon (as toMesh).
cv::Mat drawOverlay(const View& view, const PlanarModel& model);

}  // namespace massage_cell::planar
