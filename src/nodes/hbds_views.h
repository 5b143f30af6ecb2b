// How the hbds node turns a stereo pair into the views it matches and the disparity range it searches: shared by
// the nodelet (hbds_nodelet.cpp) and the stereo_bag_eval tool (src/tools/stereo_bag_eval.cpp), which scores the
// node's depth on the bundled recordings, so that both prepare a pair the same way.
#pragma once

#include <functional>

#include <sensor_msgs/CameraInfo.h>
#include <opencv2/core.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/stereo/pipeline.h"
#include "stereo_pair_input.h"

namespace massage_cell::nodes {

/// A pair rectified and downsampled, with the model of the processed images.
struct HbdsViews {
  cv::Mat images[2];
  camera::StereoModel model;  ///< of the processed (rectified, downsampled) images
  double scale = 1.0;         ///< processed / full-resolution width
};

/// The full-resolution model of a pair's calibrations: rectifying them (`rectify`, the node's ~rectify), or taking
/// the images as rectified whatever the calibrations say (D = 0, R = I, K = P). Throws std::invalid_argument as
/// camera::StereoModel does.
camera::StereoModel hbdsModel(const camera::CameraCalibration& left, const camera::CameraCalibration& right,
                              bool rectify);

/// The full-resolution model of a pair's camera_info (the caller caches it; throws BadInput when unusable).
using FullModel = std::function<const camera::StereoModel&(const sensor_msgs::CameraInfo& left,
                                                           const sensor_msgs::CameraInfo& right)>;

/// The views of a pair as the node matches them: the images checked against their camera_info, 8-bit grey or BGR
/// (grey both when mixed), rectified with `full_model`'s model, shrunk by camera::Decimation at 1/`downsample`.
/// Throws BadInput naming the problem (sizes, encodings, calibration, more processed pixels than `max_pixels`
/// (0: no limit), images too small for `downsample`).
HbdsViews prepareHbdsViews(const StereoPair& pair, int downsample, int max_pixels, const FullModel& full_model);

/// Sets params->cost.dmin / dmax to the range `min_disparity`..`min_disparity + disparity_range - 1`, set in
/// full-resolution pixels, at the views' resolution (the smallest range covering it). Throws BadInput when it is
/// wider than the processed image.
void setHbdsRange(stereo::StereoParams* params, int min_disparity, int disparity_range, int downsample,
                  const HbdsViews& views);

}  // namespace massage_cell::nodes
