// cect_eval's measurement of one rendered pair: the condition it belongs to,
// CECT's and StereoSGBM's errors on each point set, and the landmarks and the
// layout against the anatomy (cect_eval_pair.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cect_eval_options.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/evaluation.h"
#include "massage_cell/cect/locate.h"
#include "massage_cell/sim/renderer.h"

namespace massage_cell::tools::cect_eval {

/// One condition of an experiment: its light, camera shift and subjects.
struct Condition {
  std::string name;
  sim::LightPreset light = sim::LightPreset::kTopCentre;
  double shift = 0.0;
  std::vector<int> subjects;
  bool real = false;  ///< a realistic condition (cect_scenes.h: realScenario(name, ...))
};

/// Errors of one method on one point set of one pair.
struct Stats {
  int queried = 0;
  std::vector<double> errors_mm;  ///< localised points only
  /// Mean, p95 (nearest rank) and max of the errors (cect/evaluation.h); NaN each when none.
  cect::Spread spread() const { return cect::spreadOf(errors_mm); }
  double accRate() const {
    if (queried == 0) return std::nan("");
    return static_cast<double>(std::count_if(errors_mm.begin(), errors_mm.end(), [](double e) { return e < 10.0; })) /
           queried;
  }
  std::map<std::string, int> misses;  ///< why queried points were not localised
  /// CECT's uncertainty: per localised point its disparity sigma (px) and
  /// |disparity error| / sigma.
  std::vector<double> sigma_px, z;
  /// Share of the localised points whose disparity error is within 2 sigma
  /// (95 % for a calibrated Gaussian sigma).
  double within2Sigma() const {
    if (z.empty()) return std::nan("");
    return static_cast<double>(std::count_if(z.begin(), z.end(), [](double v) { return v <= 2.0; })) / z.size();
  }
  void add(const Stats& o) {
    queried += o.queried;
    errors_mm.insert(errors_mm.end(), o.errors_mm.begin(), o.errors_mm.end());
    sigma_px.insert(sigma_px.end(), o.sigma_px.begin(), o.sigma_px.end());
    z.insert(z.end(), o.z.begin(), o.z.end());
    for (const auto& [why, n] : o.misses) misses[why] += n;
  }
  std::string commonestMiss() const {
    const auto it = std::max_element(misses.begin(), misses.end(),
                                     [](const auto& a, const auto& b) { return a.second < b.second; });
    return it == misses.end() ? std::string() : it->first + " (" + std::to_string(it->second) + ")";
  }
};

/// --by-border: the bands' lower edges (px at 640 columns) and names.
const std::vector<std::pair<double, std::string>>& borderBands();

struct PairResult {
  std::map<std::string, Stats> stats;      ///< "cect/acupoints", "sgbm/random", ...
  std::map<std::string, Stats> per_point;  ///< CECT on each acupoint (by name)
  std::map<std::string, Stats> border;     ///< --by-border: "cect/<band>", "sgbm/<band>"
  double cect_ms = 0.0, sgbm_ms = 0.0;
  std::string failure;  ///< CECT's reason when the frame was not usable
  /// The landmarks, the layout (placed vs anatomical acupoints) and the acupoints in view against the anatomy
  /// (cect/evaluation.h)
  cect::PairScore score;
  cect::LayoutCheck check;  ///< the layout's plausibility as the chain judged it
  std::string landmarks;    ///< describeLandmarks
};

/// A pair's layout error as Stats: every placed acupoint in view (published valid or not), its pixel's surface point
/// against the anatomical acupoint (PairScore::layout_mm), of the acupoints in view.
Stats layoutStats(const cect::PairScore& score);

/// One condition's pairs added up.
struct ConditionResult {
  std::map<std::string, Stats> total, per_point, border;
  /// The layout and the acupoints in view over every pair, published or not (the pairs' PairScores added up;
  /// ScoreSummary's are over the published pairs)
  Stats layout;
  int in_view = 0, valid_in_view = 0, valid_out_of_view = 0;
  std::vector<double> cect_ms, sgbm_ms;
  std::vector<std::string> failures;
  std::vector<cect::PairScore> scores;  ///< per pair: landmarks, layout, trust
  /// Adds pair `subject`'s figures.
  void add(int subject, const PairResult& r);
};

/// Renders pair `subject` of condition `c` and measures both methods on it (--pictures: writes its picture).
PairResult evaluatePair(const Options& o, const Condition& c, int subject, const cect::AcupointModel& model,
                        const cect::CectParams& params);

}  // namespace massage_cell::tools::cect_eval
