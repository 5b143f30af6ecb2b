#include "massage_cell/stereo/subpixel.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace massage_cell::stereo {

namespace {

void validate(const CostVolume& volume, const cv::Mat& disparity, const SubpixelParams& params) {
  if (disparity.type() != CV_32F) throw std::invalid_argument("subpixelDisparity: the disparity map must be CV_32F");
  if (disparity.cols != volume.width() || disparity.rows != volume.height()) {
    throw std::invalid_argument("subpixelDisparity: the disparity map is " + std::to_string(disparity.cols) + "x" +
                                std::to_string(disparity.rows) + ", the cost volume " + std::to_string(volume.width()) +
                                "x" + std::to_string(volume.height()));
  }
  validate(params);
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (std::isfinite(d[x]) && (d[x] < volume.dmin() || d[x] > volume.dmax())) {
        throw std::invalid_argument("subpixelDisparity: disparity " + std::to_string(d[x]) + " at (" +
                                    std::to_string(x) + ", " + std::to_string(y) + ") is outside the cost volume's " +
                                    std::to_string(volume.dmin()) + ".." + std::to_string(volume.dmax()));
      }
    }
  }
}

/// The offset of the minimum of the curve through (-1, cm), (0, c0), (1, cp)
/// where c0 is below both neighbours.
double curveMinimum(SubpixelFit fit, double cm, double c0, double cp) {
  if (fit == SubpixelFit::kParabola) return 0.5 * (cm - cp) / (cm - 2.0 * c0 + cp);
  return cm >= cp ? 0.5 * (cm - cp) / (cm - c0) : 0.5 * (cm - cp) / (cp - c0);
}

}  // namespace

void validate(const SubpixelParams& params) {
  if (params.fit != SubpixelFit::kParabola && params.fit != SubpixelFit::kEquiangular) {
    throw std::invalid_argument("subpixel: unknown fit " + std::to_string(static_cast<int>(params.fit)));
  }
  if (params.window < 1 || params.window % 2 == 0) {
    throw std::invalid_argument("subpixel: window must be odd and >= 1, got " + std::to_string(params.window));
  }
  if (!(params.max_offset > 0.0f && params.max_offset <= 0.5f)) {
    throw std::invalid_argument("subpixel: max_offset must be in (0, 0.5], got " + std::to_string(params.max_offset));
  }
}

SubpixelFit parseSubpixelFit(const std::string& name) {
  if (name == "parabola") return SubpixelFit::kParabola;
  if (name == "equiangular") return SubpixelFit::kEquiangular;
  throw std::invalid_argument("unknown sub-pixel fit '" + name + "' (parabola, equiangular)");
}

std::string toString(SubpixelFit fit) { return fit == SubpixelFit::kParabola ? "parabola" : "equiangular"; }

cv::Mat subpixelDisparity(const CostVolume& volume, const cv::Mat& disparity, const SubpixelParams& params) {
  validate(volume, disparity, params);
  const int W = volume.width(), H = volume.height(), r = params.window / 2;
  cv::Mat out = disparity.clone();
  cv::parallel_for_(cv::Range(0, H), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* in = disparity.ptr<float>(y);
      float* o = out.ptr<float>(y);
      const int y0 = std::max(0, y - r), y1 = std::min(H - 1, y + r);
      for (int x = 0; x < W; ++x) {
        const float v = in[x];
        if (!std::isfinite(v) || v != std::round(v)) continue;  // no value, or already sub-pixel
        const int d = static_cast<int>(v);
        if (d <= volume.dmin() || d >= volume.dmax()) continue;
        const int x0 = std::max(0, x - r), x1 = std::min(W - 1, x + r);
        double cm = 0.0, c0 = 0.0, cp = 0.0;
        for (int yy = y0; yy <= y1; ++yy) {
          const std::size_t row = static_cast<std::size_t>(yy) * W;
          const float* sm = volume.slice(d - 1) + row;
          const float* s0 = volume.slice(d) + row;
          const float* sp = volume.slice(d + 1) + row;
          for (int xx = x0; xx <= x1; ++xx) {
            cm += sm[xx];
            c0 += s0[xx];
            cp += sp[xx];
          }
        }
        if (!(c0 < cm && c0 < cp)) continue;
        const double offset = curveMinimum(params.fit, cm, c0, cp);
        o[x] = static_cast<float>(
            d + std::clamp(offset, -static_cast<double>(params.max_offset), static_cast<double>(params.max_offset)));
      }
    }
  });
  return out;
}

}  // namespace massage_cell::stereo
