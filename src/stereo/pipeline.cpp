#include "massage_cell/stereo/pipeline.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <stdexcept>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/consistency.h"
#include "massage_cell/stereo/filters.h"
#include "massage_cell/stereo/optimizers.h"

namespace massage_cell::stereo {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// Integer labelling for the energy: rounded, clamped into the volume's range (NaN -> dmin).
cv::Mat toLabelling(const cv::Mat& disparity, int dmin, int dmax) {
  cv::Mat out(disparity.size(), CV_32F);
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      const float v = std::isfinite(d[x]) ? std::round(d[x]) : static_cast<float>(dmin);
      o[x] = std::min(std::max(v, static_cast<float>(dmin)), static_cast<float>(dmax));
    }
  }
  return out;
}

cv::Mat sgbm(const cv::Mat& left, const cv::Mat& right, const CostParams& cost) {
  const int levels = cost.dmax - cost.dmin + 1;
  const int num = ((levels + 15) / 16) * 16;
  const int block = 5;
  const int cn = left.channels();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // No column can be matched (OpenCV 4.6's 3-way SGBM then asserts in a
  // destructor and terminates the process): every pixel is invalid.
  if (std::max(cost.dmin + num, 0) >= left.cols + std::min(cost.dmin, 0)) return cv::Mat(left.size(), CV_32F, nan);
  auto matcher = cv::StereoSGBM::create(cost.dmin, num, block, 8 * cn * block * block, 32 * cn * block * block, 1, 63,
                                        10, 100, 2, cv::StereoSGBM::MODE_SGBM_3WAY);
  cv::Mat raw;
  matcher->compute(left, right, raw);
  cv::Mat disparity(raw.size(), CV_32F);
  for (int y = 0; y < raw.rows; ++y) {
    const short* r = raw.ptr<short>(y);
    float* d = disparity.ptr<float>(y);
    for (int x = 0; x < raw.cols; ++x) {
      d[x] = r[x] < cost.dmin * 16 ? nan : std::min(r[x] / 16.0f, static_cast<float>(cost.dmax));
    }
  }
  return disparity;
}

cv::Mat readImage(const std::filesystem::path& path, int flags) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("missing file '" + path.string() + "'");
  cv::Mat image = cv::imread(path.string(), flags);
  if (image.empty()) throw std::runtime_error("cannot read image '" + path.string() + "'");
  return image;
}

}  // namespace

Method parseMethod(const std::string& name) {
  static const std::map<std::string, Method> methods{{"hbds", Method::kHbds},
                                                     {"expansion", Method::kExpansion},
                                                     {"swap", Method::kSwap},
                                                     {"wta", Method::kWta},
                                                     {"sgbm", Method::kSgbm}};
  const auto it = methods.find(name);
  if (it == methods.end()) {
    throw std::invalid_argument("unknown method '" + name + "' (hbds, expansion, swap, wta, sgbm)");
  }
  return it->second;
}

namespace {

const std::vector<std::pair<Refinement, std::string>>& refinementNames() {
  static const std::vector<std::pair<Refinement, std::string>> names{
      {Refinement::kNone, "none"},        {Refinement::kMdc, "mdc"},          {Refinement::kFfdMdc, "ffd-mdc"},
      {Refinement::kBf2d, "2dbf"},        {Refinement::kFfdBf2d, "ffd-2dbf"}, {Refinement::kBf3d, "3dbf"},
      {Refinement::kFfdBf3d, "ffd-3dbf"}, {Refinement::kWmf, "wmf"},          {Refinement::kFfdWmf, "ffd-wmf"}};
  return names;
}

}  // namespace

Refinement parseRefinement(const std::string& name) {
  std::string all;
  for (const auto& [refinement, text] : refinementNames()) {
    if (text == name) return refinement;
    all += (all.empty() ? "" : ", ") + text;
  }
  throw std::invalid_argument("unknown refinement '" + name + "' (" + all + ")");
}

std::string toString(Refinement refinement) {
  for (const auto& [r, text] : refinementNames()) {
    if (r == refinement) return text;
  }
  return "?";
}

bool usesFattening(Refinement refinement) {
  return refinement == Refinement::kFfdMdc || refinement == Refinement::kFfdBf2d ||
         refinement == Refinement::kFfdBf3d || refinement == Refinement::kFfdWmf;
}

