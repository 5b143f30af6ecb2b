#include "massage_cell/stereo/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <limits>
#include <map>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
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
      return refineDisparity(left, disparity, rp, fattening, params.threads);
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
  require(p.smooth.tau > 0.0f && std::isfinite(p.smooth.tau), "tau", "must be > 0");
  require(p.smooth.u_min >= 0.0f && std::isfinite(p.smooth.u_min), "u_min", "must be >= 0");
  require(p.smooth.u_max >= p.smooth.u_min && std::isfinite(p.smooth.u_max), "u_max", "must be >= u_min");
  require(p.smooth.truncation >= 0.0f, "truncation", "must be >= 0");
  require(p.max_cycles >= 1, "max_cycles", "must be >= 1");
  require(p.hbds_overlap >= 0, "overlap", "must be >= 0");
  require(p.hbds_coarse >= 1 && p.hbds_coarse <= 8, "coarse", "must be in 1..8");
  require(p.polish_window >= 0, "polish_window", "must be >= 0");
  require(p.polish_cycles >= 1, "polish_cycles", "must be >= 1");
  require(p.polish_coarse >= 0 && p.polish_coarse <= 8, "polish_coarse", "must be in 0..8");
  nested("refine_window", [&] { validate(p.refine_params); });
  nested("filter", [&] { validate(p.filter_params); });
  nested("subpixel_window", [&] { validate(p.subpixel_params); });
  require(p.lr_tolerance >= 0.0f && std::isfinite(p.lr_tolerance), "lr_tolerance", "must be >= 0");
  require(p.threads >= 0, "threads", "must be >= 0");
  return problems;
}

namespace {

/// One view: the method, its refinement and the sub-pixel step.
MatchResult matchLeftView(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params) {
  MatchResult result;
  if (params.subpixel) validate(params.subpixel_params);  // before minutes of matching, not after
  auto start = Clock::now();
  const CostVolume volume = computeCostVolume(left, right, params.cost, params.threads);  // validates the input
  result.cost_ms = msSince(start);
  const PairwiseWeights weights = pairwiseWeights(left, params.smooth);
  start = Clock::now();
  switch (method) {
    case Method::kHbds: {
      OptimizerResult r = hbds(volume, weights, params.smooth, params.threads, params.hbds_overlap, params.hbds_coarse);
      if (params.polish_window > 0) {
        const int hbds_cuts = r.cuts;
        // polish_coarse >= 2: the cycle on blocks, then one full-resolution fusion (coarsePolish).
        r = params.polish_coarse >= 2 ? coarsePolish(volume, weights, params.smooth, r.disparity, params.polish_coarse,
                                                     params.polish_window, params.polish_cycles)
                                      : localExpansion(volume, weights, params.smooth, r.disparity,
                                                       params.polish_window, params.polish_cycles);
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

/// The worker threads `threads` of StereoParams stands for (0: every core).
int resolveThreads(int threads) { return threads > 0 ? threads : std::max(1, cv::getNumberOfCPUs()); }

/// The right view's disparity map: the same method on the mirrored pair (rightViewDisparity()).
cv::Mat matchRightView(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params) {
  return rightViewDisparity(
      left, right, [&](const cv::Mat& a, const cv::Mat& b) { return matchLeftView(a, b, method, params).disparity; });
}

}  // namespace

MatchResult match(const cv::Mat& left, const cv::Mat& right, Method method, const StereoParams& params) {
  if (params.lr_check && !(params.lr_tolerance >= 0.0f && std::isfinite(params.lr_tolerance))) {
    throw std::invalid_argument("lr_tolerance must be finite and >= 0, got " + std::to_string(params.lr_tolerance));
  }
  if (!params.lr_check) return matchLeftView(left, right, method, params);

  // The views are independent. With two threads or more the right one runs on a thread of its own while this thread
  // matches the left one, the threads shared between them (no view's result depends on its thread count); with one,
  // it runs after the left one, on get(). An exception of the left view leaves once the right view has finished
  // (the future's destructor waits for it), one of the right view's from get().
  const int threads = resolveThreads(params.threads);
  StereoParams left_params = params, right_params = params;
  right_params.threads = std::max(1, threads / 2);
  left_params.threads = std::max(1, threads - threads / 2);
  std::future<cv::Mat> right_view = std::async(threads >= 2 ? std::launch::async : std::launch::deferred,
                                               [&] { return matchRightView(left, right, method, right_params); });
  MatchResult result = matchLeftView(left, right, method, left_params);
  const auto start = Clock::now();  // lr_ms: the wall time the check adds to the left view's
  result.consistent = leftRightCheck(result.disparity, right_view.get(), params.lr_tolerance);
  result.disparity = fillFromBackground(result.disparity, result.consistent);
  result.lr_ms = msSince(start);
  return result;
}

}  // namespace massage_cell::stereo
