// HBDS matching cost (thesis Eq. 2.6-2.8), winner-takes-all, disparity
// histogram and break point (Eq. 2.9-2.10).
//
// Implementation notes (choices the thesis leaves open):
//
// * Colour term C (Eq. 2.7). The thesis writes C_f as the minimum over
//   t in [d - 1/2, d + 1/2] of the channel-averaged absolute difference to the
//   linearly interpolated right image (and C_r symmetrically with the roles of
//   the images swapped). We use the standard Birchfield-Tomasi closed form PER
//   CHANNEL: for each channel the minimum over t of |I_L(x) - I'_R(x - t)| is
//   max(0, I_L - Imax_R, Imin_R - I_L) with Imin/Imax the min/max of
//   I_R(x-d) and the two half-pixel interpolants (I_R(x-d) + I_R(x-d-+1)) / 2;
//   C_f is the average of the three per-channel values (C_r likewise). The
//   per-channel minimum is a lower bound of the thesis' minimum of the summed
//   difference (sum of minima <= minimum of the sum); both are identical for
//   grey images and whenever the channels reach their minimum at the same t
//   (e.g. a pure sub-pixel shift). It is the formulation used in practice
//   (Birchfield & Tomasi; OpenCV's SGBM), is branch-free and vectorises, while
//   the exact joint minimum needs the kinks of a 3-term piecewise-linear
//   function per voxel (several times slower) for no measurable gain.
//   Interpolants at the image border replicate the edge pixel (no
//   extrapolation). C = min(C_f, C_r, eta) / eta in [0, 1].
// * Texture term T (Eq. 2.8) on the grey images (cv::COLOR_BGR2GRAY, 8-bit),
//   T = (1 - NCC) / 2, NCC over the n x n window with n = ncc_window. The window
//   of the left pixel (x, y) pairs L(x+i, y+j) with R(x-d+i, y+j); pixels
//   outside an image are replicated from its edge (BORDER_REPLICATE, applied
//   to each image independently), so the statistics of a window never depend
//   on d except through the cross term. Sums are exact integers (float while
//   they stay below 2^24, i.e. n <= 15, double otherwise) and
//   NCC = (N sum(LR) - sum(L) sum(R)) / sqrt(N sum(L^2) - sum(L)^2) / sqrt(...)
//   is formed in double, so there is no cancellation error. A flat window
//   (zero variance on either side, detected exactly) has NCC := 0, T = 0.5
//   (no texture evidence either way). NCC is clamped to [-1, 1].
// * w = |Sobel| / max|Sobel| on the grey left image (3 x 3 Sobel x and y,
//   Euclidean magnitude, cv::BORDER_REFLECT_101); an all-zero gradient gives
//   w = 0.
// * S = w T + (1 - w) C; where x - d < 0, S = 1.
// * Multithreading: cv::parallel_for_ over the disparities. threads > 0
//   limits the number of stripes (hence of concurrently running workers) to
//   `threads` without touching OpenCV's global thread setting; 0 (or a negative
//   value) uses OpenCV's default. The hot row loops use OpenCV's universal
//   intrinsics (SSE2 baseline), because GCC's -O2 "very cheap" vectoriser
//   model does not vectorise them (they need alias versioning / epilogues).
// * Note on timing: the CostVolume constructor value-initialises its whole
//   buffer (40.5 MB for 450 x 375 x 60) single-threaded; on hosts with costly
//   page faults that first touch can dominate the run time (mitigations:
//   GLIBC_TUNABLES=glibc.malloc.hugetlb=1 for transparent huge pages, or an
//   in-place overload that reuses a volume's storage between frames).
// * breakPoint: Otsu maximises the between-class variance (equivalent to
//   minimising Eq. 2.9), first maximum on ties; psi = least-populated level in
//   [ceil(mu_B), floor(mu_F)] (ties: nearest (mu_B + mu_F) / 2, then smaller),
//   clamped to [lo, hi - 1]. Empty histogram: floor((lo + hi) / 2). Exactly one
//   occupied level k: k stays whole on the side with more remaining range
//   (psi = k if k - lo >= hi - k, else psi = k - 1; clamped, so k = lo gives
//   psi = lo and k = hi gives psi = hi - 1). Negative / non-finite counts throw.
// * disparityHistogram: rounds half away from zero (std::round), ignores
//   non-finite values and values outside [lo, hi].
#include "massage_cell/stereo/cost_volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>

