#include "massage_cell/cect/depth_gate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "stats_detail.h"  // quantile

namespace massage_cell::cect {

namespace {

constexpr int kCoarseRows = 120;  // rows of the coarse copy matched
constexpr int kBlock = 5;         // SGBM block size, coarse pixels

cv::Mat coarseGrey(const cv::Mat& img, int factor) {
  cv::Mat grey = img;
  if (img.channels() == 3) cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  if (factor == 1) return grey;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(img.cols / factor, img.rows / factor), 0, 0, cv::INTER_AREA);
  return small;
}

/// Each view's disparity (CV_16S, SGBM's fixed point) of the coarse pair:
/// the left view's directly, the right one's by matching the mirrored pair.
/// Padded on the left by the search range, so that the first columns (whose
/// farther points the other camera does see) get a disparity too.
void coarseDisparities(const cv::Mat& coarse_left, const cv::Mat& coarse_right, int min_d, int num_d,
                       cv::Mat disparity[2]) {
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& range) {
    for (int v = range.start; v < range.end; ++v) {
      cv::Mat l, r;
      if (v == 0) {
        l = coarse_left;
        r = coarse_right;
      } else {
        cv::flip(coarse_right, l, 1);
        cv::flip(coarse_left, r, 1);
      }
      const int pad = min_d + num_d;
      cv::copyMakeBorder(l, l, 0, 0, pad, 0, cv::BORDER_REPLICATE);
      cv::copyMakeBorder(r, r, 0, 0, pad, 0, cv::BORDER_REPLICATE);
      const cv::Ptr<cv::StereoSGBM> sgbm =
          cv::StereoSGBM::create(min_d, num_d, kBlock, 8 * kBlock * kBlock, 32 * kBlock * kBlock, 1, 0, 10);
      cv::Mat d;
      sgbm->compute(l, r, d);
      d = d.colRange(pad, d.cols).clone();
      if (v == 1) cv::flip(d, d, 1);
      disparity[v] = d;
    }
  });
}

/// `coarse` (nearest-neighbour) at the full image's size; `fill` where the
/// image's last rows and columns have no coarse pixel.
cv::Mat toFullSize(const cv::Mat& coarse, int factor, const cv::Size& size, const cv::Scalar& fill) {
  cv::Mat up;
  cv::resize(coarse, up, cv::Size(coarse.cols * factor, coarse.rows * factor), 0, 0, cv::INTER_NEAREST);
  cv::Mat out(size, coarse.type(), fill);
  up.copyTo(out(cv::Rect(0, 0, up.cols, up.rows)));
  return out;
}

}  // namespace

std::string DepthGate::summary() const {
  std::ostringstream s;
  s.precision(2);
  if (left_far.empty()) return "no depth gate";
  s << "background beyond " << std::fixed << far_depth << " m (nearest surfaces at " << nearest_depth
    << " m): " << cv::countNonZero(left_far) << " px left, " << cv::countNonZero(right_far) << " px right";
  for (int v = 0; v < 2; ++v) {
    const cv::Mat& t = v == 0 ? left_table : right_table;
    if (!t.empty())
      s << "; the table (" << cv::countNonZero(t) << " px) left out of the " << (v == 0 ? "left" : "right")
        << " view's back";
  }
  return s.str();
}

DepthGate farBackground(const cv::Mat& left_rect, const cv::Mat& right_rect, const camera::StereoModel& geometry,
                        const cv::Vec2d& range, const DepthGateParams& params) {
  if (left_rect.size() != right_rect.size() || left_rect.type() != right_rect.type())
    throw std::invalid_argument("farBackground: the two views differ in size or type");
  if (left_rect.type() != CV_8UC3 && left_rect.type() != CV_8UC1)
    throw std::invalid_argument("farBackground: expected 8-bit grey or BGR images");
  DepthGate gate;
  const double min_disparity = range[0], max_disparity = range[1];
  const double focal_baseline = geometry.fx() * geometry.baseline();
  // Rectified disparity = f B / z + offset (the principal points' difference).
  const double offset = geometry.disparityAtDepth(1.0) - focal_baseline;
  if (!(params.gap > 0.0) || !(focal_baseline > 0.0) || !(max_disparity > min_disparity) || left_rect.empty())
    return gate;
  const int factor = std::max(1, static_cast<int>(std::lround(static_cast<double>(left_rect.rows) / kCoarseRows)));
  const int min_d = std::max(0, static_cast<int>(std::floor(min_disparity / factor)));
  const int span = static_cast<int>(std::ceil(max_disparity / factor)) - min_d + 1;
  const int num_d = 16 * ((span + 15) / 16);
  if (left_rect.cols / factor < 2 * kBlock || left_rect.rows / factor < 2 * kBlock) return gate;  // nothing to match

  cv::Mat disparity[2];
  coarseDisparities(coarseGrey(left_rect, factor), coarseGrey(right_rect, factor), min_d, num_d, disparity);

  // The nearest surfaces' depth (a quantile of the left view's disparities).
  std::vector<short> valid;
  const short invalid = static_cast<short>((min_d - 1) * 16);
  for (int y = 0; y < disparity[0].rows; ++y) {
    const short* d = disparity[0].ptr<short>(y);
    for (int x = 0; x < disparity[0].cols; ++x)
      if (d[x] > invalid && d[x] > 0) valid.push_back(d[x]);
  }
  if (valid.size() < 100) return gate;
  const double nearest_d =
      detail::quantile(std::move(valid), 1.0 - params.nearest_quantile, detail::QuantileIndex::kFloorOfSpan) / 16.0 *
          factor -
      offset;
  if (!(nearest_d > 0.0)) return gate;
  gate.nearest_depth = focal_baseline / nearest_d;
  gate.far_depth = gate.nearest_depth + params.gap;
  const double far_d = 16.0 * (focal_baseline / gate.far_depth + offset) / factor;  // SGBM's fixed-point units

  for (int v = 0; v < 2; ++v) {
    cv::Mat far = (disparity[v] > invalid) & (disparity[v] < far_d);
    // Block matching fattens the near surfaces by half a block over the far
    // ones next to them: the far region grown back by as much.
    cv::dilate(far, far, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kBlock, kBlock)));
    (v == 0 ? gate.left_far : gate.right_far) = toFullSize(far, factor, left_rect.size(), cv::Scalar(0));
    // Depth: f B / (d - offset) where the disparity is valid.
    cv::Mat z(disparity[v].size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
    for (int y = 0; y < z.rows; ++y) {
      const short* d = disparity[v].ptr<short>(y);
      float* o = z.ptr<float>(y);
      for (int x = 0; x < z.cols; ++x) {
        const double dd = d[x] / 16.0 * factor - offset;
        if (d[x] > invalid && dd > 0.0) o[x] = static_cast<float>(focal_baseline / dd);
      }
    }
    (v == 0 ? gate.left_depth : gate.right_depth) =
        toFullSize(z, factor, left_rect.size(), cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  }
  return gate;
}

