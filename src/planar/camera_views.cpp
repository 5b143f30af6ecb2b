// Views from camera_info calibrations and poses (see camera_views.h).
#include "massage_cell/planar/camera_views.h"

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/calibration_io.h"

namespace massage_cell::planar {

namespace {

template <std::size_t N>
bool allFinite(const std::array<double, N>& a) {
  for (double v : a) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

cv::Mat rectifiedImage(const std::string& name, const cv::Mat& image, const camera::CameraCalibration& info,
                       const cv::Matx33d& K, const cv::Matx33d& R, const cv::Matx33d& Pk) {
  bool identity = K == Pk && R == cv::Matx33d::eye();
  for (double d : info.D) identity = identity && d == 0.0;
  if (identity) return image.clone();
  cv::Mat map1, map2;
  const cv::Size size(info.width, info.height);
  if (info.distortion_model == "plumb_bob" || info.distortion_model == "rational_polynomial") {
    cv::initUndistortRectifyMap(K, info.D, R, Pk, size, CV_32FC1, map1, map2);
  } else if (info.distortion_model == "equidistant") {
    if (info.D.size() != 4) {
      throw std::invalid_argument(name + ": equidistant distortion needs 4 coefficients, got " +
                                  std::to_string(info.D.size()));
    }
    cv::fisheye::initUndistortRectifyMap(K, info.D, R, Pk, size, CV_32FC1, map1, map2);
  } else {
    throw std::invalid_argument(name + ": unknown distortion model '" + info.distortion_model +
                                "' (expected plumb_bob, rational_polynomial or equidistant)");
  }
  cv::Mat out;
  cv::remap(image, out, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return out;
}

}  // namespace

View viewFromCameraInfo(const std::string& name, const cv::Mat& image, const camera::CameraCalibration& info,
                        const Eigen::Isometry3d& world_from_camera) {
  if (!info.isCalibrated()) throw std::invalid_argument(name + ": the camera is not calibrated (K[0] = 0)");
  if (image.empty() || image.cols != info.width || image.rows != info.height) {
    throw std::invalid_argument(name + ": image " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                                " does not match its calibration " + std::to_string(info.width) + "x" +
                                std::to_string(info.height));
  }
  bool finite = allFinite(info.K) && allFinite(info.R) && allFinite(info.P) && world_from_camera.matrix().allFinite();
  for (double d : info.D) finite = finite && std::isfinite(d);
  if (!finite) throw std::invalid_argument(name + ": non-finite value in K, D, R, P or the pose");
  const cv::Matx33d K(info.K.data()), R(info.R.data());
  const cv::Matx33d Pk(info.P[0], info.P[1], info.P[2], info.P[4], info.P[5], info.P[6], info.P[8], info.P[9],
                       info.P[10]);
  View view;
  view.name = name;
  view.image = rectifiedImage(name, image, info, K, R, Pk);
  Eigen::Matrix3d Pe, Re;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      Pe(r, c) = Pk(r, c);
      Re(r, c) = R(r, c);
    }
  }
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  Projection P;
  P.leftCols<3>() = Pe * Re * camera_from_world.linear();
  P.col(3) = Pe * Re * camera_from_world.translation();
  view.P = normalisedProjection(P);
  return view;
}

namespace {

std::vector<double> numbers(const YAML::Node& node, const std::string& key, std::size_t count,
                            const std::string& where) {
  const YAML::Node list = node[key];
  if (!list || !list.IsSequence() || list.size() != count) {
    throw std::runtime_error(where + ": '" + key + "' must be a list of " + std::to_string(count) + " numbers");
  }
  std::vector<double> out;
  for (const YAML::Node& v : list) {
    double x = 0.0;
    if (!YAML::convert<double>::decode(v, x) || !std::isfinite(x)) {
      throw std::runtime_error(where + ": '" + key + "' holds a value that is not a finite number");
    }
    out.push_back(x);
  }
  return out;
}

std::string text(const YAML::Node& node, const std::string& key, const std::string& where) {
  if (!node[key] || !node[key].IsScalar()) throw std::runtime_error(where + ": '" + key + "' is missing");
  return node[key].as<std::string>();
}

std::vector<View> viewYaml(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
  if (!root["views"] || !root["views"].IsSequence()) {
    throw std::runtime_error(file.string() + ": expected a list 'views'");
  }
  const std::filesystem::path folder = file.parent_path();
  std::vector<View> views;
  for (std::size_t i = 0; i < root["views"].size(); ++i) {
    const YAML::Node v = root["views"][i];
    const std::string where = file.string() + ": views[" + std::to_string(i) + "]";
    const std::filesystem::path image_path = folder / text(v, "image", where);
    const cv::Mat image = cv::imread(image_path.string(), cv::IMREAD_COLOR);
    if (image.empty()) throw std::runtime_error(where + ": cannot read image " + image_path.string());
    const camera::CameraCalibration info =
        camera::readCameraInfoYaml((folder / text(v, "camera_info", where)).string());
    const auto t = numbers(v, "position", 3, where);
    const auto q = numbers(v, "orientation", 4, where);
    const Eigen::Quaterniond rotation(q[3], q[0], q[1], q[2]);
    if (std::abs(rotation.norm() - 1.0) > 1e-3)
      throw std::runtime_error(where + ": orientation is not a unit quaternion");
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = rotation.normalized().toRotationMatrix();
    pose.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    try {
      views.push_back(viewFromCameraInfo(image_path.filename().string(), image, info, pose));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + ": " + e.what());
    }
  }
  return views;
}

// A yaml-cpp error the field readers did not name still names the file and its line.
std::vector<View> loadViewYaml(const std::filesystem::path& file) {
  try {
    return viewYaml(file);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
}

}  // namespace

std::vector<View> loadViewSet(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (fs::is_directory(p)) {
    if (fs::exists(p / "views.yaml")) return loadViewYaml(p / "views.yaml");
    if (fs::is_directory(p / "2D") && fs::is_directory(p / "images")) return loadVggViews(path);
    throw std::runtime_error(path + ": neither views.yaml nor a VGG layout (images/, 2D/*.P) in this folder");
  }
  if (!fs::exists(p)) throw std::runtime_error(path + ": no such file or folder");
  return loadViewYaml(p);
}

}  // namespace massage_cell::planar
