// Calibrated views and their projective geometry (see views.h).
#include "massage_cell/planar/views.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgcodecs.hpp>

namespace massage_cell::planar {

namespace {

/// SVD of the stacked linear systems (full pivoting: the most accurate QR
/// preconditioning of Eigen's one-sided Jacobi SVD).
using Svd = Eigen::JacobiSVD<Eigen::MatrixXd, Eigen::FullPivHouseholderQRPreconditioner>;

/// Singular left 3x3 blocks: smallest / largest singular value below this.
constexpr double kMinConditionRatio = 1e-12;
/// validateViews: centres closer than this times their distance from the
/// world origin are one centre.
constexpr double kSameCentreRatio = 1e-9;
/// triangulateLine: planes closer to parallel than this are one plane.
constexpr double kMinPlaneAngleRad = 0.5 * M_PI / 180.0;

std::string viewLabel(const std::vector<View>& views, std::size_t i) {
  std::string label = "view " + std::to_string(i);
  if (!views[i].name.empty()) label += " (" + views[i].name + ")";
  return label;
}

/// Empty string when P is usable, else what is wrong with it.
std::string projectionProblem(const Projection& P) {
  if (!P.allFinite()) return "P has a non-finite entry";
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::Matrix3d>(P.leftCols<3>()).singularValues();
  if (!(s(2) > kMinConditionRatio * s(0))) return "P's left 3x3 block is singular";
  return {};
}

/// A similarity of the world (X = centre + scale X') that puts the cameras'
/// centres around the origin at unit mean distance: it conditions the
/// homogeneous linear systems of the triangulations.
struct WorldNormalisation {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double scale = 1.0;

  explicit WorldNormalisation(const std::vector<Projection>& cameras) {
    std::vector<Eigen::Vector3d> centres;
    for (const Projection& P : cameras) centres.push_back(cameraCentre(P));
    for (const Eigen::Vector3d& c : centres) centre += c / static_cast<double>(centres.size());
    double spread = 0.0;
    for (const Eigen::Vector3d& c : centres) spread += (c - centre).norm() / static_cast<double>(centres.size());
    if (spread > 0.0) scale = spread;
  }
  /// P' = P H, with H: normalised world -> world.
  Projection apply(const Projection& P) const {
    Eigen::Matrix4d H = Eigen::Matrix4d::Identity();
    H.topLeftCorner<3, 3>() *= scale;
    H.topRightCorner<3, 1>() = centre;
    return P * H;
  }
  Eigen::Vector3d toWorld(const Eigen::Vector3d& X) const { return centre + scale * X; }
};

/// Focal length in pixels of a finite camera (|m1 x m3| / |m3|^2).
double focalPixels(const Projection& P) {
  const Eigen::Vector3d m1 = P.block<1, 3>(0, 0).transpose(), m3 = P.block<1, 3>(2, 0).transpose();
  return m1.cross(m3).norm() / m3.squaredNorm();
}

void checkSameSize(std::size_t cameras, std::size_t observations, const char* what) {
  if (cameras < 2)
    throw std::invalid_argument(std::string(what) + ": needs at least 2 views, got " + std::to_string(cameras));
  if (cameras != observations)
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(cameras) + " cameras but " +
                                std::to_string(observations) + " observations");
}

Projection readProjection(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("loadVggViews: cannot read " + path.string());
  Projection P;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> P(r, c)))
        throw std::runtime_error("loadVggViews: " + path.string() + " does not hold 3 rows of 4 numbers");
  const std::string problem = projectionProblem(P);
  if (!problem.empty()) throw std::runtime_error("loadVggViews: " + path.string() + ": " + problem);
  return normalisedProjection(P);
}

std::string threeDigits(int i) {
  char buffer[16];
  std::snprintf(buffer, sizeof(buffer), "%03d", i);
  return buffer;
}

}  // namespace

Projection projectionFromPose(const Eigen::Matrix3d& K, const Eigen::Isometry3d& world_from_camera) {
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  Projection Rt;
  Rt << camera_from_world.linear(), camera_from_world.translation();
  return K * Rt;
}

Projection normalisedProjection(const Projection& P) {
  const std::string problem = projectionProblem(P);
  if (!problem.empty()) throw std::invalid_argument("normalisedProjection: " + problem);
  const double sign = P.leftCols<3>().determinant() > 0.0 ? 1.0 : -1.0;
  return P * (sign / P.block<1, 3>(2, 0).norm());
}

