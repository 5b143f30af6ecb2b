// The hbds node's dynamic_reconfigure configuration (cfg/HBDS.cfg) as the library's parameters: the one place the
// cfg's names meet stereo::StereoParams, with the checks a configuration must pass before the node takes it.
#pragma once

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "massage_cell/HBDSConfig.h"
#include "massage_cell/stereo/pipeline.h"

namespace massage_cell::nodes {

/// The library's parameters of a configuration (the disparity range is set per pair, from the processed images).
/// Throws std::invalid_argument for an unknown cost, refine or subpixel name.
inline stereo::StereoParams stereoParams(const HBDSConfig& config) {
  std::string refine = config.refine;  // cfg values use '_' where the library uses '-'
  std::replace(refine.begin(), refine.end(), '_', '-');
  stereo::StereoParams params;
  params.cost.data_term = stereo::parseDataTerm(config.cost);
  params.cost.eta = static_cast<float>(config.eta);
  params.cost.ncc_window = config.ncc_window;
  params.cost.gradient_saturation = static_cast<float>(config.gradient_saturation);
  params.smooth.tau = static_cast<float>(config.tau);
  params.smooth.u_min = static_cast<float>(config.u_min);
  params.smooth.u_max = static_cast<float>(config.u_max);
  params.threads = config.threads;
  params.polish_window = config.polish_window;
  params.polish_coarse = config.polish_coarse;
  params.hbds_overlap = config.overlap;
  params.hbds_coarse = config.coarse;
  params.refine = stereo::parseRefinement(refine);
  params.refine_params.window = config.refine_window;
  params.subpixel = config.subpixel != "none";
  if (params.subpixel) params.subpixel_params.fit = stereo::parseSubpixelFit(config.subpixel);
  params.lr_check = config.lr_check;
  params.lr_tolerance = static_cast<float>(config.lr_tolerance);
  return params;
}

/// What the library or the node refuses in a configuration (what cfg/HBDS.cfg's ranges cannot rule out), each
/// naming the parameter; empty: usable.
inline std::vector<std::string> configProblems(const HBDSConfig& config) {
  std::vector<std::string> problems;
  if (config.method != "hbds" && config.method != "sgbm" && config.method != "wta") {  // (the others take minutes)
    problems.push_back("method '" + config.method + "' (hbds, sgbm or wta)");
  }
  if (config.downsample != 1 && config.downsample != 2 && config.downsample != 4) {
    problems.push_back("downsample = " + std::to_string(config.downsample) + " (1, 2 or 4)");
  }
  try {
    for (const stereo::ParamProblem& p : stereo::checkParams(stereoParams(config))) {
      problems.push_back(p.name + " " + p.problem);
    }
  } catch (const std::invalid_argument& e) {  // an unknown cost, refine or subpixel name
    problems.push_back(e.what());
  }
  return problems;
}

/// One line naming every parameter, for the log.
inline std::string describe(const HBDSConfig& c) {
  std::ostringstream s;
  s << "method " << c.method << ", disparities " << c.min_disparity << ".." << c.min_disparity + c.disparity_range - 1
    << ", cost " << c.cost << ", eta " << c.eta << ", ncc_window " << c.ncc_window << ", gradient_saturation "
    << c.gradient_saturation << ", tau " << c.tau << ", u " << c.u_min << ".." << c.u_max << ", overlap " << c.overlap
    << ", coarse " << c.coarse << ", polish_window " << c.polish_window << ", polish_coarse " << c.polish_coarse
    << ", refine " << c.refine << ", subpixel " << c.subpixel << ", lr_check " << (c.lr_check ? "on" : "off")
    << " (tolerance " << c.lr_tolerance << ", fill " << (c.lr_fill ? "on" : "off") << "), threads " << c.threads
    << ", downsample " << c.downsample;
  return s.str();
}

}  // namespace massage_cell::nodes
