// Calibrated views for piecewise-planar reconstruction, and the projective
// geometry the reconstruction needs: projection, fundamental matrices,
// triangulation of points and lines from any number of views. ROS-free
// (OpenCV, Eigen).
//
// A view is an image with its 3x4 projection matrix P (x ~ P X, pixels with
// the top-left pixel's centre at (0, 0)). World units are whatever P says:
// metres for the cell's cameras, arbitrary for the VGG sets. Every P is
// scaled so that its left 3x3 block has a positive determinant: then
// w = P.row(2) X > 0 exactly for the points in front of the camera.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace massage_cell::planar {

using Projection = Eigen::Matrix<double, 3, 4>;

struct View {
  std::string name;
  cv::Mat image;  ///< CV_8UC3 (BGR) or CV_8UC1
  Projection P = Projection::Zero();
};

/// P = K [R | t] of a camera whose optical frame has pose `world_from_camera`
/// (REP 103 optical frame: z forward, x right, y down), e.g. from a
/// sensor_msgs/CameraInfo's K (or P's left 3x3 for rectified images) and tf.
Projection projectionFromPose(const Eigen::Matrix3d& K, const Eigen::Isometry3d& world_from_camera);

/// `P` scaled to unit norm of its third row's first three entries and to a
/// positive determinant of its left 3x3 block. Throws std::invalid_argument
/// for a non-finite P or one whose left 3x3 block is singular.
Projection normalisedProjection(const Projection& P);

/// The views of a VGG multi-view folder (Oxford "Merton College I" layout):
/// images/NNN.jpg with 2D/NNN.P, NNN = 001, 002, ... Throws
/// std::runtime_error naming the missing or unreadable file.
std::vector<View> loadVggViews(const std::string& folder);

/// Throws std::invalid_argument naming the problem: fewer than 2 views, an
/// empty or non-8-bit image, a non-finite or degenerate P, two views with the
/// same centre (no baseline).
void validateViews(const std::vector<View>& views);

/// Camera centre (the right null vector of P), in world coordinates.
Eigen::Vector3d cameraCentre(const Projection& P);

/// Pixel of X; false when X is not in front of the camera.
bool project(const Projection& P, const Eigen::Vector3d& X, Eigen::Vector2d* pixel);

/// Depth-like value of X in front of the camera (w of P X with P normalised:
/// the distance along the optical axis for a metric camera).
double depthOf(const Projection& P, const Eigen::Vector3d& X);

/// Fundamental matrix F with x_b^T F x_a = 0 for the views' projections of a
/// common point.
Eigen::Matrix3d fundamental(const Projection& Pa, const Projection& Pb);

/// Point seen at pixels[i] by cameras[i] (>= 2 views): linear triangulation
/// (DLT, Eigen's SVD on normalised coordinates).
Eigen::Vector3d triangulatePoint(const std::vector<Projection>& cameras, const std::vector<Eigen::Vector2d>& pixels);

/// Image line through two pixels, homogeneous, scaled so that (a, b) is a
/// unit normal: l . (x, y, 1) is the signed distance in pixels.
Eigen::Vector3d imageLine(const Eigen::Vector2d& a, const Eigen::Vector2d& b);

/// The 3D line whose images are lines[i] in cameras[i] (>= 2 views): the
/// intersection of the back-projected planes P^T l (least squares for more
/// than two). Returns false when the planes are (nearly) parallel: the line
/// lies in an epipolar plane and cannot be triangulated.
bool triangulateLine(const std::vector<Projection>& cameras, const std::vector<Eigen::Vector3d>& lines,
                     Eigen::Vector3d* point, Eigen::Vector3d* direction);

/// Point of the line (point, unit direction) closest to the ray from `centre`
/// through `pixel` of camera P.
Eigen::Vector3d closestOnLineToRay(const Projection& P, const Eigen::Vector2d& pixel, const Eigen::Vector3d& point,
                                   const Eigen::Vector3d& direction);

/// Pixels per world unit at X in camera P (how large a small length at X,
/// perpendicular to the viewing ray, appears).
double pixelsPerUnit(const Projection& P, const Eigen::Vector3d& X);

}  // namespace massage_cell::planar
