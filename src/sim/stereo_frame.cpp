#include "massage_cell/sim/stereo_frame.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

namespace massage_cell::sim {

cv::Mat disparityFromDepth(const cv::Mat& depth, double fx, double baseline) {
  CV_Assert(depth.type() == CV_32F);
  cv::Mat disparity(depth.size(), CV_32F);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const double fb = fx * baseline;
  for (int y = 0; y < depth.rows; ++y) {
    const float* z = depth.ptr<float>(y);
    float* d = disparity.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x)
      d[x] = std::isfinite(z[x]) && z[x] > 0.0f ? static_cast<float>(fb / z[x]) : nan;
  }
  return disparity;
}

bool isVisible(const Renderer& renderer, const CameraModel& camera, const Eigen::Vector3d& p, double tolerance) {
  Eigen::Vector2d pixel;
  if (!camera.project(p, &pixel)) return false;
  if (pixel.x() < -0.5 || pixel.y() < -0.5 || pixel.x() > camera.width - 0.5 || pixel.y() > camera.height - 0.5) {
    return false;
  }
  const Eigen::Vector3d to_point = p - camera.centre();
  Hit hit;
  if (!renderer.intersect(camera.centre(), to_point, &hit)) return false;
  return hit.distance >= to_point.norm() - tolerance;
}

StereoFrame renderStereoFrame(const Renderer& renderer, const StereoPairModel& pair, const Lighting& lighting,
                              const RenderOptions& options) {
  StereoFrame frame;
  frame.left = renderer.render(pair.left, lighting, options);
  RenderOptions right_options = options;
  right_options.noise_seed = options.noise_seed ^ 0x9e3779b9u;  // independent noise in the right view
  frame.right = renderer.render(pair.right, lighting, right_options);
  if (pair.rectified) {
    const double fx = pair.left_info.P[0];
    frame.left_disparity = disparityFromDepth(frame.left.depth, fx, pair.baseline());
    frame.right_disparity = disparityFromDepth(frame.right.depth, fx, pair.baseline());
  }
  frame.left_visible = cv::Mat::zeros(frame.left.depth.size(), CV_8U);
  cv::parallel_for_(cv::Range(0, frame.left.points.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const cv::Vec3f* p = frame.left.points.ptr<cv::Vec3f>(y);
      unsigned char* v = frame.left_visible.ptr<unsigned char>(y);
      for (int x = 0; x < frame.left.points.cols; ++x) {
        if (!std::isfinite(p[x][0])) continue;
        v[x] = isVisible(renderer, pair.right, Eigen::Vector3d(p[x][0], p[x][1], p[x][2])) ? 255 : 0;
      }
    }
  });
  return frame;
}

std::map<std::string, Eigen::Vector3d> toCameraFrame(const std::map<std::string, Eigen::Vector3d>& world_points,
                                                     const CameraModel& camera) {
  const Eigen::Isometry3d camera_from_world = camera.world_from_camera.inverse();
  std::map<std::string, Eigen::Vector3d> out;
  for (const auto& [name, p] : world_points) out[name] = camera_from_world * p;
  return out;
}

void writeImage(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot write '" + path + "': " + e.what());
  }
  if (!ok) throw std::runtime_error("cannot write '" + path + "'");
}

void writePfm(const std::string& path, const cv::Mat& map) {
  CV_Assert(map.type() == CV_32F || map.type() == CV_32FC3);
  writeImage(path, map);  // OpenCV's PFM codec keeps NaN
}

}  // namespace massage_cell::sim
