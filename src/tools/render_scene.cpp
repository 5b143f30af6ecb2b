// render_scene: renders the massage cell's scenes with exact ground truth
// (massage_cell::sim): a subject lying prone under the stereo camera, stacked
// boxes, the thesis's efficiency sets and multi-view sets. See --help.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include "cli.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"

namespace {

namespace fs = std::filesystem;
namespace sim = massage_cell::sim;
namespace camera = massage_cell::camera;
using massage_cell::tools::OptionTable;
using massage_cell::tools::parseDouble;
using massage_cell::tools::parseInt;
using massage_cell::tools::parseSeed;
using massage_cell::tools::require;
using massage_cell::tools::UsageError;
using Clock = std::chrono::steady_clock;

const char* const kUsage = R"(Usage: render_scene --preset PRESET --out DIR [options]

Renders a scene of the massage cell by ray tracing (Embree) and writes the
images with their exact ground truth into DIR (created if missing).

Presets:
  back                 a subject lying prone on the massage table under the stereo camera
  boxes                textured boxes stacked on the table (planar reconstruction)
  efficiency_layers    thesis Fig. 2.9: fronto-parallel layers; left view and right
                       views R1..R8 spanning 8, 16, ..., 64 disparity levels
  efficiency_gradient  thesis Fig. 2.10: one slanted plane; same views
  multiview            --views calibrated views of the boxes scene

Options:
  --out DIR                output folder (required)
  --subject N              0 = the mean subject, 1..28 = the thesis's 28 subjects (default 0)
  --body-seed S            seed the 28 subjects are drawn from (default 2024)
  --light L                top_left | top_centre | top_right (default top_centre)
  --shift M                camera shift along the table, metres (thesis: 0, 0.04, 0.07, 0.14; default 0)
  --camera-height Z        height of the cameras above the table top, metres (default 0.95)
  --width W --height H     image size (default 640 x 480)
  --fx F                   focal length, pixels (default 500)
  --baseline B             stereo baseline, metres (default 0.10)
  --raw                    unrectified pair with lens distortion (default: rectified, ideal)
  --supersample N          rays per pixel N x N (default 2)
  --noise SIGMA            sensor noise, grey levels (default 1.0)
  --exposure E             exposure factor (default 1.0)
  --seed S                 seed of textures and noise (default 1)
  --breathing-phase P      0..1, phase of the breath (default 0)
  --breathing-amplitude A  metres (default 0.004)
  --frames N               back preset: a session of N frames of the breathing subject (default 1)
  --rate HZ                frames per second of a session (default 10; a breath lasts 4 s)
  --views N                multiview: number of views (default 3)
  --boxes N                boxes / multiview: number of stacked boxes (default 3)
  -h, --help               print this help

Output (stereo presets, one frame): left.png right.png, left_depth.pfm right_depth.pfm
(metres, z in each optical frame), left_points.pfm right_points.pfm (XYZ in each optical
frame), left_disparity.pfm right_disparity.pfm (pixels; rectified pairs only),
left_labels.png right_labels.png (0 background, 1 back, 2 table, 3 floor, 9 plane,
10+ box faces), left_visible.png (255: seen by the right camera too),
left_camera_info.yaml right_camera_info.yaml (ROS calibration), acupoints.yaml and
landmarks.yaml (back: name -> [x, y, z] in the left optical frame, metres; landmarks.yaml
also holds the spine midline), preview.png (left | right | GT disparity | acupoints
overlaid), manifest.yaml.
A session (--frames > 1) writes left_NNNN.png / right_NNNN.png, the calibrations,
ground_truth.yaml (per frame: time, breathing phase, acupoints) and manifest.yaml.
Exit status: 0 success, 1 rendering or writing failed (or the back is not in view),
2 bad command line.
)";

