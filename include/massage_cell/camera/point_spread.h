// The principal axes of a set of 3D points (the spread of a board's corners, of hand-eye poses, a plane's normal).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace massage_cell::camera {

struct PrincipalAxes {
  Eigen::Vector3d spread = Eigen::Vector3d::Zero();    ///< the centred points' singular values, descending
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  ///< their directions (columns, same order): the last is the
                                                       ///< direction of least spread (a plane's normal)
};

/// Of the 3xN matrix of centred points, through the 3x3 scatter matrix (the same values as an SVD of the points to
/// ~1e-8 of the largest; Eigen's JacobiSVD of a 3xN matrix costs 30 s of compile time per file).
inline PrincipalAxes principalAxes(const Eigen::Matrix3Xd& centred) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  PrincipalAxes p;
  for (int i = 0; i < 3; ++i) {  // the solver sorts ascending
    p.spread(i) = std::sqrt(std::max(0.0, eig.eigenvalues()(2 - i)));
    p.axes.col(i) = eig.eigenvectors().col(2 - i);
  }
  return p;
}

}  // namespace massage_cell::camera
