// Plane-induced homography NCC (see photo_consistency.h).
#include "massage_cell/planar/photo_consistency.h"

#include <cmath>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace massage_cell::planar {

namespace {

constexpr double kMinInsideShare = 0.8;   // a view scores the samples when this share lands in its image
constexpr double kMinTextureSigma = 2.0;  // grey levels: flatter samples cannot be verified
constexpr std::size_t kMinSamples = 8;

float bilinear(const cv::Mat& grey, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = grey.ptr<float>(y0);
  const float* r1 = grey.ptr<float>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

bool inside(const cv::Mat& grey, double x, double y) {
  return x >= 0.0 && y >= 0.0 && x < grey.cols - 1.0 && y < grey.rows - 1.0;
}

double ncc(const std::vector<float>& a, const std::vector<float>& b) {
  const double n = static_cast<double>(a.size());
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sa += a[i];
    sb += b[i];
    saa += double(a[i]) * a[i];
    sbb += double(b[i]) * b[i];
    sab += double(a[i]) * b[i];
  }
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  if (va <= 0.0 || vb <= 0.0) return -1.0;
  return (sab - sa * sb / n) / std::sqrt(va * vb);
}

bool inFront(const Projection& P, const Eigen::Vector4d& X) {
  return std::abs(X.w()) > 1e-12 && depthOf(P, X.hnormalized()) > 0.0;
}

}  // namespace

Eigen::Matrix<double, 4, 3> planeBackProjection(const Projection& P, const Plane& plane) {
  const Eigen::Vector4d pi(plane.n.x(), plane.n.y(), plane.n.z(), plane.d);
  const Eigen::Vector4d C = cameraCentre(P).homogeneous();
  const Eigen::Matrix<double, 4, 3> pinv = P.transpose() * (P * P.transpose()).inverse();
  const Eigen::Matrix4d M = pi.dot(C) * Eigen::Matrix4d::Identity() - C * pi.transpose();
  return M * pinv;
}

PhotoConsistency::PhotoConsistency(const std::vector<View>& views) : views_(views) {
  for (const View& view : views) {
    cv::Mat grey;
    if (view.image.channels() == 3) {
      cv::cvtColor(view.image, grey, cv::COLOR_BGR2GRAY);
    } else {
      grey = view.image;
    }
    grey.convertTo(grey, CV_32F);
    grey_.push_back(grey);
  }
}

PhotoConsistency::Samples PhotoConsistency::sample(int reference_view, const std::vector<Eigen::Vector2d>& pixels,
                                                   const std::vector<Eigen::Vector2d>& corners) const {
  Samples s;
  s.reference_view = reference_view;
  const cv::Mat& grey = grey_.at(static_cast<std::size_t>(reference_view));
  double mean = 0.0, sq = 0.0;
  for (const Eigen::Vector2d& q : pixels) {
    if (!inside(grey, q.x(), q.y())) continue;
    const float v = bilinear(grey, q.x(), q.y());
    s.pixels.push_back(q.homogeneous());
    s.values.push_back(v);
    mean += v;
    sq += double(v) * v;
  }
  for (const Eigen::Vector2d& c : corners) s.corners.push_back(c.homogeneous());
  const double n = static_cast<double>(s.values.size());
  s.textured =
      s.values.size() >= kMinSamples && std::sqrt(std::max(0.0, sq / n - (mean / n) * (mean / n))) >= kMinTextureSigma;
  return s;
}

double PhotoConsistency::score(const Samples& samples, const Plane& plane) const {
  if (!samples.textured) return -1.0;
  const Projection& Pr = views_[static_cast<std::size_t>(samples.reference_view)].P;
  const Eigen::Matrix<double, 4, 3> M = planeBackProjection(Pr, plane);
  for (const Eigen::Vector3d& c : samples.corners) {
    if (!inFront(Pr, M * c)) return -1.0;
  }
  double sum = 0.0;
  int scored = 0;
  std::vector<float> ref, other;
  for (std::size_t v = 0; v < views_.size(); ++v) {
    if (static_cast<int>(v) == samples.reference_view) continue;
    const Projection& Pv = views_[v].P;
    bool in_front = true;
    for (const Eigen::Vector3d& c : samples.corners) in_front = in_front && inFront(Pv, M * c);
    if (!in_front) continue;
    const Eigen::Matrix3d H = Pv * M;
    const cv::Mat& grey = grey_[v];
    ref.clear();
    other.clear();
    for (std::size_t i = 0; i < samples.pixels.size(); ++i) {
      const Eigen::Vector3d y = H * samples.pixels[i];
      const double x = y.x() / y.z(), yy = y.y() / y.z();
      if (!inside(grey, x, yy)) continue;
      ref.push_back(samples.values[i]);
      other.push_back(bilinear(grey, x, yy));
    }
    if (ref.size() < kMinInsideShare * samples.pixels.size()) continue;
    sum += ncc(ref, other);
    ++scored;
  }
  return scored > 0 ? sum / scored : -1.0;
}

}  // namespace massage_cell::planar