namespace {

cv::Mat applyRefinement(const cv::Mat& left, const cv::Mat& disparity, const StereoParams& params, cv::Mat* fattening) {
  switch (params.refine) {
    case Refinement::kNone:
      return disparity;
    case Refinement::kMdc:
    case Refinement::kFfdMdc: {
      RefineParams rp = params.refine_params;
      rp.detect_fattening = params.refine == Refinement::kFfdMdc;
      return refineDisparity(left, disparity, rp, fattening);
    }
    default:
      break;
  }
  validate(params.filter_params);
  cv::Mat mask;
  if (usesFattening(params.refine)) mask = detectFattening(left, disparity, params.refine_params);
  if (fattening != nullptr) *fattening = mask;
  const DisparityFilter filter =
      params.refine == Refinement::kBf2d || params.refine == Refinement::kFfdBf2d   ? DisparityFilter::kBilateral2d
      : params.refine == Refinement::kBf3d || params.refine == Refinement::kFfdBf3d ? DisparityFilter::kBilateral3d
                                                                                    : DisparityFilter::kWeightedMedian;
  return filterDisparity(left, disparity, filter, mask, params.filter_params);
}

}  // namespace

std::string toString(Method method) {
  switch (method) {
    case Method::kHbds:
      return "hbds";
    case Method::kExpansion:
      return "expansion";
    case Method::kSwap:
      return "swap";
    case Method::kWta:
      return "wta";
    case Method::kSgbm:
      return "sgbm";
  }
  return "?";
}

std::vector<ParamProblem> checkParams(const StereoParams& p) {
  std::vector<ParamProblem> problems;
  auto require = [&](bool ok, const char* name, const char* problem) {
    if (!ok) problems.push_back({name, problem});
  };
  auto nested = [&](const char* name, const std::function<void()>& validate_one) {
    try {
      validate_one();
    } catch (const std::invalid_argument& e) {
      problems.push_back({name, e.what()});
    }
  };
  require(p.cost.eta > 0.0f && std::isfinite(p.cost.eta), "eta", "must be > 0");
  require(p.cost.census_lambda > 0.0f && std::isfinite(p.cost.census_lambda), "census_lambda", "must be > 0");
  require(p.cost.ad_lambda > 0.0f && std::isfinite(p.cost.ad_lambda), "ad_lambda", "must be > 0");
  require(p.cost.ncc_window >= 1 && p.cost.ncc_window % 2 == 1, "ncc_window", "must be odd and >= 1");
  require(p.cost.gradient_saturation >= 0.0f && std::isfinite(p.cost.gradient_saturation), "gradient_saturation",
          "must be >= 0");
  require(p.cost.threads >= 0, "threads", "must be >= 0");
  require(p.smooth.tau > 0.0f && std::isfinite(p.smooth.tau), "tau", "must be > 0");
  require(p.smooth.u_min >= 0.0f && std::isfinite(p.smooth.u_min), "u_min", "must be >= 0");
  require(p.smooth.u_max >= p.smooth.u_min && std::isfinite(p.smooth.u_max), "u_max", "must be >= u_min");
  require(p.smooth.truncation >= 0.0f, "truncation", "must be >= 0");
  require(p.max_cycles >= 1, "max_cycles", "must be >= 1");
  require(p.hbds_overlap >= 0, "overlap", "must be >= 0");
  require(p.hbds_coarse >= 1 && p.hbds_coarse <= 8, "coarse", "must be in 1..8");
  require(p.polish_window >= 0, "polish_window", "must be >= 0");
  require(p.polish_cycles >= 1, "polish_cycles", "must be >= 1");
  nested("refine_window", [&] { validate(p.refine_params); });
  nested("filter", [&] { validate(p.filter_params); });
  nested("subpixel_window", [&] { validate(p.subpixel_params); });
  require(p.lr_tolerance >= 0.0f && std::isfinite(p.lr_tolerance), "lr_tolerance", "must be >= 0");
  require(p.threads >= 0, "threads", "must be >= 0");
  return problems;
}

void retainFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 512 << 20);  // blocks below 512 MB come from the heap...
  mallopt(M_TRIM_THRESHOLD, 1 << 30);    // ...which is not trimmed below 1 GB of free space
#endif
}

