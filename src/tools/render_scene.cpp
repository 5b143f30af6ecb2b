// render_scene: renders the massage cell's scenes with exact ground truth
// (massage_cell::sim): a subject lying prone under the stereo camera, stacked
// boxes, the thesis's efficiency sets and multi-view sets. See --help.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cli.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/ground_truth.h"
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
  --body-seed S            seed the 28 subjects (and the varied population) are drawn from (default 2024)
  --varied N               instead of --subject: subject N >= 1 of a wide population (male/female,
                           BMI 18..38, every Fitzpatrick skin type; BodyParameters::varied)
  --build SEX              instead of --subject: a male | female build, with --bmi B (default 24)
                           and --stature M (metres, default 1.75)
  --skin-type T            Fitzpatrick skin type 1..6: overrides the subject's skin colour

Dressing of the back preset (default: none of it, the bare back):
  --arms POSE              none | along (along the trunk) | raised (beside the head) (default none)
  --arm-angle DEG          along: abduction of both arms about the shoulders, 0 (touching the
                           flank) .. 20 degrees (default 0)
  --arm-angle-right DEG    the right arm's abduction if it differs (default: --arm-angle)
  --head                   the neck and the head face-down in a face cradle (the table then
                           ends at the shoulders)
  --hair LENGTH            with --head: none | short | nape | long (default short)
  --hair-colour C          black | brown | blond | grey | red (default brown)
  --cradle-cover COLOUR    a cloth cover on the cradle's pad (default: dark vinyl)
  --lower-body             the buttocks down to the gluteal fold and the upper thighs
  --towel COLOUR           a towel over the buttocks / lower back (implies --lower-body)
  --towel-weave W          fine | terry | waffle | stripes | checks (default terry)
  --towel-edge POS         the towel's cranial edge (default L4-0.03)
  --towel-tilt DEG         turn of the towel's edge about the vertical (default 0)
  --sheet COLOUR           the table's sheet colour (default: the standard blue-grey sheet)
  --sheet-weave W          fine | terry | waffle | stripes | checks (default fine)
  --sticker LANDMARK=C     a coloured skin marker on a landmark of the back (C7, T1..L5,
                           scapula_inferior_angle_L, iliac_crest_R, ...), repeatable; C: green,
                           blue, orange, magenta, yellow; e.g. --sticker C7=green --sticker L4=blue
  --sticker-size M         the stickers' diameter, metres (default 0.025)
  Colours: white, light_blue, green, grey, beige, peach, pink, dark_blue, black, default_sheet.
  POS: a world x in metres (x toward the head, 0 at C7), or a vertebral level with an
  optional offset in metres toward the head (+) or feet (-), e.g. C7+0.05, L4-0.18.

Camera:
  --light L                top_left | top_centre | top_right (default top_centre)
  --shift M                camera shift along the table, metres (thesis: 0, 0.04, 0.07, 0.14; default 0)
  --camera-height Z        height of the cameras above the table top, metres (default 0.95)
  --width W --height H     image size (default 640 x 480)
  --fx F                   focal length, pixels (default 500)
  --baseline B             stereo baseline, metres (default 0.10)
  --raw                    unrectified pair with lens distortion (default: rectified, ideal)
  --toe-in DEG             raw pairs: each camera turned toward the other by DEG (default 0)
  --frame-top POS          place the cameras so that the left image's top edge meets the back's
  --frame-bottom POS       height at POS and its bottom edge at the other POS (both needed;
                           replaces --shift / --camera-height), e.g. C7+0.06 and L4-0.2