#include <sys/mman.h>

#include <cstdint>

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::stereo {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("computeCostVolume: " + what); }

}  // namespace

void validateCostInputs(const cv::Mat& left, const cv::Mat& right, const CostParams& p) {
  if (left.empty() || right.empty()) fail(std::string(left.empty() ? "left" : "right") + " image is empty");
  if (left.size() != right.size()) {
    std::ostringstream s;
    s << "image sizes differ (left " << left.cols << "x" << left.rows << ", right " << right.cols << "x" << right.rows
      << ")";
    fail(s.str());
  }
  if (left.type() != right.type()) fail("image types differ");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3) fail("unsupported image type (need CV_8UC1 or CV_8UC3)");
  if (p.dmin < 0) fail("dmin < 0 (dmin = " + std::to_string(p.dmin) + ")");
  if (p.dmax < p.dmin)
    fail("dmax < dmin (dmin = " + std::to_string(p.dmin) + ", dmax = " + std::to_string(p.dmax) + ")");
  if (p.dmax >= left.cols)
    fail("disparity range wider than the image (dmax = " + std::to_string(p.dmax) +
         ", width = " + std::to_string(left.cols) + ")");
  const int n = p.ncc_window;
  if (n < 1 || n % 2 == 0 || n > std::min(left.cols, left.rows))
    fail("ncc_window must be odd, >= 1 and <= min(width, height) (got " + std::to_string(n) + ")");
  if (!(p.eta > 0.0f) || !std::isfinite(p.eta)) fail("eta must be a positive finite number");
}

