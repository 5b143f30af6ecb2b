// cect::checkParams (see cect.h).
#include <cmath>
#include <string>
#include <vector>

#include "massage_cell/cect/cect.h"

namespace massage_cell::cect {

std::vector<std::string> checkParams(const CectParams& p) {
  std::vector<std::string> problems;
  auto require = [&](bool ok, const std::string& problem) {
    if (!ok) problems.push_back(problem);
  };
  auto positive = [&](double v, const char* name) {
    require(std::isfinite(v) && v > 0.0, std::string(name) + " must be > 0");
  };
  auto nonNegative = [&](double v, const char* name) {
    require(std::isfinite(v) && v >= 0.0, std::string(name) + " must be >= 0");
  };
  positive(p.min_depth, "min_depth");
  require(std::isfinite(p.max_depth) && p.max_depth > p.min_depth, "max_depth must be > min_depth");
  nonNegative(p.min_disparity, "min_disparity");
  require(std::isfinite(p.max_disparity) && (p.max_disparity == 0.0 || p.max_disparity > p.min_disparity),
          "max_disparity must be 0 (from min_depth) or > min_disparity");
  positive(p.sample_spacing, "sample_spacing");
  require(std::isfinite(p.min_crossing_angle) && p.min_crossing_angle >= 0.0 && p.min_crossing_angle < 90.0,
          "min_crossing_angle must be in 0..90 degrees");
  nonNegative(p.edge_window, "edge_window");
  nonNegative(p.max_triangle_edge, "max_triangle_edge");
  require(p.seed_step >= 0, "seed_step must be >= 0 (0: contour only)");
  require(p.seed_column_step >= 0, "seed_column_step must be >= 0 (0: seed_step)");
  require(p.ncc_radius >= 1, "ncc_radius must be >= 1");
  require(p.ncc_half_height >= 0, "ncc_half_height must be >= 0");
  nonNegative(p.bandpass_low, "bandpass_low");
  nonNegative(p.bandpass_high, "bandpass_high");
  nonNegative(p.sheen_sigma, "sheen_sigma");
  nonNegative(p.seed_search, "seed_search");
  nonNegative(p.query_search, "query_search");
  require(std::isfinite(p.min_ncc) && p.min_ncc >= -1.0 && p.min_ncc <= 1.0, "min_ncc must be in -1..1");
  nonNegative(p.max_candidate_spread, "max_candidate_spread");
  nonNegative(p.continuity_margin, "continuity_margin");
  nonNegative(p.lr_tolerance, "lr_tolerance");
  nonNegative(p.max_extrapolation, "max_extrapolation");
  positive(p.pixel_sigma, "pixel_sigma");
  nonNegative(p.border_sigma, "border_sigma");
  nonNegative(p.border_sigma_reach, "border_sigma_reach");
  nonNegative(p.slope_sigma, "slope_sigma");
  return problems;
}

}  // namespace massage_cell::cect