Rendering:
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
left_labels.png right_labels.png (labels below), left_visible.png (255: seen by the right camera too),
left_camera_info.yaml right_camera_info.yaml (ROS calibration), acupoints.yaml and
landmarks.yaml (back: name -> [x, y, z] in the left optical frame, metres; landmarks.yaml
also holds the spine midline), acupoints_truth.yaml (back: per acupoint and landmark its
left optical position, raw left and right pixels, the label at its left pixel, in_view and
the reason when not in view), preview.png (left | right | GT disparity | acupoints in view
green, not in view red, landmarks blue), manifest.yaml.
Labels: 0 background, 1 back (and buttocks), 2 table, 3 floor, 4 arm, 5 neck, 6 head,
7 hair, 8 towel, 9 plane, 10+ box faces, 250 face cradle.
A session (--frames > 1) writes left_NNNN.png / right_NNNN.png, the calibrations,
ground_truth.yaml (per frame: time, breathing phase, acupoints, the acupoints in view) and
manifest.yaml.
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
  // Subject variety.
  int varied = 0;
  std::string build;
  double bmi = 24.0, stature = 1.75;
  int skin_type = 0;
  // Dressing.
  std::string arms = "none";
  double arm_angle = 0.0, arm_angle_right = -1.0;
  bool head = false, lower_body = false;
  std::string hair = "short", hair_colour = "brown", cradle_cover;
  std::string towel, towel_weave = "terry", towel_edge = "L4-0.03";
  double towel_tilt = 0.0;
  std::string sheet, sheet_weave = "fine";
  std::vector<std::string> stickers;  ///< --sticker LANDMARK=COLOUR
  double sticker_size = 0.025;
  // Rig.
  double toe_in = 0.0;
  std::string frame_top, frame_bottom;
  std::vector<std::string> given;  ///< options given on the command line
};

constexpr double kBreathPeriod = 4.0;  // seconds per breath (15 breaths a minute)

bool given(const Options& o, const std::string& option) {
  return std::find(o.given.begin(), o.given.end(), option) != o.given.end();
}

/// The subject, dressing and rig options: names known, ranges, combinations.
void checkCellOptions(const Options& o) {
  auto known = [](auto parse, const std::string& value) {
    try {
      parse(value);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  };
  require(o.varied >= 0, "--varied must be >= 1");
  require(o.build.empty() || o.build == "male" || o.build == "female",
          "--build must be male or female, got '" + o.build + "'");
  require(!(given(o, "--subject") + given(o, "--varied") + !o.build.empty() > 1),
          "--subject, --varied and --build are exclusive");
  require((!given(o, "--bmi") && !given(o, "--stature")) || !o.build.empty(), "--bmi and --stature need --build");
  require(o.skin_type == 0 || (o.skin_type >= 1 && o.skin_type <= 6), "--skin-type must be in 1..6");
  known(sim::armPoseFromName, o.arms);
  require(o.arm_angle >= 0.0 && o.arm_angle <= 20.0, "--arm-angle must be in 0..20 degrees");
  require(o.arm_angle_right < 0.0 || o.arm_angle_right <= 20.0, "--arm-angle-right must be in 0..20 degrees");
  known(sim::hairLengthFromName, o.hair);
  known(sim::hairColourFromName, o.hair_colour);
  for (const std::string* c : {&o.cradle_cover, &o.towel, &o.sheet}) {
    if (!c->empty()) known(sim::clothColour, *c);
  }
  known(sim::weaveFromName, o.towel_weave);
  known(sim::weaveFromName, o.sheet_weave);
  require(std::abs(o.towel_tilt) <= 15.0, "--towel-tilt must be in -15..15 degrees");
  require(o.toe_in >= 0.0 && o.toe_in <= 15.0, "--toe-in must be in 0..15 degrees");
  require(o.toe_in == 0.0 || o.raw, "--toe-in needs --raw (a toe-in pair is not rectified)");
  require(o.frame_top.empty() == o.frame_bottom.empty(), "--frame-top and --frame-bottom go together");
  const bool cell = o.arms != "none" || o.head || o.lower_body || !o.towel.empty() || !o.sheet.empty() ||
                    !o.stickers.empty() || o.varied > 0 || !o.build.empty() || o.skin_type > 0 || !o.frame_top.empty();
  require(!cell || o.preset == "back", "subject, dressing and framing options are for the back preset");
}

/// Builds the subject, its dressing and the rig once so that bad values end
/// as usage errors (defined with the rendering below).
void checkBackSetup(const Options& o);

bool parseOptions(int argc, char** argv, Options& o) {
  OptionTable t;
  auto text = [](std::string& field) { return [&field](const std::string&, const std::string& v) { field = v; }; };
  auto integer = [](int& field) {
    return [&field](const std::string& opt, const std::string& v) { field = parseInt(opt, v); };
  };
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
              {"--boxes", integer(o.boxes)},
              {"--varied", integer(o.varied)},
              {"--build", text(o.build)},
              {"--bmi", number(o.bmi)},
              {"--stature", number(o.stature)},
              {"--skin-type", integer(o.skin_type)},
              {"--arms", text(o.arms)},
              {"--arm-angle", number(o.arm_angle)},
              {"--arm-angle-right", number(o.arm_angle_right)},
              {"--hair", text(o.hair)},
              {"--hair-colour", text(o.hair_colour)},
              {"--cradle-cover", text(o.cradle_cover)},
              {"--towel", text(o.towel)},
              {"--towel-weave", text(o.towel_weave)},
              {"--towel-edge", text(o.towel_edge)},
              {"--towel-tilt", number(o.towel_tilt)},
              {"--sheet", text(o.sheet)},
              {"--sheet-weave", text(o.sheet_weave)},
              {"--sticker", [&o](const std::string&, const std::string& v) { o.stickers.push_back(v); }},
              {"--sticker-size", number(o.sticker_size)},
              {"--toe-in", number(o.toe_in)},
              {"--frame-top", text(o.frame_top)},
              {"--frame-bottom", text(o.frame_bottom)}};
  t.flags = {{"--raw", [&o] { o.raw = true; }}, {"--head", [&o] { o.head = true; }}, {"--lower-body", [&o] {
                                                                                        o.lower_body = true;
                                                                                      }}};
  for (auto& [name, setter] : t.values) {
    setter = [&o, name = name, inner = setter](const std::string& opt, const std::string& v) {
      o.given.push_back(name);
      inner(opt, v);
    };
  }
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
  require(o.breathing_amplitude >= 0.0 && o.breathing_amplitude <= 0.03,
          "--breathing-amplitude must be in [0, 0.03] m");
  require(o.frames >= 1 && o.frames <= 10000, "--frames must be in 1..10000");
  require(o.frames == 1 || o.preset == "back", "--frames > 1 is for the back preset");
  require(o.rate > 0.0 && o.rate <= 1000.0, "--rate must be in (0, 1000] Hz");
  require(o.views >= 1 && o.views <= 64, "--views must be in 1..64");
  require(o.boxes >= 1 && o.boxes <= 40, "--boxes must be in 1..40");
  checkCellOptions(o);
  if (o.preset == "back") checkBackSetup(o);
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
  for (const auto& [name, p] : points)
    out << YAML::Key << name << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
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
  for (const auto& [name, p] : landmarks)
    out << YAML::Key << name << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::Key << "midline" << YAML::Value << YAML::BeginSeq;
  for (const auto& p : midline) out << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
}

