// stereo_bench: time and energy of the stereo methods on Middlebury scenes,
// the HBDS / alpha-expansion speed ratio measured in the same run, and the
// level sweep on the simulator's efficiency sets (thesis Fig. 2.9 / 2.10).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/calibration.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/camera_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"
#include "massage_cell/stereo/memory.h"
#include "massage_cell/stereo/middlebury.h"
#include "package_paths.h"
#include "stereo_params.h"

namespace {

namespace stereo = massage_cell::stereo;
namespace sim = massage_cell::sim;
namespace camera = massage_cell::camera;
using namespace massage_cell::tools;

const char* const kUsageHead = R"(Usage: stereo_bench [--scenes teddy,cones] [--methods hbds,expansion,wta,sgbm]
                    [--sweep] [--sweep-methods hbds,expansion,wta] [--sweep-size 320x240]
                    [--plot FILE.png] [--frame] [--frame-size 640x480] [--frame-levels 64]
                    [--frame-methods hbds,sgbm] [--frame-downsample 1,4] [--repeat 3]
                    [--data DIR] [--csv] [options]

Part 1: per Middlebury scene and method, the optimisers alone (no refinement,
no left-right check, no sub-pixel step, whatever the options say): time (cost
volume + optimisation) and the energy of Eq. 2.2 of the result; then per scene
the HBDS / alpha-expansion speed ratio and energy ratio, measured in this run
(after one untimed warm-up run per scene).
Part 2 (--sweep, the optimisers alone as in Part 1): the efficiency sets
rendered by the simulator (fronto-parallel layers and a slanted plane; one
left view, right views spanning 8..64 levels): time per method per level
count and time(64) / time(8).
Part 3 (--frame): the whole pipeline with the options (StereoSGBM as it
comes: the reference) on the cell's own scenes rendered by the simulator at
--frame-size (the mean subject's back on the massage table, and stacked
boxes; camera 0.95 m above the table, baseline 10 cm, fx = 500 px at 640
wide), searched over --frame-levels disparities centred on the scene's
range: every stage's time and the total (the 640x480 x 64-level speed
target: each method's total as a multiple of StereoSGBM's), the bad pixels
> 1 and > 0.5 px and the median |error| (px) against the exact ground truth
(pixels seen by both cameras), and on the back the skin's bias: the median of
d - d_true (px) over its skin (what the acupoints' depth inherits);
times are the median of --repeat runs (default 3: a stream's steady state,
not the first run's page faults). --frame-downsample F1,F2: each method also
at 1/F resolution as the hbds node's `downsample` runs it (both views shrunk
by INTER_AREA, the disparity range scaled), its disparity brought back to
full resolution (nearest, times F) and judged in full-resolution pixels; the
shrinking counts in its cost time (method label hbds/4).
  --plot FILE.png    draw time vs levels of the sweep
  --csv              print CSV: scene,method,levels,time_ms,energy
)";

struct Options {
  std::vector<std::string> scenes{"teddy", "cones"};
  std::vector<std::string> methods{"hbds", "expansion", "wta", "sgbm"};
  std::vector<std::string> sweep_methods{"hbds", "expansion", "wta"};
  bool sweep = false;
  int sweep_width = 320, sweep_height = 240;
  bool frame = false;
  int frame_width = 640, frame_height = 480, frame_levels = 64, repeat = 3;
  std::vector<std::string> frame_methods{"hbds", "sgbm"};
  std::vector<int> frame_downsample{1};
  std::string plot;
  std::string data;
  bool csv = false;
  stereo::StereoParams params;
};