struct Options {
  std::string preset;
  std::string out;
  int subject = 0;
  std::uint32_t body_seed = 2024;
  std::string light = "top_centre";
  double shift = 0.0;
  double camera_height = 0.95;
  int width = 640, height = 480;
  double fx = 500.0;
  double baseline = 0.10;
  bool raw = false;
  int supersample = 2;
  double noise = 1.0;
  double exposure = 1.0;
  std::uint32_t seed = 1;
  double breathing_phase = 0.0;
  double breathing_amplitude = 0.004;
  int frames = 1;
  double rate = 10.0;
  int views = 3;
  int boxes = 3;
};

constexpr double kBreathPeriod = 4.0;  // seconds per breath (15 breaths a minute)

bool parseOptions(int argc, char** argv, Options& o) {
  OptionTable t;
  auto text = [](std::string& field) { return [&field](const std::string&, const std::string& v) { field = v; }; };
  auto integer = [](int& field) { return [&field](const std::string& opt, const std::string& v) { field = parseInt(opt, v); }; };
  auto number = [](double& field) {
    return [&field](const std::string& opt, const std::string& v) { field = parseDouble(opt, v); };
  };
  auto seed = [](std::uint32_t& field) {
    return [&field](const std::string& opt, const std::string& v) { field = parseSeed(opt, v); };
  };
  t.values = {{"--preset", text(o.preset)},
              {"--out", text(o.out)},
              {"--subject", integer(o.subject)},
              {"--body-seed", seed(o.body_seed)},
              {"--light", text(o.light)},
              {"--shift", number(o.shift)},
              {"--camera-height", number(o.camera_height)},
              {"--width", integer(o.width)},
              {"--height", integer(o.height)},
              {"--fx", number(o.fx)},
              {"--baseline", number(o.baseline)},
              {"--supersample", integer(o.supersample)},
              {"--noise", number(o.noise)},
              {"--exposure", number(o.exposure)},
              {"--seed", seed(o.seed)},
              {"--breathing-phase", number(o.breathing_phase)},
              {"--breathing-amplitude", number(o.breathing_amplitude)},
              {"--frames", integer(o.frames)},
              {"--rate", number(o.rate)},
              {"--views", integer(o.views)},
              {"--boxes", integer(o.boxes)}};
  t.flags = {{"--raw", [&o] { o.raw = true; }}};
  if (!massage_cell::tools::parseArguments(argc, argv, t, kUsage)) return false;

  static const std::vector<std::string> presets{"back", "boxes", "efficiency_layers", "efficiency_gradient",
                                                "multiview"};
  require(!o.preset.empty(), "--preset is required (back, boxes, efficiency_layers, efficiency_gradient, multiview)");
  require(std::find(presets.begin(), presets.end(), o.preset) != presets.end(),
          "unknown preset '" + o.preset + "' (back, boxes, efficiency_layers, efficiency_gradient, multiview)");
  require(!o.out.empty(), "--out: an output folder is required");
  require(o.subject >= 0 && o.subject <= 28, "unknown subject " + std::to_string(o.subject) + " (0 = mean, 1..28)");
  require(o.light == "top_left" || o.light == "top_centre" || o.light == "top_right",
          "--light must be top_left, top_centre or top_right, got '" + o.light + "'");
  require(o.width >= 1 && o.width <= 16384 && o.height >= 1 && o.height <= 16384,
          "--width / --height must be in 1..16384, got " + std::to_string(o.width) + "x" + std::to_string(o.height));
  require(o.fx > 0.0, "--fx must be > 0");
  require(o.baseline > 0.0 && o.baseline < 2.0, "--baseline must be in (0, 2) metres");
  require(o.camera_height > 0.0, "--camera-height must be > 0");
  require(o.supersample >= 1 && o.supersample <= 8, "--supersample must be in 1..8");
  require(o.noise >= 0.0, "--noise must be >= 0");
  require(o.exposure > 0.0, "--exposure must be > 0");
  require(o.breathing_phase >= 0.0 && o.breathing_phase <= 1.0, "--breathing-phase must be in [0, 1]");
  require(o.breathing_amplitude >= 0.0 && o.breathing_amplitude <= 0.03, "--breathing-amplitude must be in [0, 0.03] m");
  require(o.frames >= 1 && o.frames <= 10000, "--frames must be in 1..10000");
  require(o.frames == 1 || o.preset == "back", "--frames > 1 is for the back preset");
  require(o.rate > 0.0 && o.rate <= 1000.0, "--rate must be in (0, 1000] Hz");
  require(o.views >= 1 && o.views <= 64, "--views must be in 1..64");
  require(o.boxes >= 1 && o.boxes <= 40, "--boxes must be in 1..40");
  return true;
}

