// stereo_eval: the Middlebury evaluation of the stereo methods — bad-pixel
// rates at 0.5 / 1 / 2 px in the nonocc, all and disc masks.
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/colourise.h"
#include "massage_cell/stereo/consistency.h"
#include "massage_cell/stereo/memory.h"
#include "massage_cell/stereo/middlebury.h"
#include "package_paths.h"
#include "stereo_params.h"

namespace {

namespace stereo = massage_cell::stereo;
using namespace massage_cell::tools;

const char* const kUsageHead =
    R"(Usage: stereo_eval [--scenes tsukuba,venus,teddy,cones,art,dolls] [--methods hbds,sgbm]
                   [--data DIR] [--data2005 DIR] [--refiners R1,R2,...] [--csv] [--pictures DIR] [options]

Runs each method on each Middlebury scene (official range 0..dmax per scene;
0..79 for the 2005 scenes) and prints the percentage of bad pixels
(|d - d_gt| > 0.5 / 1 / 2 px) in the nonocc, all and disc masks, and the time.
The 2005 scenes ship no masks: all = known GT, nonocc = known GT whose match
lies inside the right image (x >= d_gt), disc = nonocc within 4 px of a GT
jump > 2 px. Data: --data / --data2005, else $MASSAGE_CELL_MIDDLEBURY /
$MASSAGE_CELL_MIDDLEBURY2005, else ../shared/data/middlebury2003 / middlebury2005
beside the package. Every method runs with the options below (the project's
defaults unless given); with sgbm in --methods the reference row sgbm+fill is
plain StereoSGBM 3-way (no refinement, no left-right check) with its invalid
pixels filled from the background side, and the last table gives every row's
`all` bad > 1 px and time as multiples of it. Methods: hbds, expansion, swap,
wta, sgbm.
  --refiners LIST    run each method once per refinement in LIST (instead of --refine), e.g.
                     none,2dbf,ffd-2dbf,3dbf,ffd-3dbf,wmf,ffd-wmf,mdc,ffd-mdc for the thesis's Table 2.5
  --csv              print CSV: scene,method,mask,threshold,bad_percent,time_ms
  --pictures DIR     also write DIR/<scene>_<method>.png: the disparity (colour) beside
                     the errors in the nonocc mask (> 1 px in red, NaN in blue, over the
                     grey left image; black: occluded or no ground truth) and, with --refine ffd-mdc, FFD's mask
                     (yellow) over the grey left image
)";

std::vector<std::string> allScenes() {
  std::vector<std::string> scenes = stereo::middleburyScenes();
  for (const auto& s : stereo::middlebury2005Scenes()) scenes.push_back(s);
  return scenes;
}

struct Options {
  std::vector<std::string> scenes = allScenes();
  std::vector<std::string> methods{"hbds", "sgbm"};
  std::string data, data2005;
  std::vector<stereo::Refinement> refiners;
  bool csv = false;
  std::string pictures;
  stereo::StereoParams params;
};

