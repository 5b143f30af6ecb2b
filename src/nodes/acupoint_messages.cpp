#include "acupoint_messages.h"

#include "tf_lookup.h"

#include <limits>

#include <std_msgs/ColorRGBA.h>

namespace massage_cell::nodes {

namespace {

constexpr double kMarkerLifetime = 1.0;  // s

/// Marker colour of a region (measured in this pair); held estimates are grey.
std_msgs::ColorRGBA regionColour(const std::string& region, bool measured) {
  std_msgs::ColorRGBA c;
  c.a = 1.0f;
  if (!measured) {
    c.r = c.g = c.b = 0.6f;
    c.a = 0.7f;
  } else if (region == "upper_back") {
    c.r = 1.0f, c.g = 0.55f, c.b = 0.0f;
  } else if (region == "lower_back") {
    c.r = 0.1f, c.g = 0.4f, c.b = 1.0f;
  } else if (region == "midline") {
    c.r = 0.1f, c.g = 0.85f, c.b = 0.2f;
  } else if (region == "shoulder") {
    c.r = 0.9f, c.g = 0.1f, c.b = 0.9f;
  } else {
    c.r = c.g = c.b = 1.0f;
  }
  return c;
}

}  // namespace

namespace {

geometry_msgs::Point toPoint(const Eigen::Vector3d& p) {
  geometry_msgs::Point out;
  out.x = p.x();
  out.y = p.y();
  out.z = p.z();
  return out;
}

}  // namespace

void toRowMajor(const Eigen::Matrix3d& m, double* out) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[3 * r + c] = m(r, c);
}

massage_cell::Acupoint acupointMsg(const cect::TrackedAcupoint& p) {
  massage_cell::Acupoint a;
  a.name = p.name;
  a.region = p.region;
  a.u = p.placed ? p.raw.x : std::numeric_limits<float>::quiet_NaN();
  a.v = p.placed ? p.raw.y : std::numeric_limits<float>::quiet_NaN();
  a.valid = p.valid;
  a.reason = p.reason;
  if (p.valid) {
    a.position = toPoint(p.position);
    toRowMajor(p.covariance, a.covariance.data());
  }
  return a;
}

std::vector<massage_cell::BackLandmark> landmarkMsgs(const cect::BackLandmarks& landmarks,
                                                     const camera::StereoModel& geometry,
                                                     const camera::Decimation& decimation) {
  std::vector<massage_cell::BackLandmark> out;
  for (const cect::LayoutLandmark& l : cect::layoutLandmarks(landmarks)) {
    massage_cell::BackLandmark m;
    m.name = l.landmark.level;
    m.source = cect::sourceName(l.landmark.source);
    m.detail = cect::landmarkDetail(l.landmark);
    const cv::Point2f raw = cect::cameraPixel(l.pixel, geometry, decimation);
    m.u = raw.x;
    m.v = raw.y;
    out.push_back(m);
  }
  return out;
}

geometry_msgs::TransformStamped acupointTransform(const std_msgs::Header& header, const std::string& prefix,
                                                  const cect::TrackedAcupoint& p) {
  geometry_msgs::TransformStamped t;
  t.header = header;
  t.child_frame_id = prefix + p.name;
  t.transform.translation.x = p.position.x();
  t.transform.translation.y = p.position.y();
  t.transform.translation.z = p.position.z();
  t.transform.rotation.w = 1.0;
  return t;
}

void fillResponse(const std::string& name, const cect::TrackedAcupoint& estimate, const std_msgs::Header& header,
                  const std::string& target, const tf2_ros::Buffer& tf, double wall_wait,
                  massage_cell::GetAcupoint::Response* response) {
  response->success = false;
  if (!estimate.valid) {
    response->message = estimate.reason;
    return;
  }
  toRowMajor(estimate.covariance, response->covariance.data());
  geometry_msgs::PointStamped point;
  point.header = header;
  point.point = toPoint(estimate.position);
  if (target.empty() || target == header.frame_id) {
    response->point = point;
    response->success = true;
    response->message = "in " + header.frame_id;
    return;
  }
  std::string message;
  response->success = transformPoint(tf, point, target, wall_wait, &response->point, &message);
  response->message = response->success ? message : "cannot express " + name + " in '" + target + "': " + message;
}

void fillResponse(const std_msgs::Header& header, const cect::PixelPoints& located,
                  massage_cell::LocalizePixels::Response* response) {
  const std::size_t n = located.points.size();
  response->header = header;
  response->success = located.success;
  response->message = located.message;
  response->points.assign(n, geometry_msgs::Point());
  response->covariances.assign(9 * n, 0.0);
  response->valid.assign(n, false);
  response->reasons.assign(n, "");
  for (std::size_t i = 0; i < n; ++i) {
    const cect::PixelPoint& p = located.points[i];
    response->valid[i] = p.valid;
    response->reasons[i] = p.reason;
    if (!p.valid) continue;
    response->points[i] = toPoint(p.position);
    toRowMajor(p.covariance, &response->covariances[9 * i]);
  }
}

void addAcupointMarkers(const std_msgs::Header& header, int index, const cect::TrackedAcupoint& p,
                        visualization_msgs::MarkerArray* markers) {
  visualization_msgs::Marker sphere;
  sphere.header = header;
  sphere.ns = "acupoints";
  sphere.id = 2 * index;
  sphere.lifetime = ros::Duration(kMarkerLifetime);
  visualization_msgs::Marker text = sphere;
  text.id = sphere.id + 1;
  if (!p.valid) {
    sphere.action = text.action = visualization_msgs::Marker::DELETE;
  } else {
    sphere.type = visualization_msgs::Marker::SPHERE;
    sphere.action = visualization_msgs::Marker::ADD;
    sphere.pose.position.x = p.position.x();
    sphere.pose.position.y = p.position.y();
    sphere.pose.position.z = p.position.z();
    sphere.pose.orientation.w = 1.0;
    sphere.scale.x = sphere.scale.y = sphere.scale.z = 0.012;
    sphere.color = regionColour(p.region, p.accepted);
    text.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    text.action = visualization_msgs::Marker::ADD;
    text.pose = sphere.pose;
    text.pose.position.z -= 0.015;  // toward the camera (optical z looks at the back)
    text.scale.z = 0.01;
    text.color = sphere.color;
    text.text = p.name;
  }
  markers->markers.push_back(sphere);
  markers->markers.push_back(text);
}

}  // namespace massage_cell::nodes
