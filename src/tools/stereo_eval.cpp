// stereo_eval: the Middlebury evaluation of the stereo methods — bad-pixel
// rates at 0.5 / 1 / 2 px in the nonocc, all and disc masks.
#include <cstdio>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stereo_params.h"

namespace {

namespace stereo = massage_cell::stereo;
using namespace massage_cell::tools;

const char* const kUsageHead = R"(Usage: stereo_eval [--scenes tsukuba,venus,teddy,cones] [--methods hbds,expansion,swap,wta,sgbm]
                   [--data DIR] [--csv] [--pictures DIR] [options]

Runs each method on each Middlebury scene (official range 0..dmax per scene)
and prints the percentage of bad pixels (|d - d_gt| > 0.5 / 1 / 2 px) in the
nonocc, all and disc masks, and the time. Data: --data, else
$MASSAGE_CELL_MIDDLEBURY, else ../shared/data/middlebury2003 beside the package.
  --csv              print CSV: scene,method,mask,threshold,bad_percent,time_ms
  --pictures DIR     also write DIR/<scene>_<method>.png: the disparity (colour) beside
                     the errors in the nonocc mask (> 1 px in red, NaN in blue, over the
                     grey left image; black: occluded or no ground truth) and, with --refine ffd-mdc, FFD's mask
                     (yellow) over the grey left image
)";

struct Options {
  std::vector<std::string> scenes = stereo::middleburyScenes();
  std::vector<std::string> methods{"hbds", "expansion", "swap", "wta", "sgbm"};
  std::string data;
  bool csv = false;
  std::string pictures;
  stereo::StereoParams params;
};

bool parse(int argc, char** argv, Options& o) {
  OptionTable t;
  t.values["--scenes"] = [&](const std::string&, const std::string& v) { o.scenes = splitList(v); };
  t.values["--methods"] = [&](const std::string&, const std::string& v) { o.methods = splitList(v); };
  t.values["--data"] = [&](const std::string&, const std::string& v) { o.data = v; };
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
  if (o.data.empty()) o.data = stereo::middleburyRoot();
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
      if (!(g > 0.0f) || scene.nonocc.at<uchar>(y, x) != 255) px = cv::Vec3b(0, 0, 0);
      else if (!std::isfinite(d)) px = cv::Vec3b(255, 80, 0);
      else if (std::abs(d - g) > 1.0f) px = cv::Vec3b(0, 0, 255);
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

void run(const Options& o) {
  if (!o.pictures.empty()) std::filesystem::create_directories(o.pictures);
  const double thresholds[3] = {0.5, 1.0, 2.0};
  if (o.csv) {
    std::printf("scene,method,mask,threshold,bad_percent,time_ms\n");
  } else {
    std::printf("Middlebury bad pixels (%%), data %s\n", o.data.c_str());
    std::printf("%-8s %-13s | %-20s | %-20s | %-20s | %9s\n", "scene", "method", "nonocc >0.5 >1 >2", "all >0.5 >1 >2",
                "disc >0.5 >1 >2", "time ms");
  }
  for (const auto& name : o.scenes) {
    const stereo::MiddleburyScene scene = stereo::loadMiddleburyScene(o.data, name);
    stereo::StereoParams params = o.params;
    params.cost.dmin = 0;
    params.cost.dmax = scene.dmax;
    for (const auto& method : o.methods) {
      const stereo::MatchResult r = stereo::match(scene.left, scene.right, stereo::parseMethod(method), params);
      const std::string label =
          params.refine == stereo::Refinement::kNone ? method : method + "+" + stereo::toString(params.refine);
      const std::pair<const char*, const cv::Mat*> masks[3] = {{"nonocc", &scene.nonocc}, {"all", &scene.all}, {"disc", &scene.disc}};
      if (!o.pictures.empty()) writePicture(o, scene, label, r);
      double bad[3][3];
      for (int m = 0; m < 3; ++m) {
        for (int t = 0; t < 3; ++t) bad[m][t] = stereo::badPixelPercent(r.disparity, scene.ground_truth, *masks[m].second, thresholds[t]);
      }
      if (o.csv) {
        for (int m = 0; m < 3; ++m) {
          for (int t = 0; t < 3; ++t) {
            std::printf("%s,%s,%s,%.1f,%.3f,%.1f\n", name.c_str(), label.c_str(), masks[m].first, thresholds[t], bad[m][t],
                        r.total_ms());
          }
        }
      } else {
        std::printf("%-8s %-13s | %6.2f %6.2f %6.2f | %6.2f %6.2f %6.2f | %6.2f %6.2f %6.2f | %9.1f\n", name.c_str(),
                    label.c_str(), bad[0][0], bad[0][1], bad[0][2], bad[1][0], bad[1][1], bad[1][2], bad[2][0], bad[2][1],
                    bad[2][2], r.total_ms());
      }
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  massage_cell::stereo::retainFreedMemory();
  Options options;
  return runTool("stereo_eval", [&] { return parse(argc, argv, options); }, [&] { run(options); });
}
