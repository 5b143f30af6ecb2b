// Calibrated multi-view sets rendered by the simulator, with exact planes:
// stacked textured boxes on the table (planar reconstruction, issue 27) and
// a single textured cube (the planar library's tests). ROS-free.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/scene.h"

namespace massage_cell::sim {

struct TruePlane {
  std::string name;                              ///< "table", "box 0 +z", ...
  std::uint8_t label = 0;                        ///< the renderer's label of its pixels
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  ///< unit normal, pointing out of the solid
  double d = 0.0;                                ///< n . X + d = 0
};

struct MultiViewSet {
  Scene scene;
  std::vector<CameraModel> cameras;            ///< undistorted pinhole cameras
  std::vector<Eigen::Matrix<double, 3, 4>> P;  ///< per view: projection (pixels, top-left pixel centre at (0, 0))
  std::vector<cv::Mat> images;                 ///< per view: CV_8UC3 BGR
  std::vector<cv::Mat> labels;                 ///< per view: CV_8U label image
  std::vector<cv::Mat> depth;                  ///< per view: CV_32F optical-frame z, NaN where nothing is hit
  std::vector<TruePlane> planes;               ///< every planar facet with a label of its own
  double scene_depth = 0.0;                    ///< median depth of the labelled pixels in view 0 (metres)
};

struct MultiViewOptions {
  int views = 3;
  int width = 640, height = 480;
  double fx = 600.0;
  double distance = 1.2;        ///< metres from the target
  double elevation_deg = 50.0;  ///< above the table
  double spread_deg = 30.0;     ///< azimuth spread of the views
  int supersample = 2;
  float noise_sigma = 1.0f;
  std::uint32_t seed = 1;
};

/// The boxes scene (sim::makeBoxesScene, `count` boxes on the table) seen
/// from `options.views` cameras. Planes: the table top and every box face.
/// Throws std::invalid_argument for bad options.
MultiViewSet renderBoxesViews(int count, const MultiViewOptions& options);

/// One textured cube (edge `edge` metres) standing on nothing (black
/// background): three visible faces at exact right angles.
MultiViewSet renderCubeViews(double edge, const MultiViewOptions& options);

}  // namespace massage_cell::sim
