#include "hbds_views.h"

#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

namespace massage_cell::nodes {

camera::StereoModel hbdsModel(const camera::CameraCalibration& left, const camera::CameraCalibration& right,
                              bool rectify) {
  return rectify ? camera::StereoModel(left, right)
                 : camera::StereoModel(camera::declareRectified(left), camera::declareRectified(right));
}

HbdsViews prepareHbdsViews(const StereoPair& pair, int downsample, int max_pixels, const FullModel& full_model) {
  const sensor_msgs::CameraInfo& li = *pair.left_info;
  const sensor_msgs::CameraInfo& ri = *pair.right_info;
  checkImageSize(li, *pair.left_image, "left");
  checkImageSize(ri, *pair.right_image, "right");
  const camera::StereoModel& full = full_model(li, ri);
  const long processed_pixels = static_cast<long>(li.width / downsample) * static_cast<long>(li.height / downsample);
  if (max_pixels > 0 && processed_pixels > max_pixels) {  // before minutes of work and gigabytes of cost volume
    throw BadInput("images of " + sizeText(li.width, li.height) + " at downsample " + std::to_string(downsample) +
                   " are " + std::to_string(processed_pixels) + " pixels, above ~max_pixels " +
                   std::to_string(max_pixels) + ": raise downsample or max_pixels");
  }
  if (static_cast<int>(li.width) / downsample < 8 || static_cast<int>(li.height) / downsample < 8) {
    throw BadInput("images of " + sizeText(li.width, li.height) + " are too small for downsample " +
                   std::to_string(downsample));
  }
  HbdsViews v;
  v.images[0] = matchableImage(pair.left_image, "left");
  v.images[1] = matchableImage(pair.right_image, "right");
  if (v.images[0].channels() != v.images[1].channels()) {  // mixed mono / colour: match in grey
    for (auto& image : v.images) {
      if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
    }
  }
  full.rectify(v.images[0], v.images[1], &v.images[0], &v.images[1]);
  v.model = downsample > 1 ? full.downsampled(downsample) : full;
  const camera::Decimation decimation(full.size(), downsample);
  for (auto& image : v.images) image = decimation.apply(image);
  v.scale = static_cast<double>(v.model.size().width) / full.size().width;
  return v;
}

void setHbdsRange(stereo::StereoParams* params, int min_disparity, int disparity_range, int downsample,
                  const HbdsViews& v) {
  // The range is set in full-resolution pixels; at 1/s resolution the searched range is the smallest one covering it.
  const int full_dmax = min_disparity + disparity_range - 1;
  params->cost.dmin = static_cast<int>(std::floor(min_disparity * v.scale));
  params->cost.dmax = static_cast<int>(std::ceil(full_dmax * v.scale));
  if (params->cost.dmax >= v.model.size().width) {
    throw BadInput("disparity range " + std::to_string(min_disparity) + ".." + std::to_string(full_dmax) +
                   (downsample > 1
                        ? " (" + std::to_string(params->cost.dmin) + ".." + std::to_string(params->cost.dmax) +
                              " at downsample " + std::to_string(downsample) + ")"
                        : std::string()) +
                   " is wider than the image (width " + std::to_string(v.model.size().width) + ")");
  }
}

}  // namespace massage_cell::nodes
