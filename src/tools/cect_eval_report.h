// cect_eval's report: the table's rows per condition, the optional per-point
// and by-border tables, the closing summaries, and the CSV rows.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "cect_eval_options.h"
#include "cect_eval_pair.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/evaluation.h"

namespace massage_cell::tools::cect_eval {

/// One condition's line of the closing table.
struct SummaryRow {
  std::string condition;
  int in_view = 0, valid_in_view = 0, valid_out_of_view = 0;  ///< over every pair (published or not)
  Stats layout, given, sgbm_given, near_arms;
  double cect_ms = 0.0;
  cect::ScoreSummary landmarks;
  double placedShare() const { return in_view ? 100.0 * valid_in_view / in_view : std::nan(""); }
};

/// The run's first lines: the CSV header, or the set-up and the table's header.
void printHeader(const Options& o);

/// --csv: pair `subject`'s rows, a row per point set and method, the layout's and the landmarks'.
void printCsvRows(const std::string& condition, int subject, const PairResult& r);

/// The condition's table rows, the placement and timing line, the acupoints in view, the failures and the sigmas;
/// returns its summary row.
SummaryRow printCondition(const Condition& c, ConditionResult& cr);

/// --by-border: the back's pixels by their distance to the border, per band and method.
void printBorderBands(const std::map<std::string, Stats>& border);

/// --per-point: every acupoint of the model.
void printPerPoint(const std::map<std::string, Stats>& per_point, const cect::AcupointModel& model);

/// The closing table: per condition, the acupoints in view and placed, the
/// layout's error, and the 3D error at the true acupoint pixels.
void printSummary(const std::vector<SummaryRow>& rows);

/// The closing landmark table: per condition, the levels along the body, the spine line across, refusals and the
/// pairs wrongly trusted.
void printLandmarkSummary(const std::vector<SummaryRow>& rows);

}  // namespace massage_cell::tools::cect_eval