bool parse(int argc, char** argv, Options& o) {
  OptionTable t;
  t.values["--scenes"] = [&](const std::string&, const std::string& v) { o.scenes = splitList(v); };
  t.values["--methods"] = [&](const std::string&, const std::string& v) { o.methods = splitList(v); };
  t.values["--sweep-methods"] = [&](const std::string&, const std::string& v) { o.sweep_methods = splitList(v); };
  auto size = [](int& width, int& height) {
    return [&width, &height](const std::string& opt, const std::string& v) {
      const auto x = v.find('x');
      if (x == std::string::npos) throw UsageError(opt + ": expected WxH, got '" + v + "'");
      width = parseInt(opt, v.substr(0, x));
      height = parseInt(opt, v.substr(x + 1));
    };
  };
  t.values["--sweep-size"] = size(o.sweep_width, o.sweep_height);
  t.values["--frame-size"] = size(o.frame_width, o.frame_height);
  t.values["--frame-levels"] = [&](const std::string& opt, const std::string& v) { o.frame_levels = parseInt(opt, v); };
  t.values["--frame-methods"] = [&](const std::string&, const std::string& v) { o.frame_methods = splitList(v); };
  t.values["--frame-downsample"] = [&](const std::string& opt, const std::string& v) {
    o.frame_downsample.clear();
    for (const auto& f : splitList(v)) o.frame_downsample.push_back(parseInt(opt, f));
  };
  t.values["--repeat"] = [&](const std::string& opt, const std::string& v) { o.repeat = parseInt(opt, v); };
  t.flags["--frame"] = [&] { o.frame = true; };
  t.values["--plot"] = [&](const std::string&, const std::string& v) { o.plot = v; };
  t.values["--data"] = [&](const std::string&, const std::string& v) { o.data = v; };
  t.flags["--sweep"] = [&] { o.sweep = true; };
  t.flags["--csv"] = [&] { o.csv = true; };
  addStereoParams(t, o.params);
  const std::string text = std::string(kUsageHead) + stereoParamsHelp();
  if (!parseArguments(argc, argv, t, text.c_str())) return false;
  for (const auto* list : {&o.methods, &o.sweep_methods, &o.frame_methods}) {
    for (const auto& m : *list) {
      try {
        stereo::parseMethod(m);
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
    }
  }
  require(o.sweep_width >= 64 && o.sweep_height >= 48, "--sweep-size must be at least 64x48");
  require(o.frame_width >= 160 && o.frame_height >= 120 && o.frame_width <= 4096 && o.frame_height <= 4096,
          "--frame-size must be between 160x120 and 4096x4096");
  require(o.repeat >= 1 && o.repeat <= 100, "--repeat must be in 1..100");
  require(o.frame_levels >= 2 && o.frame_levels < o.frame_width / 2,
          "--frame-levels must be >= 2 and below half the width");
  require(o.plot.empty() || o.sweep, "--plot needs --sweep");
  require(!o.frame_downsample.empty(), "--frame-downsample needs at least one factor");
  for (int f : o.frame_downsample)
    require(f == 1 || f == 2 || f == 4, "--frame-downsample factors must be 1, 2 or 4 (the hbds node's downsample)");
  checkStereoParams(o.params);
  return true;
}

struct Row {
  std::string scene, method;
  int levels;
  double ms;
  double energy;
};

void printRow(const Options& o, const Row& r, const stereo::MatchResult* m) {
  if (o.csv) {
    std::printf("%s,%s,%d,%.1f,%.4f\n", r.scene.c_str(), r.method.c_str(), r.levels, r.ms, r.energy);
  } else if (m) {
    std::printf("%-22s %-10s %6d %10.1f %10.1f %10.1f %14.2f %7d\n", r.scene.c_str(), r.method.c_str(), r.levels,
                m->cost_ms, m->optimize_ms, r.ms, r.energy, m->cuts);
  }
  std::fflush(stdout);
}

void header(const Options& o, const char* title) {
  if (o.csv) return;
  std::printf("\n%s\n%-22s %-10s %6s %10s %10s %10s %14s %7s\n", title, "scene", "method", "levels", "cost ms",
              "optim ms", "total ms", "energy", "cuts");
}

void drawPlot(const std::string& path, const std::vector<Row>& rows, const std::vector<std::string>& methods) {
  const int w = 800, h = 500, m = 60;
  cv::Mat plot(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  double max_ms = 1.0;
  for (const auto& r : rows) max_ms = std::max(max_ms, r.ms);
  const double lo = std::log10(std::max(0.1, max_ms / 1e4)), hi = std::log10(max_ms) + 0.1;
  auto px = [&](int levels, double ms) {
    return cv::Point(m + (levels - 8) * (w - 2 * m) / 56,
                     h - m - static_cast<int>((std::log10(std::max(ms, 0.1)) - lo) / (hi - lo) * (h - 2 * m)));
  };
  cv::rectangle(plot, {m, m}, {w - m, h - m}, cv::Scalar(0, 0, 0));
  for (int l = 8; l <= 64; l += 8)
    cv::putText(plot, std::to_string(l), px(l, std::pow(10, lo)) + cv::Point(-8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                {0, 0, 0});
  for (double e = std::ceil(lo); e <= hi; e += 1.0) {
    cv::putText(plot, std::to_string(static_cast<long>(std::pow(10, e))) + " ms", {5, px(8, std::pow(10, e)).y + 4},
                cv::FONT_HERSHEY_SIMPLEX, 0.4, {0, 0, 0});
  }
  cv::putText(plot, "time vs disparity levels (log scale)", {m, m - 20}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {0, 0, 0});
  const cv::Scalar colours[] = {{200, 60, 20}, {20, 20, 200}, {20, 150, 20}, {150, 20, 150}, {20, 150, 150}};
  int k = 0;
  for (const auto& method : methods) {
    const cv::Scalar colour = colours[k % 5];
    for (const char* scene : {"layers", "gradient"}) {
      cv::Point prev(-1, -1);
      for (const auto& r : rows) {
        if (r.method != method || r.scene.find(scene) == std::string::npos) continue;
        const cv::Point p = px(r.levels, r.ms);
        if (prev.x >= 0) cv::line(plot, prev, p, colour, std::string(scene) == "layers" ? 2 : 1, cv::LINE_AA);
        cv::circle(plot, p, 3, colour, cv::FILLED);
        prev = p;
      }
    }
    cv::putText(plot, method, {w - m + 5 - 60, m + 20 + 18 * k}, cv::FONT_HERSHEY_SIMPLEX, 0.5, colour);
    ++k;
  }
  cv::putText(plot, "thick: layers, thin: gradient", {m + 10, h - m - 10}, cv::FONT_HERSHEY_SIMPLEX, 0.4, {80, 80, 80});
  if (!cv::imwrite(path, plot)) throw std::runtime_error("cannot write '" + path + "'");
}

/// Median |disparity - truth| over the mask's pixels with a finite truth (NaN
/// disparities count as infinitely wrong).
/// The median of |d - truth| (or of d - truth: `absolute` false; NaN disparities then left out) over `mask`.
double medianError(const cv::Mat& disparity, const cv::Mat& truth, const cv::Mat& mask, bool absolute = true) {
  std::vector<float> errors;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const float t = truth.at<float>(y, x), d = disparity.at<float>(y, x);
      if (mask.at<uchar>(y, x) == 0 || !std::isfinite(t)) continue;
      if (absolute)
        errors.push_back(std::isfinite(d) ? std::abs(d - t) : std::numeric_limits<float>::infinity());
      else if (std::isfinite(d))
        errors.push_back(d - t);
    }
  if (errors.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

/// The optimisers compared (Parts 1 and 2), not the pipeline (Part 3): no refinement, no left-right check, no
/// sub-pixel step.
stereo::StereoParams optimiserOnly(stereo::StereoParams params) {
  params.refine = stereo::Refinement::kNone;
  params.lr_check = false;
  params.subpixel = false;
  return params;
}

/// One method on one rendered pair at 1/downsample resolution, as the hbds node's `downsample` runs it (both views
/// shrunk by camera::Decimation, the disparity range scaled outward), the median run of `repeat` by total time (the
/// methods are deterministic). The disparity is brought back to full resolution (nearest, in full-resolution
/// pixels); the shrinking counts in cost_ms.
stereo::MatchResult matchFrame(const sim::StereoFrame& frame, const std::string& method, stereo::StereoParams params,
                               int downsample, int repeat) {
  const camera::Decimation decimation(frame.left.image.size(), downsample);
  const double scale = static_cast<double>(decimation.size().width) / frame.left.image.cols;
  params.cost.dmin = static_cast<int>(std::floor(params.cost.dmin * scale));
  params.cost.dmax = static_cast<int>(std::ceil(params.cost.dmax * scale));
  std::vector<stereo::MatchResult> runs;
  for (int k = 0; k < repeat; ++k) {
    const auto start = std::chrono::steady_clock::now();
    const cv::Mat left = decimation.apply(frame.left.image), right = decimation.apply(frame.right.image);
    const double shrink_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    runs.push_back(stereo::match(left, right, stereo::parseMethod(method), params));
    runs.back().cost_ms += shrink_ms;
  }
  std::sort(runs.begin(), runs.end(), [](const auto& a, const auto& b) { return a.total_ms() < b.total_ms(); });
  stereo::MatchResult r = runs[runs.size() / 2];
  if (!decimation.identity()) {
    cv::Mat full;
    cv::resize(r.disparity, full, frame.left.image.size(), 0, 0, cv::INTER_NEAREST);
    r.disparity = full / scale;
  }
  return r;
}

/// Prints one row of Part 3: the stages' times, the energy and the errors against the frame's exact truth.
void printFrameRow(const Options& o, const std::string& scene, const std::string& method, int downsample,
                   const sim::StereoFrame& frame, const stereo::MatchResult& r) {
  const double bad = stereo::badPixelPercent(r.disparity, frame.left_disparity, frame.left_visible, 1.0);
  const double bad_half = stereo::badPixelPercent(r.disparity, frame.left_disparity, frame.left_visible, 0.5);
  const double median = medianError(r.disparity, frame.left_disparity, frame.left_visible);
  // The skin's bias (the acupoints' depth): the signed median over the back's visible skin.
  const cv::Mat skin = frame.left_visible & (frame.left.labels == sim::kLabelBack);
  const double skin_bias = medianError(r.disparity, frame.left_disparity, skin, false);
  const std::string label = downsample == 1 ? method : method + "/" + std::to_string(downsample);
  const Row row{scene, label, o.frame_levels, r.total_ms(), r.energy.total()};
  if (o.csv) {
    printRow(o, row, &r);
    return;
  }
  std::printf("%-22s %-10s %6d %9.1f %9.1f %9.1f %9.1f %9.1f %9.1f %14.2f %7d %8.2f%% %8.2f%% %10.3f %10s\n",
              row.scene.c_str(), label.c_str(), row.levels, r.cost_ms, r.optimize_ms, r.refine_ms, r.subpixel_ms,
              r.lr_ms, r.total_ms(), r.energy.total(), r.cuts, bad, bad_half, median,
              std::isfinite(skin_bias) ? format("%+.3f", skin_bias).c_str() : "-");
  std::fflush(stdout);
}

/// Part 3: the cell's own scenes at the given frame size.
void runFrames(const Options& o) {
  char title[160];
  std::snprintf(title, sizeof title, "Cell scenes (simulator) at %dx%d, %d levels: time, energy and bad pixels > 1 px",
                o.frame_width, o.frame_height, o.frame_levels);
  if (!o.csv) {
    std::printf("\n%s\n%-22s %-10s %6s %9s %9s %9s %9s %9s %9s %14s %7s %9s %9s %10s %10s\n", title, "scene", "method",
                "levels", "cost ms", "optim ms", "refine", "subpixel", "lr check", "total ms", "energy", "cuts",
                "bad>1px", "bad>.5px", "med|err|", "skin err");
  }
  sim::RigParameters rig;
  rig.width = o.frame_width;
  rig.height = o.frame_height;
  rig.fx = 500.0 * o.frame_width / 640.0;
  const sim::StereoPairModel pair = sim::makeStereoPair(rig);
  sim::RenderOptions render;
  const sim::Lighting light = sim::Lighting::preset(sim::LightPreset::kTopCentre);
  const sim::BackModel back(sim::BodyParameters::subject(0));
  for (const char* name : {"back", "boxes"}) {
    const sim::Renderer renderer(std::string(name) == "back" ? sim::makeBackScene(back, 1) : sim::makeBoxesScene(1));
    const sim::StereoFrame frame = sim::renderStereoFrame(renderer, pair, light, render);
    // Search range: frame_levels disparities centred on the scene's range.
    double lo = 0, hi = 0;
    cv::Mat finite = frame.left_disparity == frame.left_disparity;
    cv::minMaxLoc(frame.left_disparity, &lo, &hi, nullptr, nullptr, finite);
    const int centre = static_cast<int>(std::lround(0.5 * (lo + hi)));
    stereo::StereoParams params = o.params;
    params.cost.dmin = std::max(0, centre - o.frame_levels / 2);
    params.cost.dmax = params.cost.dmin + o.frame_levels - 1;
    const std::string scene =
        std::string(name) + "/" + std::to_string(o.frame_width) + "x" + std::to_string(o.frame_height);
    std::map<std::string, double> total_ms;
    for (const auto& method : o.frame_methods) {
      for (int downsample : o.frame_downsample) {
        // StereoSGBM is the reference as it comes (3-way, no refinement, no check); the others run the options.
        const stereo::StereoParams used = method == "sgbm" ? optimiserOnly(params) : params;
        const stereo::MatchResult r = matchFrame(frame, method, used, downsample, o.repeat);
        printFrameRow(o, scene, method, downsample, frame, r);
        total_ms[downsample == 1 ? method : method + "/" + std::to_string(downsample)] = r.total_ms();
      }
    }
    if (!o.csv && total_ms.count("sgbm") && total_ms["sgbm"] > 0.0) {
      for (const auto& [method, ms] : total_ms) {
        if (method != "sgbm")
          std::printf("%-22s %s: %.1fx StereoSGBM's time (%.1f Hz)\n", "", method.c_str(), ms / total_ms["sgbm"],
                      1000.0 / ms);
      }
    }
  }
}

void run(Options o) {
  if (!o.scenes.empty() && o.data.empty()) o.data = middleburyDir(sharedDataDir());
  if (o.csv) std::printf("scene,method,levels,time_ms,energy\n");
  // Part 1: Middlebury.
  if (!o.scenes.empty()) header(o, "Middlebury scenes: time and energy (Eq. 2.2) per method");
  for (const auto& name : o.scenes) {
    const stereo::MiddleburyScene scene = stereo::loadMiddleburyScene(o.data, name);
    stereo::StereoParams params = optimiserOnly(o.params);
    params.cost.dmin = 0;
    params.cost.dmax = scene.dmax;
    std::map<std::string, stereo::MatchResult> results;
    // Untimed warm-up: the first cost volume of a size pays the kernel's
    // page faults (later ones reuse the heap, see retainFreedMemory), which
    // would otherwise fall on whichever method runs first.
    stereo::match(scene.left, scene.right, stereo::Method::kWta, params);
    for (const auto& method : o.methods) {
      const stereo::MatchResult r = stereo::match(scene.left, scene.right, stereo::parseMethod(method), params);
      results[method] = r;
      printRow(o, {name, method, scene.dmax + 1, r.total_ms(), r.energy.total()}, &r);
    }
    if (!o.csv && results.count("hbds") && results.count("expansion")) {
      const auto& h = results["hbds"];
      const auto& e = results["expansion"];
      std::printf(
          "%-22s HBDS vs alpha-expansion: %.1fx faster (total time), %.1fx (optimisation only); energy ratio %.4f\n",
          name.c_str(), e.total_ms() / h.total_ms(), e.optimize_ms / h.optimize_ms,
          h.energy.total() / e.energy.total());
    }
  }
  if (o.frame) runFrames(o);
  if (!o.sweep) return;
  // Part 2: level sweep on the simulator's efficiency sets.
  header(o, "Level sweep on the efficiency sets (simulator, thesis Fig. 2.9 / 2.10)");
  std::vector<Row> rows;
  const double fx = 0.9 * o.sweep_width;
  for (bool gradient : {false, true}) {
    const sim::EfficiencySet set = sim::makeEfficiencySet(gradient, o.sweep_width, o.sweep_height, fx, 3);
    const sim::Renderer renderer(set.scene);
    sim::RenderOptions render;
    render.supersample = 2;
    render.noise_sigma = 1.0f;
    const sim::Lighting light = sim::Lighting::preset(sim::LightPreset::kTopCentre);
    const cv::Mat left = renderer.render(set.left, light, render).image;
    bool warm = false;  // untimed warm-up on the widest range (see Part 1)
    for (std::size_t k = 0; k < set.rights.size(); ++k) {
      render.noise_seed = static_cast<std::uint32_t>(k + 1);
      const cv::Mat right = renderer.render(set.rights[k], light, render).image;
      stereo::StereoParams params = optimiserOnly(o.params);
      params.cost.dmin = static_cast<int>(std::floor(fx * set.baselines[k] / set.z_far));
      params.cost.dmax = static_cast<int>(std::ceil(fx * set.baselines[k] / set.z_near));  // spans levels[k] + 1 labels
      if (!warm) {
        stereo::StereoParams widest = params;
        widest.cost.dmax = std::min(widest.cost.dmin + set.levels.back(), left.cols - 1);
        stereo::match(left, right, stereo::Method::kWta, widest);
        warm = true;
      }
      const std::string scene = std::string(gradient ? "gradient" : "layers") + "/R" + std::to_string(k + 1);
      for (const auto& method : o.sweep_methods) {
        const stereo::MatchResult r = stereo::match(left, right, stereo::parseMethod(method), params);
        Row row{scene, method, set.levels[k], r.total_ms(), r.energy.total()};
        rows.push_back(row);
        printRow(o, row, &r);
      }
    }
  }
  if (!o.csv) {
    std::printf("\ntime(64 levels) / time(8 levels):\n");
    for (const char* scene : {"layers", "gradient"}) {
      for (const auto& method : o.sweep_methods) {
        double t8 = 0, t64 = 0;
        for (const auto& r : rows) {
          if (r.method != method || r.scene.rfind(scene, 0) != 0) continue;
          if (r.levels == 8) t8 = r.ms;
          if (r.levels == 64) t64 = r.ms;
        }
        std::printf("  %-9s %-10s %6.2f  (%.1f -> %.1f ms)\n", scene, method.c_str(), t64 / t8, t8, t64);
      }
    }
  }
  if (!o.plot.empty()) {
    drawPlot(o.plot, rows, o.sweep_methods);
    if (!o.csv) std::printf("plot: %s\n", o.plot.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  massage_cell::stereo::retainFreedMemory();
  Options options;
  return runTool(
      "stereo_bench", [&] { return parse(argc, argv, options); }, [&] { run(options); });
}
