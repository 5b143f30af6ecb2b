// Options shared by the stereo tools: the cost and smoothness parameters of
// massage_cell::stereo::StereoParams.
#pragma once
#include <algorithm>
#include <string>
#include <vector>

#include <cmath>

#include "cli.h"
#include "massage_cell/stereo/pipeline.h"

namespace massage_cell::tools {

/// The options' help, their defaults printed from stereo::StereoParams (the one place they are defined).
inline std::string stereoParamsHelp() {
  const stereo::StereoParams d;
  const auto on = [](bool b) { return b ? "on" : "off"; };
  std::string h;
  h += format(R"(  --cost C           data term: thesis (Eq. 2.6-2.8), census (Hamming distance of 9x7 census
                     strings) or ad-census (census + colour difference, Mei et al.) (default %s)
  --census-lambda L  ad-census: census distance (bits) where its term reaches 1 - 1/e (default %g)
  --ad-lambda L      ad-census: colour difference (grey levels) likewise (default %g)
  --eta E            colour-cost truncation, grey levels (default %g)
  --ncc-window N     NCC window side, odd (default %d)
  --gradient-saturation G  Sobel magnitude where the texture weight reaches 1 (default %g; 0: divide by the maximum)
)",
              stereo::toString(d.cost.data_term).c_str(), d.cost.census_lambda, d.cost.ad_lambda, d.cost.eta,
              d.cost.ncc_window, d.cost.gradient_saturation);
  h += format(R"(  --tau T            intensity difference where the smoothness weight reaches u_min (default %g)
  --u-min U          smoothness weight across edges (default %g)
  --u-max U          smoothness weight in uniform regions (default %g)
  --truncation T     truncate |dp - dq| at T in the energy (default %g; 0: none)
  --overlap M        hbds: each child's disparity set reaches M levels across the break
                     point (0: the thesis's disjoint split; default %d)
  --coarse C         hbds: cut large layers coarse to fine, first on C x C pixel blocks, then
                     at full resolution near the blocks' boundary (1: off; 2 or 4; default %d)
  --polish W         hbds: then local alpha-expansion moves over labels within W levels
                     of alpha, lowering the Eq. 2.2 energy (0: pure HBDS; default %d)
  --polish-cycles N  cycles of that polish (default %d)
  --polish-coarse B  hbds, with --polish: the polish's cycles on B x B pixel blocks, then one
                     full-resolution fusion of each pixel's label with its block's (0: off,
                     the polish at full resolution; default %d)
)",
              d.smooth.tau, d.smooth.u_min, d.smooth.u_max, d.smooth.truncation, d.hbds_overlap, d.hbds_coarse,
              d.polish_window, d.polish_cycles, d.polish_coarse);
  h += format(R"(  --refine R         after the method: none, mdc (Gu's disparity calibration, thesis
                     Eq. 2.11-2.13 without FFD), ffd-mdc (the thesis's refinement: fattening
                     foreground detection, then MDC), or a conventional refiner (thesis
                     Table 2.5): 2dbf (joint bilateral on the disparity), 3dbf (bilateral on
                     a cost volume of the map), wmf (weighted median), each also as
                     ffd-2dbf / ffd-3dbf / ffd-wmf (fattening pixels no support) (default %s)
  --filter-radius R  2dbf / 3dbf / wmf window radius (default %d)
  --filter-sigma-colour S  their colour sigma, grey levels (default %g)
  --filter-sigma-space S   2dbf / 3dbf spatial sigma, pixels (default %g)
  --filter-truncation T    3dbf cost truncation, levels (default %g)
  --refine-window N  MDC support window side, odd (default %d)
)",
              stereo::toString(d.refine).c_str(), d.filter_params.radius, d.filter_params.sigma_colour,
              d.filter_params.sigma_space, d.filter_params.truncation, d.refine_params.window);
  h += format(R"(  --subpixel F       last, for every method but sgbm: each disparity moved to the minimum of the
                     cost curve through d - 1, d, d + 1: parabola, equiangular or none (default %s)
  --subpixel-window N  side of the window the cost is summed over for it, odd (default %d)
  --lr-check         also match the right view (mirrored pair, same method: twice the time);
                     left pixels it does not confirm (occluded, border band, mismatched) are
                     filled from the background side along their row (default %s)
  --no-lr-check      the left view only
  --lr-tolerance T   largest left-right disagreement confirmed, pixels (default %g)
  --max-cycles N     expansion / swap cycles at most (default %d)
  --threads N        worker threads, 0 = all cores (default %d)
)",
              d.subpixel ? stereo::toString(d.subpixel_params.fit).c_str() : "none", d.subpixel_params.window,
              on(d.lr_check), d.lr_tolerance, d.max_cycles, d.threads);
  return h;
}

