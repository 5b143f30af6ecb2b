// render_sample: writes the project's sample stereo data, a textured plane
// seen by a rectified pair (massage_cell::sim::renderStereo), as numbered
// image pairs with camera_info calibrations and the ground truth.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>

#include "cli.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/sim/textured_plane.h"

namespace {

namespace sim = massage_cell::sim;
using massage_cell::tools::OptionTable;
using massage_cell::tools::parseArguments;
using massage_cell::tools::parseDouble;
using massage_cell::tools::parseInt;
using massage_cell::tools::parseSeed;
using massage_cell::tools::require;
using massage_cell::tools::UsageError;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDriftPerFrame = 0.001;  // metres: sideways texture motion between frames
constexpr int kMaxImageSide = 16384;
constexpr int kJpegQuality = 92;

const char* const kUsage = R"(Usage: render_sample --out DIR [options]

Renders a textured plane seen by an ideal rectified stereo pair and writes
  DIR/<prefix-left>0000.<format>, DIR/<prefix-right>0000.<format>, ...
  DIR/left.yaml, DIR/right.yaml   camera_info calibrations (sample_left, sample_right)
  DIR/ground_truth.yaml           per frame: plane distance (m), disparity at the image centre (px)
The plane stays fronto-parallel; its distance "breathes" as
distance + amplitude * sin(2 pi i / frames) and its texture drifts sideways by
1 mm per frame.

Options:
  --out DIR             output directory, created if missing (required)
  --frames N            number of stereo pairs (default 20, >= 1)
  --width W             image width in pixels (default 320, at most 16384)
  --height H            image height in pixels (default 240, at most 16384)
  --fx F                focal length in pixels, fx = fy (default 300); the
                        principal point is the image centre
  --baseline B          stereo baseline in metres (default 0.06)
  --distance D          mean plane distance in metres (default 0.8)
  --amplitude A         breathing amplitude in metres (default 0.005, < distance)
  --format jpg|png      image format (default jpg, quality 92)
  --seed S              texture seed, 0..4294967295 (default 1)
  --noise SIGMA         Gaussian sensor noise in grey levels (default 1.0, 0 = none)
  --prefix-left P       left image file prefix (default left_)
  --prefix-right P      right image file prefix (default right_)
  -h, --help            print this help and exit
Exit status: 0 success, 1 output could not be written, 2 bad command line.
)";

struct Options {
  std::string out;
  int frames = 20;
  int width = 320;
  int height = 240;
  double fx = 300.0;
  double baseline = 0.06;
  double distance = 0.8;
  double amplitude = 0.005;
  std::string format = "jpg";
  std::uint32_t seed = 1;
  double noise = 1.0;
  std::string prefix_left = "left_";
  std::string prefix_right = "right_";
};

/// Parses the command line; returns false when --help was printed.
bool parseOptions(int argc, char** argv, Options& o) {
  OptionTable table;
  table.values = {
      {"--out", [&](const std::string&, const std::string& v) { o.out = v; }},
      {"--frames", [&](const std::string& opt, const std::string& v) { o.frames = parseInt(opt, v); }},
      {"--width", [&](const std::string& opt, const std::string& v) { o.width = parseInt(opt, v); }},
      {"--height", [&](const std::string& opt, const std::string& v) { o.height = parseInt(opt, v); }},
      {"--fx", [&](const std::string& opt, const std::string& v) { o.fx = parseDouble(opt, v); }},
      {"--baseline", [&](const std::string& opt, const std::string& v) { o.baseline = parseDouble(opt, v); }},
      {"--distance", [&](const std::string& opt, const std::string& v) { o.distance = parseDouble(opt, v); }},
      {"--amplitude", [&](const std::string& opt, const std::string& v) { o.amplitude = parseDouble(opt, v); }},
      {"--format", [&](const std::string&, const std::string& v) { o.format = v; }},
      {"--seed", [&](const std::string& opt, const std::string& v) { o.seed = parseSeed(opt, v); }},
      {"--noise", [&](const std::string& opt, const std::string& v) { o.noise = parseDouble(opt, v); }},
      {"--prefix-left", [&](const std::string&, const std::string& v) { o.prefix_left = v; }},
      {"--prefix-right", [&](const std::string&, const std::string& v) { o.prefix_right = v; }},
  };

  if (!parseArguments(argc, argv, table, kUsage)) return false;

  require(!o.out.empty(), "--out: an output directory is required");
  require(o.frames >= 1, "--frames must be >= 1, got " + std::to_string(o.frames));
  require(o.width >= 1 && o.width <= kMaxImageSide,
          "--width must be in 1.." + std::to_string(kMaxImageSide) + ", got " + std::to_string(o.width));
  require(o.height >= 1 && o.height <= kMaxImageSide,
          "--height must be in 1.." + std::to_string(kMaxImageSide) + ", got " + std::to_string(o.height));
  require(o.fx > 0.0, "--fx must be > 0");
  require(o.baseline > 0.0, "--baseline must be > 0");
  require(o.distance > 0.0, "--distance must be > 0");
  require(o.amplitude >= 0.0, "--amplitude must be >= 0");
  require(o.amplitude < o.distance, "--amplitude must be smaller than --distance (the plane must stay in front)");
  require(o.format == "jpg" || o.format == "png", "--format must be jpg or png, got '" + o.format + "'");
  require(o.noise >= 0.0, "--noise must be >= 0");
  for (const auto& [option, prefix] :
       {std::pair{"--prefix-left", &o.prefix_left}, std::pair{"--prefix-right", &o.prefix_right}}) {
    require(!prefix->empty() && prefix->find('/') == std::string::npos,
            std::string(option) + " must be a non-empty file name prefix without '/'");
  }
  require(o.prefix_left != o.prefix_right, "--prefix-left and --prefix-right must differ");
  return true;
}

