// From half-planes to the planar model (thesis Sec. 4.3): each verified
// half-plane is bounded by the fixed lines it shares with its neighbouring
// half-planes, grown over the feature points and line segments coplanar with
// it inside those bounds, checked as a whole by photo-consistency, and the
// extended half-planes that lie on one world plane and touch are merged into
// one facet. ROS-free.
//
// Fixed lines: two world planes induce homographies between two views that
// agree exactly on the image of the planes' common 3D line (the fixed line of
// H_a^-1 H_b). The thesis finds it with a Hough accumulator of fixed points;
// with calibrated views it is the projection of the two planes' intersection,
// which is computed here directly (exact, and no accumulator to tune). A
// fixed line bounds a half-plane only when it leaves all of the half-plane's
// own evidence (its line, its coplanar points) on one side: the far facets'
// planes cross it elsewhere and must not cut it.
#pragma once

#include <vector>

#include "massage_cell/planar/features.h"
#include "massage_cell/planar/half_plane.h"
#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

struct ExtendParams {
  double coplanar_pixels = 2.0;    ///< a point is on a plane when moving it there moves its images this little
  double growth_step = 60.0;       ///< px in the reference view: a coplanar point joins a region this near it
  double neighbour_reach = 250.0;  ///< px: half-planes whose lines come this near (reference view) bound each other
  double merge_angle_deg =
      4.0;              ///< facets within this angle, each one's evidence on the other's plane, touching, merge
  int min_support = 4;  ///< a facet needs this many points and line end points besides its own line
  /// A grown region whose pixels, carried by its plane into the other views,
  /// correlate less than this is dropped (untextured regions cannot be checked and stay).
  double min_region_ncc = 0.5;
  /// Throws std::invalid_argument naming the field for a bad value.
  void validate() const;
};

struct ExtendStats {
  int half_planes = 0;  ///< half-planes given
  int extended = 0;     ///< of which kept with enough support
  int facets = 0;       ///< after merging
  double seconds = 0.0;
};

/// The planar model from verified half-planes (from HalfPlaneSearch over the
/// same views, points and lines).
PlanarModel extendAndMerge(const std::vector<View>& views, const std::vector<PointTrack>& points,
                           const std::vector<LineTrack>& lines, const std::vector<HalfPlane>& half_planes,
                           const ExtendParams& params, ExtendStats* stats = nullptr);

}  // namespace massage_cell::planar
