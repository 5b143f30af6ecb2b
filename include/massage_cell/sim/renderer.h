// Ray-traced rendering of a Scene with Embree (intersections) and our own
// shading: ambient + one directional light, Lambertian with a little
// Blinn-Phong specularity, hard shadows, supersampling, sensor noise and
// exposure. Produces the image and its exact ground truth. ROS-free.
#pragma once

#include <cstdint>
#include <memory>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

/// The thesis's lighting experiment (Fig. 3.10): a light above the table
/// toward the head end, to the image's left, centre or right.
enum class LightPreset { kTopLeft, kTopCentre, kTopRight };

struct Lighting {
  Eigen::Vector3f direction_to_light{0.35f, 0.0f, 0.94f};  ///< world frame, unit
  float intensity = 0.85f;                                 ///< directional light
  float ambient = 0.30f;                                   ///< ambient light
  /// Light from the preset's direction (image left = world +y, top = world +x).
  static Lighting preset(LightPreset preset);
};

struct RenderOptions {
  int supersample = 2;           ///< rays per pixel = supersample^2, on a regular sub-pixel grid
  float noise_sigma = 1.0f;      ///< Gaussian sensor noise, grey levels (8-bit)
  float exposure = 1.0f;         ///< multiplies the linear radiance before encoding
  std::uint32_t noise_seed = 0;  ///< seeds the noise; same seed, same image
  bool shadows = true;
};

/// One rendered view and its ground truth (all at the view's size).
struct ViewRender {
  cv::Mat image;   ///< CV_8UC3 BGR, sRGB-encoded
  cv::Mat depth;   ///< CV_32F: z of the surface in the camera's optical frame (metres) at the pixel centre; NaN where
                   ///< nothing is hit
  cv::Mat points;  ///< CV_32FC3: world-frame XYZ of that surface point; NaN where nothing is hit
  cv::Mat labels;  ///< CV_8U: Label of that surface (kLabelBackground where nothing is hit)
};

struct Hit {
  double distance = 0.0;   ///< along the ray, metres
  Eigen::Vector3d point;   ///< world frame
  Eigen::Vector3d normal;  ///< world frame, unit, facing the ray origin
  std::uint8_t label = kLabelBackground;
  int mesh = -1;
};

class Renderer {
 public:
  /// Builds the acceleration structure once. Throws std::runtime_error if
  /// Embree fails, std::invalid_argument for malformed meshes.
  explicit Renderer(const Scene& scene);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Renders the view of `camera` (its distortion included: the image is what
  /// that raw camera sees). Multithreaded over rows.
  ViewRender render(const CameraModel& camera, const Lighting& lighting, const RenderOptions& options) const;

  /// First surface along a world ray (direction need not be unit); false if none.
  bool intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, Hit* hit) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace massage_cell::sim
