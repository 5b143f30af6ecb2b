// HBDS matching cost (thesis Eq. 2.6-2.8), winner-takes-all and the break
// point (Eq. 2.9-2.10). ROS-free (OpenCV only).
//
// Conventions: left is the reference view; pixel (x, y) of the left image
// with disparity d matches (x - d, y) of the right image (Middlebury).
#pragma once

#include <climits>
#include <cstddef>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

/// The data term S(x, y, d): the thesis's Eq. 2.6-2.8 (default); the census
/// transform's Hamming distance (Zabih & Woodfill), robust to gain and offset
/// differences between the cameras; or AD-census (Mei et al. 2011), the
/// census and the absolute colour difference each through 1 - exp(-c / lambda).
enum class DataTerm { kThesis, kCensus, kAdCensus };
DataTerm parseDataTerm(const std::string& name);  ///< "thesis" | "census" | "ad-census"
std::string toString(DataTerm term);

struct CostParams {
  int dmin = 0;        ///< smallest disparity searched (pixels)
  int dmax = 15;       ///< largest disparity searched, inclusive
  float eta = 20.0f;   ///< colour-cost truncation eta of Eq. 2.7, grey levels (0..255)
  int ncc_window = 5;  ///< odd side of the NCC window W of Eq. 2.8
  /// How the texture weight w of Eq. 2.6 is normalised: 0 divides the Sobel
  /// magnitude by its image maximum (the thesis's literal reading); > 0 divides
  /// by this magnitude and clamps at 1 (w = 1 from this much gradient on).
  float gradient_saturation = 20.0f;
  DataTerm data_term = DataTerm::kThesis;
  int census_width = 9;  ///< census window, odd sides, width x height - 1 <= 64 bits
  int census_height = 7;
  float census_lambda = 30.0f;  ///< ad-census: the census distance (bits) where its term reaches 1 - 1/e
  float ad_lambda = 10.0f;      ///< ad-census: the mean channel difference (grey levels) likewise
};

/// S(x, y, d) in [0, 1] for d in [dmin, dmax], stored disparity-major: the
/// slice of one disparity is a contiguous H x W float image. Memory:
/// W * H * (dmax - dmin + 1) * 4 bytes (450 x 375 x 60: 40.5 MB).
class CostVolume {
 public:
  /// Tag of the constructor that leaves the values unset (the caller writes
  /// every one): the pages are then first touched by the parallel workers
  /// that compute them, not by a single-threaded fill.
  struct Uninitialised {};

  CostVolume() = default;
  CostVolume(int width, int height, int dmin, int dmax, float fill = 1.0f)
      : width_(width), height_(height), dmin_(dmin), dmax_(dmax), data_(checkedSize(width, height, dmin, dmax), fill) {}
  CostVolume(int width, int height, int dmin, int dmax, Uninitialised)
      : width_(width), height_(height), dmin_(dmin), dmax_(dmax), data_(checkedSize(width, height, dmin, dmax)) {}
  int width() const { return width_; }
  int height() const { return height_; }
  int dmin() const { return dmin_; }
  int dmax() const { return dmax_; }
  int levels() const { return dmax_ - dmin_ + 1; }
  std::size_t bytes() const { return data_.size() * sizeof(float); }
  float* slice(int d) { return data_.data() + static_cast<std::size_t>(d - dmin_) * width_ * height_; }
  const float* slice(int d) const { return data_.data() + static_cast<std::size_t>(d - dmin_) * width_ * height_; }
  float& operator()(int x, int y, int d) { return slice(d)[static_cast<std::size_t>(y) * width_ + x]; }
  float operator()(int x, int y, int d) const { return slice(d)[static_cast<std::size_t>(y) * width_ + x]; }