namespace {

cv::Mat toGrey(const cv::Mat& img) {
  if (img.channels() == 1) return img;
  cv::Mat g;
  cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
  return g;
}

/// Per-channel planes for the Birchfield-Tomasi cost of one image: the value
/// and the min / max over the value and its two half-pixel interpolants.
struct BtPlanes {
  std::vector<float> val, lo, hi;  // [c][y][x], H x W per channel
};

BtPlanes btPlanes(const cv::Mat& img) {
  const int W = img.cols, H = img.rows, ch = img.channels();
  const std::size_t plane = static_cast<std::size_t>(W) * H;
  BtPlanes b;
  b.val.resize(plane * ch);
  b.lo.resize(plane * ch);
  b.hi.resize(plane * ch);
  for (int y = 0; y < H; ++y) {
    const uchar* row = img.ptr<uchar>(y);
    for (int c = 0; c < ch; ++c) {
      float* v = b.val.data() + c * plane + static_cast<std::size_t>(y) * W;
      float* lo = b.lo.data() + c * plane + static_cast<std::size_t>(y) * W;
      float* hi = b.hi.data() + c * plane + static_cast<std::size_t>(y) * W;
      for (int x = 0; x < W; ++x) v[x] = row[x * ch + c];
      for (int x = 0; x < W; ++x) {
        const float cur = v[x];
        const float minus = 0.5f * (cur + v[std::max(x - 1, 0)]);
        const float plus = 0.5f * (cur + v[std::min(x + 1, W - 1)]);
        lo[x] = std::min(cur, std::min(minus, plus));
        hi[x] = std::max(cur, std::max(minus, plus));
      }
    }
  }
  return b;
}

/// Window statistics of one grey image over the n x n windows (replicated
/// border): sum (exact, double), and 1 / sqrt(N sum(I^2) - sum(I)^2) (0 for a
/// flat window).
struct WindowStats {
  std::vector<double> sum;
  std::vector<float> inv_sd;
};

WindowStats windowStats(const cv::Mat& padded_u8, int W, int H, int n) {
  cv::Mat s, sq;
  cv::integral(padded_u8, s, sq, CV_64F, CV_64F);
  const double N = static_cast<double>(n) * n;
  WindowStats ws;
  ws.sum.resize(static_cast<std::size_t>(W) * H);
  ws.inv_sd.resize(static_cast<std::size_t>(W) * H);
  for (int y = 0; y < H; ++y) {
    const double* s0 = s.ptr<double>(y);
    const double* s1 = s.ptr<double>(y + n);
    const double* q0 = sq.ptr<double>(y);
    const double* q1 = sq.ptr<double>(y + n);
    for (int x = 0; x < W; ++x) {
      const double sum = s1[x + n] - s0[x + n] - s1[x] + s0[x];
      const double sum2 = q1[x + n] - q0[x + n] - q1[x] + q0[x];
      const double var_num = N * sum2 - sum * sum;  // exact integer
      ws.sum[static_cast<std::size_t>(y) * W + x] = sum;
      ws.inv_sd[static_cast<std::size_t>(y) * W + x] =
          var_num > 0.5 ? static_cast<float>(1.0 / std::sqrt(var_num)) : 0.0f;
    }
  }
  return ws;
}

struct Inputs {
  int W = 0, H = 0, ch = 1, n = 1, r = 0, Wp = 0;
  float inv_ch = 1.0f, eta = 1.0f, inv_eta = 1.0f;
  BtPlanes L, R;
  cv::Mat Lp, Rp;  // padded grey images, CV_32F, (H + 2r) x (W + 2r)
  WindowStats sL, sR;
  cv::Mat w;  // CV_32F
};

/// Row pointers of one output row of one disparity slice.
struct RowPtrs {
  const float* lv[3];
  const float* llo[3];
  const float* lhi[3];
  const float* rv[3];
  const float* rlo[3];
  const float* rhi[3];
  const double* sl;
  const double* sr;
  const float* il;
  const float* ir;
  const float* w;
  float* out;
};

/// Scalar reference of the per-voxel combination for i in [i0, len); also the
/// tail of the SIMD loop.
template <typename Acc>
void combineScalar(const Inputs& in, const RowPtrs& p, const Acc* box, int i0, int len) {
  const double N = static_cast<double>(in.n) * in.n;
  for (int i = i0; i < len; ++i) {
    float f = 0.0f, g = 0.0f;
    for (int c = 0; c < in.ch; ++c) {
      const float l = p.lv[c][i], r = p.rv[c][i];
      f += std::max(0.0f, std::max(l - p.rhi[c][i], p.rlo[c][i] - l));
      g += std::max(0.0f, std::max(r - p.lhi[c][i], p.llo[c][i] - r));
    }
    const float col_cost = std::min(std::min(f, g) * in.inv_ch, in.eta) * in.inv_eta;
    const float num = static_cast<float>(N * static_cast<double>(box[i]) - p.sl[i] * p.sr[i]);
    const float ncc = std::min(1.0f, std::max(-1.0f, num * p.il[i] * p.ir[i]));
    const float t = 0.5f - 0.5f * ncc;
    p.out[i] = col_cost + p.w[i] * (t - col_cost);
  }
}

/// SIMD version of combineScalar for CH channels (float accumulators);
/// returns the number of voxels done (a multiple of 4), the caller finishes.
template <int CH>
int combineSimd(const Inputs& in, const RowPtrs& p, const float* box, int len) {
  int i = 0;
#if CV_SIMD128 && CV_SIMD128_64F
  const cv::v_float32x4 z = cv::v_setzero_f32(), one = cv::v_setall_f32(1.0f), mone = cv::v_setall_f32(-1.0f),
                        half = cv::v_setall_f32(0.5f), vic = cv::v_setall_f32(in.inv_ch),
                        veta = cv::v_setall_f32(in.eta), vie = cv::v_setall_f32(in.inv_eta);
  const cv::v_float64x2 vN = cv::v_setall_f64(static_cast<double>(in.n) * in.n);
  const float *lv[CH], *llo[CH], *lhi[CH], *rv[CH], *rlo[CH], *rhi[CH];
  for (int c = 0; c < CH; ++c) {
    lv[c] = p.lv[c];
    llo[c] = p.llo[c];
    lhi[c] = p.lhi[c];
    rv[c] = p.rv[c];
    rlo[c] = p.rlo[c];
    rhi[c] = p.rhi[c];
  }
  const double *sl = p.sl, *sr = p.sr;
  const float *il = p.il, *ir = p.ir, *w = p.w;
  float* out = p.out;
  for (; i + 4 <= len; i += 4) {
    cv::v_float32x4 f = z, g = z;
    for (int c = 0; c < CH; ++c) {
      const cv::v_float32x4 l = cv::v_load(lv[c] + i), r = cv::v_load(rv[c] + i);
      f += cv::v_max(z, cv::v_max(l - cv::v_load(rhi[c] + i), cv::v_load(rlo[c] + i) - l));
      g += cv::v_max(z, cv::v_max(r - cv::v_load(lhi[c] + i), cv::v_load(llo[c] + i) - r));
    }
    const cv::v_float32x4 col_cost = cv::v_min(cv::v_min(f, g) * vic, veta) * vie;
    const cv::v_float32x4 b = cv::v_load(box + i);
    const cv::v_float64x2 n0 = vN * cv::v_cvt_f64(b) - cv::v_load(sl + i) * cv::v_load(sr + i);
    const cv::v_float64x2 n1 = vN * cv::v_cvt_f64_high(b) - cv::v_load(sl + i + 2) * cv::v_load(sr + i + 2);
    cv::v_float32x4 ncc = cv::v_cvt_f32(n0, n1) * cv::v_load(il + i) * cv::v_load(ir + i);
    ncc = cv::v_min(one, cv::v_max(mone, ncc));
    const cv::v_float32x4 t = half - half * ncc;
    cv::v_store(out + i, col_cost + cv::v_load(w + i) * (t - col_cost));
  }
#else
  (void)in;
  (void)p;
  (void)box;
  (void)len;
#endif
  return i;
}

/// Computes the slices of disparities [d0, d1). Acc = float while the window
/// sums of products are exact in float (n <= 15, SIMD path), double otherwise.
template <typename Acc>
void computeSlices(const Inputs& in, CostVolume& vol, int d0, int d1) {
  const int W = in.W, H = in.H, n = in.n, Wp = in.Wp;
  const std::size_t plane = static_cast<std::size_t>(W) * H;
  std::vector<Acc> col(Wp), box(W);
  constexpr bool kSimd = CV_SIMD128 && CV_SIMD128_64F && std::is_same<Acc, float>::value;

  for (int d = d0; d < d1; ++d) {
    float* out = vol.slice(d);
    const int x0 = d;  // first left column with a match
    const int len = W - x0;
    const int ulen = Wp - d;
    // Column sums over the padded rows [0, n) of L(u) * R(u - d), padded
    // columns u in [d, Wp) (stored at col[u - d]).
    std::fill(col.begin(), col.end(), Acc(0));
    for (int j = 0; j < n; ++j) {
      const float* lp = in.Lp.ptr<float>(j) + d;
      const float* rp = in.Rp.ptr<float>(j);
      Acc* c = col.data();
      for (int u = 0; u < ulen; ++u) c[u] += static_cast<Acc>(lp[u] * rp[u]);
    }
    for (int y = 0; y < H; ++y) {
      if (y > 0) {  // slide the vertical window: add padded row y + n - 1, drop y - 1
        const float* la = in.Lp.ptr<float>(y + n - 1) + d;
        const float* ra = in.Rp.ptr<float>(y + n - 1);
        const float* ls = in.Lp.ptr<float>(y - 1) + d;
        const float* rs = in.Rp.ptr<float>(y - 1);
        Acc* c = col.data();
        int u = 0;
#if CV_SIMD128
        if constexpr (kSimd) {
          for (; u + 4 <= ulen; u += 4) {
            const cv::v_float32x4 add = cv::v_load(la + u) * cv::v_load(ra + u);
            const cv::v_float32x4 sub = cv::v_load(ls + u) * cv::v_load(rs + u);
            cv::v_store(c + u, cv::v_load(c + u) + add - sub);  // exact integers
          }
        }
#endif
        for (; u < ulen; ++u) c[u] += static_cast<Acc>(la[u] * ra[u]) - static_cast<Acc>(ls[u] * rs[u]);
      }
      float* orow = out + static_cast<std::size_t>(y) * W;
      for (int x = 0; x < x0; ++x) orow[x] = 1.0f;
      if (len <= 0) continue;

      // Horizontal box sum: box[i] = sum of col[i .. i + n) (left column x0 + i).
      {
        Acc* b = box.data();
        const Acc* c = col.data();
        std::copy(c, c + len, b);
        for (int k = 1; k < n; ++k) {
          const Acc* ck = c + k;
          int i = 0;
#if CV_SIMD128
          if constexpr (kSimd)
            for (; i + 4 <= len; i += 4) cv::v_store(b + i, cv::v_load(b + i) + cv::v_load(ck + i));
#endif
          for (; i < len; ++i) b[i] += ck[i];
        }
      }

      RowPtrs p;
      const std::size_t ro = static_cast<std::size_t>(y) * W;
      for (int c = 0; c < in.ch; ++c) {
        const std::size_t co = c * plane + ro;
        p.lv[c] = in.L.val.data() + co + x0;
        p.llo[c] = in.L.lo.data() + co + x0;
        p.lhi[c] = in.L.hi.data() + co + x0;
        p.rv[c] = in.R.val.data() + co;
        p.rlo[c] = in.R.lo.data() + co;
        p.rhi[c] = in.R.hi.data() + co;
      }
      p.sl = in.sL.sum.data() + ro + x0;
      p.sr = in.sR.sum.data() + ro;
      p.il = in.sL.inv_sd.data() + ro + x0;
      p.ir = in.sR.inv_sd.data() + ro;
      p.w = in.w.ptr<float>(y) + x0;
      p.out = orow + x0;

      int i = 0;
      if constexpr (kSimd)
        i = in.ch == 3 ? combineSimd<3>(in, p, box.data(), len) : combineSimd<1>(in, p, box.data(), len);
      combineScalar(in, p, box.data(), i, len);
    }
  }
}

}  // namespace