namespace {

/// One view: the method, its refinement and the sub-pixel step.
MatchResult matchLeftView(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params) {
  MatchResult result;
  if (params.subpixel) validate(params.subpixel_params);  // before minutes of matching, not after
  auto start = Clock::now();
  const CostVolume volume = computeCostVolume(left, right, params.cost);  // validates the input
  result.cost_ms = msSince(start);
  const PairwiseWeights weights = pairwiseWeights(left, params.smooth);
  start = Clock::now();
  switch (method) {
    case Method::kHbds: {
      OptimizerResult r = hbds(volume, weights, params.smooth, params.threads, params.hbds_overlap, params.hbds_coarse);
      if (params.polish_window > 0) {
        const int hbds_cuts = r.cuts;
        r = localExpansion(volume, weights, params.smooth, r.disparity, params.polish_window, params.polish_cycles);
        r.cuts += hbds_cuts;
      }
      result.optimize_ms = msSince(start);
      result.disparity = r.disparity;
      result.cuts = r.cuts;
      break;
    }
    case Method::kExpansion:
    case Method::kSwap: {
      const OptimizerResult r = method == Method::kExpansion
                                    ? alphaExpansion(volume, weights, params.smooth, cv::Mat(), params.max_cycles)
                                    : alphaBetaSwap(volume, weights, params.smooth, cv::Mat(), params.max_cycles);
      result.optimize_ms = msSince(start);
      result.disparity = r.disparity;
      result.cuts = r.cuts;
      break;
    }
    case Method::kWta:
      result.disparity = winnerTakesAll(volume);
      result.optimize_ms = msSince(start);
      break;
    case Method::kSgbm:
      result.disparity = sgbm(left, right, params.cost);
      result.optimize_ms = msSince(start);
      result.cost_ms = 0.0;  // SGBM computes its own cost
      break;
  }
  if (params.refine != Refinement::kNone) {
    start = Clock::now();
    result.disparity = applyRefinement(left, result.disparity, params, &result.fattening);
    result.refine_ms = msSince(start);
  }
  if (params.subpixel && method != Method::kSgbm) {
    start = Clock::now();
    result.disparity = subpixelDisparity(volume, result.disparity, params.subpixel_params);
    result.subpixel_ms = msSince(start);
  }
  result.energy = labellingEnergy(volume, weights, toLabelling(result.disparity, volume.dmin(), volume.dmax()),
                                  params.smooth.truncation);
  return result;
}

}  // namespace

MatchResult match(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params) {
  if (params.lr_check && !(params.lr_tolerance >= 0.0f && std::isfinite(params.lr_tolerance))) {
    throw std::invalid_argument("lr_tolerance must be finite and >= 0, got " + std::to_string(params.lr_tolerance));
  }
  MatchResult result = matchLeftView(left, right, method, params);
  if (!params.lr_check) return result;
  const auto start = Clock::now();
  const cv::Mat right_disparity = rightViewDisparity(
      left, right, [&](const cv::Mat& a, const cv::Mat& b) { return matchLeftView(a, b, method, params).disparity; });
  result.consistent = leftRightCheck(result.disparity, right_disparity, params.lr_tolerance);
  result.disparity = fillFromBackground(result.disparity, result.consistent);
  result.lr_ms = msSince(start);
  return result;
}

namespace {

std::string dataFolder(const char* variable, const std::string& shared_data, const char* folder) {
  if (const char* env = std::getenv(variable)) return env;
  return (std::filesystem::path(shared_data) / folder).lexically_normal().string();
}

/// Pixels within 4 of a ground-truth jump of more than 2 px (a 9x9 window, as Middlebury's disc masks),
/// inside `nonocc`.
cv::Mat discontinuityMask(const cv::Mat& ground_truth, const cv::Mat& nonocc) {
  cv::Mat jumps(ground_truth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < ground_truth.rows; ++y) {
    for (int x = 0; x < ground_truth.cols; ++x) {
      const float g = ground_truth.at<float>(y, x);
      if (!(g > 0.0f)) continue;
      const float right = x + 1 < ground_truth.cols ? ground_truth.at<float>(y, x + 1) : 0.0f;
      const float down = y + 1 < ground_truth.rows ? ground_truth.at<float>(y + 1, x) : 0.0f;
      if ((right > 0.0f && std::abs(right - g) > 2.0f) || (down > 0.0f && std::abs(down - g) > 2.0f)) {
        jumps.at<uchar>(y, x) = 255;
      }
    }
  }
  cv::Mat disc;
  cv::dilate(jumps, disc, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(9, 9)));
  return disc & nonocc;
}

