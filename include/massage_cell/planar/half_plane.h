// Half-planes about 3D lines (thesis Sec. 4.2, after Baillard & Zisserman,
// CVPR 1999). A world plane bordered by a 3D line L is one of the
// one-parameter family of half-planes that rotate about L. Which one is
// decided by photo-consistency: the region beside L's image in a reference
// view — the strip along it, widened to the convex hull of the feature points
// the candidate plane holds there — is carried into the other views by the
// homography the candidate induces, and the normalised cross-correlation of
// the grey levels scores it (near the line every plane about it agrees, so the
// points' region is what tells them apart).
//
// Two searches share that score:
// - byFeaturePoints (the thesis): the candidates are the planes through L and
//   the 3D feature points beside it. The region constraint keeps the points
//   whose reference pixels lie on the strip's side of L, within
//   `region_depth` pixels of it and alongside the segment; the coplanar
//   constraint groups those points by their angle about L (within each
//   one's coplanarity tolerance), so each group of points coplanar with L is
//   one candidate (its plane fitted to L and the
//   group; groups of fewer than `min_coplanar_points` are no candidates).
//   A few candidates per side instead of 180 angles.
// - bySweep (Baillard's baseline): every `sweep_step_deg` about L, each angle
//   verified over the strip and the region of the points on that plane.
// Both keep a side's best candidate when its score reaches `min_ncc`.
//
// Tolerances are in pixels (coplanarity.h), so world units may be metres or
// the arbitrary units of a VGG set. ROS-free.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/planar/coplanarity.h"
#include "massage_cell/planar/features.h"
#include "massage_cell/planar/model.h"
#include "massage_cell/planar/photo_consistency.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

struct HalfPlaneParams {
  double strip_width = 18.0;    ///< px: the verified region beside the line in the reference view
  double strip_offset = 2.0;    ///< px next to the line left out (the edge itself agrees under every plane about L)
  double sample_step = 2.0;     ///< px between samples along and across the strip
  double min_ncc = 0.65;        ///< a half-plane is accepted at this score or above
  double region_depth = 150.0;  ///< px: the region constraint's reach from the line in the reference view
  double coplanar_pixels =
      2.0;  ///< a point is on a plane when moving it there moves its images this little (coplanarity.h)
  int min_coplanar_points = 2;  ///< the coplanar constraint: a candidate needs this many points coplanar with the line
  double sweep_step_deg = 1.0;  ///< the exhaustive sweep's step about the line
  double grazing_deg = 10.0;    ///< planes within this angle of the reference camera's viewing direction are skipped
  /// Throws std::invalid_argument naming the field for a bad value.
  void validate() const;
};

struct HalfPlane {
  int line = -1;  ///< index into the line tracks
  int side = 1;   ///< +1 / -1: the side of the line's image (sign of the image line's equation) in the reference view
  int reference_view = 0;
  Plane plane;
  double score = 0.0;       ///< NCC of the strip against the other views
  std::vector<int> points;  ///< point tracks coplanar with the plane inside the region (byFeaturePoints)
};

struct SearchStats {
  long candidates = 0;   ///< candidate planes scored
  double seconds = 0.0;  ///< wall time of the search
};

class HalfPlaneSearch {
 public:
  /// Keeps references to the arguments (they must outlive the search).
  /// Throws std::invalid_argument for invalid views or parameters.
  HalfPlaneSearch(const std::vector<View>& views, const std::vector<PointTrack>& points,
                  const std::vector<LineTrack>& lines, const HalfPlaneParams& params);

  /// The thesis's search: candidates from the feature points beside each line.
  std::vector<HalfPlane> byFeaturePoints(SearchStats* stats = nullptr) const;
  /// Baillard's exhaustive sweep about each line.
  std::vector<HalfPlane> bySweep(SearchStats* stats = nullptr) const;

  /// Photo-consistency of `plane` on `side` of `line` seen from
  /// `reference_view`: the mean NCC over the other views that see the whole
  /// strip in front of them (-1 when none does, or the strip has no texture).
  double score(int line, int side, int reference_view, const Plane& plane) const;

  /// The view in which the line's image is longest.
  int referenceView(int line) const;

  /// Which points lie on which planes (coplanar_pixels).
  const CoplanarityTest& coplanarity() const { return coplanarity_; }

 private:
  struct Strip;
  /// A point of the region constraint: its track, angle about the line, distance from it, tolerance, pixel.
  struct RegionPoint {
    int index;
    double angle, radius, tolerance;
    Eigen::Vector2d pixel;
  };
  /// The strip beside the line; with `region` pixels, the convex hull of the strip and them.
  Strip makeStrip(int line, int side, int reference_view, const std::vector<Eigen::Vector2d>& region = {}) const;
  std::vector<RegionPoint> regionPoints(int line, int side, int reference_view) const;
  double scoreStrip(const Strip& strip, const Plane& plane) const;
  std::vector<Plane> pointCandidates(int line, int side, int reference_view,
                                     std::vector<std::vector<int>>* groups) const;
  bool grazing(int line, int reference_view, const Plane& plane) const;

  const std::vector<View>& views_;
  const std::vector<PointTrack>& points_;
  const std::vector<LineTrack>& lines_;
  HalfPlaneParams params_;
  CoplanarityTest coplanarity_;
  PhotoConsistency photo_;
};

/// The plane through the 3D line (point, unit direction) at `angle` radians
/// about it, measured from a fixed basis perpendicular to the line.
Plane planeAboutLine(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double angle);

/// The angle of X about the line, in the basis of planeAboutLine, in [0, pi).
double angleAboutLine(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, const Eigen::Vector3d& X);

}  // namespace massage_cell::planar
