// render_scene's output files: the rendered images and maps, the
// calibrations, the ground truth YAML files and the preview picture.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <opencv2/core.hpp>

#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/ground_truth.h"
#include "massage_cell/sim/stereo_frame.h"

namespace massage_cell::tools::render_scene {

namespace fs = std::filesystem;

/// Writes `out` (and a newline) to `path`; throws std::runtime_error when it cannot.
void writeYaml(const fs::path& path, const YAML::Emitter& out);

/// Map entries name: [x, y, z] (flow lists) into an open map.
void emitPointEntries(YAML::Emitter& out, const std::map<std::string, Eigen::Vector3d>& points);

/// acupoints.yaml: name -> [x, y, z].
void writePoints(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& points);

/// Landmarks (name -> [x, y, z]) plus the spine midline as a list of points.
void writeLandmarks(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& landmarks,
                    const std::vector<Eigen::Vector3d>& midline);

/// acupoints_truth.yaml: the acupoints' and landmarks' truth in the left optical frame and raw pixels.
void writeTruth(const fs::path& path, const std::map<std::string, sim::PointTruth>& acupoints,
                const std::map<std::string, sim::PointTruth>& landmarks);

/// A picture of a rendered pair: left | right | GT disparity (colour) | left
/// with the acupoints (green: in view, red: not in view), landmarks (blue) and midline (yellow).
cv::Mat previewImage(const sim::StereoFrame& f, const sim::CameraModel& left,
                     const std::map<std::string, sim::PointTruth>& acupoints,
                     const std::map<std::string, Eigen::Vector3d>& landmarks,
                     const std::vector<Eigen::Vector3d>& midline);

/// The names of the points whose `in_view` is `in_view`.
std::vector<std::string> namesInView(const std::map<std::string, sim::PointTruth>& truth, bool in_view);

/// The pair's images and maps (see the usage's Output), their names added to `files`.
void writeStereoFrame(const fs::path& dir, const sim::StereoPairModel& pair, const sim::StereoFrame& f,
                      std::vector<std::string>& files);

/// left_camera_info.yaml and right_camera_info.yaml, their names added to `files`.
void writeCalibrations(const fs::path& dir, const sim::StereoPairModel& pair, std::vector<std::string>& files);

}  // namespace massage_cell::tools::render_scene