/// Middlebury 2005 (third size): no masks ship; `all` = every pixel (the GT's 0 = unknown is skipped by
/// badPixelPercent), `nonocc` = the pixels whose match lies inside the right image (x >= d_gt), `disc` =
/// discontinuityMask.
void derive2005Masks(MiddleburyScene& scene) {
  scene.all = cv::Mat(scene.ground_truth.size(), CV_8U, cv::Scalar(255));
  scene.nonocc = cv::Mat(scene.ground_truth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < scene.ground_truth.rows; ++y) {
    for (int x = 0; x < scene.ground_truth.cols; ++x) {
      const float g = scene.ground_truth.at<float>(y, x);
      if (g > 0.0f && x >= g) scene.nonocc.at<uchar>(y, x) = 255;
    }
  }
  scene.disc = discontinuityMask(scene.ground_truth, scene.nonocc);
}

struct SceneFacts {
  int dmax, scale;
  bool year2005;
};

const std::map<std::string, SceneFacts>& sceneFacts() {
  static const std::map<std::string, SceneFacts> facts{{"tsukuba", {15, 16, false}}, {"venus", {19, 8, false}},
                                                       {"teddy", {59, 4, false}},    {"cones", {59, 4, false}},
                                                       {"art", {79, 3, true}},       {"dolls", {79, 3, true}}};
  return facts;
}

}  // namespace

std::string middleburyRoot(const std::string& shared_data) {
  return dataFolder("MASSAGE_CELL_MIDDLEBURY", shared_data, "middlebury2003");
}

std::string middlebury2005Root(const std::string& shared_data) {
  return dataFolder("MASSAGE_CELL_MIDDLEBURY2005", shared_data, "middlebury2005");
}

const std::vector<std::string>& middleburyScenes() {
  static const std::vector<std::string> scenes{"tsukuba", "venus", "teddy", "cones"};
  return scenes;
}

const std::vector<std::string>& middlebury2005Scenes() {
  static const std::vector<std::string> scenes{"art", "dolls"};
  return scenes;
}

bool isMiddlebury2005Scene(const std::string& name) {
  const auto fact = sceneFacts().find(name);
  return fact != sceneFacts().end() && fact->second.year2005;
}

MiddleburyScene loadMiddleburyScene(const std::string& root, const std::string& name) {
  const auto fact = sceneFacts().find(name);
  if (fact == sceneFacts().end()) {
    throw std::runtime_error("unknown Middlebury scene '" + name + "' (tsukuba, venus, teddy, cones, art, dolls)");
  }
  const std::filesystem::path dir = std::filesystem::path(root) / name;
  if (!std::filesystem::is_directory(dir))
    throw std::runtime_error("missing Middlebury scene folder '" + dir.string() + "'");
  MiddleburyScene scene;
  scene.name = name;
  scene.dmax = fact->second.dmax;
  scene.scale = fact->second.scale;
  scene.left = readImage(dir / "left.png", cv::IMREAD_COLOR);
  scene.right = readImage(dir / "right.png", cv::IMREAD_COLOR);
  readImage(dir / "gt_disp_left.png", cv::IMREAD_GRAYSCALE).convertTo(scene.ground_truth, CV_32F, 1.0 / scene.scale);
  if (fact->second.year2005) {
    derive2005Masks(scene);
  } else {
    scene.nonocc = readImage(dir / "nonocc.png", cv::IMREAD_GRAYSCALE);
    scene.all = readImage(dir / "all.png", cv::IMREAD_GRAYSCALE);
    scene.disc = readImage(dir / "disc.png", cv::IMREAD_GRAYSCALE);
  }
  return scene;
}

double badPixelPercent(const cv::Mat& disparity, const cv::Mat& ground_truth, const cv::Mat& mask, double threshold) {
  CV_Assert(disparity.size() == ground_truth.size() && mask.size() == disparity.size());
  long evaluated = 0, bad = 0;
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    const float* g = ground_truth.ptr<float>(y);
    const unsigned char* m = mask.ptr<unsigned char>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (m[x] != 255 || !(g[x] > 0.0f)) continue;
      ++evaluated;
      if (!std::isfinite(d[x]) || std::abs(d[x] - g[x]) > threshold) ++bad;
    }
  }
  return evaluated > 0 ? 100.0 * bad / evaluated : 0.0;
}

cv::Mat colourise(const cv::Mat& disparity, double dmin, double dmax) {
  cv::Mat valid = disparity == disparity, scaled, out;
  const double range = std::max(1e-6, dmax - dmin);
  disparity.convertTo(scaled, CV_8U, 255.0 / range, -dmin * 255.0 / range);
  cv::applyColorMap(scaled, out, cv::COLORMAP_TURBO);
  out.setTo(cv::Scalar(0, 0, 0), ~valid);
  return out;
}

}  // namespace massage_cell::stereo
