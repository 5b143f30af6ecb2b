// AcupointTracker, localizePixels, drawAcupoints (see tracker.h).
#include "massage_cell/cect/tracker.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

/// Why a measured point was not taken: the distance to the estimate it contradicts.
std::string rejection(const LocatedAcupoint& p, const FilteredPoint* estimate) {
  std::ostringstream why;
  why << "measurement rejected as an outlier";
  if (estimate) why << " (" << (p.point.position - estimate->position).norm() * 100.0 << " cm from the estimate)";
  return why.str();
}

}  // namespace

AcupointTracker::AcupointTracker(AcupointModel model) : model_(std::move(model)) {
  model_.validate();
  if (model_.points.empty()) throw std::invalid_argument("the acupoint model has no acupoints");
  last_.points.resize(model_.points.size());
  for (std::size_t i = 0; i < model_.points.size(); ++i) {
    last_.points[i].name = model_.points[i].name;
    last_.points[i].region = model_.points[i].region;
    last_.points[i].reason = "no stereo pair analysed yet";
  }
}

void AcupointTracker::setParams(const TemporalFilterParams& params) {
  filter_.setParams(params);  // throws for bad ones, keeping the previous
  params_ = params;
}

const TrackerUpdate& AcupointTracker::update(const LocatedAcupoints& located, double stamp,
                                             const camera::Decimation& decimation) {
  TrackerUpdate u;
  if (any_ && stamp < last_stamp_) {  // a replay starting over sends the clock back: the estimates belong elsewhere
    filter_.clear();
    layout_covariance_.clear();
    u.reset = true;
  }
  any_ = true;
  last_stamp_ = stamp;
  u.problem = located.valid ? std::string() : located.reason;
  if (located.landmarks.valid) {  // a refused layout's too: the landmarks say what it was built on
    u.landmarks = describeLandmarks(located.landmarks);
    for (const std::string& note : located.check.notes) u.landmarks += "; noted: " + note;
    u.body_angle_deg = located.landmarks.body_angle_deg;
  }
  if (!located.valid && u.problem.empty()) u.problem = "no acupoints located";
  u.points.resize(model_.points.size());
  for (std::size_t i = 0; i < u.points.size(); ++i) {
    TrackedAcupoint& t = u.points[i];
    t.name = model_.points[i].name;
    t.region = model_.points[i].region;
    t.stamp = stamp;
    if (i < located.points.size()) {
      // 1. This pair's measurement into the filter.
      const LocatedAcupoint& p = located.points[i];
      t.placed = p.placed;
      t.rectified = p.rectified;
      t.raw = decimation.toFull(p.raw);
      t.reason = p.reason;
      if (p.valid) {
        t.measured = true;
        ++u.measured;
        t.accepted = filter_.update(p.name, p.point.position, p.point.covariance, stamp);
        if (t.accepted) layout_covariance_[p.name] = p.layout_covariance;
        if (!t.accepted) t.reason = rejection(p, filter_.get(p.name, stamp));
      }
    }
    if (!u.problem.empty()) t.reason = u.problem;
    // 2. The estimate that stands after it.
    const FilteredPoint* f = u.problem.empty() ? filter_.get(t.name, stamp) : nullptr;
    if (!f) {
      if (t.reason.empty()) t.reason = "no current estimate";
      continue;
    }
    t.valid = true;
    ++u.valid;
    const auto layout = layout_covariance_.find(t.name);
    t.position = f->position;
    t.covariance = f->covariance + (layout != layout_covariance_.end() ? layout->second : Eigen::Matrix3d::Zero());
    if (t.accepted) {
      t.reason.clear();
    } else {  // held from earlier pairs: say why this one did not measure it
      std::ostringstream why;
      why << t.reason << "; estimate from " << stamp - f->stamp << " s before";
      t.reason = why.str();
    }
  }
  last_ = std::move(u);
  return last_;
}

TrackedAcupoint AcupointTracker::estimate(const std::string& name, double now) const {
  TrackedAcupoint out;
  out.name = name;
  const auto it =
      std::find_if(last_.points.begin(), last_.points.end(), [&](const TrackedAcupoint& p) { return p.name == name; });
  if (it == last_.points.end()) {
    out.reason = "unknown acupoint '" + name + "' (known: " + joined(model_.names()) + ")";
    return out;
  }
  if (!it->valid) {
    out = *it;
    out.reason = "no valid estimate of " + name + ": " + it->reason;
    return out;
  }
  const double age = now - it->stamp;
  if (age > params_.max_age) {
    out = *it;
    out.valid = false;
    std::ostringstream m;
    m << "the estimate of " << name << " is " << age << " s old (max_age " << params_.max_age
      << " s): no usable stereo pair since";
    out.reason = m.str();
    return out;
  }
  return *it;
}