// ------------------------------------------------------------ YAML output --

void emitMatrix(YAML::Emitter& out, const Eigen::MatrixXd& m) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int r = 0; r < m.rows(); ++r) {
    out << YAML::Flow << YAML::BeginSeq;
    for (int c = 0; c < m.cols(); ++c) out << m(r, c);
    out << YAML::EndSeq;
  }
  out << YAML::EndSeq;
}

void emitCamera(YAML::Emitter& out, const std::string& name, const sim::CameraModel& c) {
  out << YAML::Key << name << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width" << YAML::Value << c.width << YAML::Key << "height" << YAML::Value << c.height;
  out << YAML::Key << "K" << YAML::Value;
  emitMatrix(out, c.K);
  out << YAML::Key << "D" << YAML::Value << YAML::Flow << c.D;
  out << YAML::Key << "world_from_camera" << YAML::Value;
  emitMatrix(out, c.world_from_camera.matrix());
  out << YAML::Key << "projection" << YAML::Value;  // world -> undistorted pixels
  emitMatrix(out, c.projectionMatrix());
  out << YAML::EndMap;
}

void writePoints(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& points) {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  out << YAML::BeginMap;
  for (const auto& [name, p] : points) out << YAML::Key << name << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
}

/// Landmarks (name -> [x, y, z]) plus the spine midline as a list of points.
void writeLandmarks(const fs::path& path, const std::map<std::string, Eigen::Vector3d>& landmarks,
                    const std::vector<Eigen::Vector3d>& midline) {
  YAML::Emitter out;
  out.SetDoublePrecision(9);
  out << YAML::BeginMap;
  for (const auto& [name, p] : landmarks) out << YAML::Key << name << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::Key << "midline" << YAML::Value << YAML::BeginSeq;
  for (const auto& p : midline) out << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
}

/// A picture of a rendered pair: left | right | GT disparity (colour) | left
/// with the acupoints (green), landmarks (red) and midline (yellow).
cv::Mat previewImage(const sim::StereoFrame& f, const sim::CameraModel& left,
                     const std::map<std::string, Eigen::Vector3d>& acupoints,
                     const std::map<std::string, Eigen::Vector3d>& landmarks, const std::vector<Eigen::Vector3d>& midline) {
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
  for (const auto& [name, p] : acupoints) dot(p, cv::Scalar(40, 200, 40), r);
  for (const auto& [name, p] : landmarks) dot(p, cv::Scalar(40, 40, 230), r);
  tiles.push_back(overlay);
  cv::Mat out;
  cv::hconcat(tiles, out);
  return out;
}

