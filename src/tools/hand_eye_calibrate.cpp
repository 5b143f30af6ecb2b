// hand_eye_calibrate: the stereo camera's pose in the gantry's base frame from
// a ChArUco marker carried by the press tool, in the simulated cell (--sim) or
// from a folder of recorded pairs (--data DIR). See --help.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli.h"
#include "massage_cell/arm/config.h"
#include "massage_cell/calib/hand_eye.h"
#include "massage_cell/calib/recorded_set.h"
#include "massage_cell/calib/stereo_marker.h"
#include "massage_cell/sim/hand_eye_scene.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using tools::require;

const char* const kUsage = R"(Usage: hand_eye_calibrate (--sim | --data DIR) [--out FILE]
                          [--offset X,Y,Z] [--board NX,NY,SQUARE,MARKER] [--dictionary N]
                          [--warn-rms MM]
       sim only:          [--poses N] [--arm-config FILE] [--seed S] [--noise SIGMA] [--blur PX]
                          [--save-pairs DIR]

Fits the rigid transform stereo_left_optical_frame <- arm_base_link from the
marker's reference point (the ChArUco board's centre) seen by the stereo camera
at N >= 4 tool positions (arm base frame = commanded tool tip + --offset).
Prints one row per pose (tool tip, marker in the camera, corners used, board
fit RMS, residual after the fit), the transform, RMS / max residuals and any
warning; --out writes the calibration YAML.

  --sim            render the marker in the simulated cell (the rig of
                   sim::makeStereoPair, the URDF's gantry) at --poses positions
                   (default 12) spread over the workspace of --arm-config
                   (default config/arm.yaml) where both cameras see the whole
                   board, and compare with the exact transform (mm, degrees)
  --data DIR       recorded pairs: DIR/left.yaml, DIR/right.yaml (camera_info),
                   DIR/poses.yaml (see include/massage_cell/calib/recorded_set.h
                   or docs/hand_eye.md); --offset overrides its marker_offset
  --out FILE       write the calibration (parent/child frames, translation,
                   quaternion xyzw, residuals, date)
  --offset X,Y,Z   marker centre - tool tip, metres, arm base frame (default 0,0,0.06)
  --board NX,NY,SQUARE,MARKER   ChArUco squares and lengths in metres (default 5,4,0.048,0.036)
  --dictionary N   cv::aruco predefined dictionary (default 0 = DICT_4X4_50)
  --warn-rms MM    warn above this RMS residual (default 1.0)
  --seed S         sim: texture and noise seed (default 1)
  --noise SIGMA    sim: sensor noise, grey levels (default 1.0)
  --blur PX        sim: lens blur sigma, pixels (default 0.7)
  --save-pairs DIR sim: also write the rendered pairs in the --data format

Exit status: 0 calibrated (warnings included), 1 bad data or no calibration
(fewer than 4 detections, degenerate poses), 2 bad usage.
)";

struct Options {
  bool sim = false;
  std::string data, out, save_pairs;
  std::string arm_config;  // default: the package's config/arm.yaml
  std::optional<Eigen::Vector3d> offset;
  calib::CharucoSpec spec;
  calib::FitOptions fit;
  int poses = 12;
  std::uint32_t seed = 1;
  double noise = 1.0, blur = 0.7;
};

std::vector<double> numbers(const std::string& option, const std::string& value, std::size_t count) {
  const std::vector<std::string> items = tools::splitList(value);
  require(items.size() == count, option + ": expected " + std::to_string(count) + " comma-separated numbers");
  std::vector<double> out;
  for (const auto& s : items) out.push_back(tools::parseDouble(option, s));
  return out;
}

