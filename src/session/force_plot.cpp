// The report's force plot of one press by force (see report.h): drawn with
// OpenCV's lines and Hershey text, no plotting library.
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "massage_cell/session/report.h"
#include "report_detail.h"

namespace massage_cell::session {

namespace {

constexpr int kLeft = 60, kRight = 16, kTop = 44, kBottom = 42;  // margins, px
const cv::Scalar kInk{40, 40, 40}, kGrid{225, 225, 225}, kHoldShade{215, 238, 250};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

/// A round tick step (1, 2 or 5 × 10^k) giving about `ticks` ticks over `range`.
double niceStep(double range, int ticks) {
  const double raw = std::max(range, 1e-9) / ticks;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * magnitude >= raw * (1.0 - 1e-9)) return m * magnitude;
  }
  return 10.0 * magnitude;
}

std::string tickLabel(double value, double step) {
  return detail::format(step >= 1.0 ? "%.0f" : (step >= 0.1 ? "%.1f" : "%.2f"), std::abs(value) < 1e-9 ? 0.0 : value);
}

void text(cv::Mat& image, const std::string& s, cv::Point at, double scale, const cv::Scalar& colour) {
  cv::putText(image, s, at, kFont, scale, colour, 1, cv::LINE_AA);
}

cv::Size textSize(const std::string& s, double scale) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, 1, &baseline);
}

/// A label written up the left margin (rotated a quarter turn).
void verticalText(cv::Mat& image, const std::string& s, cv::Point centre, double scale) {
  const cv::Size size = textSize(s, scale);
  cv::Mat strip(size.height + 6, size.width + 4, image.type(), cv::Scalar::all(255));
  text(strip, s, {2, size.height + 2}, scale, kInk);
  cv::rotate(strip, strip, cv::ROTATE_90_COUNTERCLOCKWISE);
  cv::Rect where(centre.x - strip.cols / 2, centre.y - strip.rows / 2, strip.cols, strip.rows);
  where &= cv::Rect(0, 0, image.cols, image.rows);
  strip(cv::Rect(0, 0, where.width, where.height)).copyTo(image(where));
}

}  // namespace

int ForcePlotAxes::col(double t) const {
  return area.x + static_cast<int>(std::lround(std::clamp(t / t_max, 0.0, 1.0) * (area.width - 1)));
}

int ForcePlotAxes::row(double f) const {
  const double u = std::clamp((f - f_min) / (f_max - f_min), 0.0, 1.0);
  return area.y + area.height - 1 - static_cast<int>(std::lround(u * (area.height - 1)));
}

ForcePlotAxes forcePlotAxes(const std::vector<ForceSample>& trace, cv::Size size) {
  ForcePlotAxes a;
  a.area = cv::Rect(kLeft, kTop, std::max(size.width - kLeft - kRight, 2), std::max(size.height - kTop - kBottom, 2));
  double t_end = 0.0, f_hi = 0.0, f_lo = 0.0;
  for (const ForceSample& s : trace) {
    if (std::isfinite(s.t)) t_end = std::max(t_end, s.t);
    for (double f : {s.force, s.target, s.limit}) {
      if (!std::isfinite(f)) continue;
      f_hi = std::max(f_hi, f);
      f_lo = std::min(f_lo, f);
    }
  }
  // Time to the next half tick after the last sample.
  a.t_step = niceStep(std::max(t_end, 0.5), 8);
  const double t_half = a.t_step / 2.0;
  a.t_max = std::max(2.0, std::ceil(t_end / t_half - 1e-9)) * t_half;
  // 10 % of head room over the highest of force, set-point and cap, to a tick; below 0 (to a fifth of a tick) only
  // as far as the force went there.
  a.f_step = niceStep(std::max(1.1 * f_hi, 1.0), 6);
  a.f_max = std::max(1.0, std::ceil(1.1 * f_hi / a.f_step - 1e-9)) * a.f_step;
  a.f_min = f_lo < 0.0 ? -std::ceil(-f_lo / (a.f_step / 5.0) - 1e-9) * (a.f_step / 5.0) : 0.0;
  return a;
}