bool parse(int argc, char** argv, Options& o) {
  OptionTable t;
  t.values["--scenes"] = [&](const std::string&, const std::string& v) { o.scenes = splitList(v); };
  t.values["--methods"] = [&](const std::string&, const std::string& v) { o.methods = splitList(v); };
  t.values["--data"] = [&](const std::string&, const std::string& v) { o.data = v; };
  t.values["--data2005"] = [&](const std::string&, const std::string& v) { o.data2005 = v; };
  t.values["--refiners"] = [&](const std::string&, const std::string& v) {
    o.refiners.clear();
    for (const auto& name : splitList(v)) {
      try {
        o.refiners.push_back(stereo::parseRefinement(name));
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
    }
  };
  t.flags["--csv"] = [&] { o.csv = true; };
  t.values["--pictures"] = [&](const std::string&, const std::string& v) { o.pictures = v; };
  addStereoParams(t, o.params);
  const std::string text = std::string(kUsageHead) + stereoParamsHelp();
  if (!parseArguments(argc, argv, t, text.c_str())) return false;
  require(!o.scenes.empty() && !o.methods.empty(), "--scenes and --methods need at least one name");
  for (const auto& m : o.methods) {
    try {
      stereo::parseMethod(m);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }
  checkStereoParams(o.params);
  if (o.refiners.empty()) o.refiners.push_back(o.params.refine);
  return true;
}

/// Disparity | errors > 1 px in nonocc | (FFD mask): one picture per scene and method.
void writePicture(const Options& o, const stereo::MiddleburyScene& scene, const std::string& label,
                  const stereo::MatchResult& r) {
  cv::Mat grey, base;
  cv::cvtColor(scene.left, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(grey / 2, base, cv::COLOR_GRAY2BGR);
  cv::Mat errors = base.clone();
  for (int y = 0; y < errors.rows; ++y) {
    for (int x = 0; x < errors.cols; ++x) {
      const float g = scene.ground_truth.at<float>(y, x), d = r.disparity.at<float>(y, x);
      cv::Vec3b& px = errors.at<cv::Vec3b>(y, x);
      if (!(g > 0.0f) || scene.nonocc.at<uchar>(y, x) != 255)
        px = cv::Vec3b(0, 0, 0);
      else if (!std::isfinite(d))
        px = cv::Vec3b(255, 80, 0);
      else if (std::abs(d - g) > 1.0f)
        px = cv::Vec3b(0, 0, 255);
    }
  }
  std::vector<cv::Mat> parts{stereo::colourise(r.disparity, 0, scene.dmax), errors};
  if (!r.fattening.empty()) {
    cv::Mat mask = base.clone();
    mask.setTo(cv::Scalar(0, 255, 255), r.fattening);
    parts.push_back(mask);
  }
  cv::Mat picture;
  cv::hconcat(parts, picture);
  const std::string path = (std::filesystem::path(o.pictures) / (scene.name + "_" + label + ".png")).string();
  if (!cv::imwrite(path, picture)) throw std::runtime_error("cannot write '" + path + "'");
}

struct Row {
  std::string scene, label;
  double bad[3][3];  // [nonocc, all, disc][> 0.5, > 1, > 2]
  double ms;
};

const char* const kMasks[3] = {"nonocc", "all", "disc"};
const double kThresholds[3] = {0.5, 1.0, 2.0};

Row evaluate(const stereo::MiddleburyScene& scene, const std::string& label, const cv::Mat& disparity, double ms) {
  const cv::Mat* masks[3] = {&scene.nonocc, &scene.all, &scene.disc};
  Row row{scene.name, label, {}, ms};
  for (int m = 0; m < 3; ++m) {
    for (int t = 0; t < 3; ++t)
      row.bad[m][t] = stereo::badPixelPercent(disparity, scene.ground_truth, *masks[m], kThresholds[t]);
  }
  return row;
}

void print(const Options& o, const Row& r) {
  if (o.csv) {
    for (int m = 0; m < 3; ++m) {
      for (int t = 0; t < 3; ++t) {
        std::printf("%s,%s,%s,%.1f,%.3f,%.1f\n", r.scene.c_str(), r.label.c_str(), kMasks[m], kThresholds[t],
                    r.bad[m][t], r.ms);
      }
    }
  } else {
    std::printf("%-8s %-17s | %6.2f %6.2f %6.2f | %6.2f %6.2f %6.2f | %6.2f %6.2f %6.2f | %9.1f\n", r.scene.c_str(),
                r.label.c_str(), r.bad[0][0], r.bad[0][1], r.bad[0][2], r.bad[1][0], r.bad[1][1], r.bad[1][2],
                r.bad[2][0], r.bad[2][1], r.bad[2][2], r.ms);
  }
  std::fflush(stdout);
}

/// The thesis's Tables 2.4-2.6 layout: one row per method (+ refinement), nonocc / all / disc bad > 1 px
/// per scene.
void printTable(const std::vector<Row>& rows, const std::vector<std::string>& scenes) {
  std::vector<std::string> labels;
  for (const Row& r : rows) {
    if (std::find(labels.begin(), labels.end(), r.label) == labels.end()) labels.push_back(r.label);
  }
  std::printf("\nbad > 1 px (%%): nonocc / all / disc\n%-18s", "method");
  for (const auto& scene : scenes) std::printf(" | %-20s", scene.c_str());
  std::printf("\n");
  for (const auto& label : labels) {
    std::printf("%-18s", label.c_str());
    for (const auto& scene : scenes) {
      const auto it =
          std::find_if(rows.begin(), rows.end(), [&](const Row& r) { return r.scene == scene && r.label == label; });
      if (it == rows.end()) {
        std::printf(" | %-20s", "");
      } else {
        std::printf(" | %6.2f %6.2f %6.2f", it->bad[0][1], it->bad[1][1], it->bad[2][1]);
      }
    }
    std::printf("\n");
  }
}

/// Each method's `all` bad > 1 px and time as a multiple of StereoSGBM's with its invalid pixels filled
/// from the background side (the issue's reference), scene by scene.
void printRatios(const std::vector<Row>& rows) {
  std::printf(
      "\nall > 1 px and time relative to sgbm+fill (StereoSGBM 3-way, invalid filled from the background side)\n");
  for (const Row& ref : rows) {
    if (ref.label != "sgbm+fill") continue;
    for (const Row& r : rows) {
      if (r.scene != ref.scene || r.label == "sgbm+fill") continue;
      std::printf("%-8s %-17s  %5.2f x bad   %7.1f x time\n", r.scene.c_str(), r.label.c_str(),
                  ref.bad[1][1] > 0 ? r.bad[1][1] / ref.bad[1][1] : 0.0, ref.ms > 0 ? r.ms / ref.ms : 0.0);
    }
  }
}

/// The reference: plain StereoSGBM 3-way (whatever the options' refinement and left-right check), its invalid
/// pixels filled from the background side along their row.
Row sgbmReference(const stereo::MiddleburyScene& scene, stereo::StereoParams params) {
  params.refine = stereo::Refinement::kNone;
  params.lr_check = false;
  const stereo::MatchResult r = stereo::match(scene.left, scene.right, stereo::Method::kSgbm, params);
  const cv::Mat filled = stereo::fillFromBackground(r.disparity, r.disparity == r.disparity);
  return evaluate(scene, "sgbm+fill", filled, r.total_ms());
}

void run(Options o) {
  if (o.data.empty()) o.data = middleburyDir(sharedDataDir());
  if (o.data2005.empty()) o.data2005 = middlebury2005Dir(sharedDataDir());
  if (!o.pictures.empty()) std::filesystem::create_directories(o.pictures);
  if (o.csv) {
    std::printf("scene,method,mask,threshold,bad_percent,time_ms\n");
  } else {
    std::printf("Middlebury bad pixels (%%), data %s, %s\n", o.data.c_str(), o.data2005.c_str());
    std::printf("%-8s %-17s | %-20s | %-20s | %-20s | %9s\n", "scene", "method", "nonocc >0.5 >1 >2", "all >0.5 >1 >2",
                "disc >0.5 >1 >2", "time ms");
  }
  std::vector<Row> rows;
  for (const auto& name : o.scenes) {
    const stereo::MiddleburyScene scene =
        stereo::loadMiddleburyScene(stereo::isMiddlebury2005Scene(name) ? o.data2005 : o.data, name);
    stereo::StereoParams params = o.params;
    params.cost.dmin = 0;
    params.cost.dmax = scene.dmax;
    for (const auto& method : o.methods) {
      for (const stereo::Refinement refiner : o.refiners) {
        params.refine = refiner;
        const stereo::MatchResult r = stereo::match(scene.left, scene.right, stereo::parseMethod(method), params);
        const std::string label =
            method + (params.refine == stereo::Refinement::kNone ? "" : "+" + stereo::toString(params.refine)) +
            (params.lr_check ? "+lr" : "");
        if (!o.pictures.empty()) writePicture(o, scene, label, r);
        rows.push_back(evaluate(scene, label, r.disparity, r.total_ms()));
        print(o, rows.back());
      }
      if (method == "sgbm") {
        rows.push_back(sgbmReference(scene, params));
        print(o, rows.back());
      }
    }
  }
  if (!o.csv) {
    printTable(rows, o.scenes);
    printRatios(rows);
  }
}

}  // namespace

int main(int argc, char** argv) {
  massage_cell::stereo::retainFreedMemory();
  Options options;
  return runTool(
      "stereo_eval", [&] { return parse(argc, argv, options); }, [&] { run(options); });
}
