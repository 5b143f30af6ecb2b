// Scoring a piecewise-planar model against a reference (thesis Tables
// 4.1/4.2): true planes matched to reconstructed facets, the angle errors
// between plane pairs, the share of the true facets' visible area covered,
// the distance of the model's vertices to their true planes; and the
// reference of a VGG multi-view set (Merton College I: planes fitted to its
// 3D points). ROS-free.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

struct ReferencePlane {
  std::string name;
  Plane plane;
  /// Per view: mask (CV_8U, 255 = visible pixel of this true facet), or
  /// empty where the reference has no pixel masks (VGG sets).
  std::vector<cv::Mat> visible;
  /// Reference 3D points on the facet (the VGG points assigned to it; for
  /// rendered scenes, points sampled on the visible facet).
  std::vector<Eigen::Vector3d> points;
};

struct PlaneMatch {
  int reference = -1;      ///< index into the reference planes
  int facet = -1;          ///< index into the model's facets (-1: none found)
  double angle_deg = 0.0;  ///< between the facet's and the reference plane's normals
  double coverage =
      0.0;  ///< share of the reference's visible pixels (all views) covered by the facet's polygons (NaN without masks)
};

struct PairAngleError {
  int reference_a = -1, reference_b = -1;
  double true_angle_deg = 0.0;   ///< between the two reference planes
  double model_angle_deg = 0.0;  ///< between the facets matched to them
  double error_deg = 0.0;        ///< |model - true|
};

struct Evaluation {
  std::vector<PlaneMatch> matches;          ///< one per reference plane
  std::vector<PairAngleError> pair_errors;  ///< every pair of non-parallel (> 5 deg) reference planes both matched
  double mean_pair_error_deg = 0.0, max_pair_error_deg = 0.0;
  double coverage = 0.0;  ///< visible reference area covered, all planes with masks together (NaN without masks)
  double vertex_distance_mean = 0.0,
         vertex_distance_max = 0.0;  ///< model vertices to their matched reference plane, world units
  int reconstructed = 0;             ///< reference planes with a matched facet
};

/// Matches each reference plane to the facet that covers most of its
/// reference points / visible pixels and lies within max_angle_deg and
/// max_distance of it (each facet used once), then scores the model.
Evaluation evaluateModel(const PlanarModel& model, const std::vector<View>& views,
                         const std::vector<ReferencePlane>& reference, double max_angle_deg, double max_distance);

/// Per view, the pixels covered by the model's polygons, labelled with the
/// facet index + 1 (CV_32S; 0 = none), nearest facet wins.
cv::Mat facetIndexImage(const PlanarModel& model, const View& view);

/// The VGG set's reference: 3D points (3D/p3d) split into planes by sequential
/// RANSAC (inlier distance `tolerance`, planes of at least `min_points`
/// points, largest first), named "plane 1", "plane 2", ... Throws
/// std::runtime_error naming a missing or malformed file.
std::vector<ReferencePlane> vggReferencePlanes(const std::string& folder, double tolerance, int min_points);

/// The VGG set's 3D points (3D/p3d) and segments (3D/l3d: a, b per row).
std::vector<Eigen::Vector3d> loadVggPoints(const std::string& folder);
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> loadVggLines(const std::string& folder);

}  // namespace massage_cell::planar
