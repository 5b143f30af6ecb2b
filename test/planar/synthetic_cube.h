// A textured cube seen by calibrated cameras, drawn exactly with OpenCV's
// perspective warps (no renderer): the planar tests' views with exact 3D
// edges, exact points on the faces and exact planes.
#pragma once

#include <array>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "massage_cell/planar/features.h"
#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar::test {

struct CubeFace {
  Eigen::Vector3d corner, ex, ey;  ///< X = corner + s ex + t ey, s, t in [0, 1]
  Eigen::Vector3d normal;          ///< outward
};

struct SyntheticCube {
  double edge = 0.3;
  std::vector<View> views;
  std::array<CubeFace, 3> faces;   ///< +x, +y, +z (the three the cameras see)
  std::vector<PointTrack> points;  ///< exact points on the three faces
  std::vector<LineTrack> lines;    ///< the nine visible edges, exact
};

/// A camera at `eye` looking at `target` (image y down toward world -z).
inline Projection lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double f, int w, int h) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;  // camera from world
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  Eigen::Matrix3d K;
  K << f, 0, (w - 1) / 2.0, 0, f, (h - 1) / 2.0, 0, 0, 1;
  Projection P;
  P.leftCols<3>() = K * R;
  P.col(3) = -K * R * eye;
  return P;
}

inline cv::Mat faceTexture(unsigned seed) {
  cv::Mat noise(256, 256, CV_8UC3);
  cv::theRNG().state = seed;
  cv::randu(noise, cv::Scalar::all(30), cv::Scalar::all(225));
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
  return noise;
}

/// The cube [0, edge]^3 from `views` cameras on an arc around (1, 1, 1).
inline SyntheticCube makeSyntheticCube(int view_count = 3, int width = 640, int height = 480, double f = 700.0) {
  SyntheticCube cube;
  const double e = cube.edge;
  cube.faces = {CubeFace{{e, 0, 0}, {0, e, 0}, {0, 0, e}, {1, 0, 0}},
                CubeFace{{0, e, 0}, {e, 0, 0}, {0, 0, e}, {0, 1, 0}},
                CubeFace{{0, 0, e}, {e, 0, 0}, {0, e, 0}, {0, 0, 1}}};
  const Eigen::Vector3d centre = Eigen::Vector3d::Constant(e / 2);
  for (int v = 0; v < view_count; ++v) {
    const double az = (45.0 + 12.0 * (v - (view_count - 1) / 2.0)) * M_PI / 180.0;
    const double el = (35.0 + 4.0 * (v % 2)) * M_PI / 180.0;
    const Eigen::Vector3d eye =
        centre + 1.3 * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    View view;
    view.name = "cube" + std::to_string(v);
    view.P = normalisedProjection(lookAt(eye, centre, f, width, height));
    view.image = cv::Mat::zeros(height, width, CV_8UC3);
    for (int k = 0; k < 3; ++k) {
      const CubeFace& face = cube.faces[static_cast<std::size_t>(k)];
      Eigen::Matrix<double, 4, 3> A = Eigen::Matrix<double, 4, 3>::Zero();
      A.block<3, 1>(0, 0) = face.ex / 255.0;
      A.block<3, 1>(0, 1) = face.ey / 255.0;
      A.block<3, 1>(0, 2) = face.corner;
      A(3, 2) = 1.0;
      const Eigen::Matrix3d H = view.P * A;
      cv::Mat Hcv(3, 3, CV_64F);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) Hcv.at<double>(r, c) = H(r, c);
      cv::Mat warped, mask;
      cv::warpPerspective(faceTexture(11u + 7u * static_cast<unsigned>(k)), warped, Hcv, view.image.size(),
                          cv::INTER_LINEAR);
      cv::warpPerspective(cv::Mat(256, 256, CV_8U, cv::Scalar(255)), mask, Hcv, view.image.size(), cv::INTER_NEAREST);
      warped.copyTo(view.image, mask);
    }
    cube.views.push_back(view);
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.03, 0.97);
  for (const CubeFace& face : cube.faces) {
    for (int i = 0; i < 40; ++i) {
      PointTrack p;
      p.X = face.corner + u(rng) * face.ex + u(rng) * face.ey;
      for (int v = 0; v < view_count; ++v) p.observations.push_back({v, i});
      cube.points.push_back(p);
    }
  }
  const Eigen::Vector3d c[8] = {{0, 0, 0}, {e, 0, 0}, {0, e, 0}, {e, e, 0}, {0, 0, e}, {e, 0, e}, {0, e, e}, {e, e, e}};
  const int edges[9][2] = {{1, 3}, {1, 5}, {3, 7}, {2, 3}, {2, 6}, {5, 7}, {6, 7}, {4, 5}, {4, 6}};
  for (const auto& ed : edges) {
    LineTrack l;
    l.a = c[ed[0]];
    l.b = c[ed[1]];
    for (int v = 0; v < view_count; ++v) l.observations.push_back({v, 0});
    cube.lines.push_back(l);
  }
  return cube;
}

inline Plane facePlane(const CubeFace& face) {
  Plane p;
  p.n = face.normal;
  p.d = -face.normal.dot(face.corner);
  return p;
}

}  // namespace massage_cell::planar::test