std::vector<View> loadVggViews(const std::string& folder) {
  namespace fs = std::filesystem;
  const fs::path root(folder);
  std::vector<View> views;
  for (int i = 1;; ++i) {
    const std::string name = threeDigits(i);
    const fs::path image_path = root / "images" / (name + ".jpg"), p_path = root / "2D" / (name + ".P");
    const bool has_image = fs::exists(image_path), has_p = fs::exists(p_path);
    if (i > 1 && !has_image && !has_p) break;
    if (!has_image) throw std::runtime_error("loadVggViews: missing " + image_path.string());
    if (!has_p) throw std::runtime_error("loadVggViews: missing " + p_path.string());
    View view;
    view.name = name;
    view.image = cv::imread(image_path.string(), cv::IMREAD_COLOR);
    if (view.image.empty()) throw std::runtime_error("loadVggViews: cannot decode " + image_path.string());
    view.P = readProjection(p_path);
    views.push_back(std::move(view));
  }
  return views;
}

void validateViews(const std::vector<View>& views) {
  if (views.size() < 2)
    throw std::invalid_argument("planar views: need at least 2 views, got " + std::to_string(views.size()));
  std::vector<Eigen::Vector3d> centres;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const View& v = views[i];
    if (v.image.empty()) throw std::invalid_argument("planar views: " + viewLabel(views, i) + " has an empty image");
    if (v.image.depth() != CV_8U || (v.image.channels() != 1 && v.image.channels() != 3))
      throw std::invalid_argument("planar views: " + viewLabel(views, i) + " image is not 8-bit grey or BGR (type " +
                                  std::to_string(v.image.type()) + ")");
    const std::string problem = projectionProblem(v.P);
    if (!problem.empty()) throw std::invalid_argument("planar views: " + viewLabel(views, i) + ": " + problem);
    centres.push_back(cameraCentre(v.P));
  }
  for (std::size_t i = 0; i < centres.size(); ++i)
    for (std::size_t j = i + 1; j < centres.size(); ++j) {
      const double scale = std::max(centres[i].norm(), centres[j].norm());
      if ((centres[i] - centres[j]).norm() <= kSameCentreRatio * scale)
        throw std::invalid_argument("planar views: " + viewLabel(views, i) + " and " + viewLabel(views, j) +
                                    " have the same camera centre (no baseline)");
    }
}

Eigen::Vector3d cameraCentre(const Projection& P) {
  // P (C, 1) = 0  <=>  M C = -p4.
  return P.leftCols<3>().colPivHouseholderQr().solve(-P.col(3));
}

bool project(const Projection& P, const Eigen::Vector3d& X, Eigen::Vector2d* pixel) {
  const Eigen::Vector3d x = P * X.homogeneous();
  if (!(depthOf(P, X) > 0.0)) return false;
  *pixel = x.hnormalized();
  return true;
}

double depthOf(const Projection& P, const Eigen::Vector3d& X) {
  const double w = P.row(2).dot(X.homogeneous());
  const double sign = P.leftCols<3>().determinant() > 0.0 ? 1.0 : -1.0;
  return sign * w / P.block<1, 3>(2, 0).norm();
}

Eigen::Matrix3d fundamental(const Projection& Pa, const Projection& Pb) {
  // F = [e_b]x Pb Pa^+ with e_b = Pb (C_a, 1), the epipole in b. Any right
  // inverse of Pa serves as Pa^+ (it maps x to a point on x's ray); for a
  // finite camera (M | p4) that is (M^-1 ; 0), so F = [e_b]x Mb Ma^-1.
  const Eigen::Vector3d e = Pb * cameraCentre(Pa).homogeneous();
  Eigen::Matrix3d ex;
  ex << 0.0, -e.z(), e.y(), e.z(), 0.0, -e.x(), -e.y(), e.x(), 0.0;
  const Eigen::Matrix3d F = ex * Pb.leftCols<3>() * Pa.leftCols<3>().inverse();
  return F / F.norm();
}