inline void addStereoParams(OptionTable& table, stereo::StereoParams& p) {
  auto number = [](float& field) {
    return [&field](const std::string& opt, const std::string& v) { field = static_cast<float>(parseDouble(opt, v)); };
  };
  auto integer = [](int& field) {
    return [&field](const std::string& opt, const std::string& v) { field = parseInt(opt, v); };
  };
  table.values["--cost"] = [&p](const std::string&, const std::string& v) {
    try {
      p.cost.data_term = stereo::parseDataTerm(v);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  };
  table.values["--census-lambda"] = number(p.cost.census_lambda);
  table.values["--ad-lambda"] = number(p.cost.ad_lambda);
  table.values["--eta"] = number(p.cost.eta);
  table.values["--ncc-window"] = integer(p.cost.ncc_window);
  table.values["--gradient-saturation"] = number(p.cost.gradient_saturation);
  table.values["--tau"] = number(p.smooth.tau);
  table.values["--u-min"] = number(p.smooth.u_min);
  table.values["--u-max"] = number(p.smooth.u_max);
  table.values["--truncation"] = number(p.smooth.truncation);
  table.values["--max-cycles"] = integer(p.max_cycles);
  table.values["--overlap"] = integer(p.hbds_overlap);
  table.values["--coarse"] = integer(p.hbds_coarse);
  table.values["--polish"] = integer(p.polish_window);
  table.values["--polish-cycles"] = integer(p.polish_cycles);
  table.values["--polish-coarse"] = integer(p.polish_coarse);
  table.values["--refine"] = [&p](const std::string&, const std::string& v) {
    try {
      p.refine = stereo::parseRefinement(v);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  };
  table.values["--refine-window"] = integer(p.refine_params.window);
  table.values["--filter-radius"] = integer(p.filter_params.radius);
  table.values["--filter-sigma-colour"] = number(p.filter_params.sigma_colour);
  table.values["--filter-sigma-space"] = number(p.filter_params.sigma_space);
  table.values["--filter-truncation"] = number(p.filter_params.truncation);
  table.values["--subpixel"] = [&p](const std::string&, const std::string& v) {
    p.subpixel = v != "none";
    if (!p.subpixel) return;
    try {
      p.subpixel_params.fit = stereo::parseSubpixelFit(v);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(e.what()) + " or none");
    }
  };
  table.values["--subpixel-window"] = integer(p.subpixel_params.window);
  table.flags["--lr-check"] = [&p] { p.lr_check = true; };
  table.flags["--no-lr-check"] = [&p] { p.lr_check = false; };
  table.values["--lr-tolerance"] = number(p.lr_tolerance);
  table.values["--threads"] = integer(p.threads);
}

/// The tools' option for a parameter stereo::checkParams names (the hbds node's name).
inline std::string stereoOption(const std::string& name) {
  if (name == "polish_window") return "--polish";
  if (name == "filter") return "--filter-*:";
  std::string option = "--" + name;
  std::replace(option.begin(), option.end(), '_', '-');
  return option;
}

/// UsageError naming the option of the first problem stereo::checkParams finds.
inline void checkStereoParams(const stereo::StereoParams& p) {
  const std::vector<stereo::ParamProblem> problems = stereo::checkParams(p);
  if (!problems.empty()) throw UsageError(stereoOption(problems.front().name) + " " + problems.front().problem);
}

}  // namespace massage_cell::tools
