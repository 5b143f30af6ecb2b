// The massage session's routine, fix and report (see session.h).
#include "massage_cell/arm/session.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgproc.hpp>

namespace massage_cell::arm {

namespace {

void require(bool ok, const std::string& field, const std::string& want) {
  if (!ok) throw std::invalid_argument("session: " + field + ": " + want);
}

std::string format(const char* fmt, double a, double b = 0.0, double c = 0.0) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c);
  return buf;
}

}  // namespace

void SessionConfig::validate() const {
  require(!acupoints.empty(), "acupoints", "expected a non-empty list of acupoint names");
  std::set<std::string> seen;
  for (const std::string& a : acupoints) {
    require(!a.empty(), "acupoints", "an empty name");
    require(seen.insert(a).second, "acupoints", "'" + a + "' is listed twice");
  }
  require(technique == "press" || technique == "knead", "technique",
          "expected press or knead, got '" + technique + "'");
  require(std::isfinite(depth) && depth >= 0.0 && depth <= 0.03, "depth", "expected 0 .. 0.03 m");
  require(mode == "depth" || mode == "force", "mode", "expected force or depth, got '" + mode + "'");
  require(std::isfinite(force) && force >= 0.0 && force <= 100.0, "force", "expected 0 .. 100 N (0: the region's)");
  require(std::isfinite(hold) && hold >= 0.0 && hold <= 60.0, "hold", "expected 0 .. 60 s");
  require(repeats >= 1 && repeats <= 20, "repeats", "expected 1 .. 20");
  require(std::isfinite(fix_window) && fix_window > 0.0, "fix_window", "expected > 0 s");
  require(fix_samples >= 1, "fix_samples", "expected >= 1");
  require(std::isfinite(fix_tolerance) && fix_tolerance > 0.0, "fix_tolerance", "expected > 0 m");
  require(std::isfinite(fix_timeout) && fix_timeout > 0.0, "fix_timeout", "expected > 0 s");
}

