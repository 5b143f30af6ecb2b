// The massage session's report as index.html, with its force plots (see report.h).
#include <fstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

#include "massage_cell/session/report.h"
#include "report_detail.h"

namespace massage_cell::session {

namespace {

using detail::format;

std::string escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

void figure(std::ostream& out, const std::string& file, const std::string& caption) {
  out << "<figure style=\"display:inline-block;max-width:48%\"><img style=\"max-width:100%\" src=\"" << escape(file)
      << "\"><figcaption>" << escape(caption) << "</figcaption></figure>\n";
}

/// The force plots of the presses with a force trace, written into `dir`: (file, caption) each.
std::vector<std::pair<std::string, std::string>> writeForcePlots(const std::string& dir,
                                                                 const std::vector<PressRecord>& presses) {
  std::vector<std::pair<std::string, std::string>> plots;
  for (std::size_t i = 0; i < presses.size(); ++i) {
    const PressRecord& p = presses[i];
    if (p.force_trace.empty()) continue;
    const std::string file = forcePlotFile(i, p.acupoint);
    const std::string title = (p.stroke ? "stroke " : "press ") + std::to_string(i + 1) + ": " + p.acupoint;
    if (!cv::imwrite(dir + "/" + file, drawForcePlot(p.force_trace, title)))
      throw std::runtime_error("cannot write " + dir + "/" + file);
    plots.emplace_back(file, title + ": " + detail::forceLine(p.force()) + format(" (cap %.1f N)", p.force().limit));
  }
  return plots;
}

}  // namespace

void SessionReport::writeHtml(const std::string& dir, double tolerance,
                              const std::vector<std::pair<std::string, std::string>>& pictures) const {
  const std::string path = dir + "/index.html";
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  const auto plots = writeForcePlots(dir, presses);
  out << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Massage session</title>\n"
      << "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
      << "td,th{border:1px solid #aaa;padding:4px 10px;text-align:left}.bad{color:#b00}img{max-width:48%;margin:4px}"
      << "</style></head><body>\n<h1>Massage session</h1>\n<pre>" << escape(summary(tolerance)) << "</pre>\n";
  out << "<h2>Presses</h2>\n<table><tr><th>acupoint</th><th>result</th><th>s</th><th>tool at depth vs truth (mm; by "
         "force: across the skin, the force held)</th>"
      << "<th>vs CECT's acupoint (mm)</th><th>peak force (N)</th><th>hold (a stroke: glide) within ±10 % of the "
         "set-point (s of s)</th>"
      << "<th>arm's answer</th></tr>\n";
  for (const PressRecord& p : presses) {
    const ForceFigures f = p.force();
    std::string within = "-";
    if (!p.force_trace.empty())
      within = f.has_hold
                   ? format("%.1f of %.1f (%.0f %%)", f.within_seconds, f.hold_seconds, 100.0 * f.withinFraction())
                   : "no hold";
    out << "<tr" << (p.success ? "" : " class=\"bad\"") << "><td>" << escape(p.acupoint) << "</td><td>"
        << (p.success ? "done" : "failed") << "</td><td>" << format("%.1f", p.seconds) << "</td><td>"
        << (p.stroke     ? format("stroke: %.1f from the true path", 1e3 * p.path_error)
            : p.measured ? format("%.1f", 1e3 * p.error()) + (p.by_force ? format(" (%.1f N)", p.force_held) : "")
                         : "-")
        << "</td><td>" << (p.targeted ? format("%.1f", 1e3 * p.placement()) : "-") << "</td><td>"
        << (p.force_trace.empty() ? "-" : format("%.1f", f.peak)) << "</td><td>" << within << "</td><td>"
        << escape(p.message) << "</td></tr>\n";
  }
  out << "</table>\n<h2>Acupoint fix against the ground truth</h2>\n<table><tr><th>acupoint</th><th>mm</th><th>x, y, z "
         "mm (camera: right, down, depth)</th></tr>\n";
  for (const FixRecord& f : fix)
    out << "<tr><td>" << escape(f.acupoint) << "</td><td>" << format("%.1f", 1e3 * f.error) << "</td><td>"
        << format("%+.1f, %+.1f, %+.1f", 1e3 * f.offset.x(), 1e3 * f.offset.y(), 1e3 * f.offset.z()) << "</td></tr>\n";
  out << "</table>\n<h2>Latency</h2>\n<table><tr><th>stage</th><th>p50 ms</th><th>p95 ms</th><th>samples</th></tr>\n";
  for (const LatencyRecord& l : latencies) {
    out << "<tr><td>" << escape(l.stage) << "</td><td>" << format("%.0f", 1e3 * l.quantile(0.5)) << "</td><td>"
        << format("%.0f", 1e3 * l.quantile(0.95)) << "</td><td>" << l.samples.size() << "</td></tr>\n";
  }
  out << "</table>\n";
  if (!plots.empty()) {
    out << "<h2>Force</h2>\n<p>Each press by force: the measured force (blue), the set-point (green), the press's cap "
           "(red); the hold phase (a stroke's glide) shaded.</p>\n";
    for (const auto& [file, caption] : plots) figure(out, file, caption);
  }
  out << "<h2>Pictures</h2>\n";
  for (const auto& [file, caption] : pictures) figure(out, file, caption);
  out << "</body></html>\n";
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace massage_cell::session
