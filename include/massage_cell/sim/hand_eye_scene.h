// The simulated hand-eye calibration cell: the gantry's base on the table
// (urdf/massage_arm.urdf), the ChArUco marker carried by the press tool as
// scene geometry, and rendered stereo pairs of it with the exact camera pose.
// ROS-free; built with the calibration library (cmake/hand_eye.cmake), since
// it draws the board with OpenCV's aruco module.
//
// The marker is geometry, not a texture: a white backing plate and one flat
// black quad per run of black board pixels, so the existing renderer shades
// it (light, shadows, supersampling, noise) unchanged. The ink lies on the
// board's face; the plate's top is 0.05 mm below it.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "massage_cell/calib/stereo_marker.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

/// Pose of arm_base_link in the table frame: the URDF's fixed joint
/// table_to_arm_base (xyz 0.15 0.25 0, yaw pi).
Eigen::Isometry3d tableFromArmBase();

/// How the marker rides on the tool: board centre = tool tip + offset (arm
/// base frame); the board lies flat, face up, its image x along the base's y
/// and its image y along the base's x (so the camera of the cell sees it upright).
struct MarkerMount {
  calib::CharucoSpec spec;
  Eigen::Vector3d offset{0.0, 0.0, 0.06};  ///< metres, arm base frame
  double pixels_per_metre = 2000.0;        ///< resolution of the board drawing turned into geometry
};

/// Table <- board-drawing frame (origin at the drawing's top-left corner, x
/// right, y down, z into the board) for the tool tip at `tip_in_base`.
Eigen::Isometry3d boardPose(const Eigen::Vector3d& tip_in_base, const MarkerMount& mount);

/// The marker's meshes (backing plate, ink) at `table_from_board`, label kLabelPlane.
std::vector<Mesh> makeMarkerMeshes(const MarkerMount& mount, const Eigen::Isometry3d& table_from_board);

/// The table (cloth top at z = 0) and the floor, without a subject.
Scene makeEmptyTableScene(std::uint32_t seed);

/// true when every chessboard corner of the board at `tip_in_base` projects
/// at least `margin` pixels inside both images of `pair`.
bool markerInView(const StereoPairModel& pair, const Eigen::Vector3d& tip_in_base, const MarkerMount& mount,
                  double margin = 20.0);

/// `count` tool-tip positions inside [lo, hi] (arm base frame) with the marker
/// in view, spread over the box: a 6 x 6 x 4 grid of candidates, then
/// farthest-point selection from the one nearest the box's centre.
/// Throws std::invalid_argument when fewer than `count` candidates are in view.
std::vector<Eigen::Vector3d> spreadTipPositions(int count, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                                const StereoPairModel& pair, const MarkerMount& mount);

/// One rendered calibration pose.
struct MarkerPose {
  Eigen::Vector3d tip_in_base;
  Eigen::Vector3d marker_in_camera;  ///< exact reference point, left optical frame
  cv::Mat left, right;               ///< rendered (rectified) BGR images
};

/// Renders the empty table with the marker at `tip_in_base`, both views of
/// `pair`: the renderer's image (options.noise_sigma withheld), a Gaussian
/// lens blur of `blur_sigma` pixels (a real lens is never as sharp as the
/// box-filtered pinhole, and corner refinement locks onto the pixel grid of
/// such edges), then Gaussian sensor noise of options.noise_sigma grey levels
/// seeded by options.noise_seed and `seed`. Throws std::invalid_argument for
/// blur_sigma outside 0..5.
MarkerPose renderMarkerPose(const StereoPairModel& pair, const Eigen::Vector3d& tip_in_base, const MarkerMount& mount,
                            const RenderOptions& options, std::uint32_t seed, double blur_sigma = 0.7);

/// The exact camera <- arm base transform of `pair`'s left camera.
Eigen::Isometry3d trueCameraFromBase(const StereoPairModel& pair);

}  // namespace massage_cell::sim