SessionConfig SessionConfig::load(const std::string& path) {
  SessionConfig c;
  try {
    const YAML::Node root = YAML::LoadFile(path);
    static const std::set<std::string> known = {"acupoints",  "technique",   "mode",          "force",
                                                "depth",      "hold",        "repeats",       "frame_prefix",
                                                "fix_window", "fix_samples", "fix_tolerance", "fix_timeout"};
    for (const auto& kv : root) {
      const std::string key = kv.first.as<std::string>();
      if (!known.count(key)) throw std::invalid_argument("session: unknown field '" + key + "'");
    }
    if (root["acupoints"]) c.acupoints = root["acupoints"].as<std::vector<std::string>>();
    if (root["technique"]) c.technique = root["technique"].as<std::string>();
    if (root["mode"]) c.mode = root["mode"].as<std::string>();
    if (root["force"]) c.force = root["force"].as<double>();
    if (root["depth"]) c.depth = root["depth"].as<double>();
    if (root["hold"]) c.hold = root["hold"].as<double>();
    if (root["repeats"]) c.repeats = root["repeats"].as<int>();
    if (root["frame_prefix"]) c.frame_prefix = root["frame_prefix"].as<std::string>();
    if (root["fix_window"]) c.fix_window = root["fix_window"].as<double>();
    if (root["fix_samples"]) c.fix_samples = root["fix_samples"].as<int>();
    if (root["fix_tolerance"]) c.fix_tolerance = root["fix_tolerance"].as<double>();
    if (root["fix_timeout"]) c.fix_timeout = root["fix_timeout"].as<double>();
    c.validate();
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  return c;
}

StableFix::StableFix(double window_s, int samples, double tolerance_m)
    : window_(window_s), tolerance_(tolerance_m), samples_(samples) {}

void StableFix::add(const std::string& name, double t, const Eigen::Vector3d& position, bool valid) {
  auto& h = history_[name];
  if (!valid || !position.allFinite()) {
    h.clear();
    return;
  }
  h.push_back({t, position});
  while (!h.empty() && h.front().t < t - window_) h.erase(h.begin());
}

std::vector<StableFix::Sample> StableFix::recent(const std::string& name, double now) const {
  std::vector<Sample> out;
  const auto it = history_.find(name);
  if (it == history_.end()) return out;
  for (const Sample& s : it->second) {
    if (s.t >= now - window_ && s.t <= now) out.push_back(s);
  }
  return out;
}

Eigen::Vector3d StableFix::mean(const std::string& name, double now) const {
  const std::vector<Sample> r = recent(name, now);
  if (r.empty()) return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (const Sample& s : r) m += s.p;
  return m / static_cast<double>(r.size());
}

bool StableFix::stable(const std::string& name, double now) const {
  const std::vector<Sample> r = recent(name, now);
  if (static_cast<int>(r.size()) < samples_) return false;
  const Eigen::Vector3d m = mean(name, now);
  for (const Sample& s : r) {
    if ((s.p - m).norm() > tolerance_) return false;
  }
  return true;
}

std::vector<std::string> StableFix::unstable(const std::vector<std::string>& names, double now) const {
  std::vector<std::string> out;
  for (const std::string& n : names) {
    if (!stable(n, now)) out.push_back(n);
  }
  return out;
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
  for (const PressRecord& p : presses) n += (p.success && p.measured && p.error() <= tolerance) ? 1 : 0;
  return n;
}

std::string SessionReport::summary(double tolerance) const {
  std::ostringstream out;
  out << "massage session: " << pairs << " stereo pairs; stable acupoint fix after " << format("%.1f s", seconds_to_fix)
      << "\n";
  for (const FixRecord& f : fix)
    out << "  fix   " << f.acupoint << ": " << format("%.1f mm from the ground truth", 1e3 * f.error)
        << format(" (x %+.1f, y %+.1f, z %+.1f mm)", 1e3 * f.offset.x(), 1e3 * f.offset.y(), 1e3 * f.offset.z())
        << "\n";
  if (!landmarks.empty()) out << "  layout: " << landmarks << "\n";
  for (const PressRecord& p : presses) {
    out << "  press " << p.acupoint << ": " << (p.success ? "done" : "FAILED") << format(" in %.1f s", p.seconds);
    if (p.measured && p.by_force) {
      out << format(", %.1f N held, tool %.1f mm from the ground truth across the skin", p.force_held, 1e3 * p.error())
          << format(" and %.1f mm into it", 1e3 * p.indentation());
    } else if (p.measured) {
      out << format(", tool at depth %.1f mm from the ground truth", 1e3 * p.error());
    }
    if (p.targeted) out << format(" (%.1f mm from CECT's acupoint)", 1e3 * p.placement());
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
  int done = 0;
  for (const PressRecord& p : presses) done += p.success ? 1 : 0;
  out << "result: " << done << " of " << presses.size() << " presses done, " << within(tolerance) << " within "
      << format("%.0f mm", 1e3 * tolerance) << " of the ground truth"
      << (faults.empty() ? "" : ", " + std::to_string(faults.size()) + " fault(s)") << "\n";
  return out.str();
}

namespace {

std::string escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

}  // namespace

void SessionReport::writeHtml(const std::string& dir, double tolerance,
                              const std::vector<std::pair<std::string, std::string>>& pictures) const {
  const std::string path = dir + "/index.html";
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Massage session</title>\n"
      << "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
      << "td,th{border:1px solid #aaa;padding:4px 10px;text-align:left}.bad{color:#b00}img{max-width:48%;margin:4px}"
      << "</style></head><body>\n<h1>Massage session</h1>\n<pre>" << escape(summary(tolerance)) << "</pre>\n";
  out << "<h2>Presses</h2>\n<table><tr><th>acupoint</th><th>result</th><th>s</th><th>tool at depth vs truth (mm; by "
         "force: across the skin, the force held)</th>"
      << "<th>vs CECT's acupoint (mm)</th><th>arm's answer</th></tr>\n";
  for (const PressRecord& p : presses) {
    out << "<tr" << (p.success ? "" : " class=\"bad\"") << "><td>" << escape(p.acupoint) << "</td><td>"
        << (p.success ? "done" : "failed") << "</td><td>" << format("%.1f", p.seconds) << "</td><td>"
        << (p.measured ? format("%.1f", 1e3 * p.error()) + (p.by_force ? format(" (%.1f N)", p.force_held) : "") : "-")
        << "</td><td>" << (p.targeted ? format("%.1f", 1e3 * p.placement()) : "-") << "</td><td>" << escape(p.message)
        << "</td></tr>\n";
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
  out << "</table>\n<h2>Pictures</h2>\n";
  for (const auto& [file, caption] : pictures) {
    out << "<figure style=\"display:inline-block;max-width:48%\"><img style=\"max-width:100%\" src=\"" << escape(file)
        << "\"><figcaption>" << escape(caption) << "</figcaption></figure>\n";
  }
  out << "</body></html>\n";
  if (!out) throw std::runtime_error("cannot write " + path);
}

namespace {

cv::Mat bgr(const cv::Mat& image) {
  cv::Mat out;
  if (image.channels() == 1) {
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  } else {
    out = image.clone();
  }
  return out;
}

}  // namespace

cv::Mat drawAcupoints(const cv::Mat& image, const std::vector<MarkedPixel>& estimates,
                      const std::vector<MarkedPixel>& truth, const std::vector<MarkedPixel>& landmarks) {
  cv::Mat out = bgr(image);
  const int r = std::max(2, out.cols / 160);
  for (const MarkedPixel& t : truth) cv::drawMarker(out, t.pixel, {0, 200, 0}, cv::MARKER_CROSS, 3 * r, 1);
  for (const MarkedPixel& l : landmarks) {
    cv::drawMarker(out, l.pixel, {255, 255, 0}, cv::MARKER_DIAMOND, 4 * r, 1, cv::LINE_AA);
    // Ending left of the diamond: the routine's labels run to the right of their points, on and beside the spine.
    const double scale = 0.3 * r / 2.0 + 0.2;
    int baseline = 0;
    const cv::Size text = cv::getTextSize(l.label, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    cv::putText(out, l.label, l.pixel + cv::Point2d(-2.0 * r - 2 - text.width, 0.5 * text.height),
                cv::FONT_HERSHEY_SIMPLEX, scale, {255, 255, 0}, 1, cv::LINE_AA);
  }
  for (const MarkedPixel& e : estimates) {
    if (!e.labelled) {
      cv::circle(out, e.pixel, std::max(1, r / 2), {0, 0, 160}, cv::FILLED, cv::LINE_AA);
      continue;
    }
    cv::circle(out, e.pixel, r, {0, 0, 255}, cv::FILLED, cv::LINE_AA);
    cv::putText(out, e.label, e.pixel + cv::Point2d(r + 2, -r), cv::FONT_HERSHEY_SIMPLEX, 0.3 * r / 2.0 + 0.2,
                {0, 255, 255}, 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat drawTrajectory(const cv::Mat& image, const std::vector<cv::Point2d>& path) {
  cv::Mat out = bgr(image);
  for (std::size_t i = 1; i < path.size(); ++i) {
    const double a = static_cast<double>(i) / path.size();
    cv::line(out, path[i - 1], path[i], cv::Scalar(255 * a, 80, 255 * (1 - a)), 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat colourDisparity(const cv::Mat& disparity) {
  cv::Mat d;
  disparity.convertTo(d, CV_32F);
  const cv::Mat valid = (d > 0.0f) & (d == d);
  double lo = 0.0, hi = 1.0;
  if (cv::countNonZero(valid) > 0) cv::minMaxLoc(d, &lo, &hi, nullptr, nullptr, valid);
  cv::Mat grey;
  d.convertTo(grey, CV_8U, 255.0 / std::max(hi - lo, 1e-6), -lo * 255.0 / std::max(hi - lo, 1e-6));
  cv::Mat out;
  cv::applyColorMap(grey, out, cv::COLORMAP_TURBO);
  out.setTo(cv::Scalar::all(0), ~valid);
  return out;
}

}  // namespace massage_cell::arm