void writeYaml(const fs::path& path, const YAML::Emitter& out) {
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write '" + path.string() + "'");
}

/// A picture of a rendered pair: left | right | GT disparity (colour) | left
/// with the acupoints (green: in view, red: not in view), landmarks (blue) and midline (yellow).
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

/// acupoints_truth.yaml: the acupoints' and landmarks' truth in the left optical frame and raw pixels.
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

std::vector<std::string> namesInView(const std::map<std::string, sim::PointTruth>& truth, bool in_view) {
  std::vector<std::string> names;
  for (const auto& [name, t] : truth) {
    if (t.in_view == in_view) names.push_back(name);
  }
  return names;
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

constexpr double kDegree = 3.14159265358979323846 / 180.0;

/// A world x from "0.05" (metres) or a vertebral level with an optional offset ("L4-0.18").
double anatomicalX(const std::string& option, const std::string& text, const sim::BackModel& back) {
  std::size_t split = 0;
  while (split < text.size() && (std::isalnum(static_cast<unsigned char>(text[split])) != 0)) ++split;
  if (split == 0 || std::isdigit(static_cast<unsigned char>(text[0])) != 0) return parseDouble(option, text);
  const std::string level = text.substr(0, split);
  const auto& levels = sim::vertebralLevels();
  require(std::find(levels.begin(), levels.end(), level) != levels.end(),
          option + ": unknown vertebral level '" + level + "' in '" + text + "' (C7, T1..T12, L1..L5)");
  return back.levelX(level) + (split < text.size() ? parseDouble(option, text.substr(split)) : 0.0);
}

/// The stereo rig; framed on the back when --frame-top / --frame-bottom are given (`back` needed then).
sim::StereoPairModel makePair(const Options& o, const sim::BackModel* back = nullptr) {
  sim::RigParameters rig;
  rig.width = o.width;
  rig.height = o.height;
  rig.fx = o.fx;
  rig.baseline = o.baseline;
  rig.centre.z() = o.camera_height;
  rig.shift = o.shift;
  rig.rectified = !o.raw;
  rig.toe_in = o.toe_in * kDegree;
  try {
    if (back && !o.frame_top.empty()) {
      rig = sim::frameRig(rig, anatomicalX("--frame-top", o.frame_top, *back),
                          anatomicalX("--frame-bottom", o.frame_bottom, *back), back->body().back_height);
    }
    return sim::makeStereoPair(rig);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

sim::BodyParameters bodyParameters(const Options& o) {
  sim::BodyParameters body;
  try {
    if (o.varied > 0) {
      body = sim::BodyParameters::varied(o.varied, o.body_seed);
    } else if (!o.build.empty()) {
      sim::Build b;
      b.female = o.build == "female";
      b.bmi = o.bmi;
      b.stature = o.stature;
      b.skin_type = o.skin_type > 0 ? o.skin_type : 2;
      body = sim::bodyFromBuild(b);
    } else {
      body = sim::BodyParameters::subject(o.subject, o.body_seed);
    }
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (o.skin_type > 0) body.skin_albedo = sim::fitzpatrickAlbedo(o.skin_type);
  return body;
}

sim::Cloth cloth(const std::string& colour, const std::string& weave) {
  return {sim::clothColour(colour), sim::weaveFromName(weave)};
}

/// --sticker LANDMARK=COLOUR (the landmark is checked with the dressing).
sim::SkinSticker sticker(const std::string& value, double diameter) {
  const std::size_t eq = value.find('=');
  require(eq != std::string::npos && eq > 0 && eq + 1 < value.size(),
          "--sticker expects LANDMARK=COLOUR (e.g. C7=green), got '" + value + "'");
  sim::SkinSticker s;
  s.landmark = value.substr(0, eq);
  try {
    s.albedo = sim::stickerColour(value.substr(eq + 1));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--sticker: ") + e.what());
  }
  s.diameter = diameter;
  return s;
}

sim::Dressing dressing(const Options& o, const sim::BackModel& back) {
  sim::Dressing d;
  d.arms = sim::armPoseFromName(o.arms);
  d.arm_abduction_left = o.arm_angle * kDegree;
  d.arm_abduction_right = (o.arm_angle_right >= 0.0 ? o.arm_angle_right : o.arm_angle) * kDegree;
  d.head = o.head;
  d.hair = sim::hairLengthFromName(o.hair);
  d.hair_colour = sim::hairColourFromName(o.hair_colour);
  if (!o.cradle_cover.empty()) d.cradle_cover = cloth(o.cradle_cover, "fine");
  d.lower_body = o.lower_body || !o.towel.empty();
  if (!o.towel.empty()) {
    d.towel = cloth(o.towel, o.towel_weave);
    d.towel_edge_x = anatomicalX("--towel-edge", o.towel_edge, back);
    d.towel_edge_tilt = o.towel_tilt * kDegree;
  }
  if (!o.sheet.empty()) d.sheet = cloth(o.sheet, o.sheet_weave);
  for (const std::string& s : o.stickers) d.stickers.push_back(sticker(s, o.sticker_size));
  try {
    d.validate(back);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return d;
}

void checkBackSetup(const Options& o) {
  const sim::BackModel back(bodyParameters(o));
  (void)dressing(o, back);
  (void)makePair(o, &back);
}

/// true when the options dress the back or frame the cameras on it.
bool dressed(const Options& o) {
  return o.arms != "none" || o.head || o.lower_body || !o.towel.empty() || !o.sheet.empty() || !o.frame_top.empty();
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
  if (o.varied > 0) m << YAML::Key << "varied" << YAML::Value << o.varied;
  if (!o.build.empty()) {
    m << YAML::Key << "build" << YAML::Value << o.build << YAML::Key << "bmi" << YAML::Value << o.bmi;
    m << YAML::Key << "stature" << YAML::Value << o.stature;
  }
  if (o.skin_type > 0) m << YAML::Key << "skin_type" << YAML::Value << o.skin_type;
  m << YAML::Key << "shoulder_width" << YAML::Value << b.shoulder_width;
  m << YAML::Key << "waist_width" << YAML::Value << b.waist_width;
  m << YAML::Key << "hip_width" << YAML::Value << b.hip_width;
  m << YAML::Key << "torso_length" << YAML::Value << b.torso_length;
  m << YAML::Key << "back_height" << YAML::Value << b.back_height;
  m << YAML::Key << "spine_depth" << YAML::Value << b.spine_depth;
  m << YAML::Key << "scapula_medial_offset" << YAML::Value << b.scapula_medial_offset;
  m << YAML::Key << "shoulder_slope" << YAML::Value << b.shoulder_slope;
  m << YAML::Key << "lateral_rounding" << YAML::Value << b.lateral_rounding;
  m << YAML::Key << "scapula_prominence" << YAML::Value << b.scapula_prominence;
  m << YAML::Key << "spinous_prominence" << YAML::Value << b.spinous_prominence;
  m << YAML::Key << "skin_albedo" << YAML::Value << YAML::Flow
    << std::vector<float>{b.skin_albedo.x(), b.skin_albedo.y(), b.skin_albedo.z()};
  m << YAML::EndMap;
  m << YAML::Key << "light" << YAML::Value << o.light;
  m << YAML::Key << "camera_shift" << YAML::Value << o.shift;
  m << YAML::Key << "breathing_amplitude" << YAML::Value << o.breathing_amplitude;
}

void emitDressing(YAML::Emitter& m, const Options& o, const sim::Dressing& d) {
  m << YAML::Key << "dressing" << YAML::Value << YAML::BeginMap;
  m << YAML::Key << "arms" << YAML::Value << o.arms;
  m << YAML::Key << "arm_abduction" << YAML::Value << YAML::Flow
    << std::vector<double>{d.arm_abduction_left, d.arm_abduction_right};
  m << YAML::Key << "head" << YAML::Value << d.head;
  if (d.head)
    m << YAML::Key << "hair" << YAML::Value << o.hair << YAML::Key << "hair_colour" << YAML::Value << o.hair_colour;
  m << YAML::Key << "lower_body" << YAML::Value << d.lower_body;
  m << YAML::Key << "towel" << YAML::Value << (o.towel.empty() ? "none" : o.towel);
  if (d.towel) {
    m << YAML::Key << "towel_weave" << YAML::Value << o.towel_weave;
    m << YAML::Key << "towel_edge_x" << YAML::Value << d.towel_edge_x;
  }
  m << YAML::Key << "sheet" << YAML::Value << (o.sheet.empty() ? "default_sheet" : o.sheet);
  if (!o.stickers.empty()) {
    m << YAML::Key << "stickers" << YAML::Value << YAML::Flow << o.stickers;
    m << YAML::Key << "sticker_diameter" << YAML::Value << o.sticker_size;
  }
  m << YAML::Key << "toe_in_degrees" << YAML::Value << o.toe_in;
  if (!o.frame_top.empty()) {
    m << YAML::Key << "frame_top" << YAML::Value << o.frame_top << YAML::Key << "frame_bottom" << YAML::Value
      << o.frame_bottom;
  }
  m << YAML::EndMap;
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
    for (const auto& [n, p] : sim::toCameraFrame(acupoints, c.pair.left)) {
      gt << YAML::Key << n << YAML::Value << YAML::Flow << std::vector<double>{p.x(), p.y(), p.z()};
    }
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
  m << YAML::Key << "rectified" << YAML::Value << c.pair.rectified;
  m << YAML::Key << "baseline" << YAML::Value << c.pair.baseline();
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  emitCamera(m, "left", c.pair.left);
  emitCamera(m, "right", c.pair.right);
  m << YAML::EndMap;

  double total_render = 0.0;
  if (o.frames == 1) {
    total_render = renderBackFrame(o, c, dir, m, files);
  } else {
    total_render = renderBackSession(o, c, dir, files);
    m << YAML::Key << "frames" << YAML::Value << o.frames << YAML::Key << "rate" << YAML::Value << o.rate;
    m << YAML::Key << "breath_period" << YAML::Value << kBreathPeriod;
  }
  m << YAML::Key << "render_seconds_per_pair" << YAML::Value << total_render / o.frames;
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
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
    camera::writeCameraInfoYaml((dir / (id + "_camera_info.yaml")).string(), sim::monoCalibration(cameras[k]),
                                "sim_" + id);
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
