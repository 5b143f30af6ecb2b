// The massage session's records and its summary (see report.h).
#include "massage_cell/session/report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "report_detail.h"

namespace massage_cell::session {

std::string detail::format(const char* fmt, double a, double b, double c) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c);
  return buf;
}

std::string detail::forceLine(const ForceFigures& f) {
  std::string out = format("peak %.1f N", f.peak);
  if (!f.has_hold) return out + ", no hold phase (0 s within ±10 % of the set-point)";
  return out + format(", %.1f of %.1f s of hold within ±10 %% of the set-point (%.0f %%)", f.within_seconds,
                      f.hold_seconds, 100.0 * f.withinFraction());
}

ForceFigures forceFigures(const std::vector<ForceSample>& trace) {
  ForceFigures f;
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const ForceSample& s = trace[i];
    if (std::isfinite(s.force)) f.peak = std::max(f.peak, s.force);
    if (std::isfinite(s.limit)) f.limit = std::max(f.limit, s.limit);
    if (s.phase != "hold" && s.phase != "glide") continue;
    f.has_hold = true;
    // The sample stands until the next one; the last one for the spacing before it.
    double dt = 0.0;
    if (i + 1 < trace.size()) {
      dt = trace[i + 1].t - s.t;
    } else if (i > 0) {
      dt = s.t - trace[i - 1].t;
    }
    dt = std::isfinite(dt) ? std::max(dt, 0.0) : 0.0;
    f.hold_seconds += dt;
    if (std::isfinite(s.force) && s.target > 0.0 && std::abs(s.force - s.target) <= 0.1 * s.target)
      f.within_seconds += dt;
  }
  return f;
}

std::string forcePlotFile(std::size_t index, const std::string& acupoint) {
  std::string name = acupoint;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  }
  return "force_" + std::to_string(index + 1) + "_" + name + ".png";
}

double LatencyRecord::quantile(double q) const {
  if (samples.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> v = samples;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(std::clamp(q, 0.0, 1.0) * v.size()));
  return v[rank == 0 ? 0 : rank - 1];
}

int SessionReport::within(double tolerance) const {
  int n = 0;
  for (const PressRecord& p : presses) {
    const double error = p.stroke ? p.path_error : p.measured ? p.error() : NAN;
    n += p.success && error <= tolerance ? 1 : 0;
  }
  return n;
}

std::string SessionReport::summary(double tolerance) const {
  using detail::format;
  std::ostringstream out;
  out << "massage session: " << pairs << " stereo pairs; stable acupoint fix after " << format("%.1f s", seconds_to_fix)
      << "\n";
  for (const FixRecord& f : fix)
    out << "  fix   " << f.acupoint << ": " << format("%.1f mm from the ground truth", 1e3 * f.error)
        << format(" (x %+.1f, y %+.1f, z %+.1f mm)", 1e3 * f.offset.x(), 1e3 * f.offset.y(), 1e3 * f.offset.z())
        << "\n";
  if (!landmarks.empty()) out << "  layout: " << landmarks << "\n";
  for (const PressRecord& p : presses) {
    out << (p.stroke ? "  stroke " : "  press ") << p.acupoint << ": " << (p.success ? "done" : "FAILED")
        << format(" in %.1f s", p.seconds);
    if (p.stroke && std::isfinite(p.path_error)) {
      out << format(", tool within %.1f mm of the true path across the skin (%.1f mm of the path it was given)",
                    1e3 * p.path_error, 1e3 * p.tracking_error);
    } else if (p.measured && p.by_force) {
      out << format(", %.1f N held, tool %.1f mm from the ground truth across the skin", p.force_held, 1e3 * p.error())
          << format(" and %.1f mm into it", 1e3 * p.indentation());
    } else if (p.measured) {
      out << format(", tool at depth %.1f mm from the ground truth", 1e3 * p.error());
    }
    if (p.targeted) out << format(" (%.1f mm from CECT's acupoint)", 1e3 * p.placement());
    if (!p.force_trace.empty()) out << "; " << detail::forceLine(p.force());
    if (!p.success) out << " (" << p.message << ")";
    out << "\n";
  }
  for (const LatencyRecord& l : latencies) {
    if (l.samples.empty()) continue;
    out << "  latency " << l.stage << ": p50 "
        << format("%.0f ms, p95 %.0f ms", 1e3 * l.quantile(0.5), 1e3 * l.quantile(0.95)) << " (" << l.samples.size()
        << ")\n";
  }
  for (const std::string& f : faults) out << "  fault: " << f << "\n";
  int done = 0, strokes = 0, stroked = 0;
  for (const PressRecord& p : presses) {
    (p.stroke ? stroked : done) += p.success ? 1 : 0;
    strokes += p.stroke ? 1 : 0;
  }
  out << "result: " << done << " of " << presses.size() - strokes << " presses"
      << (strokes ? " and " + std::to_string(stroked) + " of " + std::to_string(strokes) + " strokes" : std::string())
      << " done, " << within(tolerance) << " within " << format("%.0f mm", 1e3 * tolerance) << " of the ground truth"
      << (faults.empty() ? "" : ", " + std::to_string(faults.size()) + " fault(s)") << "\n";
  return out.str();
}

}  // namespace massage_cell::session
