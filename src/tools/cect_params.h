// The CECT parameters the tools' --param option sets, by their CectParams
// names (cect_eval, cect_locate).
#pragma once

#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "massage_cell/cect/cect.h"

namespace massage_cell::tools {

/// The CectParams fields --param can set.
inline const std::map<std::string, std::function<void(cect::CectParams&, double)>>& paramSetters() {
  using P = cect::CectParams;
  static const std::map<std::string, std::function<void(P&, double)>> m{
      {"auto_scale", [](P& p, double v) { p.auto_scale = v != 0.0; }},
      {"min_depth", [](P& p, double v) { p.min_depth = v; }},
      {"max_depth", [](P& p, double v) { p.max_depth = v; }},
      {"min_disparity", [](P& p, double v) { p.min_disparity = v; }},
      {"max_disparity", [](P& p, double v) { p.max_disparity = v; }},
      {"background_gap", [](P& p, double v) { p.background.gap = v; }},
      {"table_margin", [](P& p, double v) { p.background.table_margin = v; }},
      {"min_crossing_angle", [](P& p, double v) { p.min_crossing_angle = v; }},
      {"sample_spacing", [](P& p, double v) { p.sample_spacing = v; }},
      {"seed_step", [](P& p, double v) { p.seed_step = static_cast<int>(v); }},
      {"seed_column_step", [](P& p, double v) { p.seed_column_step = static_cast<int>(v); }},
      {"ncc_radius", [](P& p, double v) { p.ncc_radius = static_cast<int>(v); }},
      {"ncc_half_height", [](P& p, double v) { p.ncc_half_height = static_cast<int>(v); }},
      {"bandpass_low", [](P& p, double v) { p.bandpass_low = v; }},
      {"bandpass_high", [](P& p, double v) { p.bandpass_high = v; }},
      {"seed_margin", [](P& p, double v) { p.seed_margin = v; }},
      {"direct_min_sharpness", [](P& p, double v) { p.direct_min_sharpness = v; }},
      {"seed_search", [](P& p, double v) { p.seed_search = v; }},
      {"max_relief", [](P& p, double v) { p.max_relief = v; }},
      {"smooth_radius", [](P& p, double v) { p.smooth_radius = v; }},
      {"quartic_across", [](P& p, double v) { p.quartic_across = v != 0.0; }},
      {"rim_profile", [](P& p, double v) { p.rim_profile = v != 0.0; }},
      {"slanted_windows", [](P& p, double v) { p.slanted_windows = v != 0.0; }},
      {"min_slant", [](P& p, double v) { p.min_slant = v; }},
      {"edge_window", [](P& p, double v) { p.edge_window = v; }},
      {"max_triangle_edge", [](P& p, double v) { p.max_triangle_edge = v; }},
      {"edge_min_bend", [](P& p, double v) { p.edge_min_bend = v; }},
      {"sheen_sigma", [](P& p, double v) { p.sheen_sigma = v; }},
      {"sheen_twicing", [](P& p, double v) { p.sheen_twicing = v != 0.0; }},
      {"max_extrapolation", [](P& p, double v) { p.max_extrapolation = v; }},
      {"query_search", [](P& p, double v) { p.query_search = v; }},
      {"min_ncc", [](P& p, double v) { p.min_ncc = v; }},
      {"max_candidate_spread", [](P& p, double v) { p.max_candidate_spread = v; }},
      {"continuity_margin", [](P& p, double v) { p.continuity_margin = v; }},
      {"lr_tolerance", [](P& p, double v) { p.lr_tolerance = v; }},
      {"pixel_sigma", [](P& p, double v) { p.pixel_sigma = v; }},
      {"border_sigma", [](P& p, double v) { p.border_sigma = v; }},
      {"border_sigma_reach", [](P& p, double v) { p.border_sigma_reach = v; }},
      {"slope_sigma", [](P& p, double v) { p.slope_sigma = v; }},
      {"reject_cloth", [](P& p, double v) { p.segmentation.trunk.reject_cloth = v != 0.0; }},
      {"cloth_contrast", [](P& p, double v) { p.segmentation.trunk.cloth_contrast = v; }},
      {"separate_arms", [](P& p, double v) { p.segmentation.trunk.separate_arms = v != 0.0; }},
      {"crease_strength", [](P& p, double v) { p.segmentation.trunk.crease_strength = v; }},
      {"min_arm_fraction", [](P& p, double v) { p.segmentation.trunk.min_arm_fraction = v; }},
  };
  return m;
}

/// `params` with each --param NAME=VALUE set, then checked (cect::checkParams): throws std::invalid_argument
/// naming the first problem.
inline void applyParams(cect::CectParams& params, const std::vector<std::pair<std::string, double>>& values) {
  for (const auto& [name, value] : values) paramSetters().at(name)(params, value);
  const std::vector<std::string> problems = cect::checkParams(params);
  if (!problems.empty()) throw std::invalid_argument("CECT parameters: " + problems.front());
}

}  // namespace massage_cell::tools