cv::Mat drawForcePlot(const std::vector<ForceSample>& trace, const std::string& title, cv::Size size) {
  if (trace.empty()) return {};
  const ForcePlotAxes a = forcePlotAxes(trace, size);
  cv::Mat out(size, CV_8UC3, cv::Scalar::all(255));
  const cv::Rect& area = a.area;
  const int bottom = area.y + area.height - 1, right = area.x + area.width - 1;
  // The hold phase (a stroke's glide), shaded: each such sample until the next one.
  for (std::size_t i = 0; i < trace.size(); ++i) {
    if (trace[i].phase != "hold" && trace[i].phase != "glide") continue;
    const double t_next = i + 1 < trace.size() ? trace[i + 1].t : trace[i].t;
    const int x0 = a.col(trace[i].t), x1 = std::max(a.col(t_next), x0 + 1);
    cv::rectangle(out, cv::Rect(x0, area.y, x1 - x0, area.height), kHoldShade, cv::FILLED);
  }
  // Grid and ticks.
  const double t_step = a.t_step, f_step = a.f_step;
  for (double t = 0.0; t <= a.t_max + 1e-9; t += t_step) {
    const int x = a.col(t);
    cv::line(out, {x, area.y}, {x, bottom}, kGrid, 1);
    cv::line(out, {x, bottom}, {x, bottom + 4}, kInk, 1);
    const std::string label = tickLabel(t, t_step);
    text(out, label, {x - textSize(label, 0.4).width / 2, bottom + 18}, 0.4, kInk);
  }
  for (double f = std::ceil(a.f_min / f_step - 1e-9) * f_step; f <= a.f_max + 1e-9; f += f_step) {
    const int y = a.row(f);
    cv::line(out, {area.x, y}, {right, y}, kGrid, 1);
    cv::line(out, {area.x - 4, y}, {area.x, y}, kInk, 1);
    const std::string label = tickLabel(f, f_step);
    const cv::Size s = textSize(label, 0.4);
    text(out, label, {area.x - 7 - s.width, y + s.height / 2}, 0.4, kInk);
  }
  cv::line(out, {area.x, area.y}, {area.x, bottom}, kInk, 1);
  cv::line(out, {area.x, bottom}, {right, bottom}, kInk, 1);
  const std::string t_label = "time since the press began (s)";
  text(out, t_label, {area.x + (area.width - textSize(t_label, 0.45).width) / 2, size.height - 6}, 0.45, kInk);
  verticalText(out, "force (N)", {14, area.y + area.height / 2}, 0.45);
  // The measured force (a sample without a force breaks the curve), then the set-point over it, thin and crisp.
  for (std::size_t i = 1; i < trace.size(); ++i) {
    const ForceSample &p = trace[i - 1], &q = trace[i];
    if (!std::isfinite(p.force) || !std::isfinite(q.force)) continue;
    cv::line(out, {a.col(p.t), a.row(p.force)}, {a.col(q.t), a.row(q.force)}, kMeasuredColour, 2, cv::LINE_AA);
  }
  for (std::size_t i = 1; i < trace.size(); ++i) {
    const ForceSample &p = trace[i - 1], &q = trace[i];
    if (!std::isfinite(p.target) || !std::isfinite(q.target)) continue;
    cv::line(out, {a.col(p.t), a.row(p.target)}, {a.col(q.t), a.row(q.target)}, kTargetColour, 1, cv::LINE_8);
  }
  // The cap: a red line across at its force.
  const double limit = forceFigures(trace).limit;
  if (limit > 0.0) cv::line(out, {area.x, a.row(limit)}, {right, a.row(limit)}, kLimitColour, 1, cv::LINE_8);
  // Title, and the legend in the top margin.
  text(out, title, {area.x, 17}, 0.5, kInk);
  int x = area.x;
  const int y = 35;
  const auto entry = [&](const std::string& label, const cv::Scalar& colour, int thickness) {
    if (thickness > 0) {
      cv::line(out, {x, y - 4}, {x + 18, y - 4}, colour, thickness, cv::LINE_AA);
    } else {
      cv::rectangle(out, cv::Rect(x, y - 9, 18, 10), colour, cv::FILLED);
    }
    text(out, label, {x + 22, y}, 0.4, kInk);
    x += 22 + textSize(label, 0.4).width + 14;
  };
  entry("measured", kMeasuredColour, 2);
  entry("set-point", kTargetColour, 1);
  entry(detail::format("cap %.1f N", limit), kLimitColour, 1);
  entry("hold", kHoldShade, 0);
  return out;
}

}  // namespace massage_cell::session