void writeYaml(const fs::path& path, const YAML::Emitter& out) {
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
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

// ------------------------------------------------------------- rendering --

sim::LightPreset lightPreset(const std::string& name) {
  if (name == "top_left") return sim::LightPreset::kTopLeft;
  if (name == "top_right") return sim::LightPreset::kTopRight;
  return sim::LightPreset::kTopCentre;
}

sim::StereoPairModel makePair(const Options& o) {
  sim::RigParameters rig;
  rig.width = o.width;
  rig.height = o.height;
  rig.fx = o.fx;
  rig.baseline = o.baseline;
  rig.centre.z() = o.camera_height;
  rig.shift = o.shift;
  rig.rectified = !o.raw;
  try {
    return sim::makeStereoPair(rig);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

sim::RenderOptions renderOptions(const Options& o, std::uint32_t frame) {
  sim::RenderOptions r;
  r.supersample = o.supersample;
  r.noise_sigma = static_cast<float>(o.noise);
  r.exposure = static_cast<float>(o.exposure);
  r.noise_seed = o.seed * 7919u + frame;
  return r;
}

double secondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

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

/// Fails (exit 1) when the back is not seen by both cameras.
void requireBackInView(const sim::Renderer& renderer, const sim::StereoPairModel& pair, const sim::BackModel& back,
                       const std::map<std::string, Eigen::Vector3d>& acupoints, std::vector<std::string>& hidden) {
  for (const auto& [name, p] : acupoints) {
    if (!sim::isVisible(renderer, pair.left, p) || !sim::isVisible(renderer, pair.right, p)) hidden.push_back(name);
  }
  const auto landmarks = back.landmarks();
  for (const char* key : {"C7", "L4"}) {
    const Eigen::Vector3d& p = landmarks.at(key);
    if (!sim::isVisible(renderer, pair.left, p) || !sim::isVisible(renderer, pair.right, p)) {
      throw std::runtime_error(std::string("the back is not in view: landmark ") + key +
                               " is not seen by both cameras (check --shift, --camera-height, --fx)");
    }
  }
}

void beginManifest(YAML::Emitter& m, const Options& o) {
  m << YAML::BeginMap;
  m << YAML::Key << "preset" << YAML::Value << o.preset;
  m << YAML::Key << "frame" << YAML::Value
    << "world frame 'table': x toward the head, y to the subject's left, z up, origin on the table top under C7";
  m << YAML::Key << "seed" << YAML::Value << o.seed;
  m << YAML::Key << "supersample" << YAML::Value << o.supersample;
  m << YAML::Key << "noise_sigma" << YAML::Value << o.noise;
  m << YAML::Key << "exposure" << YAML::Value << o.exposure;
}

void emitBody(YAML::Emitter& m, const Options& o, const sim::BodyParameters& b) {
  m << YAML::Key << "subject" << YAML::Value << YAML::BeginMap;
  m << YAML::Key << "index" << YAML::Value << o.subject << YAML::Key << "body_seed" << YAML::Value << o.body_seed;
  m << YAML::Key << "shoulder_width" << YAML::Value << b.shoulder_width;
  m << YAML::Key << "waist_width" << YAML::Value << b.waist_width;
  m << YAML::Key << "hip_width" << YAML::Value << b.hip_width;
  m << YAML::Key << "torso_length" << YAML::Value << b.torso_length;
  m << YAML::Key << "back_height" << YAML::Value << b.back_height;
  m << YAML::Key << "spine_depth" << YAML::Value << b.spine_depth;
  m << YAML::Key << "scapula_medial_offset" << YAML::Value << b.scapula_medial_offset;
  m << YAML::Key << "shoulder_slope" << YAML::Value << b.shoulder_slope;
  m << YAML::Key << "skin_albedo" << YAML::Value << YAML::Flow
    << std::vector<float>{b.skin_albedo.x(), b.skin_albedo.y(), b.skin_albedo.z()};
  m << YAML::EndMap;
  m << YAML::Key << "light" << YAML::Value << o.light;
  m << YAML::Key << "camera_shift" << YAML::Value << o.shift;
  m << YAML::Key << "breathing_amplitude" << YAML::Value << o.breathing_amplitude;
}

void renderBack(const Options& o, const fs::path& dir) {
  const sim::BodyParameters body = sim::BodyParameters::subject(o.subject, o.body_seed);
  const sim::StereoPairModel pair = makePair(o);
  const sim::Lighting lighting = sim::Lighting::preset(lightPreset(o.light));
  std::vector<std::string> files;
  writeCalibrations(dir, pair, files);

  YAML::Emitter m;
  m.SetDoublePrecision(9);
  beginManifest(m, o);
  emitBody(m, o, body);
  m << YAML::Key << "rectified" << YAML::Value << pair.rectified;
  m << YAML::Key << "baseline" << YAML::Value << pair.baseline();
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  emitCamera(m, "left", pair.left);
  emitCamera(m, "right", pair.right);
  m << YAML::EndMap;

  double total_render = 0.0;
  if (o.frames == 1) {
    const sim::BackModel back(body, o.breathing_phase, o.breathing_amplitude);
    const sim::Renderer renderer(sim::makeBackScene(back, o.seed));
    std::vector<std::string> hidden;
    const auto acupoints = back.acupoints();
    requireBackInView(renderer, pair, back, acupoints, hidden);
    const auto start = Clock::now();
    const sim::StereoFrame frame = sim::renderStereoFrame(renderer, pair, lighting, renderOptions(o, 0));
    total_render = secondsSince(start);
    writeStereoFrame(dir, pair, frame, files);
    writePoints(dir / "acupoints.yaml", sim::toCameraFrame(acupoints, pair.left));
    const Eigen::Isometry3d left_from_world = pair.left.world_from_camera.inverse();
    std::vector<Eigen::Vector3d> midline;
    for (const auto& p : back.midline()) midline.push_back(left_from_world * p);
    writeLandmarks(dir / "landmarks.yaml", sim::toCameraFrame(back.landmarks(), pair.left), midline);
    sim::writeImage((dir / "preview.png").string(),
                    previewImage(frame, pair.left, acupoints, back.landmarks(), back.midline()));
    files.push_back("acupoints.yaml");
    files.push_back("landmarks.yaml");
    files.push_back("preview.png");
    m << YAML::Key << "breathing_phase" << YAML::Value << o.breathing_phase;
    m << YAML::Key << "acupoints_not_visible_in_both" << YAML::Value << YAML::Flow << hidden;
  } else {
    YAML::Emitter gt;
    gt.SetDoublePrecision(9);
    gt << YAML::BeginMap << YAML::Key << "frame_id" << YAML::Value << "left optical frame";
    gt << YAML::Key << "rate" << YAML::Value << o.rate << YAML::Key << "frames" << YAML::Value << YAML::BeginSeq;
    for (int i = 0; i < o.frames; ++i) {
      const double t = i / o.rate;
      const double phase = std::fmod(o.breathing_phase + t / kBreathPeriod, 1.0);
      const sim::BackModel back(body, phase, o.breathing_amplitude);
      const sim::Renderer renderer(sim::makeBackScene(back, o.seed));
      const auto acupoints = back.acupoints();
      if (i == 0) {
        std::vector<std::string> hidden;
        requireBackInView(renderer, pair, back, acupoints, hidden);
      }
      const auto start = Clock::now();
      const sim::StereoFrame frame = sim::renderStereoFrame(renderer, pair, lighting, renderOptions(o, i));
      total_render += secondsSince(start);
      char name[32];
      std::snprintf(name, sizeof name, "left_%04d.png", i);
      sim::writeImage((dir / name).string(), frame.left.image);
      files.push_back(name);
      std::snprintf(name, sizeof name, "right_%04d.png", i);
      sim::writeImage((dir / name).string(), frame.right.image);
      files.push_back(name);
      gt << YAML::BeginMap << YAML::Key << "index" << YAML::Value << i << YAML::Key << "time" << YAML::Value << t;
      gt << YAML::Key << "breathing_phase" << YAML::Value << phase;
      gt << YAML::Key << "acupoints" << YAML::Value << YAML::BeginMap;
      for (const auto& [n, p] : sim::toCameraFrame(acupoints, pair.left)) {
        gt << YAML::Key << n << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
      }
      gt << YAML::EndMap << YAML::EndMap;
    }
    gt << YAML::EndSeq << YAML::EndMap;
    writeYaml(dir / "ground_truth.yaml", gt);
    files.push_back("ground_truth.yaml");
    m << YAML::Key << "frames" << YAML::Value << o.frames << YAML::Key << "rate" << YAML::Value << o.rate;
    m << YAML::Key << "breath_period" << YAML::Value << kBreathPeriod;
  }
  m << YAML::Key << "render_seconds_per_pair" << YAML::Value << total_render / o.frames;
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
  std::printf("render_scene: back, subject %d, light %s, shift %.3f m, %s %dx%d: %d pair%s in %.3f s (%.3f s per pair) -> %s\n",
              o.subject, o.light.c_str(), o.shift, pair.rectified ? "rectified" : "raw", o.width, o.height, o.frames,
              o.frames == 1 ? "" : "s", total_render, total_render / o.frames, dir.string().c_str());
}

void renderBoxes(const Options& o, const fs::path& dir) {
  const sim::StereoPairModel pair = makePair(o);
  const sim::Renderer renderer(sim::makeBoxesScene(o.seed, o.boxes));
  std::vector<std::string> files;
  writeCalibrations(dir, pair, files);
  const auto start = Clock::now();
  const sim::StereoFrame frame =
      sim::renderStereoFrame(renderer, pair, sim::Lighting::preset(lightPreset(o.light)), renderOptions(o, 0));
  const double seconds = secondsSince(start);
  writeStereoFrame(dir, pair, frame, files);
  YAML::Emitter m;
  m.SetDoublePrecision(9);
  beginManifest(m, o);
  m << YAML::Key << "boxes" << YAML::Value << o.boxes << YAML::Key << "rectified" << YAML::Value << pair.rectified;
  m << YAML::Key << "baseline" << YAML::Value << pair.baseline();
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  emitCamera(m, "left", pair.left);
  emitCamera(m, "right", pair.right);
  m << YAML::EndMap;
  m << YAML::Key << "render_seconds_per_pair" << YAML::Value << seconds;
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
  std::printf("render_scene: boxes (%d), %dx%d stereo pair in %.3f s -> %s\n", o.boxes, o.width, o.height, seconds,
              dir.string().c_str());
}

void renderEfficiency(const Options& o, const fs::path& dir, bool gradient) {
  const sim::EfficiencySet set = sim::makeEfficiencySet(gradient, o.width, o.height, o.fx, o.seed);
  const sim::Renderer renderer(set.scene);
  const sim::Lighting lighting = sim::Lighting::preset(sim::LightPreset::kTopCentre);
  std::vector<std::string> files;
  const auto start = Clock::now();
  const sim::ViewRender left = renderer.render(set.left, lighting, renderOptions(o, 0));
  sim::writeImage((dir / "left.png").string(), left.image);
  sim::writePfm((dir / "left_depth.pfm").string(), left.depth);
  sim::writeImage((dir / "left_labels.png").string(), left.labels);
  const camera::CameraCalibration left_info = sim::monoCalibration(set.left);
  camera::writeCameraInfoYaml((dir / "left_camera_info.yaml").string(), left_info, "sim_left");
  files.insert(files.end(), {"left.png", "left_depth.pfm", "left_labels.png", "left_camera_info.yaml"});

  YAML::Emitter m;
  m.SetDoublePrecision(9);
  beginManifest(m, o);
  m << YAML::Key << "z_near" << YAML::Value << set.z_near << YAML::Key << "z_far" << YAML::Value << set.z_far;
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  emitCamera(m, "left", set.left);
  for (std::size_t k = 0; k < set.rights.size(); ++k) emitCamera(m, "right_" + std::to_string(k + 1), set.rights[k]);
  m << YAML::EndMap << YAML::Key << "right_views" << YAML::Value << YAML::BeginSeq;
  for (std::size_t k = 0; k < set.rights.size(); ++k) {
    const std::string id = std::to_string(k + 1);
    const sim::ViewRender right = renderer.render(set.rights[k], lighting, renderOptions(o, static_cast<std::uint32_t>(k + 1)));
    sim::writeImage((dir / ("right_" + id + ".png")).string(), right.image);
    const cv::Mat disparity = sim::disparityFromDepth(left.depth, o.fx, set.baselines[k]);
    sim::writePfm((dir / ("left_disparity_" + id + ".pfm")).string(), disparity);
    camera::CameraCalibration info = left_info;
    info.P[3] = -o.fx * set.baselines[k];
    camera::writeCameraInfoYaml((dir / ("right_" + id + "_camera_info.yaml")).string(), info, "sim_right");
    files.insert(files.end(), {"right_" + id + ".png", "left_disparity_" + id + ".pfm", "right_" + id + "_camera_info.yaml"});
    double dmin = 0, dmax = 0;
    cv::minMaxLoc(disparity, &dmin, &dmax, nullptr, nullptr, disparity == disparity);
    m << YAML::BeginMap << YAML::Key << "name" << YAML::Value << "R" + id << YAML::Key << "image" << YAML::Value
      << "right_" + id + ".png" << YAML::Key << "baseline" << YAML::Value << set.baselines[k] << YAML::Key
      << "levels" << YAML::Value << set.levels[k] << YAML::Key << "min_disparity" << YAML::Value << dmin << YAML::Key
      << "max_disparity" << YAML::Value << dmax << YAML::EndMap;
  }
  const double seconds = secondsSince(start);
  m << YAML::EndSeq << YAML::Key << "render_seconds" << YAML::Value << seconds;
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
  std::printf("render_scene: %s, left + %zu right views (%d..%d levels) in %.3f s -> %s\n", o.preset.c_str(),
              set.rights.size(), set.levels.front(), set.levels.back(), seconds, dir.string().c_str());
}

void renderMultiview(const Options& o, const fs::path& dir) {
  const sim::Renderer renderer(sim::makeBoxesScene(o.seed, o.boxes));
  const std::vector<sim::CameraModel> cameras =
      sim::makeMultiView(o.views, Eigen::Vector3d(-0.27, 0.0, 0.1), o.camera_height, 1.0, 0.9, o.width, o.height, o.fx);
  const sim::Lighting lighting = sim::Lighting::preset(lightPreset(o.light));
  std::vector<std::string> files;
  YAML::Emitter m;
  m.SetDoublePrecision(9);
  beginManifest(m, o);
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  const auto start = Clock::now();
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    const std::string id = "view_" + std::to_string(k);
    const sim::ViewRender view = renderer.render(cameras[k], lighting, renderOptions(o, static_cast<std::uint32_t>(k)));
    sim::writeImage((dir / (id + ".png")).string(), view.image);
    sim::writePfm((dir / (id + "_depth.pfm")).string(), view.depth);
    sim::writeImage((dir / (id + "_labels.png")).string(), view.labels);
    camera::writeCameraInfoYaml((dir / (id + "_camera_info.yaml")).string(), sim::monoCalibration(cameras[k]), "sim_" + id);
    files.insert(files.end(), {id + ".png", id + "_depth.pfm", id + "_labels.png", id + "_camera_info.yaml"});
    emitCamera(m, id, cameras[k]);
  }
  const double seconds = secondsSince(start);
  m << YAML::EndMap << YAML::Key << "render_seconds" << YAML::Value << seconds;
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
  std::printf("render_scene: multiview, %d views %dx%d in %.3f s -> %s\n", o.views, o.width, o.height, seconds,
              dir.string().c_str());
}

void run(const Options& o) {
  const fs::path dir(o.out);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw std::runtime_error("cannot create output folder '" + o.out + "'");
  if (o.preset == "back") {
    renderBack(o, dir);
  } else if (o.preset == "boxes") {
    renderBoxes(o, dir);
  } else if (o.preset == "efficiency_layers" || o.preset == "efficiency_gradient") {
    renderEfficiency(o, dir, o.preset == "efficiency_gradient");
  } else {
    renderMultiview(o, dir);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  return massage_cell::tools::runTool(
      "render_scene", [&] { return parseOptions(argc, argv, options); }, [&] { run(options); });
}