Eigen::Vector3d triangulatePoint(const std::vector<Projection>& cameras, const std::vector<Eigen::Vector2d>& pixels) {
  checkSameSize(cameras.size(), pixels.size(), "triangulatePoint");
  // Hartley normalisation: the world by the cameras' centres, each image by
  // moving its observation to the origin and dividing by the focal length.
  // The observation is then (0, 0) and the DLT rows are the first two rows
  // of the normalised camera.
  const WorldNormalisation world(cameras);
  Eigen::MatrixXd A(2 * cameras.size(), 4);
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const double f = focalPixels(cameras[i]);
    Eigen::Matrix3d T;
    T << 1.0 / f, 0.0, -pixels[i].x() / f, 0.0, 1.0 / f, -pixels[i].y() / f, 0.0, 0.0, 1.0;
    const Projection Pn = T * normalisedProjection(world.apply(cameras[i]));
    A.row(static_cast<Eigen::Index>(2 * i)) = Pn.row(0);
    A.row(static_cast<Eigen::Index>(2 * i + 1)) = Pn.row(1);
  }
  const Eigen::Vector4d X = Svd(A, Eigen::ComputeFullV).matrixV().col(3);
  return world.toWorld(X.hnormalized());
}

Eigen::Vector3d imageLine(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d l = a.homogeneous().cross(b.homogeneous());
  const double n = l.head<2>().norm();
  if (!(n > 0.0)) throw std::invalid_argument("imageLine: the two pixels coincide");
  return l / n;
}

bool triangulateLine(const std::vector<Projection>& cameras, const std::vector<Eigen::Vector3d>& lines,
                     Eigen::Vector3d* point, Eigen::Vector3d* direction) {
  checkSameSize(cameras.size(), lines.size(), "triangulateLine");
  // Planes P^T l in the normalised world, scaled to unit normals (each row's
  // residual is then a point's distance from that view's plane).
  const WorldNormalisation world(cameras);
  Eigen::MatrixXd A(cameras.size(), 4);
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Eigen::Vector4d plane = world.apply(cameras[i]).transpose() * lines[i];
    const double n = plane.head<3>().norm();
    if (!(n > 0.0)) return false;
    A.row(static_cast<Eigen::Index>(i)) = plane.transpose() / n;
  }
  // The normals must span two dimensions: for two planes at angle t the
  // normals' singular values are sqrt(1 +- cos t), their ratio tan(t / 2).
  const Eigen::VectorXd s = Svd(A.leftCols<3>()).singularValues();  // min(views, 3) values
  if (!(s(1) > std::tan(0.5 * kMinPlaneAngleRad) * s(0))) return false;
  // The line is the (least-squares) null space of the stacked planes,
  // spanned by the last two right singular vectors u, v.
  const Eigen::MatrixXd V = Svd(A, Eigen::ComputeFullV).matrixV();
  const Eigen::Vector4d u = V.col(2), v = V.col(3);
  const Eigen::Vector3d d = (u.w() * v.head<3>() - v.w() * u.head<3>()).normalized();  // its point at infinity
  const double w = u.w() * u.w() + v.w() * v.w();
  if (!(w > 0.0) || !d.allFinite()) return false;                             // the line at infinity
  const Eigen::Vector3d p = (u.w() * u.head<3>() + v.w() * v.head<3>()) / w;  // a finite point of the span
  *point = world.toWorld(p - p.dot(d) * d);
  *direction = d;
  return true;
}

Eigen::Vector3d closestOnLineToRay(const Projection& P, const Eigen::Vector2d& pixel, const Eigen::Vector3d& point,
                                   const Eigen::Vector3d& direction) {
  const Eigen::Vector3d centre = cameraCentre(P);
  const Eigen::Vector3d ray = P.leftCols<3>().colPivHouseholderQr().solve(pixel.homogeneous());
  // min over (t, s) of |point + t direction - centre - s ray|.
  Eigen::Matrix<double, 3, 2> A;
  A << direction, -ray;
  const Eigen::Vector2d ts = A.colPivHouseholderQr().solve(centre - point);
  return point + ts(0) * direction;
}

double pixelsPerUnit(const Projection& P, const Eigen::Vector3d& X) {
  // Jacobian of the projection at X, restricted to the plane through X
  // perpendicular to the viewing ray; the geometric mean of its stretches.
  const Eigen::Vector3d x = P * X.homogeneous();
  Eigen::Matrix<double, 2, 3> J;
  J.row(0) = (P.block<1, 3>(0, 0) - x(0) / x(2) * P.block<1, 3>(2, 0)) / x(2);
  J.row(1) = (P.block<1, 3>(1, 0) - x(1) / x(2) * P.block<1, 3>(2, 0)) / x(2);
  const Eigen::Vector3d ray = (X - cameraCentre(P)).normalized();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = ray.unitOrthogonal();
  B.col(1) = ray.cross(B.col(0));
  return std::sqrt(std::abs((J * B).determinant()));
}

}  // namespace massage_cell::planar