PixelPoints localizePixels(const CectFrame* frame, const camera::Decimation& decimation,
                           const std::vector<cv::Point2d>& raw_pixels) {
  PixelPoints out;
  out.points.resize(raw_pixels.size());
  if (frame == nullptr || !frame->valid()) {
    out.message = frame == nullptr ? "no stereo pair analysed yet"
                                   : "the latest pair has no usable view of the back: " + frame->reason();
    for (auto& p : out.points) p.reason = out.message;
    return out;
  }
  int valid = 0;
  for (std::size_t i = 0; i < raw_pixels.size(); ++i) {
    const cv::Point2d& pixel = raw_pixels[i];
    PixelPoint& p = out.points[i];
    if (!std::isfinite(pixel.x) || !std::isfinite(pixel.y)) {
      p.reason = "the pixel is not finite";
      continue;
    }
    LocalizedPoint l;
    try {
      l = frame->localize(
          decimation.toDecimated(cv::Point2f(static_cast<float>(pixel.x), static_cast<float>(pixel.y))));
    } catch (const std::exception& e) {
      p.reason = std::string("localisation failed: ") + e.what();
      continue;
    }
    if (!l.valid) {
      p.reason = l.reason.empty() ? "not localised" : l.reason;
      continue;
    }
    p.valid = true;
    p.position = l.position;
    p.covariance = l.covariance;
    ++valid;
  }
  out.success = true;
  out.message = std::to_string(valid) + " of " + std::to_string(raw_pixels.size()) + " pixels localised";
  return out;
}

int debugImageScale(int cols, int min_width) { return cols > 0 ? std::max(1, (min_width + cols - 1) / cols) : 1; }

cv::Mat drawAcupoints(const CectFrame& frame, const std::vector<TrackedAcupoint>& points, int min_width,
                      const std::vector<LayoutLandmark>& landmarks) {
  cv::Mat image;
  try {
    image = frame.drawDebug();
  } catch (const std::exception&) {  // the analysis' own drawing failed: the plain left view
  }
  if (image.empty()) image = frame.leftRectified().clone();
  if (image.empty()) return image;
  if (image.type() == CV_8UC1) cv::cvtColor(image, image, cv::COLOR_GRAY2BGR);
  if (image.type() != CV_8UC3) return cv::Mat();
  const int scale = debugImageScale(image.cols, min_width);
  if (scale > 1) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_NEAREST);
  for (const TrackedAcupoint& p : points) {
    if (!p.placed) continue;
    const cv::Point centre(cvRound((p.rectified.x + 0.5) * scale - 0.5), cvRound((p.rectified.y + 0.5) * scale - 0.5));
    const cv::Scalar colour = p.accepted   ? cv::Scalar(0, 255, 255)
                              : p.measured ? cv::Scalar(0, 0, 255)
                                           : cv::Scalar(160, 160, 160);
    cv::circle(image, centre, 3, colour, p.accepted ? cv::FILLED : 1, cv::LINE_AA);
    cv::putText(image, p.name, centre + cv::Point(4, -2), cv::FONT_HERSHEY_PLAIN, 0.7, colour, 1, cv::LINE_AA);
  }
  for (const LayoutLandmark& l : landmarks) {
    const cv::Point centre(cvRound((l.pixel.x + 0.5) * scale - 0.5), cvRound((l.pixel.y + 0.5) * scale - 0.5));
    const cv::Scalar colour = l.landmark.given()                               ? cv::Scalar(255, 0, 255)
                              : l.landmark.source == LandmarkSource::kMeasured ? cv::Scalar(255, 255, 0)
                                                                               : cv::Scalar(160, 160, 160);
    cv::drawMarker(image, centre, colour, cv::MARKER_CROSS, 14, 2, cv::LINE_AA);
    // Named to the left of the cross: the midline's acupoints (GV) are named to their right.
    const std::string text = describeLandmark(l);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_PLAIN, 0.8, 1, &baseline);
    cv::putText(image, text, centre + cv::Point(-10 - size.width, size.height / 2), cv::FONT_HERSHEY_PLAIN, 0.8, colour,
                1, cv::LINE_AA);
  }
  return image;
}

}  // namespace massage_cell::cect
