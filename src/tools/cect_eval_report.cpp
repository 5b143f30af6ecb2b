#include "cect_eval_report.h"

#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace massage_cell::tools::cect_eval {
namespace {

std::string fmt(double v, int prec = 2) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(prec) << v;
  return s.str();
}

std::string validShare(const Stats& st) {
  return fmt(st.queried ? 100.0 * st.errors_mm.size() / st.queried : std::nan(""), 1);
}

/// mean / p95 / max of a spread, one decimal.
std::string spreadText(const cect::Spread& s) { return fmt(s.mean, 1) + " / " + fmt(s.p95, 1) + " / " + fmt(s.max, 1); }

/// The condition's landmarks against the anatomy and how often the layout was trusted when it should not have been.
void printLandmarks(const std::string& condition, const cect::ScoreSummary& l) {
  std::cout << std::left << std::setw(18) << condition << "landmarks of the " << l.published
            << " published pairs (mean / p95 / max mm along the body):";
  for (const std::string& level : cect::scoredLevels())
    std::cout << " " << level << " " << spreadText(l.levels.at(level)) << ";";
  std::cout << " spine line across " << spreadText(l.midline_across) << "\n"
            << std::setw(18) << ""
            << "refused " << l.refused << " of " << l.pairs << " pairs (" << l.refused_wrong << " of them > "
            << fmt(cect::PairScore::kWrongLevelMm, 0)
            << " mm off); wrongly trusted (published, a level along the body or the spine line across it > "
            << fmt(cect::PairScore::kWrongLevelMm, 0) << " mm off) " << l.wrongly_trusted << "\n";
}

/// --csv: one method's figures on one point set of one pair.
void printCsvRow(const std::string& condition, int subject, const std::string& method, const std::string& points,
                 const Stats& st) {
  std::cout << condition << "," << subject << "," << method << "," << points << "," << fmt(st.spread().mean, 3) << ","
            << fmt(st.spread().max, 3) << "," << fmt(st.accRate(), 4) << "\n";
}

}  // namespace

void printHeader(const Options& o) {
  if (o.csv)
    std::cout << "condition,subject,method,points,mean_mm,max_mm,acc_rate\n";
  else
    std::cout << "CECT vs StereoSGBM at the same left pixels; " << o.width << "x" << o.height << ", fx " << o.fx
              << " px, baseline " << o.baseline << " m, camera " << o.camera_height << " m above the table"
              << (o.yaw_deg != 0.0 ? ", subject turned " + fmt(o.yaw_deg, 1) + " deg" : std::string())
              << (o.raw ? ", raw (distorted, unrectified) pairs" : ", rectified pairs") << "\n\n"
              << std::left << std::setw(18) << "condition" << std::setw(8) << "method" << std::setw(11) << "points"
              << std::right << std::setw(8) << "queried" << std::setw(8) << "valid%" << std::setw(9) << "mean mm"
              << std::setw(9) << "max mm" << std::setw(9) << "p95 mm" << std::setw(9) << "acc<1cm"
              << "\n";
}

void printCsvRows(const std::string& condition, int subject, const PairResult& r) {
  for (const auto& [key, st] : r.stats) {
    const auto slash = key.find('/');
    printCsvRow(condition, subject, key.substr(0, slash), key.substr(slash + 1), st);
  }
  printCsvRow(condition, subject, "model", "layout", layoutStats(r.score));
  const cect::PairScore& ps = r.score;
  std::cout << condition << "," << subject << ",landmarks," << (ps.published ? "published" : "refused");
  for (const cect::LevelError& e : ps.levels) std::cout << "," << e.level << "=" << fmt(e.along_mm, 1);
  const cect::LayoutCheck& k = r.check;
  std::cout << ",midline=" << fmt(ps.midline_across_mm, 1) << ",length_m=" << fmt(k.length_m, 3)
            << ",shoulder_m=" << fmt(k.shoulder_width_m, 3) << ",ratio=" << fmt(k.length_per_shoulder_width, 3)
            << ",shoulder_below_c7=" << fmt(k.shoulder_below_c7, 3) << ",\"" << r.landmarks << "\"\n";
}

