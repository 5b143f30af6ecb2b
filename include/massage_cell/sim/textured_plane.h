// A textured plane seen by a rectified stereo pair, rendered by exact ray
// casting: the project's own sample data and the seed of the scene simulator.
// ROS-free (OpenCV + Eigen only).
//
// Frames and units: everything is expressed in the LEFT camera's optical
// frame (REP 103: x right, y down, z forward), lengths in metres, image
// coordinates in pixels with (0, 0) at the centre of the top-left pixel (the
// OpenCV / camera_info convention). Both cameras are ideal pinholes sharing
// the same intrinsics, with the right centre at (+baseline, 0, 0): a point at
// depth z appears in the right image fx * baseline / z pixels to the left of
// where it appears in the left image.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"

namespace massage_cell::sim {

/// An ideal rectified stereo pair (no distortion, identical intrinsics).
struct StereoRig {
  int width = 320;         ///< image width, pixels
  int height = 240;        ///< image height, pixels
  double fx = 300;         ///< focal length along x, pixels
  double fy = 300;         ///< focal length along y, pixels
  double cx = 159.5;       ///< principal point x, pixels
  double cy = 119.5;       ///< principal point y, pixels
  double baseline = 0.06;  ///< metres; right camera centre at (+baseline, 0, 0) in the left optical frame
};

/// An infinite plane carrying a deterministic procedural colour texture.
///
/// The texture is attached to the plane: it is a function of 2D plane
/// coordinates (u, v) = ((X - point) . e1, (X - point) . e2) + texture_offset,
/// where e1, e2 is an orthonormal in-plane basis chosen deterministically from
/// the normal's direction (not its sign): e1 is the left camera's x axis
/// projected onto the plane (its y axis when the normal is nearly along x),
/// e2 its y axis (else its z axis) made orthogonal to the normal and e1. For a
/// fronto-parallel plane e1 = x and e2 = y, so u grows to the right and v
/// downwards in the image.
struct TexturedPlane {
  Eigen::Vector3d point{0, 0, 0.8};  ///< a point on the plane, metres, left optical frame
  Eigen::Vector3d normal{0, 0, -1};  ///< plane normal (either sign, need not be unit; not zero)
  double feature_size = 0.01;        ///< metres: typical size of the texture blobs
  std::uint32_t seed = 1;            ///< texture seed: same seed, same texture
  /// Metres, added to the plane coordinates before the texture is evaluated:
  /// increasing texture_offset.x() slides the pattern along -e1 (to the left
  /// in the image for a fronto-parallel plane). Use it to animate motion.
  Eigen::Vector2d texture_offset{0, 0};
};

/// One rendered stereo frame. All images have the rig's size.
struct StereoRender {
  cv::Mat left, right;     ///< CV_8UC3 BGR; pixels whose rays miss the plane are black
  cv::Mat left_depth;      ///< CV_32F, z (metres) of the left ray through each pixel centre, NaN where it misses
  cv::Mat left_disparity;  ///< CV_32F, pixels, fx * baseline / z, NaN where the depth is NaN
};

/// Renders `plane` as seen by both cameras of `rig`.
///
/// Every pixel averages supersample x supersample rays through a regular
/// sub-pixel grid (anti-aliasing); a ray hits the plane only in front of its
/// camera (ray parameter > 0), so a plane behind the cameras or seen exactly
/// edge-on yields black images and all-NaN depth. The depth and disparity maps
/// are exact at the left pixel centres. With noise_sigma > 0, independent
/// Gaussian noise of that standard deviation (grey levels, per channel) is added
/// to each view, drawn from a cv::RNG seeded with noise_seed, so the output is
/// fully deterministic.
///
/// Throws std::invalid_argument for a non-positive image size, focal length or
/// baseline, a non-finite principal point or plane point, a zero or non-finite
/// normal, feature_size <= 0, supersample < 1 or a negative noise_sigma.
StereoRender renderStereo(const StereoRig& rig, const TexturedPlane& plane, int supersample = 3,
                          double noise_sigma = 0.0, std::uint32_t noise_seed = 0);

/// camera_info of the left camera: plumb_bob with D = 0, R = I,
/// K = [fx 0 cx; 0 fy cy; 0 0 1], P = [K | 0]. Throws std::invalid_argument
/// for an invalid rig (as renderStereo).
massage_cell::camera::CameraCalibration leftCalibration(const StereoRig& rig);

/// camera_info of the right camera: as the left one but with
/// P[3] = Tx = -fx * baseline (ROS convention). Throws std::invalid_argument
/// for an invalid rig (as renderStereo).
massage_cell::camera::CameraCalibration rightCalibration(const StereoRig& rig);

}  // namespace massage_cell::sim