/// Asks the kernel to back a large, not yet touched buffer with transparent
/// huge pages (2 MB): the first touch of a 40-80 MB cost volume then costs a
/// few dozen page faults instead of ~20 000. Only a hint; harmless if refused.
void adviseHugePages(void* data, std::size_t bytes) {
  constexpr std::uintptr_t kHuge = 2u << 20;
  const auto begin = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

cv::Mat textureWeight(const cv::Mat& left, float gradient_saturation) {
  if (left.empty()) throw std::invalid_argument("textureWeight: empty image");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3)
    throw std::invalid_argument("textureWeight: unsupported image type (need CV_8UC1 or CV_8UC3)");
  const cv::Mat grey = toGrey(left);
  cv::Mat gx, gy, mag;
  cv::Sobel(grey, gx, CV_32F, 1, 0, 3);
  cv::Sobel(grey, gy, CV_32F, 0, 1, 3);
  cv::magnitude(gx, gy, mag);
  if (gradient_saturation > 0.0f) {
    mag *= 1.0 / gradient_saturation;
    cv::min(mag, 1.0f, mag);
    return mag;
  }
  double mx = 0.0;
  cv::minMaxLoc(mag, nullptr, &mx);
  if (mx > 0.0)
    mag *= 1.0 / mx;
  else
    mag.setTo(0.0f);
  return mag;
}

