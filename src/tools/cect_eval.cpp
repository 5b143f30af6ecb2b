// cect_eval: the thesis's three CECT experiments on rendered subjects
// (ideal conditions over 28 subjects, three light directions, four camera
// shifts), with CECT and dense StereoSGBM at the same pixels against the
// simulator's exact ground truth.
#include <iostream>
#include <string>
#include <vector>

#include "cect_eval_options.h"
#include "cect_eval_pair.h"
#include "cect_eval_report.h"
#include "cect_params.h"
#include "cect_scenes.h"
#include "cli.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/stereo/memory.h"
#include "package_paths.h"

namespace massage_cell::tools::cect_eval {
namespace {

/// The experiments' conditions, each with its subjects.
std::vector<Condition> conditionsOf(const Options& o) {
  std::vector<Condition> conditions;
  auto range = [](int n, int first = 1) {
    std::vector<int> v;
    for (int i = first; i < first + n; ++i) v.push_back(i);
    return v;
  };
  for (const std::string& e : o.experiments) {
    if (e == "ideal") {
      conditions.push_back({"ideal", sim::LightPreset::kTopCentre, 0.0, range(o.subjects)});
    } else if (e == "lighting") {
      conditions.push_back({"light_top_left", sim::LightPreset::kTopLeft, 0.0, range(o.condition_subjects)});
      conditions.push_back({"light_top_centre", sim::LightPreset::kTopCentre, 0.0, range(o.condition_subjects)});
      conditions.push_back({"light_top_right", sim::LightPreset::kTopRight, 0.0, range(o.condition_subjects)});
    } else if (e == "real") {
      for (const std::string& name : o.conditions.empty() ? tools::realConditions() : o.conditions)
        conditions.push_back(
            {name, sim::LightPreset::kTopCentre, 0.0, range(o.condition_subjects, o.first_subject), true});
    } else if (e == "shift") {
      for (int cm : {0, 4, 7, 14})
        conditions.push_back({"shift_" + std::to_string(cm) + "cm", sim::LightPreset::kTopCentre, cm / 100.0,
                              range(o.condition_subjects)});
    }
  }
  return conditions;
}

/// Every subject of the condition (--csv: a row per subject and figure as they come).
ConditionResult evaluateCondition(const Options& o, const Condition& c, const cect::AcupointModel& model,
                                  const cect::CectParams& params) {
  ConditionResult cr;
  for (int s : c.subjects) {
    const PairResult r = evaluatePair(o, c, s, model, params);
    cr.add(s, r);
    if (o.csv) printCsvRows(c.name, s, r);
  }
  return cr;
}

void run(const Options& o) {
  stereo::retainFreedMemory();  // page faults would otherwise dominate the per-pair timings
  const cect::AcupointModel model =
      cect::loadAcupointModel(o.acupoints.empty() ? tools::packageFile("config/acupoints.yaml") : o.acupoints);
  cect::CectParams params;
  if (o.seed_step >= 0) params.seed_step = o.seed_step;
  if (o.query_search >= 0) params.query_search = o.query_search;
  tools::applyParams(params, o.params);
  params.skin_markers = o.markers;

  printHeader(o);
  std::vector<SummaryRow> summary;
  for (const Condition& c : conditionsOf(o)) {
    ConditionResult cr = evaluateCondition(o, c, model, params);
    if (o.csv) continue;
    summary.push_back(printCondition(c, cr));
    if (o.by_border) printBorderBands(cr.border);
    if (o.per_point) printPerPoint(cr.per_point, model);
    std::cout << "\n";
  }
  if (!o.csv) {
    printSummary(summary);
    printLandmarkSummary(summary);
  }
}

}  // namespace
}  // namespace massage_cell::tools::cect_eval

int main(int argc, char** argv) {
  namespace eval = massage_cell::tools::cect_eval;
  eval::Options o;
  return massage_cell::tools::runTool(
      "cect_eval", [&] { return eval::parseOptions(argc, argv, o); }, [&] { eval::run(o); });
}