std::string frameName(const std::string& prefix, int index, const std::string& format) {
  char number[16];
  std::snprintf(number, sizeof number, "%04d", index);
  return prefix + number + "." + format;
}

void writeImage(const std::filesystem::path& path, const cv::Mat& image, const std::string& format) {
  std::vector<int> params;
  if (format == "jpg") params = {cv::IMWRITE_JPEG_QUALITY, kJpegQuality};
  if (!cv::imwrite(path.string(), image, params)) throw std::runtime_error("cannot write '" + path.string() + "'");
}

/// Renders and writes everything; throws std::runtime_error (or cv::Exception
/// from the image encoders) when the output cannot be written.
void run(const Options& o) {
  const std::filesystem::path dir(o.out);
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw std::runtime_error("cannot create output directory '" + o.out + "': " + error.message());

  sim::StereoRig rig;
  rig.width = o.width;
  rig.height = o.height;
  rig.fx = rig.fy = o.fx;
  rig.cx = (o.width - 1) / 2.0;
  rig.cy = (o.height - 1) / 2.0;
  rig.baseline = o.baseline;
  massage_cell::camera::writeCameraInfoYaml((dir / "left.yaml").string(), sim::leftCalibration(rig), "sample_left");
  massage_cell::camera::writeCameraInfoYaml((dir / "right.yaml").string(), sim::rightCalibration(rig), "sample_right");

  sim::TexturedPlane plane;
  plane.seed = o.seed;

  YAML::Emitter gt;
  gt.SetDoublePrecision(10);
  gt << YAML::BeginMap;
  gt << YAML::Key << "description" << YAML::Value
     << "fronto-parallel textured plane, left optical frame; disparity = fx * baseline / distance";
  gt << YAML::Key << "image_width" << YAML::Value << o.width;
  gt << YAML::Key << "image_height" << YAML::Value << o.height;
  gt << YAML::Key << "fx" << YAML::Value << rig.fx;
  gt << YAML::Key << "baseline" << YAML::Value << rig.baseline;
  gt << YAML::Key << "texture_seed" << YAML::Value << o.seed;
  gt << YAML::Key << "feature_size" << YAML::Value << plane.feature_size;
  gt << YAML::Key << "noise_sigma" << YAML::Value << o.noise;
  gt << YAML::Key << "frames" << YAML::Value << YAML::BeginSeq;

  double min_z = o.distance, max_z = o.distance;
  for (int i = 0; i < o.frames; ++i) {
    const double z = o.distance + o.amplitude * std::sin(2.0 * kPi * i / o.frames);
    const double disparity = rig.fx * rig.baseline / z;
    min_z = std::min(min_z, z);
    max_z = std::max(max_z, z);
    plane.point = {0.0, 0.0, z};
    plane.texture_offset = {kDriftPerFrame * i, 0.0};
    const std::uint32_t noise_seed = o.seed * 2654435761u + static_cast<std::uint32_t>(i) + 1u;
    const sim::StereoRender render = sim::renderStereo(rig, plane, 3, o.noise, noise_seed);

    const std::string left_name = frameName(o.prefix_left, i, o.format);
    const std::string right_name = frameName(o.prefix_right, i, o.format);
    writeImage(dir / left_name, render.left, o.format);
    writeImage(dir / right_name, render.right, o.format);

    gt << YAML::BeginMap;
    gt << YAML::Key << "index" << YAML::Value << i;
    gt << YAML::Key << "left" << YAML::Value << left_name;
    gt << YAML::Key << "right" << YAML::Value << right_name;
    gt << YAML::Key << "plane_distance" << YAML::Value << z;
    gt << YAML::Key << "centre_disparity" << YAML::Value << disparity;
    gt << YAML::Key << "texture_offset" << YAML::Value << YAML::Flow << YAML::BeginSeq << plane.texture_offset.x()
       << plane.texture_offset.y() << YAML::EndSeq;
    gt << YAML::EndMap;
  }
  gt << YAML::EndSeq << YAML::EndMap;

  const std::filesystem::path gt_path = dir / "ground_truth.yaml";
  std::ofstream file(gt_path);
  file << gt.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + gt_path.string() + "'");

  const double fb = rig.fx * rig.baseline;
  std::printf(
      "render_sample: wrote %d stereo pair%s (%dx%d %s) to %s; plane distance %.4f..%.4f m, "
      "disparity %.3f..%.3f px\n",
      o.frames, o.frames == 1 ? "" : "s", o.width, o.height, o.format.c_str(), dir.string().c_str(), min_z, max_z,
      fb / max_z, fb / min_z);
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  return massage_cell::tools::runTool(
      "render_sample", [&] { return parseOptions(argc, argv, options); }, [&] { run(options); });
}