bool parse(int argc, char** argv, Options* o) {
  tools::OptionTable t;
  t.flags["--sim"] = [o] { o->sim = true; };
  t.values["--data"] = [o](const std::string&, const std::string& v) { o->data = v; };
  t.values["--out"] = [o](const std::string&, const std::string& v) { o->out = v; };
  t.values["--save-pairs"] = [o](const std::string&, const std::string& v) { o->save_pairs = v; };
  t.values["--arm-config"] = [o](const std::string&, const std::string& v) { o->arm_config = v; };
  t.values["--offset"] = [o](const std::string& opt, const std::string& v) {
    const auto n = numbers(opt, v, 3);
    o->offset = Eigen::Vector3d(n[0], n[1], n[2]);
  };
  t.values["--board"] = [o](const std::string& opt, const std::string& v) {
    const auto n = numbers(opt, v, 4);
    require(n[0] == std::floor(n[0]) && n[1] == std::floor(n[1]), opt + ": NX and NY must be integers");
    o->spec.squares_x = static_cast<int>(n[0]);
    o->spec.squares_y = static_cast<int>(n[1]);
    o->spec.square_length = n[2];
    o->spec.marker_length = n[3];
  };
  t.values["--dictionary"] = [o](const std::string& opt, const std::string& v) {
    o->spec.dictionary = tools::parseInt(opt, v);
  };
  t.values["--warn-rms"] = [o](const std::string& opt, const std::string& v) {
    o->fit.warn_rms_mm = tools::parseDouble(opt, v);
    require(o->fit.warn_rms_mm > 0.0, opt + ": expected > 0 mm");
  };
  t.values["--poses"] = [o](const std::string& opt, const std::string& v) {
    o->poses = tools::parseInt(opt, v);
    require(o->poses >= 4 && o->poses <= 100, opt + ": expected 4 .. 100 poses");
  };
  t.values["--seed"] = [o](const std::string& opt, const std::string& v) { o->seed = tools::parseSeed(opt, v); };
  t.values["--noise"] = [o](const std::string& opt, const std::string& v) {
    o->noise = tools::parseDouble(opt, v);
    require(o->noise >= 0.0 && o->noise <= 50.0, opt + ": expected 0 .. 50 grey levels");
  };
  t.values["--blur"] = [o](const std::string& opt, const std::string& v) {
    o->blur = tools::parseDouble(opt, v);
    require(o->blur >= 0.0 && o->blur <= 5.0, opt + ": expected 0 .. 5 pixels");
  };
  if (!tools::parseArguments(argc, argv, t, kUsage)) return false;
  require(o->sim != !o->data.empty(), "give exactly one of --sim and --data DIR");
  require(o->sim || o->save_pairs.empty(), "--save-pairs needs --sim");
  try {
    o->spec.validate();
  } catch (const std::invalid_argument& e) {
    throw tools::UsageError(std::string("--board / --dictionary: ") + e.what());
  }
  return true;
}

/// One pose's measurement, as the table prints it.
struct Row {
  Eigen::Vector3d tip;
  calib::MarkerDetection detection;
  double truth_error_mm = std::nan("");  ///< sim: detected vs exact marker point
};

std::string mm(const Eigen::Vector3d& v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%7.1f %7.1f %7.1f", v.x() * 1e3, v.y() * 1e3, v.z() * 1e3);
  return buf;
}

void printTransform(const char* name, const Eigen::Isometry3d& t) {
  const Eigen::Quaterniond q(t.linear());
  std::printf("%-10s translation [m] %9.5f %9.5f %9.5f   quaternion xyzw %9.6f %9.6f %9.6f %9.6f\n", name,
              t.translation().x(), t.translation().y(), t.translation().z(), q.x(), q.y(), q.z(), q.w());
}

/// Fits, prints the table and the result; returns it.
calib::HandEyeResult fitAndReport(const std::vector<Row>& rows, const Eigen::Vector3d& offset, const Options& o) {
  std::vector<calib::Correspondence> pairs;
  std::vector<std::size_t> used;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (!rows[i].detection.found) continue;
    pairs.push_back({calib::markerInBase(rows[i].tip, offset), rows[i].detection.point});
    used.push_back(i);
  }
  if (pairs.size() < 4) {
    throw std::runtime_error("the marker was found in " + std::to_string(pairs.size()) + " of " +
                             std::to_string(rows.size()) + " poses; at least 4 are needed");
  }
  const calib::HandEyeResult r = calib::fitHandEye(pairs, o.fit);
  std::printf("%4s  %-23s  %-23s  %7s  %8s  %8s%s\n", "pose", "tool tip [mm]", "marker in camera [mm]", "corners",
              "fit [mm]", "res [mm]", o.sim ? "  vs exact [mm]" : "");
  std::size_t k = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& row = rows[i];
    if (!row.detection.found) {
      std::printf("%4zu  %s  not used: %s\n", i, mm(row.tip).c_str(), row.detection.problem.c_str());
      continue;
    }
    std::printf("%4zu  %s  %s  %7d  %8.3f  %8.3f", i, mm(row.tip).c_str(), mm(row.detection.point).c_str(),
                row.detection.corners, row.detection.fit_rms_mm, r.residuals_mm[k++]);
    if (o.sim) std::printf("  %8.3f", row.truth_error_mm);
    std::printf("\n");
  }
  std::printf(
      "poses used %zu of %zu; residual RMS %.3f mm, max %.3f mm; singular values of the poses"
      " %.0f %.0f %.0f mm\n",
      pairs.size(), rows.size(), r.rms_mm, r.max_mm, r.singular_values(0) * 1e3, r.singular_values(1) * 1e3,
      r.singular_values(2) * 1e3);
  printTransform("fitted", r.camera_from_base);
  for (const auto& w : r.warnings) std::cerr << "hand_eye_calibrate: warning: " << w << "\n";
  return r;
}