SummaryRow printCondition(const Condition& c, ConditionResult& cr) {
  for (const auto& [key, st] : cr.total) {
    const auto slash = key.find('/');
    const cect::Spread e = st.spread();
    std::cout << std::left << std::setw(18) << c.name << std::setw(8) << key.substr(0, slash) << std::setw(11)
              << key.substr(slash + 1) << std::right << std::setw(8) << st.queried << std::setw(8) << validShare(st)
              << std::setw(9) << fmt(e.mean) << std::setw(9) << fmt(e.max) << std::setw(9) << fmt(e.p95) << std::setw(8)
              << fmt(100.0 * st.accRate(), 1) << "%\n";
  }
  const cect::Spread layout = cr.layout.spread(), cect_ms = cect::spreadOf(cr.cect_ms),
                     sgbm_ms = cect::spreadOf(cr.sgbm_ms);
  std::cout << std::left << std::setw(18) << c.name << "model placement vs anatomical acupoints: mean "
            << fmt(layout.mean, 1) << " mm, max " << fmt(layout.max, 1) << " mm; CECT " << fmt(cect_ms.median, 1)
            << " ms median (max " << fmt(cect_ms.max, 1) << "), SGBM " << fmt(sgbm_ms.median, 1) << " ms; "
            << c.subjects.size() << " subjects\n";
  const Stats& g = cr.total["cect/given"];
  const Stats& sg = cr.total["sgbm/given"];
  const cect::Spread ge = g.spread();
  SummaryRow row{c.name, cr.in_view, cr.valid_in_view,           cr.valid_out_of_view, cr.layout,
                 g,      sg,         cr.total["cect/near_arms"], cect_ms.median,       cect::summarise(cr.scores)};
  printLandmarks(c.name, row.landmarks);
  std::cout << std::left << std::setw(18) << c.name << "acupoints in view " << cr.in_view << ": "
            << fmt(row.placedShare(), 1) << " % placed (" << cr.valid_out_of_view
            << " placed though out of view); layout vs anatomical mean " << fmt(layout.mean, 1) << " mm, p95 "
            << fmt(layout.p95, 1) << " mm\n"
            << std::setw(18) << ""
            << "at the true acupoint pixels: CECT mean " << fmt(ge.mean) << " mm, p95 " << fmt(ge.p95) << ", "
            << fmt(100.0 * g.accRate(), 1) << " % within 1 cm; SGBM mean " << fmt(sg.spread().mean) << " mm, "
            << fmt(100.0 * sg.accRate(), 1) << " % within 1 cm\n";
  for (const auto& f : cr.failures) std::cout << "  CECT failed on " << f << "\n";
  const Stats& a = cr.total["cect/acupoints"];
  const Stats& r = cr.total["cect/random"];
  std::cout << std::left << std::setw(18) << c.name << "CECT's disparity sigma: acupoints median "
            << fmt(cect::spreadOf(a.sigma_px).median) << " px, " << fmt(100.0 * a.within2Sigma(), 1)
            << " % of their errors within 2 sigma; random points " << fmt(cect::spreadOf(r.sigma_px).median) << " px, "
            << fmt(100.0 * r.within2Sigma(), 1) << " %\n";
  return row;
}

void printBorderBands(const std::map<std::string, Stats>& border) {
  std::cout << "  back pixels by distance to the border (every 4th pixel, both views):\n"
            << "  " << std::left << std::setw(10) << "band" << std::setw(8) << "method" << std::right << std::setw(8)
            << "queried" << std::setw(8) << "valid%" << std::setw(9) << "mean mm" << std::setw(9) << "max mm"
            << std::setw(9) << "acc<1cm" << std::setw(10) << "sigma px" << std::setw(9) << "in 2sig"
            << "\n";
  for (const auto& [edge, band] : borderBands())
    for (const char* method : {"cect", "sgbm"}) {
      const auto it = border.find(std::string(method) + "/" + band);
      if (it == border.end()) continue;
      const Stats& st = it->second;
      std::cout << "  " << std::left << std::setw(10) << band << std::setw(8) << method << std::right << std::setw(8)
                << st.queried << std::setw(8) << validShare(st) << std::setw(9) << fmt(st.spread().mean) << std::setw(9)
                << fmt(st.spread().max) << std::setw(8) << fmt(100.0 * st.accRate(), 1) << "%" << std::setw(10)
                << fmt(cect::spreadOf(st.sigma_px).median) << std::setw(8) << fmt(100.0 * st.within2Sigma(), 1)
                << (st.z.empty() ? " " : "%") << "\n";
    }
}

