// The reconstruction pipeline (see reconstruct.h).
#include "massage_cell/planar/reconstruct.h"

#include <chrono>
#include <stdexcept>

#include <opencv2/core/utility.hpp>

namespace massage_cell::planar {

namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

void ReconstructParams::validate() const {
  features.validate();
  half_planes.validate();
  extension.validate();
  delineation.validate();
}

HalfPlaneMethod halfPlaneMethod(const std::string& name) {
  if (name == "points") return HalfPlaneMethod::kFeaturePoints;
  if (name == "sweep") return HalfPlaneMethod::kSweep;
  throw std::invalid_argument("unknown half-plane method '" + name + "' (expected points or sweep)");
}

const char* halfPlaneMethodName(HalfPlaneMethod method) {
  return method == HalfPlaneMethod::kSweep ? "sweep" : "points";
}

Reconstruction reconstruct(const std::vector<View>& views, const ReconstructParams& params) {
  validateViews(views);
  params.validate();
  Reconstruction r;
  auto t0 = std::chrono::steady_clock::now();
  r.features.resize(views.size());
  cv::parallel_for_(cv::Range(0, static_cast<int>(views.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      r.features[static_cast<std::size_t>(i)] = detectFeatures(views[static_cast<std::size_t>(i)], params.features);
    }
  });
  r.times.features = secondsSince(t0);

  t0 = std::chrono::steady_clock::now();
  r.points = matchPoints(views, r.features, params.features);
  r.lines = matchLines(views, r.features, params.features);
  r.times.matching = secondsSince(t0);

  const HalfPlaneSearch search(views, r.points, r.lines, params.half_planes);
  r.half_planes =
      params.method == HalfPlaneMethod::kSweep ? search.bySweep(&r.search) : search.byFeaturePoints(&r.search);
  r.times.half_planes = r.search.seconds;

  r.model = extendAndMerge(views, r.points, r.lines, r.half_planes, params.extension, &r.extension);
  r.times.extension = r.extension.seconds;
  r.model = delineate(views, r.points, r.model, params.delineation, &r.delineation);
  r.times.delineation = r.delineation.seconds;
  return r;
}

}  // namespace massage_cell::planar