std::vector<Row> simulate(const Options& o, const Eigen::Vector3d& offset, Eigen::Isometry3d* truth) {
  const arm::ArmConfig arm =
      arm::loadArmConfig(o.arm_config.empty() ? tools::packageFile("config/arm.yaml") : o.arm_config);
  const sim::StereoPairModel pair = sim::makeStereoPair(sim::RigParameters{});
  sim::MarkerMount mount;
  mount.spec = o.spec;
  mount.offset = offset;
  const std::vector<Eigen::Vector3d> tips =
      sim::spreadTipPositions(o.poses, arm.workspace_min, arm.workspace_max, pair, mount);
  const calib::RectifiedGeometry geometry = calib::rectifiedGeometry(pair.left_info, pair.right_info);
  sim::RenderOptions render;
  render.supersample = 3;
  render.noise_sigma = static_cast<float>(o.noise);
  render.noise_seed = o.seed;
  calib::RecordedSet recorded{pair.left_info, pair.right_info, offset, {}};
  std::vector<Row> rows;
  for (std::size_t i = 0; i < tips.size(); ++i) {
    const sim::MarkerPose pose = sim::renderMarkerPose(pair, tips[i], mount, render, o.seed + i, o.blur);
    Row row{tips[i], calib::detectMarker(pose.left, pose.right, geometry, o.spec)};
    if (row.detection.found) row.truth_error_mm = (row.detection.point - pose.marker_in_camera).norm() * 1e3;
    rows.push_back(row);
    if (!o.save_pairs.empty()) {
      const std::string name = "pose_" + std::to_string(i);
      cv::imwrite(o.save_pairs + "/" + name + "_left.png", pose.left);
      cv::imwrite(o.save_pairs + "/" + name + "_right.png", pose.right);
      recorded.poses.push_back({name + "_left.png", name + "_right.png", tips[i]});
    }
  }
  if (!o.save_pairs.empty()) calib::writeRecordedSet(o.save_pairs, recorded);
  *truth = sim::trueCameraFromBase(pair);
  return rows;
}

std::vector<Row> readRecorded(const Options& o, Eigen::Vector3d* offset) {
  const calib::RecordedSet set = calib::readRecordedSet(o.data);
  if (!o.offset && !set.marker_offset) {
    throw std::runtime_error(o.data + "/poses.yaml: no marker_offset; give it there or with --offset");
  }
  *offset = o.offset ? *o.offset : *set.marker_offset;
  const calib::RectifiedGeometry geometry = calib::rectifiedGeometry(set.left_info, set.right_info);
  std::vector<Row> rows;
  for (const calib::RecordedPose& p : set.poses) {
    const cv::Mat left = cv::imread(o.data + "/" + p.left, cv::IMREAD_COLOR);
    const cv::Mat right = cv::imread(o.data + "/" + p.right, cv::IMREAD_COLOR);
    if (left.empty() || right.empty()) {
      throw std::runtime_error(o.data + ": cannot read image " + (left.empty() ? p.left : p.right));
    }
    rows.push_back({p.tool_tip, calib::detectMarker(calib::rectify(set.left_info, left),
                                                    calib::rectify(set.right_info, right), geometry, o.spec)});
  }
  return rows;
}

void run(const Options& o) {
  if (!o.save_pairs.empty()) std::filesystem::create_directories(o.save_pairs);
  Eigen::Vector3d offset = o.offset.value_or(Eigen::Vector3d(0.0, 0.0, 0.06));
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  const std::vector<Row> rows = o.sim ? simulate(o, offset, &truth) : readRecorded(o, &offset);
  const calib::HandEyeResult r = fitAndReport(rows, offset, o);
  if (o.sim) {
    printTransform("exact", truth);
    std::printf("error vs exact: translation %.3f mm, rotation %.4f deg\n",
                (r.camera_from_base.translation() - truth.translation()).norm() * 1e3,
                calib::rotationAngle(r.camera_from_base.linear().transpose() * truth.linear()) * 180.0 / M_PI);
  }
  if (!o.out.empty()) {
    calib::writeHandEyeYaml(o.out, r);
    std::printf("wrote %s\n", o.out.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_WARNING);
  Options options;
  return tools::runTool(
      "hand_eye_calibrate", [&] { return parse(argc, argv, &options); }, [&] { run(options); });
}
