// Ground truth of named points in a rendered stereo frame (ground_truth.h).
#include "massage_cell/sim/ground_truth.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace massage_cell::sim {

namespace {

bool inside(const CameraModel& c, const Eigen::Vector2d& px) {
  return px.x() >= -0.5 && px.y() >= -0.5 && px.x() <= c.width - 0.5 && px.y() <= c.height - 0.5;
}

/// Which edge of the image a pixel outside it lies beyond (rows first: the
/// table's length runs along the image's columns).
std::string outsideReason(const CameraModel& c, const Eigen::Vector2d& px, const std::string& image) {
  if (px.y() < -0.5) return "above " + image + "'s top edge";
  if (px.y() > c.height - 0.5) return "below " + image + "'s bottom edge";
  if (px.x() < -0.5) return "beyond " + image + "'s left edge";
  return "beyond " + image + "'s right edge";
}

std::string coverReason(std::uint8_t label) {
  switch (label) {
    case kLabelTowel:
      return "under the towel";
    case kLabelArm:
      return "under an arm";
    case kLabelHair:
      return "under the hair";
    case kLabelBackground:
      return "nothing rendered at its pixel";
    default:
      return std::string("covered by the ") + labelName(label);
  }
}

/// Fills the left-image part of `t`; returns the reason it is not in view there (empty: fine so far).
std::string leftImageTruth(const CameraModel& left, const ViewRender& view, double tolerance, PointTruth& t) {
  Eigen::Vector2d px;
  if (!left.project(t.world, &px)) return "behind the left camera";
  t.left_pixel = px;
  if (!inside(left, px)) return outsideReason(left, px, "the image");
  const int u = std::clamp(static_cast<int>(std::lround(px.x())), 0, left.width - 1);
  const int v = std::clamp(static_cast<int>(std::lround(px.y())), 0, left.height - 1);
  t.left_label = view.labels.at<std::uint8_t>(v, u);
  const cv::Vec3f s = view.points.at<cv::Vec3f>(v, u);
  if (std::isfinite(s[0])) t.surface_distance = (Eigen::Vector3d(s[0], s[1], s[2]) - t.world).norm();
  if (t.left_label != kLabelBack) return coverReason(t.left_label);
  if (!(t.surface_distance <= tolerance)) return "hidden behind another part of the body";
  return {};
}

}  // namespace

std::map<std::string, PointTruth> acupointTruth(const std::map<std::string, Eigen::Vector3d>& world_points,
                                                const StereoPairModel& pair, const StereoFrame& frame,
                                                double tolerance) {
  if (!(tolerance > 0.0)) throw std::invalid_argument("acupointTruth: tolerance must be > 0");
  if (frame.left.labels.size() != cv::Size(pair.left.width, pair.left.height) || frame.left_visible.empty()) {
    throw std::invalid_argument("acupointTruth: the frame was not rendered from this pair");
  }
  const Eigen::Isometry3d left_from_world = pair.left.world_from_camera.inverse();
  std::map<std::string, PointTruth> out;
  for (const auto& [name, p] : world_points) {
    PointTruth t;
    t.world = p;
    t.left_optical = left_from_world * p;
    std::string reason = leftImageTruth(pair.left, frame.left, tolerance, t);
    Eigen::Vector2d rp;
    const bool in_front = pair.right.project(p, &rp);
    if (in_front) t.right_pixel = rp;
    if (reason.empty() && !in_front) reason = "behind the right camera";
    if (reason.empty() && !inside(pair.right, rp)) reason = outsideReason(pair.right, rp, "the right image");
    if (reason.empty()) {
      const int u = static_cast<int>(std::lround(t.left_pixel.x())),
                v = static_cast<int>(std::lround(t.left_pixel.y()));
      if (frame.left_visible.at<std::uint8_t>(std::clamp(v, 0, pair.left.height - 1),
                                              std::clamp(u, 0, pair.left.width - 1)) == 0) {
        reason = "hidden from the right camera";
      }
    }
    t.in_view = reason.empty();
    t.reason = reason;
    out.emplace(name, t);
  }
  return out;
}

}  // namespace massage_cell::sim
