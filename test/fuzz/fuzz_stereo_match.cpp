// Fuzz target: stereo::match — every method and refinement on small pairs of
// any content (the input's bytes, or a textured pattern shifted by a known
// disparity), sizes, types and parameters, some of them invalid (NaN, Inf,
// negative, even windows, disparity ranges outside the image). match() must
// either throw std::invalid_argument naming the problem or return a CV_32F
// disparity map of the pair's size whose values are NaN or within the range
// searched; any other exception (OpenCV's own included) is a finding.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <map>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "fuzz_input.h"
#include "massage_cell/stereo/pipeline.h"

using namespace massage_cell;

namespace {

// With FUZZ_STATS set: how many inputs got a disparity map, and the refusals by reason.
struct Stats {
  long matched = 0;
  std::map<std::string, long> refused;
  ~Stats() {
    if (!std::getenv("FUZZ_STATS")) return;
    std::cerr << "matched " << matched << "\n";
    for (const auto& [why, n] : refused) std::cerr << n << "  " << why << "\n";
  }
} stats;

[[noreturn]] void broken(const std::string& what) {
  std::cerr << "fuzz_stereo_match: " << what << "\n";
  std::abort();
}

cv::Mat image(fuzz::FuzzInput& in, cv::Size size, int type) {
  cv::Mat m(size, type);
  const std::uint8_t fill = in.byte();
  if (fill % 4 == 0) {
    m.setTo(cv::Scalar::all(in.byte()));  // texture-less
  } else {
    CV_Assert(m.isContinuous());
    for (std::size_t i = 0; i < m.total() * m.elemSize(); ++i) m.data[i] = in.byte();  // every channel
  }
  return m;
}

// A random texture and the same shifted left by `d` pixels: a pair with a known answer.
void shiftedPair(fuzz::FuzzInput& in, cv::Size size, int type, int d, cv::Mat& left, cv::Mat& right) {
  cv::Mat wide(size.height, size.width + d, type);
  cv::RNG rng(in.bits<std::uint32_t>());
  rng.fill(wide, cv::RNG::UNIFORM, 0, 256);
  left = wide.colRange(d, d + size.width).clone();
  right = wide.colRange(0, size.width).clone();
}

int odd(fuzz::FuzzInput& in, int max) { return 1 + 2 * static_cast<int>(in.range(0, (max - 1) / 2)); }

// Parameters within their documented ranges...
stereo::StereoParams validParams(fuzz::FuzzInput& in, cv::Size size) {
  stereo::StereoParams p;
  p.cost.dmin = static_cast<int>(in.range(0, 2));
  p.cost.dmax = static_cast<int>(in.range(p.cost.dmin, std::max(p.cost.dmin, std::min(size.width - 1, 16))));
  p.cost.eta = static_cast<float>(in.real(1, 100));
  p.cost.ncc_window = odd(in, std::min({size.width, size.height, 7}));
  p.cost.gradient_saturation = static_cast<float>(in.real(0, 50));
  p.smooth.tau = static_cast<float>(in.real(1, 60));
  p.smooth.u_min = static_cast<float>(in.real(0, 0.05));
  p.smooth.u_max = p.smooth.u_min + static_cast<float>(in.real(0, 0.15));
  p.smooth.truncation = static_cast<float>(in.real(0, 5));
  p.max_cycles = static_cast<int>(in.range(0, 2));
  p.hbds_overlap = static_cast<int>(in.range(0, 2));
  p.polish_window = static_cast<int>(in.range(0, 2));
  p.polish_cycles = static_cast<int>(in.range(1, 2));
  p.refine = static_cast<stereo::Refinement>(in.range(0, 8));
  p.filter_params.radius = static_cast<int>(in.range(1, 5));
  p.filter_params.sigma_colour = static_cast<float>(in.real(1, 40));
  p.filter_params.sigma_space = static_cast<float>(in.real(1, 10));
  p.filter_params.truncation = static_cast<float>(in.real(0.5, 4));
  auto& r = p.refine_params;
  r.superpixels = static_cast<stereo::Superpixels>(in.range(0, 2));
  r.region_size = static_cast<int>(in.range(4, 16));
  r.ruler = static_cast<float>(in.real(1, 40));
  r.slic_iterations = static_cast<int>(in.range(1, 4));
  r.canny_low = static_cast<float>(in.real(0.5, 5));
  r.canny_high = r.canny_low + static_cast<float>(in.real(0, 3));
  r.edge_tolerance = static_cast<float>(in.real(0, 4));
  r.boundary_contrast = static_cast<float>(in.real(0, 20));
  r.max_fattening_contrast = static_cast<float>(in.real(0, 20));
  r.min_edge_pixels = static_cast<int>(in.range(1, 20));
  r.min_jump = static_cast<float>(in.real(0.5, 5));
  r.min_class_fraction = static_cast<float>(in.real(0, 0.49));
  r.window = odd(in, 9);
  r.gamma_c = static_cast<float>(in.real(1, 20));
  r.gamma_g = static_cast<float>(in.real(1, 20));
  p.threads = static_cast<int>(in.range(0, 2));
  p.subpixel = in.flag();
  p.subpixel_params.fit = in.flag() ? stereo::SubpixelFit::kParabola : stereo::SubpixelFit::kEquiangular;
  p.subpixel_params.window = odd(in, 9);
  p.subpixel_params.max_offset = static_cast<float>(in.real(0.01, 0.5));
  p.lr_check = in.flag();
  p.lr_tolerance = static_cast<float>(in.real(0, 2));
  p.cost.data_term = static_cast<stereo::DataTerm>(in.range(0, 2));
  p.cost.census_width = 3 + 2 * static_cast<int>(in.range(0, 3));
  p.cost.census_height = 3 + 2 * static_cast<int>(in.range(0, 2));
  p.cost.census_lambda = static_cast<float>(in.real(1, 60));
  p.cost.ad_lambda = static_cast<float>(in.real(1, 60));
  p.hbds_coarse = static_cast<int>(in.range(1, 4));
  p.polish_coarse = static_cast<int>(in.range(0, 3));
  return p;
}

// ... and one in eight with one of them broken: NaN, Inf, zero, negative, even, too wide.
void breakOne(fuzz::FuzzInput& in, stereo::StereoParams& p, cv::Size size) {
  const double v = in.real(-3, 3, true);
  const auto i = static_cast<int>(std::lround(std::isfinite(v) ? v : -1));
  auto& r = p.refine_params;
  switch (in.range(0, 31)) {
    case 0:
      p.cost.dmin = i;
      break;
    case 1:
      p.cost.dmax = p.cost.dmin + i;
      break;
    case 2:
      p.cost.dmax = size.width + i;
      break;
    case 3:
      p.cost.eta = static_cast<float>(v);
      break;
    case 4:
      p.cost.ncc_window = i + 1;
      break;
    case 5:
      p.cost.gradient_saturation = static_cast<float>(v);
      break;
    case 6:
      p.smooth.tau = static_cast<float>(v);
      break;
    case 7:
      p.smooth.u_min = static_cast<float>(v);
      break;
    case 8:
      p.smooth.u_max = static_cast<float>(v);
      break;
    case 9:
      p.smooth.truncation = static_cast<float>(v);
      break;
    case 10:
      p.max_cycles = i;
      break;
    case 11:
      p.hbds_overlap = i;
      break;
    case 12:
      p.polish_window = i;
      break;
    case 13:
      p.polish_cycles = i;
      break;
    case 14:
      r.region_size = i + 2;
      break;
    case 15:
      r.ruler = static_cast<float>(v);
      break;
    case 16:
      r.slic_iterations = i;
      break;
    case 17:
      r.canny_low = static_cast<float>(v);
      break;
    case 18:
      r.canny_high = static_cast<float>(v);
      break;
    case 19:
      r.min_class_fraction = static_cast<float>(v);
      break;
    case 20:
      r.window = i + 1;
      break;
    case 21:
      r.gamma_c = static_cast<float>(v);
      break;
    case 22:
      r.gamma_g = static_cast<float>(v);
      break;
    case 23:
      p.subpixel = true;
      p.subpixel_params.window = i + 1;
      break;
    case 24:
      p.subpixel = true;
      p.subpixel_params.max_offset = static_cast<float>(v);
      break;
    case 25:
      p.cost.data_term = stereo::DataTerm::kCensus;
      p.cost.census_width = i + 8;  // even, or over 64 bits
      break;
    case 26:
      p.cost.data_term = stereo::DataTerm::kAdCensus;
      p.cost.census_lambda = static_cast<float>(v);
      break;
    case 27:
      p.cost.data_term = stereo::DataTerm::kAdCensus;
      p.cost.ad_lambda = static_cast<float>(v);
      break;
    case 28:
      p.refine = stereo::Refinement::kBf3d;
      p.filter_params.radius = i;
      break;
    case 29:
      p.refine = stereo::Refinement::kFfdWmf;
      p.filter_params.sigma_colour = static_cast<float>(v);
      break;
    case 30:
      p.hbds_coarse = 4 * i;  // 0, negative or over 8 (or 4 / 8: valid)
      break;
    default:
      p.lr_check = true;
      p.lr_tolerance = static_cast<float>(v);
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::FuzzInput in(data, size);
  const cv::Size sz(static_cast<int>(in.range(1, 40)), static_cast<int>(in.range(1, 24)));
  const int type = in.flag() ? CV_8UC3 : CV_8UC1;
  const auto method = static_cast<stereo::Method>(in.range(0, 4));
  const std::uint8_t shape = in.byte();
  cv::Mat left, right;
  if (shape % 3 == 0) {
    shiftedPair(in, sz, type, static_cast<int>(in.range(0, 8)), left, right);
  } else {
    left = image(in, sz, type);
    right = image(in, sz, type);
  }
  if (shape % 17 == 1) right = right.colRange(0, std::max(0, right.cols - 1)).clone();  // sizes differ
  if (shape % 19 == 2) right.convertTo(right, CV_16U);                                  // a type it does not take
  if (shape % 23 == 3) left = cv::Mat();                                                // empty
  stereo::StereoParams p = validParams(in, sz);
  if (in.byte() % 8 == 7) breakOne(in, p, sz);  // (an exhausted input reads 0: valid)
  if (std::getenv("FUZZ_VERBOSE")) {
    std::cerr << "pair " << left.cols << "x" << left.rows << " type " << left.type() << " / " << right.cols << "x"
              << right.rows << " type " << right.type() << ", method " << stereo::toString(method) << ", d "
              << p.cost.dmin << ".." << p.cost.dmax << ", " << stereo::toString(p.cost.data_term) << " census "
              << p.cost.census_width << "x" << p.cost.census_height << ", ncc " << p.cost.ncc_window << ", refine "
              << stereo::toString(p.refine) << ", superpixels " << static_cast<int>(p.refine_params.superpixels)
              << ", region " << p.refine_params.region_size << ", ruler " << p.refine_params.ruler << ", iterations "
              << p.refine_params.slic_iterations << ", window " << p.refine_params.window << ", subpixel " << p.subpixel
              << " " << stereo::toString(p.subpixel_params.fit) << " window " << p.subpixel_params.window
              << " max_offset " << p.subpixel_params.max_offset << ", lr_check " << p.lr_check << " tolerance "
              << p.lr_tolerance << "\n";
  }
  stereo::MatchResult result;
  try {
    result = stereo::match(left, right, method, p);
  } catch (const std::invalid_argument& e) {
    if (std::string(e.what()).empty()) broken("std::invalid_argument without a message");
    ++stats.refused[std::string(e.what()).substr(0, 60)];
    return 0;
  } catch (const cv::Exception& e) {
    broken(std::string("OpenCV's exception escaped (the input was not checked): ") + e.what());
  } catch (const std::exception& e) {
    broken(std::string("an exception other than std::invalid_argument: ") + e.what());
  }
  ++stats.matched;
  const cv::Mat& d = result.disparity;
  if (d.type() != CV_32FC1 || d.size() != left.size())
    broken("the disparity map's size or type differs from the pair's");
  const int lo = p.cost.dmin, hi = p.cost.dmax;
  for (auto it = d.begin<float>(); it != d.end<float>(); ++it) {
    if (!std::isnan(*it) && !(*it >= lo - 1e-3f && *it <= hi + 1e-3f))
      broken("disparity " + std::to_string(*it) + " outside the range searched [" + std::to_string(lo) + ", " +
             std::to_string(hi) + "] with method " + stereo::toString(method));
  }
  return 0;
}