CostVolume computeCostVolume(const cv::Mat& left, const cv::Mat& right, const CostParams& params, int threads) {
  if (params.data_term != DataTerm::kThesis) return computeCensusCostVolume(left, right, params, threads);
  validateCostInputs(left, right, params);
  Inputs in;
  in.W = left.cols;
  in.H = left.rows;
  in.ch = left.channels();
  in.inv_ch = 1.0f / static_cast<float>(in.ch);
  in.n = params.ncc_window;
  in.r = in.n / 2;
  in.Wp = in.W + 2 * in.r;
  in.eta = params.eta;
  in.inv_eta = 1.0f / params.eta;
  in.L = btPlanes(left);
  in.R = btPlanes(right);
  cv::Mat lp8, rp8;
  cv::copyMakeBorder(toGrey(left), lp8, in.r, in.r, in.r, in.r, cv::BORDER_REPLICATE);
  cv::copyMakeBorder(toGrey(right), rp8, in.r, in.r, in.r, in.r, cv::BORDER_REPLICATE);
  lp8.convertTo(in.Lp, CV_32F);
  rp8.convertTo(in.Rp, CV_32F);
  in.sL = windowStats(lp8, in.W, in.H, in.n);
  in.sR = windowStats(rp8, in.W, in.H, in.n);
  in.w = textureWeight(left, params.gradient_saturation);

  // computeSlices writes every element (1 where x - d is outside the right image).
  CostVolume vol(in.W, in.H, params.dmin, params.dmax, CostVolume::Uninitialised{});
  adviseHugePages(vol.slice(vol.dmin()), vol.bytes());
  const int levels = vol.levels();
  // Window sums of products (<= n^2 * 255^2) are exact in float below 2^24.
  const bool exact_float = static_cast<double>(in.n) * in.n * 255.0 * 255.0 < 16777216.0;
  const double stripes = threads > 0 ? std::min(threads, levels) : -1.0;
  cv::parallel_for_(
      cv::Range(0, levels),
      [&](const cv::Range& r) {
        const int d0 = params.dmin + r.start, d1 = params.dmin + r.end;
        if (exact_float)
          computeSlices<float>(in, vol, d0, d1);
        else
          computeSlices<double>(in, vol, d0, d1);
      },
      stripes);
  return vol;
}