void printPerPoint(const std::map<std::string, Stats>& per_point, const cect::AcupointModel& model) {
  std::cout << "  " << std::left << std::setw(14) << "acupoint" << std::right << std::setw(8) << "queried"
            << std::setw(8) << "valid%" << std::setw(9) << "mean mm" << std::setw(9) << "max mm" << std::setw(9)
            << "acc<1cm"
            << "  commonest miss\n";
  for (const std::string& name : model.names()) {
    const auto it = per_point.find(name);
    if (it == per_point.end()) continue;
    const Stats& st = it->second;
    std::cout << "  " << std::left << std::setw(14) << name << std::right << std::setw(8) << st.queried << std::setw(8)
              << validShare(st) << std::setw(9) << fmt(st.spread().mean) << std::setw(9) << fmt(st.spread().max)
              << std::setw(8) << fmt(100.0 * st.accRate(), 1) << "%  " << st.commonestMiss() << "\n";
  }
}

void printSummary(const std::vector<SummaryRow>& rows) {
  std::cout << "Summary (acupoints in view = the simulator's truth; layout = the placed pixel's surface point vs the\n"
               "anatomical acupoint; given = CECT at the true acupoint pixels; near arms = back pixels within 20 px of "
               "an arm)\n"
            << std::left << std::setw(18) << "condition" << std::right << std::setw(8) << "in view" << std::setw(9)
            << "placed%" << std::setw(8) << "extra" << std::setw(12) << "layout mm" << std::setw(10) << "lay p95"
            << std::setw(11) << "given mm" << std::setw(10) << "giv p95" << std::setw(9) << "giv<1cm" << std::setw(10)
            << "sgbm<1cm" << std::setw(10) << "arms mm" << std::setw(10) << "arms<1cm" << std::setw(8) << "ms"
            << "\n";
  for (const SummaryRow& r : rows) {
    const cect::Spread layout = r.layout.spread(), given = r.given.spread();
    std::cout << std::left << std::setw(18) << r.condition << std::right << std::setw(8) << r.in_view << std::setw(9)
              << fmt(r.placedShare(), 1) << std::setw(8) << r.valid_out_of_view << std::setw(12) << fmt(layout.mean, 1)
              << std::setw(10) << fmt(layout.p95, 1) << std::setw(11) << fmt(given.mean) << std::setw(10)
              << fmt(given.p95) << std::setw(8) << fmt(100.0 * r.given.accRate(), 1) << "%" << std::setw(9)
              << fmt(100.0 * r.sgbm_given.accRate(), 1) << "%" << std::setw(10) << fmt(r.near_arms.spread().mean)
              << std::setw(9) << fmt(100.0 * r.near_arms.accRate(), 1) << "%" << std::setw(8) << fmt(r.cect_ms, 1)
              << "\n";
  }
}

void printLandmarkSummary(const std::vector<SummaryRow>& rows) {
  std::cout
      << "\nLandmarks against the anatomy (published pairs; mean / p95 mm along the body; spine line mean mm across;\n"
         "layout = their acupoints against the anatomical ones, mean / p95 mm; refused = pairs not published;\n"
         "wrong = published with a level along the body or the spine line across it more than "
      << fmt(cect::PairScore::kWrongLevelMm, 0) << " mm off)\n"
      << std::left << std::setw(18) << "condition" << std::right << std::setw(14) << "C7" << std::setw(14) << "T7"
      << std::setw(14) << "L4" << std::setw(8) << "spine" << std::setw(14) << "layout" << std::setw(10) << "refused"
      << std::setw(8) << "wrong" << std::setw(9) << "placed%"
      << "\n";
  for (const SummaryRow& r : rows) {
    const cect::ScoreSummary& l = r.landmarks;
    auto level = [&](const char* name) {
      const cect::Spread& s = l.levels.at(name);
      return fmt(s.mean, 1) + " / " + fmt(s.p95, 1);
    };
    std::cout << std::left << std::setw(18) << r.condition << std::right << std::setw(14) << level("C7")
              << std::setw(14) << level("T7") << std::setw(14) << level("L4") << std::setw(8)
              << fmt(l.midline_across.mean, 1) << std::setw(14)
              << (fmt(l.layout.mean, 1) + " / " + fmt(l.layout.p95, 1)) << std::setw(10)
              << (std::to_string(l.refused) + "/" + std::to_string(l.pairs)) << std::setw(8) << l.wrongly_trusted
              << std::setw(9) << fmt(100.0 * l.placedShare(), 1) << "\n";
  }
}

}  // namespace massage_cell::tools::cect_eval
