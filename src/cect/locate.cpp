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

/// The pair not published: every point keeps its placement and 3D point but is not valid, for `why`.
void refuse(LocatedAcupoints* out, const std::string& why) {
  out->valid = false;
  out->reason = why;
  for (LocatedAcupoint& p : out->points) {
    p.valid = false;
    p.reason = why;
  }
}

/// A valid pair whose points are yet to be placed.
LocatedAcupoints validPair(const AcupointModel& model) {
  LocatedAcupoints out = unplaced(model, "not placed by the acupoint model");
  out.valid = true;
  out.reason.clear();
  return out;
}

/// The model's placement of `name`, or null.
const AcupointPixel* placementOf(const std::vector<AcupointPixel>& placed, const std::string& name) {
  const auto it = std::find_if(placed.begin(), placed.end(), [&](const AcupointPixel& a) { return a.name == name; });
  return it == placed.end() ? nullptr : &*it;
}

/// The skin markers of the frame's kit in its rectified pair, searched on its segmented back.
SkinMarkers findSkinMarkers(const CectFrame& frame) {
  const std::optional<SkinMarkerOptions>& kit = frame.params().skin_markers;
  if (!kit || !frame.valid()) return {};
  return detectSkinMarkers(frame.leftRectified(), frame.rightRectified(), frame.left().mask, frame.disparityRange(),
                           *kit, frameScale(frame));
}

/// Whether `given` holds `name`.
bool gives(const std::vector<GivenLandmark>& given, const std::string& name) {
  return std::any_of(given.begin(), given.end(), [&](const GivenLandmark& g) { return g.name == name; });
}

/// The given landmarks: `options.given`, then each marker found whose landmark it does not have, or has stale (a
/// marker seen again where the subject lies now).
std::vector<GivenLandmark> givenWithMarkers(const LocateOptions& options, const SkinMarkers& markers) {
  std::vector<GivenLandmark> given = options.given;
  for (const SkinMarkerDetection& m : markers.found) {
    given.erase(std::remove_if(given.begin(), given.end(),
                               [&](const GivenLandmark& g) { return g.name == m.landmark && !g.stale.empty(); }),
                given.end());
    if (!gives(given, m.landmark)) given.push_back({m.landmark, m.left, LandmarkSource::kGivenMarker});
  }
  return given;
}

/// The given landmarks put into `landmarks`; false, with `refused` naming the problem, when they cannot be.
bool putGiven(BackLandmarks* landmarks, const AcupointModel& model, const std::vector<GivenLandmark>& given,
              const PointLookup& points, LocatedAcupoints* refused) {
  const std::string problem = applyGivenLandmarks(landmarks, given, points);
  if (problem.empty()) return true;
  *refused = unplaced(model, "given landmarks not usable: " + problem);
  refused->landmarks = std::move(*landmarks);
  return false;
}

/// The layout's plausibility into `out` (refused when it fails and the options check it), and its landmarks.
void checkAndKeep(LocatedAcupoints* out, BackLandmarks&& landmarks, const AcupointModel& model, const PixelScale& scale,
                  const LocateOptions& options) {
  out->check = checkLayout(landmarks, model, scale, options.trust);
  if (options.check_layout && !out->check.trusted) refuse(out, out->check.reason());
  out->landmarks = std::move(landmarks);
}

}  // namespace

LocatedAcupoints locateAcupoints(const CectFrame& frame, const AcupointModel& model, const LocateOptions& options) {
  if (!frame.valid()) return unplaced(model, "no usable view of the back: " + frame.reason());
  SkinMarkers markers = findSkinMarkers(frame);
  const std::vector<GivenLandmark> given = givenWithMarkers(options, markers);
  BackLandmarks landmarks = findLandmarks(frame.left(), model, gives(given, "L4"));
  if (!landmarks.valid) {
    LocatedAcupoints none = unplaced(model, "no landmarks of the back: " + landmarks.reason);
    none.markers = std::move(markers);
    return none;
  }

  const PointLookup points = framePoints(frame);
  if (options.correct_parallax) correctMidlineParallax(&landmarks, frame.left(), points);
  if (options.levels_in_3d) correctWaistParallax(&landmarks, model, frame.left(), points);
  if (LocatedAcupoints refused; !putGiven(&landmarks, model, given, points, &refused)) {
    refused.markers = std::move(markers);
    return refused;
  }
  if (options.levels_in_3d) measureLevelsIn3D(&landmarks, points);
  const PixelScale scale = frameScale(frame);
  const std::vector<AcupointPixel> placed = placeAcupoints(landmarks, model, scale);

  LocatedAcupoints out = validPair(model);
  for (LocatedAcupoint& p : out.points) {
    const AcupointPixel* it = placementOf(placed, p.name);
    if (!it) continue;
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
  checkAndKeep(&out, std::move(landmarks), model, scale, options);
  out.markers = std::move(markers);
  return out;
}

LocatedAcupoints locateLayout(const Segmentation& view, const AcupointModel& model, const LocateOptions& options) {
  BackLandmarks landmarks = findLandmarks(view, model, gives(options.given, "L4"));
  if (!landmarks.valid) return unplaced(model, "no landmarks of the back: " + landmarks.reason);
  if (LocatedAcupoints refused; !putGiven(&landmarks, model, options.given, PointLookup(), &refused)) return refused;
  // One scale for the whole image: placeAcupoints takes the cun as cun_per_shoulder_width x shoulder width (px) x
  // scale and converts it back to pixels with the same scale, so any constant gives lateral offsets of
  // lateral_cun x cun_per_shoulder_width x shoulder width pixels.
  const PixelScale one_metre_per_pixel = [](const cv::Point2f&) { return 1.0; };
  const std::vector<AcupointPixel> placed = placeAcupoints(landmarks, model, one_metre_per_pixel);
  LocatedAcupoints out = validPair(model);
  for (LocatedAcupoint& p : out.points) {
    const AcupointPixel* it = placementOf(placed, p.name);
    if (!it) continue;
    p.placed = it->valid;
    p.valid = it->valid;
    p.rectified = p.raw = it->pixel;
    p.reason = it->valid ? std::string() : "not placed: " + it->reason;
  }
  checkAndKeep(&out, std::move(landmarks), model, PixelScale(), options);  // no scale: the proportions only
  return out;
}

}  // namespace massage_cell::cect