cv::Mat winnerTakesAll(const CostVolume& volume, int lo, int hi) {
  if (volume.levels() <= 0 || volume.width() <= 0 || volume.height() <= 0)
    throw std::invalid_argument("winnerTakesAll: empty cost volume");
  lo = std::max(lo, volume.dmin());
  hi = std::min(hi, volume.dmax());
  if (lo > hi) throw std::invalid_argument("winnerTakesAll: [lo, hi] does not intersect the volume's disparity range");
  const int W = volume.width(), H = volume.height();
  cv::Mat disp(H, W, CV_32F);
  cv::parallel_for_(cv::Range(0, H), [&](const cv::Range& rows) {
    std::vector<float> best(W);
    for (int y = rows.start; y < rows.end; ++y) {
      float* dr = disp.ptr<float>(y);
      const float* s = volume.slice(lo) + static_cast<std::size_t>(y) * W;
      for (int x = 0; x < W; ++x) {
        best[x] = s[x];
        dr[x] = static_cast<float>(lo);
      }
      for (int d = lo + 1; d <= hi; ++d) {
        const float* sd = volume.slice(d) + static_cast<std::size_t>(y) * W;
        const float fd = static_cast<float>(d);
        float* b = best.data();
        int x = 0;
#if CV_SIMD128
        const cv::v_float32x4 vd = cv::v_setall_f32(fd);
        for (; x + 4 <= W; x += 4) {
          const cv::v_float32x4 c = cv::v_load(sd + x), cur = cv::v_load(b + x);
          const cv::v_float32x4 better = c < cur;  // strict: ties keep the smaller d
          cv::v_store(b + x, cv::v_select(better, c, cur));
          cv::v_store(dr + x, cv::v_select(better, vd, cv::v_load(dr + x)));
        }
#endif
        for (; x < W; ++x) {
          const bool better = sd[x] < b[x];  // strict: ties keep the smaller d
          b[x] = better ? sd[x] : b[x];
          dr[x] = better ? fd : dr[x];
        }
      }
    }
  });
  return disp;
}

std::vector<double> disparityHistogram(const cv::Mat& disparity, int lo, int hi, const cv::Mat& mask) {
  if (hi < lo) throw std::invalid_argument("disparityHistogram: hi < lo");
  if (disparity.empty()) throw std::invalid_argument("disparityHistogram: empty disparity map");
  if (disparity.channels() != 1) throw std::invalid_argument("disparityHistogram: disparity must be single-channel");
  if (!mask.empty() && (mask.size() != disparity.size() || mask.type() != CV_8UC1))
    throw std::invalid_argument("disparityHistogram: mask must be CV_8UC1 of the disparity's size");
  cv::Mat d32;
  if (disparity.type() == CV_32F)
    d32 = disparity;
  else
    disparity.convertTo(d32, CV_32F);
  std::vector<double> h(static_cast<std::size_t>(hi) - lo + 1, 0.0);
  for (int y = 0; y < d32.rows; ++y) {
    const float* dr = d32.ptr<float>(y);
    const uchar* mr = mask.empty() ? nullptr : mask.ptr<uchar>(y);
    for (int x = 0; x < d32.cols; ++x) {
      if (mr && !mr[x]) continue;
      const float v = dr[x];
      if (!std::isfinite(v)) continue;
      const double rv = std::round(static_cast<double>(v));  // half away from zero
      if (rv < lo || rv > hi) continue;
      h[static_cast<std::size_t>(rv - lo)] += 1.0;
    }
  }
  return h;
}

