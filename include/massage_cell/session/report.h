// The massage session's report (the cell's main job): the record of each
// press against the recording's ground truth, with a press by force's force
// over time, the acupoint fix and the pipeline's latencies, summarised for
// the terminal and written as index.html with its pictures (the acupoints,
// the tool's path, the disparity, one force plot per press by force).
// ROS-free (OpenCV + Eigen); the massage_session node
// (src/nodes/massage_session.cpp) fills it. The routine itself and the
// stable-fix test are the arm's (arm/session.h).
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace massage_cell::session {

/// One sample of a press by force, as the arm's ~state reported it.
struct ForceSample {
  double t = 0.0;       ///< s since the press began (its first sample)
  double force = 0.0;   ///< N measured on the tool (NaN: not known then)
  double target = 0.0;  ///< N, the press's set-point then (ramps included)
  double limit = 0.0;   ///< N, the press's cap
  std::string phase;    ///< seek, ramp, hold (glide: a stroke's, a knead's), release, back off
};

/// What a force trace says. Each sample stands for the time to the next one
/// (the last for the spacing before it).
struct ForceFigures {
  bool has_hold = false;        ///< the trace has samples at the force: the hold phase (or the glide, a stroke's)
  double peak = 0.0;            ///< N, the highest measured force (0: none measured)
  double limit = 0.0;           ///< N, the press's cap (the highest of the trace; 0: none)
  double hold_seconds = 0.0;    ///< s in the hold phase
  double within_seconds = 0.0;  ///< s of the hold within ±10 % of the set-point
  /// within_seconds / hold_seconds (0 with no hold).
  double withinFraction() const { return hold_seconds > 0.0 ? within_seconds / hold_seconds : 0.0; }
};
/// Peak, hold and time within ±10 % of the set-point (counted over hold and glide samples only).
ForceFigures forceFigures(const std::vector<ForceSample>& trace);

/// One acupoint's press, or a stroke along a path of acupoints, as the session saw it.
struct PressRecord {
  std::string acupoint;  ///< a stroke: "BL13_L -> BL23_L"
  /// A stroke: while it glided, the tool's farthest distance across the skin from the path through the acupoints'
  /// true positions (path_error) and from the path it was given, their tf frames (tracking_error); m, NaN unknown.
  bool stroke = false;
  double path_error = std::numeric_limits<double>::quiet_NaN();
  double tracking_error = std::numeric_limits<double>::quiet_NaN();
  bool success = false;
  std::string message;  ///< the arm's answer
  double seconds = 0.0;
  bool measured = false;  ///< the tool was seen holding at depth and the truth was known
  /// Pressed by force: the depth is the body's answer to the force, so error() is across the skin (x, y) and the
  /// tool's depth into it and the force held are reported beside it.
  bool by_force = false;
  double force_held = 0.0;            ///< N, the arm's mean force while holding (mode force)
  Eigen::Vector3d tool_at_depth{};    ///< mean tool tip while holding, arm base frame
  Eigen::Vector3d truth_at_depth{};   ///< ground-truth acupoint pushed `depth` down (-z of the arm base)
  bool targeted = false;              ///< the acupoint's tf frame was seen while holding
  Eigen::Vector3d target_at_depth{};  ///< CECT's acupoint (its tf frame) pushed `depth` down, likewise
  /// A press by force: its force over time (empty: a press to a depth, or no sample seen).
  std::vector<ForceSample> force_trace;
  double error() const {
    return by_force ? (tool_at_depth - truth_at_depth).head<2>().norm() : (tool_at_depth - truth_at_depth).norm();
  }
  /// Mode force: how deep the tool held below the true skin point, m.
  double indentation() const { return truth_at_depth.z() - tool_at_depth.z(); }
  /// The arm's own share: the tool against where it was sent (CECT's acupoint).
  double placement() const { return (tool_at_depth - target_at_depth).norm(); }
  /// The figures of force_trace.
  ForceFigures force() const { return forceFigures(force_trace); }
};

/// The acupoint fix against the truth at the moment the session started.
struct FixRecord {
  std::string acupoint;
  double error = 0.0;               ///< m, |estimate - truth|
  Eigen::Vector3d offset{0, 0, 0};  ///< m, estimate - truth in the camera's optical frame (x right, y down, z depth)
};

/// Latencies of one stage of the pipeline, seconds.
struct LatencyRecord {
  std::string stage;  ///< e.g. "camera stamp -> acupoint tf"
  std::vector<double> samples;
  /// The q-quantile (0..1) of the samples, nearest rank; NaN when there are none.
  double quantile(double q) const;
};

struct SessionReport {
  int pairs = 0;                ///< stereo pairs the CECT node reported on
  double seconds_to_fix = 0.0;  ///< from start to a stable fix
  std::vector<FixRecord> fix;
  /// The layout's landmarks at the fix, e.g. "C7 given (marker), L4 measured (the waist)" (empty: not known).
  std::string landmarks;
  std::vector<PressRecord> presses;
  std::vector<std::string> faults;  ///< what went wrong (empty: nothing)
  std::vector<LatencyRecord> latencies;
  /// Presses done and within `tolerance` m of the truth (strokes: their path_error).
  int within(double tolerance) const;
  /// Lines for the terminal: the fix, every press (by force: its peak and time within ±10 % of the set-point),
  /// the verdict.
  std::string summary(double tolerance) const;
  /// Writes `dir`/index.html: the summary's facts as tables, the force plot
  /// of every press with a force trace (written beside it, forcePlotFile),
  /// and the pictures named in `pictures` (file names in `dir`, with
  /// captions). Throws std::runtime_error naming the file when one cannot be
  /// written.
  void writeHtml(const std::string& dir, double tolerance,
                 const std::vector<std::pair<std::string, std::string>>& pictures) const;
};

/// The file name of the force plot of press `index` (0-based) of `acupoint`: force_<index + 1>_<acupoint>.png
/// (characters other than letters, digits, '-' and '_' as '_').
std::string forcePlotFile(std::size_t index, const std::string& acupoint);

/// Where a force plot puts its values: the plotting area, its ranges (0 .. t_max s, f_min .. f_max N; f_min is 0
/// unless the force went below it) and tick steps.
struct ForcePlotAxes {
  cv::Rect area;
  double t_max = 1.0;
  double f_min = 0.0;
  double f_max = 1.0;
  double t_step = 1.0;
  double f_step = 1.0;
  int col(double t) const;  ///< the image column of time t
  int row(double f) const;  ///< the image row of force f
};
ForcePlotAxes forcePlotAxes(const std::vector<ForceSample>& trace, cv::Size size);
/// Colours of the force plot (BGR).
inline const cv::Scalar kMeasuredColour{160, 70, 0};  ///< measured force: dark blue, solid
inline const cv::Scalar kTargetColour{0, 150, 0};     ///< the set-point: green
inline const cv::Scalar kLimitColour{0, 0, 255};      ///< the cap: red horizontal line
/// Force against time of one press: measured (solid), the set-point, the
/// limit (a red horizontal line), the hold phase shaded, labelled axes with
/// ticks in s and N, a legend and `title` above. Empty for an empty trace.
cv::Mat drawForcePlot(const std::vector<ForceSample>& trace, const std::string& title,
                      cv::Size size = cv::Size(640, 360));

/// Pictures of the report. A marked pixel: its label, where it is, and
/// whether the label is written (the routine's points; the others are dots).
struct MarkedPixel {
  std::string label;
  cv::Point2d pixel;
  bool labelled = true;
};
/// The image (BGR or grey) with the estimates as filled circles, named when
/// labelled (small unnamed dots otherwise: 108 names overprint each other at
/// 320x240), and the true positions as crosses.
/// `landmarks` (the layout's C7 / L4, labelled e.g. "C7 marker") as cyan diamonds.
cv::Mat drawAcupoints(const cv::Mat& image, const std::vector<MarkedPixel>& estimates,
                      const std::vector<MarkedPixel>& truth, const std::vector<MarkedPixel>& landmarks = {});
/// The image with the tool's path (pixels in order) as a line, darker at its start.
cv::Mat drawTrajectory(const cv::Mat& image, const std::vector<cv::Point2d>& path);
/// A float disparity image in colour (invalid: black), scaled over its valid range.
cv::Mat colourDisparity(const cv::Mat& disparity);

}  // namespace massage_cell::session
