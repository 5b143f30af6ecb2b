#include "massage_cell/cect/locate.h"

#include <algorithm>
#include <sstream>

namespace massage_cell::cect {

int LocatedAcupoints::validCount() const {
  return static_cast<int>(
      std::count_if(points.begin(), points.end(), [](const LocatedAcupoint& p) { return p.valid; }));
}

namespace {

/// Every point of the model, not placed, with `why`.
LocatedAcupoints unplaced(const AcupointModel& model, const std::string& why) {
  LocatedAcupoints out;
  out.reason = why;
  for (const AcupointSpec& spec : model.points) {
    LocatedAcupoint p;
    p.name = spec.name;
    p.region = spec.region;
    p.reason = why;
    out.points.push_back(std::move(p));
  }
  return out;
}

}  // namespace

LocatedAcupoints locateAcupoints(const CectFrame& frame, const AcupointModel& model, const LocateOptions& options) {
  if (!frame.valid()) return unplaced(model, "no usable view of the back: " + frame.reason());
  BackLandmarks landmarks = findLandmarks(frame.left(), model);
  if (!landmarks.valid) return unplaced(model, "no landmarks of the back: " + landmarks.reason);

  const PointLookup points = framePoints(frame);
  if (options.correct_parallax) correctMidlineParallax(&landmarks, frame.left(), points);
  if (options.levels_in_3d) {
    correctWaistParallax(&landmarks, model, frame.left(), points);
    measureLevelsIn3D(&landmarks, points);
  }
  const PixelScale scale = frameScale(frame);
  const std::vector<AcupointPixel> placed = placeAcupoints(landmarks, model, scale);

  LocatedAcupoints out = unplaced(model, "not placed by the acupoint model");
  out.valid = true;
  out.reason.clear();
  for (LocatedAcupoint& p : out.points) {
    const auto it =
        std::find_if(placed.begin(), placed.end(), [&](const AcupointPixel& a) { return a.name == p.name; });
    if (it == placed.end()) continue;
    if (!it->valid) {
      p.reason = "not placed: " + it->reason;
      continue;
    }
    p.placed = true;
    p.rectified = it->pixel;
    p.raw = frame.geometry().toRaw(it->pixel);
    const cv::Size size = frame.geometry().size();
    if (!(p.raw.x >= -0.5f && p.raw.y >= -0.5f && p.raw.x <= size.width - 0.5f && p.raw.y <= size.height - 0.5f)) {
      // Rectification can bring in pixels the camera never saw (a strong distortion or rotation).
      std::ostringstream reason;
      reason << "not seen: its raw pixel (" << p.raw.x << ", " << p.raw.y << ") lies outside the " << size.width << "x"
             << size.height << " image";
      p.reason = reason.str();
      continue;
    }
    p.point = frame.localizeRectified(it->pixel);
    p.valid = p.point.valid;
    if (p.valid) {
      const AcupointSpec* spec = model.find(p.name);
      p.layout_covariance =
          layoutCovariance(landmarks, model, spec->level, p.point.position.z() / frame.geometry().fx());
      p.covariance = p.point.covariance + p.layout_covariance;
    }
    p.reason = p.valid ? std::string() : "not localised: " + p.point.reason;
  }
  out.landmarks = std::move(landmarks);
  return out;
}

}  // namespace massage_cell::cect
