// Cameras of the simulator: pinhole + plumb_bob distortion, stereo pairs
// (rectified and raw, with the camera_info a calibrated driver publishes) and
// multi-view sets.
//
// Choices (see also the comments at each function):
//  * Distortion is OpenCV's / ROS's plumb_bob model exactly; the full upper
//    triangular K is applied (a skew K(0,1) is honoured; with zero skew this
//    is identical to cv::projectPoints, which ignores the skew).
//  * rayDirection() removes K by hand (triangular, closed form) and then lets
//    OpenCV undo the distortion on normalised coordinates with
//    cv::undistortPoints' TermCriteria variant (many iterations, tiny epsilon),
//    which keeps the skew handled and the round trip well below 1e-4 px.
//  * Stereo rig: base orientation optical x = -world y, optical y = -world x,
//    optical z = -world z (looking down, head at the top of the image, the
//    subject's left on the image left). The left camera sits at -B/2 along the
//    optical x axis (i.e. at +B/2 along world y), the right one at +B/2.
//    Raw pairs rotate each camera by its rotation vector about its own optical
//    axes: world_R_cam = world_R_base * AngleAxis(rotation_vector).
//  * Multi-view: see makeMultiView().
#include "massage_cell/sim/camera_model.h"

#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string vec(const Eigen::Vector3d& v) { return "(" + num(v.x()) + ", " + num(v.y()) + ", " + num(v.z()) + ")"; }

void requireDistortionSize(const std::vector<double>& D) {
  if (!D.empty() && D.size() != 5) {
    throw std::invalid_argument("CameraModel: plumb_bob distortion needs 0 or 5 coefficients, got " +
                                std::to_string(D.size()));
  }
}

/// Rotation matrix of a rotation vector (axis * angle); identity for a zero vector.
Eigen::Matrix3d rotationFromVector(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, v / angle).toRotationMatrix();
}

/// Base orientation of the rig cameras (world <- optical): columns are the
/// optical axes in world coordinates: x = -world y, y = -world x, z = -world z.
Eigen::Matrix3d rigBaseOrientation() {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0.0, -1.0, 0.0);
  R.col(1) = Eigen::Vector3d(-1.0, 0.0, 0.0);
  R.col(2) = Eigen::Vector3d(0.0, 0.0, -1.0);
  return R;
}

Eigen::Matrix3d rigK(const RigParameters& rig) {
  Eigen::Matrix3d K;
  K << rig.fx, 0.0, (rig.width - 1) / 2.0, 0.0, rig.fx, (rig.height - 1) / 2.0, 0.0, 0.0, 1.0;
  return K;
}

std::array<double, 9> rowMajor(const Eigen::Matrix3d& m) {
  std::array<double, 9> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[static_cast<std::size_t>(3 * r + c)] = m(r, c);
  return a;
}

std::array<double, 12> rowMajor(const Eigen::Matrix<double, 3, 4>& m) {
  std::array<double, 12> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) a[static_cast<std::size_t>(4 * r + c)] = m(r, c);
  return a;
}

std::array<double, 9> rowMajor3(const cv::Mat& m) {
  std::array<double, 9> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[static_cast<std::size_t>(3 * r + c)] = m.at<double>(r, c);
  return a;
}

std::array<double, 12> rowMajor34(const cv::Mat& m) {
  std::array<double, 12> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) a[static_cast<std::size_t>(4 * r + c)] = m.at<double>(r, c);
  return a;
}

camera::CameraCalibration baseInfo(const CameraModel& cam) {
  camera::CameraCalibration info;
  info.width = cam.width;
  info.height = cam.height;
  info.distortion_model = "plumb_bob";
  info.D = cam.D.empty() ? std::vector<double>(5, 0.0) : cam.D;
  info.K = rowMajor(cam.K);
  return info;
}

