// render_scene: renders the massage cell's scenes with exact ground truth
// (massage_cell::sim): a subject lying prone under the stereo camera, stacked
// boxes, the thesis's efficiency sets and multi-view sets. See --help.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <opencv2/core.hpp>

#include "cli.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/ground_truth.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"
#include "render_scene_files.h"
#include "render_scene_manifest.h"
#include "render_scene_options.h"
#include "render_scene_setup.h"

namespace massage_cell::tools::render_scene {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kBreathPeriod = 4.0;  // seconds per breath (15 breaths a minute)

double secondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

/// Fails (exit 1) when the back is not seen by both cameras: C7 and L4 for
/// the bare back, at least one acupoint when dressed or framed (where C7 or
/// L4 may well be covered or out of the image).
void requireBackInView(const sim::Renderer& renderer, const sim::StereoPairModel& pair, const sim::BackModel& back,
                       const std::map<std::string, Eigen::Vector3d>& acupoints, bool dressed_scene,
                       std::vector<std::string>& hidden) {
  for (const auto& [name, p] : acupoints) {
    if (!sim::isVisible(renderer, pair.left, p) || !sim::isVisible(renderer, pair.right, p)) hidden.push_back(name);
  }
  if (dressed_scene) {
    if (hidden.size() == acupoints.size()) {
      throw std::runtime_error(
          "the back is not in view: no acupoint is seen by both cameras (check the framing, "
          "--shift, --camera-height, --fx)");
    }
    return;
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

/// The subject, its dressing and the rig of a back preset run.
struct BackSetup {
  sim::BodyParameters body;
  sim::Dressing dressing;
  sim::StereoPairModel pair;
  sim::Lighting lighting;
};

/// One pair with the full ground truth. Returns the render time.
double renderBackFrame(const Options& o, const BackSetup& c, const fs::path& dir, YAML::Emitter& m,
                       std::vector<std::string>& files) {
  const sim::BackModel back(c.body, o.breathing_phase, o.breathing_amplitude);
  const sim::Renderer renderer(sim::makeCellScene(back, o.seed, c.dressing));
  std::vector<std::string> hidden;
  const auto acupoints = back.acupoints();
  requireBackInView(renderer, c.pair, back, acupoints, dressed(o), hidden);
  const auto start = Clock::now();
  const sim::StereoFrame frame = sim::renderStereoFrame(renderer, c.pair, c.lighting, renderOptions(o, 0));
  const double seconds = secondsSince(start);
  writeStereoFrame(dir, c.pair, frame, files);
  writePoints(dir / "acupoints.yaml", sim::toCameraFrame(acupoints, c.pair.left));
  const Eigen::Isometry3d left_from_world = c.pair.left.world_from_camera.inverse();
  std::vector<Eigen::Vector3d> midline;
  for (const auto& p : back.midline()) midline.push_back(left_from_world * p);
  writeLandmarks(dir / "landmarks.yaml", sim::toCameraFrame(back.landmarks(), c.pair.left), midline);
  const auto truth = sim::acupointTruth(acupoints, c.pair, frame);
  writeTruth(dir / "acupoints_truth.yaml", truth, sim::acupointTruth(back.landmarks(), c.pair, frame));
  sim::writeImage((dir / "preview.png").string(),
                  previewImage(frame, c.pair.left, truth, back.landmarks(), back.midline()));
  files.insert(files.end(), {"acupoints.yaml", "landmarks.yaml", "acupoints_truth.yaml", "preview.png"});
  m << YAML::Key << "breathing_phase" << YAML::Value << o.breathing_phase;
  m << YAML::Key << "acupoints_not_visible_in_both" << YAML::Value << YAML::Flow << hidden;
  m << YAML::Key << "acupoints_in_view" << YAML::Value << namesInView(truth, true).size();
  m << YAML::Key << "acupoints_not_in_view" << YAML::Value << YAML::Flow << namesInView(truth, false);
  return seconds;
}

/// A session of breathing frames: numbered pairs and per-frame ground truth. Returns the render time.
double renderBackSession(const Options& o, const BackSetup& c, const fs::path& dir, std::vector<std::string>& files) {
  double total = 0.0;
  YAML::Emitter gt;
  gt.SetDoublePrecision(9);
  gt << YAML::BeginMap << YAML::Key << "frame_id" << YAML::Value << "left optical frame";
  gt << YAML::Key << "rate" << YAML::Value << o.rate << YAML::Key << "frames" << YAML::Value << YAML::BeginSeq;
  for (int i = 0; i < o.frames; ++i) {
    const double t = i / o.rate;
    const double phase = std::fmod(o.breathing_phase + t / kBreathPeriod, 1.0);
    const sim::BackModel back(c.body, phase, o.breathing_amplitude);
    const sim::Renderer renderer(sim::makeCellScene(back, o.seed, c.dressing));
    const auto acupoints = back.acupoints();
    if (i == 0) {
      std::vector<std::string> hidden;
      requireBackInView(renderer, c.pair, back, acupoints, dressed(o), hidden);
    }
    const auto start = Clock::now();
    const sim::StereoFrame frame = sim::renderStereoFrame(renderer, c.pair, c.lighting, renderOptions(o, i));
    total += secondsSince(start);
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
    emitPointEntries(gt, sim::toCameraFrame(acupoints, c.pair.left));
    gt << YAML::EndMap << YAML::Key << "in_view" << YAML::Value << YAML::Flow
       << namesInView(sim::acupointTruth(acupoints, c.pair, frame), true) << YAML::EndMap;
  }
  gt << YAML::EndSeq << YAML::EndMap;
  writeYaml(dir / "ground_truth.yaml", gt);
  files.push_back("ground_truth.yaml");
  return total;
}

void renderBack(const Options& o, const fs::path& dir) {
  BackSetup c;
  c.body = bodyParameters(o);
  const sim::BackModel at_rest(c.body);
  c.dressing = dressing(o, at_rest);
  c.pair = makePair(o, &at_rest);
  c.lighting = sim::Lighting::preset(lightPreset(o.light));
  std::vector<std::string> files;
  writeCalibrations(dir, c.pair, files);

  YAML::Emitter m;
  m.SetDoublePrecision(9);
  beginManifest(m, o);
  emitBody(m, o, c.body);
  emitDressing(m, o, c.dressing);
  emitStereoCameras(m, c.pair);

  double total_render = 0.0;
  if (o.frames == 1) {
    total_render = renderBackFrame(o, c, dir, m, files);
  } else {
    total_render = renderBackSession(o, c, dir, files);
    m << YAML::Key << "frames" << YAML::Value << o.frames << YAML::Key << "rate" << YAML::Value << o.rate;
    m << YAML::Key << "breath_period" << YAML::Value << kBreathPeriod;
  }
  m << YAML::Key << "render_seconds_per_pair" << YAML::Value << total_render / o.frames;
  endManifest(m, files, dir);
  const std::string who = o.varied > 0       ? "varied subject " + std::to_string(o.varied)
                          : !o.build.empty() ? o.build + " build, BMI " + std::to_string(o.bmi).substr(0, 4)
                                             : "subject " + std::to_string(o.subject);
  std::printf(
      "render_scene: back, %s%s, light %s, shift %.3f m, %s %dx%d: %d pair%s in %.3f s (%.3f s per pair) -> %s\n",
      who.c_str(), dressed(o) ? " (dressed)" : "", o.light.c_str(), o.shift, c.pair.rectified ? "rectified" : "raw",
      o.width, o.height, o.frames, o.frames == 1 ? "" : "s", total_render, total_render / o.frames,
      dir.string().c_str());
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
  m << YAML::Key << "boxes" << YAML::Value << o.boxes;
  emitStereoCameras(m, pair);
  m << YAML::Key << "render_seconds_per_pair" << YAML::Value << seconds;
  endManifest(m, files, dir);
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
    const sim::ViewRender right =
        renderer.render(set.rights[k], lighting, renderOptions(o, static_cast<std::uint32_t>(k + 1)));
    sim::writeImage((dir / ("right_" + id + ".png")).string(), right.image);
    const cv::Mat disparity = sim::disparityFromDepth(left.depth, o.fx, set.baselines[k]);
    sim::writePfm((dir / ("left_disparity_" + id + ".pfm")).string(), disparity);
    camera::CameraCalibration info = left_info;
    info.P[3] = -o.fx * set.baselines[k];
    camera::writeCameraInfoYaml((dir / ("right_" + id + "_camera_info.yaml")).string(), info, "sim_right");
    files.insert(files.end(),
                 {"right_" + id + ".png", "left_disparity_" + id + ".pfm", "right_" + id + "_camera_info.yaml"});
    double dmin = 0, dmax = 0;
    cv::minMaxLoc(disparity, &dmin, &dmax, nullptr, nullptr, disparity == disparity);
    m << YAML::BeginMap << YAML::Key << "name" << YAML::Value << "R" + id << YAML::Key << "image" << YAML::Value
      << "right_" + id + ".png" << YAML::Key << "baseline" << YAML::Value << set.baselines[k] << YAML::Key << "levels"
      << YAML::Value << set.levels[k] << YAML::Key << "min_disparity" << YAML::Value << dmin << YAML::Key
      << "max_disparity" << YAML::Value << dmax << YAML::EndMap;
  }
  const double seconds = secondsSince(start);
  m << YAML::EndSeq << YAML::Key << "render_seconds" << YAML::Value << seconds;
  endManifest(m, files, dir);
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
    camera::writeCameraInfoYaml((dir / (id + "_camera_info.yaml")).string(), sim::monoCalibration(cameras[k]),
                                "sim_" + id);
    files.insert(files.end(), {id + ".png", id + "_depth.pfm", id + "_labels.png", id + "_camera_info.yaml"});
    emitCamera(m, id, cameras[k]);
  }
  const double seconds = secondsSince(start);
  m << YAML::EndMap << YAML::Key << "render_seconds" << YAML::Value << seconds;
  endManifest(m, files, dir);
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
}  // namespace massage_cell::tools::render_scene

int main(int argc, char** argv) {
  namespace render = massage_cell::tools::render_scene;
  render::Options options;
  return massage_cell::tools::runTool(
      "render_scene", [&] { return render::parseOptions(argc, argv, options); }, [&] { render::run(options); });
}
