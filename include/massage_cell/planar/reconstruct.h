// The whole piecewise-planar reconstruction of a set of calibrated views
// (thesis Ch. 4): features and line segments per view, point and line tracks,
// half-planes (the thesis's feature-point search or Baillard's sweep),
// extension, bounding, merging. ROS-free.
#pragma once

#include <string>
#include <vector>

#include "massage_cell/planar/delineate.h"
#include "massage_cell/planar/extend.h"
#include "massage_cell/planar/features.h"
#include "massage_cell/planar/half_plane.h"
#include "massage_cell/planar/model.h"
#include "massage_cell/planar/views.h"

namespace massage_cell::planar {

enum class HalfPlaneMethod { kFeaturePoints, kSweep };

struct ReconstructParams {
  FeatureParams features;
  HalfPlaneParams half_planes;
  ExtendParams extension;
  DelineateParams delineation;
  HalfPlaneMethod method = HalfPlaneMethod::kFeaturePoints;
  /// Throws std::invalid_argument naming the field for a bad value.
  void validate() const;
};

struct StageTimes {
  double features = 0.0, matching = 0.0, half_planes = 0.0, extension = 0.0, delineation = 0.0;  ///< seconds
  double total() const { return features + matching + half_planes + extension + delineation; }
};

struct Reconstruction {
  PlanarModel model;
  std::vector<ViewFeatures> features;
  std::vector<PointTrack> points;
  std::vector<LineTrack> lines;
  std::vector<HalfPlane> half_planes;
  SearchStats search;
  ExtendStats extension;
  DelineateStats delineation;
  StageTimes times;
};

/// Throws std::invalid_argument naming the problem for a bad view set (see
/// validateViews) or parameters; a set in which nothing planar is found is
/// not an error (an empty model, the counts say why).
Reconstruction reconstruct(const std::vector<View>& views, const ReconstructParams& params);

/// "points" / "sweep" <-> HalfPlaneMethod; throws std::invalid_argument for another name.
HalfPlaneMethod halfPlaneMethod(const std::string& name);
const char* halfPlaneMethodName(HalfPlaneMethod method);

}  // namespace massage_cell::planar