 private:
  /// std::allocator that default-initialises (leaves floats unset) when no value is given.
  template <typename T>
  struct DefaultInitAllocator : std::allocator<T> {
    template <typename U>
    struct rebind {
      using other = DefaultInitAllocator<U>;
    };
    DefaultInitAllocator() = default;
    template <typename U>
    DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
    template <typename U>
    void construct(U* p) noexcept {
      ::new (static_cast<void*>(p)) U;
    }
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) {
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
  };
  static std::size_t checkedSize(int width, int height, int dmin, int dmax) {
    if (width <= 0 || height <= 0 || dmax < dmin) throw std::invalid_argument("CostVolume: empty size or dmax < dmin");
    return static_cast<std::size_t>(width) * height * (dmax - dmin + 1);
  }

  int width_ = 0, height_ = 0, dmin_ = 0, dmax_ = -1;
  std::vector<float, DefaultInitAllocator<float>> data_;
};

/// The matching cost S = w T + (1 - w) C of Eq. 2.6: C the truncated,
/// normalised, sampling-insensitive (Birchfield-Tomasi, linearly
/// interpolated, both directions) colour cost of Eq. 2.7; T = (1 - NCC) / 2
/// over the window W (Eq. 2.8, box filters); w the normalised Sobel gradient
/// magnitude of the left image. Where x - d falls outside the right image the
/// cost is 1. With params.data_term census or ad-census, computeCensusCostVolume
/// instead. Inputs: CV_8UC3 (BGR) or CV_8UC1, same size. Throws
/// std::invalid_argument naming the problem (empty, sizes or types differ,
/// unsupported type, dmax < dmin, range wider than the image, bad window).
/// `threads`: worker threads over the disparities, 0 = all cores (the result does not depend on it).
CostVolume computeCostVolume(const cv::Mat& left, const cv::Mat& right, const CostParams& params, int threads = 0);

/// The checks computeCostVolume makes before it starts (the images, the
/// range, the thesis term's window and eta); throws std::invalid_argument
/// naming the problem.
void validateCostInputs(const cv::Mat& left, const cv::Mat& right, const CostParams& params);

/// S for DataTerm::kCensus (Hamming distance / window bits) or kAdCensus
/// ((rho(census, census_lambda) + rho(|I_L - I_R|, ad_lambda)) / 2 with
/// rho(c, l) = 1 - exp(-c / l)); in [0, 1], 1 where x - d is outside the
/// right image. Called by computeCostVolume; throws as it does, and for a
/// census window that is even, under 3 or over 64 bits, or lambdas <= 0.
CostVolume computeCensusCostVolume(const cv::Mat& left, const cv::Mat& right, const CostParams& params,
                                   int threads = 0);

/// The texture weight w of Eq. 2.6: Sobel gradient magnitude of the left
/// image (grey), divided by its maximum (gradient_saturation 0) or by
/// gradient_saturation and clamped at 1; CV_32F in [0, 1].
cv::Mat textureWeight(const cv::Mat& left, float gradient_saturation = 0.0f);

/// Winner-takes-all: for each pixel the d in [lo, hi] (default: the whole
/// volume) of least cost; ties go to the smaller d. CV_32F.
cv::Mat winnerTakesAll(const CostVolume& volume, int lo = INT_MIN, int hi = INT_MAX);

/// Histogram of the integer disparities of `disparity` (CV_32F) in [lo, hi]
/// (index d - lo), over the pixels where `mask` (CV_8U, optional) is non-zero.
std::vector<double> disparityHistogram(const cv::Mat& disparity, int lo, int hi, const cv::Mat& mask = cv::Mat());

/// The break point psi of Eq. 2.10 for a histogram over disparities
/// lo..hi (histogram.size() == hi - lo + 1, hi > lo): Otsu's threshold (Eq.
/// 2.9) gives the two class means; psi is the least-populated level between
/// them (ties: the one nearest the middle). The set splits into B = [lo, psi]
/// and F = [psi + 1, hi], so lo <= psi < hi always. Defined cases: an empty
/// histogram splits in the middle; a one-level-occupied or unimodal histogram
/// still yields lo <= psi < hi. Throws std::invalid_argument if hi <= lo or
/// the size does not match.
int breakPoint(const std::vector<double>& histogram, int lo, int hi);

}  // namespace massage_cell::stereo
