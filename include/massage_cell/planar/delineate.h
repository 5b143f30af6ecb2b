// Delineation: each facet extended to the full extent of the image region its
// plane carries consistently into the other views (the photo-consistency the
// half-planes were verified with, now per pixel). In one labelling view every
// textured pixel goes to the facet whose plane-induced homographies correlate
// best around it (the best other view: a view that is occluded there does not
// veto); each facet keeps the connected parts of its pixels that touch its
// polygon, and its polygon becomes their convex hull on its plane. A facet
// whose own textured pixels mostly prefer other planes, or none, is dropped.
// Untextured pixels (a blank sheet) cannot be judged: a facet keeps them
// where its polygon already covered them.
//
// Where no line bounds a surface (an edge without contrast, a face whose
// half-planes failed), its feature points are left over: planes through
// coplanar groups of them (RANSAC, local in the labelling view) join the
// labelling as further hypotheses and are kept only where they win their
// pixels like any facet (ours; the thesis grows planes from lines only).
// ROS-free.
#pragma once

#include <vector>

#include "massage_cell/planar/features.h"
#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

struct DelineateParams {
  bool enabled = false;          ///< off by default: see docs/planar.md (repetitive print spills it)
  int window = 9;                ///< px, odd: the NCC window around each pixel
  double min_ncc = 0.6;          ///< a pixel agrees with a plane at this NCC in some other view
  double min_texture = 3.0;      ///< grey-level standard deviation in the window for a pixel to be judged
  double min_agreeing = 0.25;    ///< a facet is kept when this share of its own judged pixels agree with it
  int min_judged = 200;          ///< ... when it has this many judged pixels (fewer: it stays as it was)
  double reach = 1.0;            ///< a facet's pixels lie within this many times its polygon's size of it
  int point_planes = 8;          ///< at most this many planes from the left-over feature points (0: none)
  int min_plane_points = 10;     ///< ... each through at least this many coplanar points
  double point_reach = 120.0;    ///< px in the labelling view: a point plane's points lie this near its first point
  double coplanar_pixels = 2.0;  ///< as ExtendParams::coplanar_pixels
  /// Throws std::invalid_argument naming the field for a bad value.
  void validate() const;
};

struct DelineateStats {
  int labelling_view = -1;
  int facets_in = 0;
  int point_planes = 0;  ///< hypotheses from left-over feature points
  int delineated = 0;    ///< facets whose polygons were redrawn from their pixels
  int dropped = 0;       ///< facets whose pixels mostly prefer other planes
  double seconds = 0.0;
};

/// The view in which the model's polygons cover the most pixels (ties: the
/// first); 0 for an empty model.
int labellingView(const std::vector<View>& views, const PlanarModel& model);

/// Per pixel of `view`, the index of the facet its pixels agree with best
/// (-1: untextured, or no facet at min_ncc). CV_32S of the view's size.
cv::Mat labelPixels(const std::vector<View>& views, int view, const PlanarModel& model, const DelineateParams& params);

/// Planes through coplanar groups of the point tracks that `model` does not
/// explain in `labels` (labelPixels of `view`: no facet agrees at the point's
/// pixel, or the one that does has the point off its plane), largest first;
/// each a facet whose polygon is the hull of its points.
std::vector<Facet> pointPlanes(const std::vector<View>& views, int view, const std::vector<PointTrack>& points,
                               const PlanarModel& model, const cv::Mat& labels, const DelineateParams& params);

/// The model with each facet delineated (see above); `points` are the
/// reconstruction's point tracks. Throws std::invalid_argument for bad
/// parameters.
PlanarModel delineate(const std::vector<View>& views, const std::vector<PointTrack>& points, const PlanarModel& model,
                      const DelineateParams& params, DelineateStats* stats = nullptr);

}  // namespace massage_cell::planar
