// The cect node's dynamic_reconfigure configuration (cfg/CECT.cfg) as the library's parameters: the one place the
// cfg's names meet cect::CectParams, cect::LocateOptions and cect::TemporalFilterParams.
#pragma once

#include <sstream>
#include <string>

#include "massage_cell/CECTConfig.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/cect/temporal_filter.h"

namespace massage_cell::nodes {

inline cect::CectParams cectParams(const CECTConfig& c) {
  cect::CectParams p;
  p.auto_scale = c.auto_scale;
  p.sample_spacing = c.sample_spacing;
  p.min_depth = c.min_depth;
  p.max_depth = c.max_depth;
  p.background.gap = c.background_gap;
  p.background.table_margin = c.table_margin;
  p.min_disparity = c.min_disparity;
  p.max_disparity = c.max_disparity;
  p.min_crossing_angle = c.min_crossing_angle;
  p.edge_window = c.edge_window;
  p.edge_min_bend = c.edge_min_bend;
  p.seed_step = c.seed_step;
  p.seed_column_step = c.seed_column_step;
  p.ncc_radius = c.ncc_radius;
  p.bandpass_low = c.bandpass_low;
  p.bandpass_high = c.bandpass_high;
  p.sheen_sigma = c.sheen_sigma;
  p.sheen_twicing = c.sheen_twicing;
  p.smooth_radius = c.smooth_radius;
  p.quartic_across = c.quartic_across;
  p.rim_profile = c.rim_profile;
  p.slanted_windows = c.slanted_windows;
  p.min_slant = c.min_slant;
  p.max_extrapolation = c.max_extrapolation;
  p.max_triangle_edge = c.max_triangle_edge;
  p.direct_min_sharpness = c.direct_min_sharpness;
  p.seed_search = c.seed_search;
  p.query_search = c.query_search;
  p.min_ncc = c.min_ncc;
  p.max_candidate_spread = c.max_candidate_spread;
  p.continuity_margin = c.continuity_margin;
  p.lr_tolerance = c.lr_tolerance;
  p.pixel_sigma = c.pixel_sigma;
  p.border_sigma = c.border_sigma;
  p.border_sigma_reach = c.border_sigma_reach;
  p.slope_sigma = c.slope_sigma;
  return p;
}

/// The acupoint chain's options of the configuration (the given landmarks come from the node's set of them).
inline cect::LocateOptions locateOptions(const CECTConfig& c) {
  cect::LocateOptions o;
  o.correct_parallax = c.correct_parallax;
  o.levels_in_3d = c.levels_in_3d;
  o.trust.c7_at_neck = c.require_c7_at_neck;
  o.trust.l4_measured = c.require_l4_measured;
  return o;
}

inline cect::TemporalFilterParams filterParams(const CECTConfig& c) {
  cect::TemporalFilterParams p;
  p.alpha = c.alpha;
  p.gate = c.gate;
  p.reacquire_after = c.reacquire_after;
  p.max_age = c.max_age;
  return p;
}

/// The parameters a user tunes most, in one line for the log.
inline std::string describe(const CECTConfig& c) {
  auto bound = [](double px, const char* otherwise) {
    std::ostringstream s;
    if (px > 0)
      s << px;
    else
      s << otherwise;
    return s.str();
  };
  std::ostringstream s;
  s << "seed_step " << c.seed_step << ", ncc_radius " << c.ncc_radius << ", seed_search " << c.seed_search
    << ", query_search " << c.query_search << ", min_ncc " << c.min_ncc << ", depths " << c.min_depth << ".."
    << c.max_depth << " m, disparities " << bound(c.min_disparity, "from max_depth") << ".."
    << bound(c.max_disparity, "from min_depth") << ", filter alpha " << c.alpha << " gate " << c.gate
    << " m reacquire_after " << c.reacquire_after << " max_age " << c.max_age << " s";
  return s.str();
}

}  // namespace massage_cell::nodes