int breakPoint(const std::vector<double>& histogram, int lo, int hi) {
  if (hi <= lo) throw std::invalid_argument("breakPoint: need hi > lo");
  const std::size_t levels = static_cast<std::size_t>(static_cast<long long>(hi) - lo + 1);
  if (histogram.size() != levels)
    throw std::invalid_argument("breakPoint: histogram size " + std::to_string(histogram.size()) +
                                " does not match hi - lo + 1 = " + std::to_string(levels));
  double total = 0.0, moment = 0.0;
  int occupied = 0, first_occ = -1;
  for (std::size_t i = 0; i < levels; ++i) {
    const double c = histogram[i];
    if (!(c >= 0.0) || !std::isfinite(c)) throw std::invalid_argument("breakPoint: negative or non-finite count");
    if (c > 0.0) {
      ++occupied;
      if (first_occ < 0) first_occ = static_cast<int>(i);
    }
    total += c;
    moment += c * static_cast<double>(i);
  }
  const auto clampPsi = [&](long long psi) { return static_cast<int>(std::clamp<long long>(psi, lo, hi - 1)); };
  if (occupied == 0) {  // empty: split in the middle (floor)
    const long long s = static_cast<long long>(lo) + hi;
    return clampPsi(s >= 0 ? s / 2 : -((-s + 1) / 2));
  }
  if (occupied == 1) {
    // The single occupied level k stays whole and goes to the side with more
    // of the remaining range (ties: background, psi = k), so the other subset
    // is the (empty) short side.
    const long long k = static_cast<long long>(lo) + first_occ;
    const long long below = k - lo, above = hi - k;
    return clampPsi(below >= above ? k : k - 1);
  }
  // Otsu (Eq. 2.9): maximise the between-class variance w_B w_F (mu_B - mu_F)^2,
  // classes B = levels <= t and F = levels > t (t in lo..hi-1; first maximum).
  double best = -1.0, muB = 0.0, muF = 0.0;
  double wB = 0.0, mB = 0.0;
  for (std::size_t t = 0; t + 1 < levels; ++t) {
    wB += histogram[t];
    mB += histogram[t] * static_cast<double>(t);
    const double wF = total - wB;
    if (wB <= 0.0 || wF <= 0.0) continue;
    const double mb = mB / wB, mf = (moment - mB) / wF;
    const double between = wB * wF * (mb - mf) * (mb - mf);
    if (between > best * (1.0 + 1e-12)) {
      best = between;
      muB = mb;
      muF = mf;
    }
  }
  // Eq. 2.10: least-populated level T in [ceil(mu_B), floor(mu_F)]
  // (ties: nearest to the middle, then the smaller T). Indices are relative
  // to lo. mu_B <= t < t + 1 <= mu_F, so the interval is never empty.
  const long long a = static_cast<long long>(std::ceil(muB - 1e-9));
  const long long b = static_cast<long long>(std::floor(muF + 1e-9));
  const double mid = 0.5 * (muB + muF);
  long long arg = a;
  for (long long T = a; T <= b; ++T) {
    const double c = histogram[static_cast<std::size_t>(T)], cb = histogram[static_cast<std::size_t>(arg)];
    if (c < cb ||
        (c == cb && std::abs(static_cast<double>(T) - mid) < std::abs(static_cast<double>(arg) - mid) - 1e-12))
      arg = T;
  }
  return clampPsi(static_cast<long long>(lo) + arg);
}

}  // namespace massage_cell::stereo
