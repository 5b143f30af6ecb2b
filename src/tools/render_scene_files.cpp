#include "render_scene_files.h"

#include <algorithm>
#include <fstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/sim/renderer.h"

namespace massage_cell::tools::render_scene {
namespace {

void emitTruth(YAML::Emitter& out, const std::map<std::string, sim::PointTruth>& truth) {
  out << YAML::BeginMap;
  for (const auto& [name, t] : truth) {
    out << YAML::Key << name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "left_optical" << YAML::Value << YAML::Flow
        << std::vector<double>{t.left_optical.x(), t.left_optical.y(), t.left_optical.z()};
    out << YAML::Key << "left_pixel" << YAML::Value << YAML::Flow
        << std::vector<double>{t.left_pixel.x(), t.left_pixel.y()};
    out << YAML::Key << "right_pixel" << YAML::Value << YAML::Flow
        << std::vector<double>{t.right_pixel.x(), t.right_pixel.y()};
    out << YAML::Key << "label" << YAML::Value << sim::labelName(t.left_label);
    out << YAML::Key << "in_view" << YAML::Value << t.in_view;
    out << YAML::Key << "reason" << YAML::Value << t.reason << YAML::EndMap;
  }
  out << YAML::EndMap;
}

/// World points -> optical-frame point map (NaN kept).
cv::Mat opticalPoints(const cv::Mat& world_points, const sim::CameraModel& c) {
  const Eigen::Isometry3f camera_from_world = c.world_from_camera.inverse().cast<float>();
  cv::Mat out(world_points.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y) {
    const cv::Vec3f* in = world_points.ptr<cv::Vec3f>(y);
    cv::Vec3f* o = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < out.cols; ++x) {
      const Eigen::Vector3f p = camera_from_world * Eigen::Vector3f(in[x][0], in[x][1], in[x][2]);
      o[x] = cv::Vec3f(p.x(), p.y(), p.z());
    }
  }
  return out;
}

}  // namespace

void writeYaml(const fs::path& path, const YAML::Emitter& out) {
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
}

void emitPointEntries(YAML::Emitter& out, const std::map<std::string, Eigen::Vector3d>& points) {
  for (const auto& [name, p] : points)
    out << YAML::Key << name << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
}

void writePoints(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& points) {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  out << YAML::BeginMap;
  emitPointEntries(out, points);
  out << YAML::EndMap;
  writeYaml(path, out);
}

void writeLandmarks(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& landmarks,
                    const std::vector<Eigen::Vector3d>& midline) {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  out << YAML::BeginMap;
  emitPointEntries(out, landmarks);
  out << YAML::Key << "midline" << YAML::Value << YAML::BeginSeq;
  for (const auto& p : midline) out << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::EndSeq << YAML::EndMap;
  writeYaml(path, out);
}

void writeTruth(const fs::path& path, const std::map<std::string, sim::PointTruth>& acupoints,
                const std::map<std::string, sim::PointTruth>& landmarks) {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  out << YAML::BeginMap << YAML::Key << "frame_id" << YAML::Value << "left optical frame";
  out << YAML::Key << "pixels" << YAML::Value << "raw images as rendered, (0, 0) = centre of the top-left pixel";
  out << YAML::Key << "acupoints" << YAML::Value;
  emitTruth(out, acupoints);
  out << YAML::Key << "landmarks" << YAML::Value;
  emitTruth(out, landmarks);
  out << YAML::EndMap;
  writeYaml(path, out);
}

cv::Mat previewImage(const sim::StereoFrame& f, const sim::CameraModel& left,
                     const std::map<std::string, sim::PointTruth>& acupoints,
                     const std::map<std::string, Eigen::Vector3d>& landmarks,
                     const std::vector<Eigen::Vector3d>& midline) {
  std::vector<cv::Mat> tiles{f.left.image, f.right.image};
  if (!f.left_disparity.empty()) {
    cv::Mat d = f.left_disparity.clone(), valid = (d == d), shown;
    double lo = 0, hi = 1;
    cv::minMaxLoc(d, &lo, &hi, nullptr, nullptr, valid);
    cv::patchNaNs(d, lo);
    d.convertTo(shown, CV_8U, 255.0 / std::max(1e-6, hi - lo), -lo * 255.0 / std::max(1e-6, hi - lo));
    cv::applyColorMap(shown, shown, cv::COLORMAP_TURBO);
    shown.setTo(cv::Scalar(0, 0, 0), ~valid);
    tiles.push_back(shown);
  }
  cv::Mat overlay = f.left.image.clone();
  const int r = std::max(2, overlay.cols / 200);
  auto dot = [&](const Eigen::Vector3d& p, const cv::Scalar& colour, int radius) {
    Eigen::Vector2d px;
    if (left.project(p, &px)) cv::circle(overlay, cv::Point2d(px.x(), px.y()), radius, colour, cv::FILLED, cv::LINE_AA);
  };
  for (const auto& p : midline) dot(p, cv::Scalar(0, 220, 255), std::max(1, r / 2));
  for (const auto& [name, t] : acupoints)
    dot(t.world, t.in_view ? cv::Scalar(40, 200, 40) : cv::Scalar(40, 40, 230), r);
  for (const auto& [name, p] : landmarks) dot(p, cv::Scalar(230, 120, 40), r);
  tiles.push_back(overlay);
  cv::Mat out;
  cv::hconcat(tiles, out);
  return out;
}

std::vector<std::string> namesInView(const std::map<std::string, sim::PointTruth>& truth, bool in_view) {
  std::vector<std::string> names;
  for (const auto& [name, t] : truth) {
    if (t.in_view == in_view) names.push_back(name);
  }
  return names;
}

void writeStereoFrame(const fs::path& dir, const sim::StereoPairModel& pair, const sim::StereoFrame& f,
                      std::vector<std::string>& files) {
  auto add = [&](const std::string& name) {
    files.push_back(name);
    return (dir / name).string();
  };
  sim::writeImage(add("left.png"), f.left.image);
  sim::writeImage(add("right.png"), f.right.image);
  sim::writePfm(add("left_depth.pfm"), f.left.depth);
  sim::writePfm(add("right_depth.pfm"), f.right.depth);
  sim::writePfm(add("left_points.pfm"), opticalPoints(f.left.points, pair.left));
  sim::writePfm(add("right_points.pfm"), opticalPoints(f.right.points, pair.right));
  if (pair.rectified) {
    sim::writePfm(add("left_disparity.pfm"), f.left_disparity);
    sim::writePfm(add("right_disparity.pfm"), f.right_disparity);
  }
  sim::writeImage(add("left_labels.png"), f.left.labels);
  sim::writeImage(add("right_labels.png"), f.right.labels);
  sim::writeImage(add("left_visible.png"), f.left_visible);
}

void writeCalibrations(const fs::path& dir, const sim::StereoPairModel& pair, std::vector<std::string>& files) {
  camera::writeCameraInfoYaml((dir / "left_camera_info.yaml").string(), pair.left_info, "sim_left");
  camera::writeCameraInfoYaml((dir / "right_camera_info.yaml").string(), pair.right_info, "sim_right");
  files.push_back("left_camera_info.yaml");
  files.push_back("right_camera_info.yaml");
}

}  // namespace massage_cell::tools::render_scene