void validateRig(const RigParameters& rig) {
  constexpr int kMaxSize = 16384;
  if (rig.width <= 0 || rig.height <= 0 || rig.width > kMaxSize || rig.height > kMaxSize) {
    throw std::invalid_argument("makeStereoPair: width/height must be in 1.." + std::to_string(kMaxSize) + ", got " +
                                std::to_string(rig.width) + "x" + std::to_string(rig.height));
  }
  if (!std::isfinite(rig.fx) || !(rig.fx > 0.0)) {
    throw std::invalid_argument("makeStereoPair: fx must be positive and finite, got " + num(rig.fx));
  }
  if (!std::isfinite(rig.baseline) || !(rig.baseline > 0.0) || !(rig.baseline < 2.0)) {
    throw std::invalid_argument("makeStereoPair: baseline must be in (0, 2) m, got " + num(rig.baseline));
  }
  if (!rig.centre.allFinite()) {
    throw std::invalid_argument("makeStereoPair: centre must be finite, got " + vec(rig.centre));
  }
  if (!std::isfinite(rig.shift)) {
    throw std::invalid_argument("makeStereoPair: shift must be finite, got " + num(rig.shift));
  }
  // Distortion and rotations only exist for raw pairs; a rectified pair
  // ignores them, so they are not checked there. Toe-in would make a
  // rectified pair unrectified, so it is refused there.
  if (rig.rectified && rig.toe_in != 0.0) {
    throw std::invalid_argument("makeStereoPair: toe_in = " + num(rig.toe_in) +
                                " needs a raw pair (rectified = false)");
  }
  if (!rig.rectified) {
    if (rig.distortion.size() != 5) {
      throw std::invalid_argument("makeStereoPair: distortion of a raw pair needs 5 plumb_bob coefficients, got " +
                                  std::to_string(rig.distortion.size()));
    }
    for (double d : rig.distortion) {
      if (!std::isfinite(d)) throw std::invalid_argument("makeStereoPair: distortion holds a non-finite value");
    }
    if (!std::isfinite(rig.toe_in) || rig.toe_in < 0.0 || rig.toe_in > 0.3) {
      throw std::invalid_argument("makeStereoPair: toe_in must be in 0 .. 0.3 rad, got " + num(rig.toe_in));
    }
    const std::pair<const char*, const Eigen::Vector3d*> rotations[] = {{"left_rotation", &rig.left_rotation},
                                                                        {"right_rotation", &rig.right_rotation}};
    for (const auto& [name, r] : rotations) {
      if (!r->allFinite() || !(r->norm() < 0.2)) {
        throw std::invalid_argument(std::string("makeStereoPair: ") + name +
                                    " must be finite with |rotation| < 0.2 rad, got " + vec(*r));
      }
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// CameraModel

bool CameraModel::project(const Eigen::Vector3d& p_world, Eigen::Vector2d* pixel) const {
  requireDistortionSize(D);
  const Eigen::Vector3d p = world_from_camera.inverse() * p_world;
  if (!(p.z() > 1e-9)) return false;
  const double x = p.x() / p.z();
  const double y = p.y() / p.z();
  double xd = x, yd = y;
  if (D.size() == 5) {
    const double k1 = D[0], k2 = D[1], p1 = D[2], p2 = D[3], k3 = D[4];
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
  }
  if (pixel) {
    // (0, 0) = centre of the top-left pixel: no half-pixel offset.
    (*pixel) << K(0, 0) * xd + K(0, 1) * yd + K(0, 2), K(1, 1) * yd + K(1, 2);
  }
  return true;
}

Eigen::Vector3d CameraModel::rayDirection(double x, double y) const {
  requireDistortionSize(D);
  // Distorted normalised coordinates: invert the upper-triangular K in closed form.
  const double yd = (y - K(1, 2)) / K(1, 1);
  const double xd = (x - K(0, 2) - K(0, 1) * yd) / K(0, 0);
  double xn = xd, yn = yd;
  if (D.size() == 5) {
    // OpenCV's fixed-point undistortion on normalised points (identity camera
    // matrix, so the skew above stays handled); its EPS criterion then
    // measures the reprojection error in normalised units: 1e-15 ~ 1e-12 px.
    const cv::Mat src(1, 1, CV_64FC2, cv::Scalar(xd, yd));
    cv::Mat dst;
    const cv::Mat D_mat(1, 5, CV_64F, const_cast<double*>(D.data()));
    cv::undistortPoints(src, dst, cv::Mat::eye(3, 3, CV_64F), D_mat, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 1000, 1e-15));
    const cv::Vec2d n = dst.at<cv::Vec2d>(0, 0);
    xn = n[0];
    yn = n[1];
  }
  return (world_from_camera.linear() * Eigen::Vector3d(xn, yn, 1.0)).normalized();
}

Eigen::Matrix<double, 3, 4> CameraModel::projectionMatrix() const {
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  Eigen::Matrix<double, 3, 4> Rt;
  Rt.leftCols<3>() = camera_from_world.linear();
  Rt.col(3) = camera_from_world.translation();
  return K * Rt;
}

void CameraModel::validate() const {
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("CameraModel: image size must be positive, got " + std::to_string(width) + "x" +
                                std::to_string(height));
  }
  if (!K.allFinite()) throw std::invalid_argument("CameraModel: K holds a non-finite value");
  if (K(1, 0) != 0.0 || K(2, 0) != 0.0 || K(2, 1) != 0.0) {
    throw std::invalid_argument("CameraModel: K must be upper triangular");
  }
  if (!(K(0, 0) > 0.0) || !(K(1, 1) > 0.0)) {
    throw std::invalid_argument("CameraModel: focal lengths must be positive, got fx=" + num(K(0, 0)) +
                                " fy=" + num(K(1, 1)));
  }
  if (K(2, 2) != 1.0) throw std::invalid_argument("CameraModel: K(2,2) must be 1, got " + num(K(2, 2)));
  requireDistortionSize(D);
  for (double d : D) {
    if (!std::isfinite(d)) throw std::invalid_argument("CameraModel: distortion holds a non-finite value");
  }
  if (!world_from_camera.matrix().allFinite()) {
    throw std::invalid_argument("CameraModel: world_from_camera holds a non-finite value");
  }
  // The pose must be rigid (project/rayDirection rely on it).
  const Eigen::Matrix3d R = world_from_camera.linear();
  if (!(R.transpose() * R).isIdentity(1e-6) || std::abs(R.determinant() - 1.0) > 1e-6) {
    throw std::invalid_argument("CameraModel: world_from_camera rotation is not a rotation matrix");
  }
}

// ---------------------------------------------------------------------------
// Stereo pair

double StereoPairModel::baseline() const { return (right.centre() - left.centre()).norm(); }

StereoPairModel makeStereoPair(const RigParameters& rig) {
  validateRig(rig);
  const Eigen::Matrix3d base = rigBaseOrientation();
  const Eigen::Matrix3d K = rigK(rig);
  const Eigen::Vector3d mid = rig.centre + Eigen::Vector3d(rig.shift, 0.0, 0.0);
  const Eigen::Vector3d half = 0.5 * rig.baseline * base.col(0);  // along optical x

  StereoPairModel pair;
  pair.rectified = rig.rectified;
  for (CameraModel* cam : {&pair.left, &pair.right}) {
    cam->width = rig.width;
    cam->height = rig.height;
    cam->K = K;
  }
  pair.left.world_from_camera = Eigen::Isometry3d::Identity();
  pair.right.world_from_camera = Eigen::Isometry3d::Identity();
  pair.left.world_from_camera.translation() = mid - half;  // image left
  pair.right.world_from_camera.translation() = mid + half;

  if (rig.rectified) {
    pair.left.world_from_camera.linear() = base;
    pair.right.world_from_camera.linear() = base;
    pair.left.D.clear();
    pair.right.D.clear();

    Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
    P.leftCols<3>() = K;
    pair.left_info = baseInfo(pair.left);
    pair.left_info.R = rowMajor(Eigen::Matrix3d::Identity().eval());
    pair.left_info.P = rowMajor(P);
    pair.right_info = baseInfo(pair.right);
    pair.right_info.R = pair.left_info.R;
    P(0, 3) = -rig.fx * rig.baseline;
    pair.right_info.P = rowMajor(P);
    return pair;
  }

  // Raw pair: toe-in (left camera turned toward +optical x, the right one
  // toward -x), small rotations about each camera's own axes, lens distortion.
  const Eigen::Matrix3d toe_left = Eigen::AngleAxisd(rig.toe_in, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d toe_right = Eigen::AngleAxisd(-rig.toe_in, Eigen::Vector3d::UnitY()).toRotationMatrix();
  pair.left.world_from_camera.linear() = base * toe_left * rotationFromVector(rig.left_rotation);
  pair.right.world_from_camera.linear() = base * toe_right * rotationFromVector(rig.right_rotation);
  pair.left.D = rig.distortion;
  pair.right.D = rig.distortion;

  // x_r = R x_l + T (left optical frame -> right optical frame).
  const Eigen::Isometry3d right_from_left = pair.right.world_from_camera.inverse() * pair.left.world_from_camera;
  const Eigen::Matrix3d R_e = right_from_left.linear();
  const Eigen::Vector3d T_e = right_from_left.translation();

  cv::Mat K_cv, R_cv, T_cv;
  cv::eigen2cv(K, K_cv);
  cv::eigen2cv(R_e, R_cv);
  cv::eigen2cv(T_e, T_cv);
  const cv::Mat D_cv = cv::Mat(rig.distortion, true).reshape(1, 1);
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(K_cv, D_cv, K_cv, D_cv, cv::Size(rig.width, rig.height), R_cv, T_cv, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0.0);
  if (!(P2.at<double>(0, 3) < 0.0)) {
    throw std::runtime_error(
        "makeStereoPair: cv::stereoRectify gave a right projection with Tx = " + num(P2.at<double>(0, 3)) + " >= 0");
  }

  pair.left_info = baseInfo(pair.left);
  pair.left_info.R = rowMajor3(R1);
  pair.left_info.P = rowMajor34(P1);
  pair.right_info = baseInfo(pair.right);
  pair.right_info.R = rowMajor3(R2);
  pair.right_info.P = rowMajor34(P2);
  return pair;
}

// ---------------------------------------------------------------------------
// Framing

// For a fixed orientation the ray through a pixel meets the plane z = z_s at
// x = c_x + (c_z - z_s) k with k = d_x / -d_z: linear in the camera's centre,
// so the two edge conditions give the height D = c_z - z_s and c_x directly.
RigParameters frameRig(const RigParameters& rig, double x_top, double x_bottom, double surface_z) {
  if (!std::isfinite(x_top) || !std::isfinite(x_bottom) || !std::isfinite(surface_z)) {
    throw std::invalid_argument("frameRig: x_top, x_bottom and surface_z must be finite");
  }
  if (!(x_top > x_bottom)) {
    throw std::invalid_argument("frameRig: x_top = " + num(x_top) + " must lie above (> ) x_bottom = " + num(x_bottom));
  }
  RigParameters out = rig;
  out.shift = 0.0;
  const StereoPairModel pair = makeStereoPair(out);
  const CameraModel& cam = pair.left;
  const double cx = (cam.width - 1) / 2.0;
  const Eigen::Vector3d d_top = cam.rayDirection(cx, -0.5), d_bottom = cam.rayDirection(cx, cam.height - 0.5);
  if (!(d_top.z() < -1e-6) || !(d_bottom.z() < -1e-6)) {
    throw std::invalid_argument("frameRig: the image's top and bottom edges do not look down at the table");
  }
  const double k_top = d_top.x() / -d_top.z(), k_bottom = d_bottom.x() / -d_bottom.z();
  if (!(k_top > k_bottom)) throw std::invalid_argument("frameRig: the image's top edge does not look toward +x");
  const double D = (x_top - x_bottom) / (k_top - k_bottom);
  out.centre.x() = x_top - D * k_top;
  out.centre.z() = surface_z + D;
  return out;
}

// ---------------------------------------------------------------------------
// Multi-view sets

// Placement: azimuth az is measured about the world z axis through `target`,
// counter-clockwise seen from above; az = 0 puts the camera on the -x side of
// the target (toward the subject's feet) looking toward +x (toward the head).
// Camera i sits at
//   target + distance * (-cos(el) cos(az), -cos(el) sin(az), sin(el)),
// so positive azimuths move toward -y (the subject's right). Azimuths are
// evenly spread over [-spread/2, +spread/2] (count = 1: az = 0); when
// |spread| >= 2 pi the cameras instead go round the full circle with step
// 2 pi / count (no duplicated first/last camera).
// Orientation: optical z toward the target; image "up" (-optical y) is world
// +z projected onto the image plane, i.e. (sin el cos az, sin el sin az, cos el),
// which stays well defined when looking straight down (el = pi/2: image up
// points horizontally away from the camera's side, e.g. +x for az = 0, like the
// stereo rig with the head at the top). elevation must lie in [-pi/2, pi/2].
// K = [fx 0 (w-1)/2; 0 fx (h-1)/2; 0 0 1], no distortion.
std::vector<CameraModel> makeMultiView(int count, const Eigen::Vector3d& target, double distance, double elevation,
                                       double spread, int width, int height, double fx) {
  if (count < 1) throw std::invalid_argument("makeMultiView: count must be >= 1, got " + std::to_string(count));
  if (!std::isfinite(distance) || !(distance > 0.0)) {
    throw std::invalid_argument("makeMultiView: distance must be positive and finite, got " + num(distance));
  }
  if (!target.allFinite()) throw std::invalid_argument("makeMultiView: target must be finite, got " + vec(target));
  if (!std::isfinite(elevation) || std::abs(elevation) > kPi / 2.0) {
    throw std::invalid_argument("makeMultiView: elevation must be in [-pi/2, pi/2], got " + num(elevation));
  }
  if (!std::isfinite(spread)) throw std::invalid_argument("makeMultiView: spread must be finite, got " + num(spread));
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("makeMultiView: width/height must be positive, got " + std::to_string(width) + "x" +
                                std::to_string(height));
  }
  if (!std::isfinite(fx) || !(fx > 0.0)) {
    throw std::invalid_argument("makeMultiView: fx must be positive and finite, got " + num(fx));
  }

  std::vector<CameraModel> cameras;
  cameras.reserve(static_cast<std::size_t>(count));
  const bool full_circle = std::abs(spread) >= 2.0 * kPi;
  const double step = count == 1 ? 0.0 : full_circle ? 2.0 * kPi / count : spread / (count - 1);
  const double start = count == 1 ? 0.0 : full_circle ? 0.0 : -spread / 2.0;
  const double ce = std::cos(elevation), se = std::sin(elevation);
  for (int i = 0; i < count; ++i) {
    const double az = start + step * i;
    const double ca = std::cos(az), sa = std::sin(az);
    CameraModel cam;
    cam.width = width;
    cam.height = height;
    cam.K << fx, 0.0, (width - 1) / 2.0, 0.0, fx, (height - 1) / 2.0, 0.0, 0.0, 1.0;
    const Eigen::Vector3d z_opt(ce * ca, ce * sa, -se);  // camera -> target
    const Eigen::Vector3d up(se * ca, se * sa, ce);      // image up, orthogonal to z_opt
    const Eigen::Vector3d y_opt = -up;
    Eigen::Matrix3d R;
    R.col(0) = y_opt.cross(z_opt);
    R.col(1) = y_opt;
    R.col(2) = z_opt;
    cam.world_from_camera = Eigen::Isometry3d::Identity();
    cam.world_from_camera.linear() = R;
    cam.world_from_camera.translation() = target - distance * z_opt;
    cameras.push_back(cam);
  }
  return cameras;
}

camera::CameraCalibration monoCalibration(const CameraModel& camera) {
  camera::CameraCalibration info = baseInfo(camera);
  info.R = rowMajor(Eigen::Matrix3d::Identity().eval());
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
  P.leftCols<3>() = camera.K;
  info.P = rowMajor(P);
  return info;
}

}  // namespace massage_cell::sim
