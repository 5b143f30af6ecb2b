// Geometry of the parts that dress the back scene (cell_scene.h): swept tubes
// and ellipsoids (arms, neck, head, hair, the face cradle's ring), the lower
// body (buttocks and upper thighs continuing BackModel), and the trunk's
// surface the arms and the towel rest against. ROS-free (Eigen only).
//
// Frame: the world frame `table` of scene.h; metres.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

/// One cross-section of a tube: an ellipse around `centre`, semi-axis `a`
/// along the horizontal normal of the tube's path, `b` along the normal
/// that points up (for a horizontal path: a = half width, b = half height).
struct TubeRing {
  Eigen::Vector3d centre;
  double a = 0.01;
  double b = 0.01;
};

struct TubeOptions {
  int segments = 40;      ///< vertices around each ring
  bool cap_start = true;  ///< close the first end with a half ellipsoid
  bool cap_end = true;    ///< close the last end with a half ellipsoid
  /// Part of the ring swept, radians from the horizontal normal (0) over the
  /// top (pi/2); the default full ring puts its seam underneath.
  double angle_from = -1.5707963267948966;
  double angle_to = 4.71238898038469;
};

/// A tube swept along the rings' centres (at least 2, consecutive centres
/// distinct, the path never vertical). uv = (arc length, angle * mean radius)
/// in metres; normals from the elliptic sections and their taper.
/// Throws std::invalid_argument for bad rings or options.
Mesh makeTube(const std::string& name, const std::vector<TubeRing>& rings, const TubeOptions& options,
              const Material& material, std::uint8_t label);

/// An ellipsoid with semi-axes `axes` along the columns of `rotation`, about
/// `centre`; `keep` (optional) keeps only the triangles whose three vertices
/// it accepts (world points), e.g. a scalp. uv = (polar angle from the +first
/// axis * axes[0], azimuth * axes[1]) in metres, so that meridians run from
/// the first axis' pole. Throws std::invalid_argument.
Mesh makeEllipsoid(const std::string& name, const Eigen::Vector3d& centre, const Eigen::Matrix3d& rotation,
                   const Eigen::Vector3d& axes, int rings, int segments, const Material& material, std::uint8_t label,
                   const std::function<bool(const Eigen::Vector3d&)>& keep = {});

/// Recomputes per-vertex normals as area-weighted triangle normals.
void smoothNormals(Mesh& mesh);

/// The buttocks down to the gluteal fold and the upper thighs, continuing a
/// BackModel caudally from its full-height end (above its buttock end cap,
/// which it hides) with the same skin. Height field over x in
/// [xEnd(), xStart()], label kLabelBack.
class LowerBody {
 public:
  explicit LowerBody(const BackModel& back);
  double xStart() const { return x_start_; }  ///< where it joins the back (full height)
  double xEnd() const { return x_end_; }      ///< caudal end (upper-to-mid thighs)
  double foldX() const { return x_fold_; }    ///< the gluteal fold
  double halfWidth(double x) const;           ///< 0 outside [xEnd, xStart]
  /// Height of the skin at (x, y); NaN outside the outline.
  double height(double x, double y) const;
  /// Mesh with the back's skin material; `spacing` metres between rows.
  Mesh mesh(const Material& skin, double spacing = 0.004) const;

 private:
  double profile(double x, double s) const;  // height at normalised lateral s in [-1, 1]
  double x_start_, x_end_, x_fold_;
  double hw_join_;
  std::vector<double> join_profile_;  // back height at x_start over s in [0, 1]
  double peak_rise_, cleft_depth_;
};

/// The subject's trunk as the arms and the towel see it: the back, and the
/// lower body when present. Height 0 off the body (the table top). Keeps
/// references: `back` and `lower` must outlive it.
class TrunkSurface {
 public:
  TrunkSurface(const BackModel& back, const LowerBody* lower);
  double height(double x, double y) const;
  double halfWidth(double x) const;
  double xMin() const;
  double xMax() const;

 private:
  const BackModel& back_;
  const LowerBody* lower_;
};

}  // namespace massage_cell::sim