namespace {

double signedDistance(const Eigen::Vector4d& plane, const Eigen::Vector3d& p) {
  return plane.head<3>().dot(p) + plane(3);
}

/// The plane with the most points within `tolerance` among `tries` random
/// triples, of those with at most `max_behind` of the points more than
/// `tolerance` behind it (farther from the camera); normal toward the camera.
bool ransacSupport(const std::vector<Eigen::Vector3d>& pts, double tolerance, double max_behind, int tries,
                   Eigen::Vector4d* best) {
  std::mt19937 rng(12345u);
  std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
  std::size_t best_in = 0;
  for (int it = 0; it < tries; ++it) {
    const Eigen::Vector3d &a = pts[pick(rng)], &b = pts[pick(rng)], &c = pts[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n.norm() > 1e-9)) continue;
    n.normalize();
    Eigen::Vector4d plane(n.x(), n.y(), n.z(), -n.dot(a));
    if (plane(3) < 0.0) plane = -plane;
    std::size_t in = 0, behind = 0;
    for (const Eigen::Vector3d& p : pts) {
      const double s = signedDistance(plane, p);
      if (std::abs(s) < tolerance)
        ++in;
      else if (s < -tolerance)
        ++behind;
    }
    if (behind > max_behind * pts.size() || in <= best_in) continue;
    best_in = in;
    *best = plane;
  }
  return best_in > 0;
}

}  // namespace

cv::Mat tablePixels(const cv::Mat& depth, const cv::Mat& far, const camera::StereoModel& geometry, double margin) {
  constexpr double kTolerance = 0.02, kMaxBehind = 0.05, kMinShare = 0.1;
  constexpr int kStep = 4, kTries = 200;
  if (depth.empty() || depth.type() != CV_32FC1 || !(margin > 0.0) || geometry.empty()) return cv::Mat();
  std::vector<Eigen::Vector3d> pts;
  for (int y = kStep / 2; y < depth.rows; y += kStep)
    for (int x = kStep / 2; x < depth.cols; x += kStep) {
      const float z = depth.at<float>(y, x);
      if (!(z > 0.0f) || (!far.empty() && far.at<std::uint8_t>(y, x))) continue;
      pts.push_back(geometry.triangulate(x, y, geometry.disparityAtDepth(z)));
    }
  Eigen::Vector4d plane;
  if (pts.size() < 100 || !ransacSupport(pts, kTolerance, kMaxBehind, kTries, &plane)) return cv::Mat();
  // Least squares on its points: the normal is the smallest principal axis.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (const Eigen::Vector3d& p : pts)
    if (std::abs(signedDistance(plane, p)) < kTolerance) mean += p, ++n;
  if (n < kMinShare * pts.size()) return cv::Mat();
  mean /= static_cast<double>(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : pts)
    if (std::abs(signedDistance(plane, p)) < kTolerance) cov += (p - mean) * (p - mean).transpose();
  const Eigen::Vector3d normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
  plane << normal, -normal.dot(mean);
  if (plane(3) < 0.0) plane = -plane;
  cv::Mat table(depth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < depth.rows; ++y) {
    const float* z = depth.ptr<float>(y);
    std::uint8_t* t = table.ptr<std::uint8_t>(y);
    for (int x = 0; x < depth.cols; ++x)
      if (z[x] > 0.0f && signedDistance(plane, geometry.triangulate(x, y, geometry.disparityAtDepth(z[x]))) < margin)
        t[x] = 255;
  }
  return table;
}

}  // namespace massage_cell::cect
