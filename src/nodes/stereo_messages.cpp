#include "stereo_messages.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <boost/make_shared.hpp>

#include "calibration_msg.h"

namespace massage_cell::nodes {

namespace {

std::uint32_t packRgb(const cv::Mat& image, int x, int y) {
  if (image.channels() == 1) {
    const std::uint32_t g = image.at<std::uint8_t>(y, x);
    return (g << 16) | (g << 8) | g;
  }
  const cv::Vec3b& bgr = image.at<cv::Vec3b>(y, x);
  return (static_cast<std::uint32_t>(bgr[2]) << 16) | (static_cast<std::uint32_t>(bgr[1]) << 8) | bgr[0];
}

}  // namespace

ValidDisparity validDisparity(const stereo::MatchResult& result, const stereo::StereoParams& params, bool lr_fill) {
  const int width = result.disparity.cols, height = result.disparity.rows;
  ValidDisparity v;
  v.x0 = params.lr_check ? 0 : params.cost.dmax;
  v.disparity.create(height, width, CV_32F);
  v.mask.create(height, width, CV_8U);
  v.confirmed.create(height, width, CV_8U);
  const cv::Mat checked = params.lr_check ? result.consistent : cv::Mat();
  long found_pixels = 0, far_pixels = 0, near_pixels = 0;
  for (int y = 0; y < height; ++y) {
    const float* in = result.disparity.ptr<float>(y);
    float* out = v.disparity.ptr<float>(y);
    unsigned char* mask = v.mask.ptr<unsigned char>(y);
    unsigned char* sure = v.confirmed.ptr<unsigned char>(y);
    const unsigned char* c = checked.empty() ? nullptr : checked.ptr<unsigned char>(y);
    for (int x = 0; x < width; ++x) {
      const bool found = x >= v.x0 && std::isfinite(in[x]);
      const bool far = found && atFarEnd(in[x], params.cost.dmin), near = found && atNearEnd(in[x], params.cost.dmax);
      found_pixels += found;
      far_pixels += far;
      near_pixels += near;
      const bool confirmed = found && (c == nullptr || c[x] != 0) && !far && !near;
      const bool ok = c != nullptr && !lr_fill ? confirmed : found;
      out[x] = ok ? in[x] : std::numeric_limits<float>::quiet_NaN();
      mask[x] = ok ? 255 : 0;
      sure[x] = confirmed ? 255 : 0;
    }
  }
  if (found_pixels > 0) {
    v.far_end = static_cast<double>(far_pixels) / static_cast<double>(found_pixels);
    v.near_end = static_cast<double>(near_pixels) / static_cast<double>(found_pixels);
  }
  return v;
}

stereo_msgs::DisparityImagePtr disparityImage(const std_msgs::Header& header, const camera::StereoModel& model,
                                              const stereo::StereoParams& params, const ValidDisparity& valid,
                                              float delta_d) {
  const float offset = static_cast<float>(model.offset());
  auto msg = boost::make_shared<stereo_msgs::DisparityImage>();
  msg->header = header;
  msg->f = static_cast<float>(model.fx());
  msg->T = static_cast<float>(model.baseline());
  msg->min_disparity = static_cast<float>(params.cost.dmin) - offset;
  msg->max_disparity = static_cast<float>(params.cost.dmax) - offset;
  msg->delta_d = delta_d;
  msg->valid_window.x_offset = valid.x0;
  msg->valid_window.width = valid.disparity.cols - valid.x0;
  msg->valid_window.height = valid.disparity.rows;
  cv::Mat published = valid.disparity - offset;
  cv::patchNaNs(published, msg->min_disparity - 1.0f);
  msg->image = *cv_bridge::CvImage(header, sensor_msgs::image_encodings::TYPE_32FC1, published).toImageMsg();
  return msg;
}

sensor_msgs::CameraInfo depthInfo(const std_msgs::Header& header, const camera::StereoModel& model) {
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = model.size().width;
  info.height = model.size().height;
  fromCalibration(model.rectifiedLeft(), info);
  return info;
}

sensor_msgs::PointCloud2Ptr pointCloud(const std_msgs::Header& header, const cv::Mat& points, const cv::Mat& colours) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header = header;
  cloud->height = points.rows;
  cloud->width = points.cols;
  sensor_msgs::PointCloud2Modifier modifier(*cloud);
  modifier.setPointCloud2Fields(4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                                "z", 1, sensor_msgs::PointField::FLOAT32, "rgb", 1, sensor_msgs::PointField::FLOAT32);
  cloud->is_dense = false;
  cloud->is_bigendian = false;
  sensor_msgs::PointCloud2Iterator<float> it(*cloud, "x");
  for (int y = 0; y < points.rows; ++y) {
    const cv::Vec3f* p = points.ptr<cv::Vec3f>(y);
    for (int x = 0; x < points.cols; ++x, ++it) {
      float* out = &it[0];
      out[0] = p[x][0];
      out[1] = p[x][1];
      out[2] = p[x][2];
      const std::uint32_t rgb = packRgb(colours, x, y);
      std::memcpy(&out[3], &rgb, sizeof(rgb));
    }
  }
  return cloud;
}

sensor_msgs::PointCloud2Ptr surfaceCloud(const std_msgs::Header& header, const cv::Mat& points,
                                         const cv::Mat& confirmed, int step) {
  std::vector<cv::Vec3f> kept;
  for (int y = step / 2; y < points.rows; y += step) {
    for (int x = step / 2; x < points.cols; x += step) {
      const cv::Vec3f& p = points.at<cv::Vec3f>(y, x);
      if (confirmed.at<unsigned char>(y, x) == 0) continue;
      if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) kept.push_back(p);
    }
  }
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header = header;
  sensor_msgs::PointCloud2Modifier modifier(*cloud);
  modifier.setPointCloud2Fields(3, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                                "z", 1, sensor_msgs::PointField::FLOAT32);
  modifier.resize(kept.size());
  cloud->height = 1;
  cloud->width = static_cast<std::uint32_t>(kept.size());
  cloud->is_dense = true;
  cloud->is_bigendian = false;
  sensor_msgs::PointCloud2Iterator<float> it(*cloud, "x");
  for (const cv::Vec3f& p : kept) {
    it[0] = p[0];
    it[1] = p[1];
    it[2] = p[2];
    ++it;
  }
  return cloud;
}

}  // namespace massage_cell::nodes
