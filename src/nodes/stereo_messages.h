// The hbds node's outputs as ROS messages: which disparities are valid, and the stereo_msgs/DisparityImage,
// organised sensor_msgs/PointCloud2 and depth camera_info (REP 118) built from them.
#pragma once

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <stereo_msgs/DisparityImage.h>
#include <opencv2/core.hpp>

#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/stereo/pipeline.h"

namespace massage_cell::nodes {

/// The disparities a pair's result may publish.
struct ValidDisparity {
  cv::Mat disparity;  ///< CV_32F x_l - x_r where valid, NaN elsewhere
  cv::Mat mask;       ///< CV_8U 255 where valid
  cv::Mat confirmed;  ///< CV_8U 255 where the disparity is a measurement (the node's `confidence`), 0 elsewhere
  int x0 = 0;         ///< the first column that can be valid
  /// Shares (0..1) of the pixels with a disparity (x >= x0, filled ones included) at the range's far / near end.
  double far_end = 0.0, near_end = 0.0;
};

/// Whether a disparity lies at an end of the search range dmin..dmax (within half a level): whatever is farther than
/// the range piles up at its far end (`dmin`), whatever is nearer at its near end (`dmax`), so such a disparity only
/// bounds the depth, whatever the left-right check says.
inline bool atFarEnd(float d, int dmin) { return d <= static_cast<float>(dmin) + 0.5f; }
inline bool atNearEnd(float d, int dmax) { return d >= static_cast<float>(dmax) - 0.5f; }

/// Invalid: what the method left empty (NaN); without the left-right check the left band x < dmax, whose search ran
/// off the right image's edge; with it and `lr_fill` off, what is not confirmed (with `lr_fill` on those pixels hold
/// the background's disparity and `confirmed` marks them). Confirmed: what the right view confirms (without the
/// check: what is valid), except the range's ends (atFarEnd, atNearEnd).
ValidDisparity validDisparity(const stereo::MatchResult& result, const stereo::StereoParams& params, bool lr_fill);

/// stereo_msgs/DisparityImage as the message defines it: d = x_l - x_r - (cx_l - cx_r); invalid pixels hold
/// min_disparity - 1, below the searched range (as stereo_image_proc does). `delta_d`: the disparity's resolution.
stereo_msgs::DisparityImagePtr disparityImage(const std_msgs::Header& header, const camera::StereoModel& model,
                                              const stereo::StereoParams& params, const ValidDisparity& valid,
                                              float delta_d);

/// The camera_info of the depth image: the processed images' rectified left camera.
sensor_msgs::CameraInfo depthInfo(const std_msgs::Header& header, const camera::StereoModel& model);

/// Organised cloud `x y z rgb` of `points` (CV_32FC3, NaN where unknown) coloured by `colours` (8-bit grey or BGR of
/// the same size): REP 103, the left optical frame.
sensor_msgs::PointCloud2Ptr pointCloud(const std_msgs::Header& header, const cv::Mat& points, const cv::Mat& colours);

/// The confident surface for a robot (the arm's body model): an unorganised cloud `x y z` of `points` (CV_32FC3,
/// the left optical frame) where `confirmed` (ValidDisparity::confirmed of a left-right checked result) is non-zero,
/// one pixel in `step` across and down.
sensor_msgs::PointCloud2Ptr surfaceCloud(const std_msgs::Header& header, const cv::Mat& points,
                                         const cv::Mat& confirmed, int step);

}  // namespace massage_cell::nodes
