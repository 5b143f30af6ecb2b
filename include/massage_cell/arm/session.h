// A massage session (the cell's main job): the routine from
// config/session.yaml, the wait for a stable acupoint fix before the arm
// moves, and the record of each press against the recording's ground truth,
// summarised for the user. ROS-free (Eigen + yaml-cpp); the massage_session
// node (src/nodes/massage_session.cpp) drives it.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace massage_cell::arm {

struct SessionConfig {
  std::vector<std::string> acupoints;  ///< pressed in this order (names of config/acupoints.yaml)
  std::string technique = "press";     ///< press or knead
  std::string mode = "depth";          ///< force (each press held at `force`) or depth (pressed `depth` past the skin)
  double force = 0.0;                  ///< N (mode force); 0: each region's default force
  double depth = 0.003;                ///< m past the surface (mode depth; the arm clamps it to the region's limit)
  double hold = 2.0;                   ///< s at depth
  int repeats = 1;                     ///< presses per acupoint
  std::string frame_prefix = "acupoint/";
  /// A fix is stable when every acupoint of the routine has `fix_samples`
  /// valid estimates within the last `fix_window` s, all within
  /// `fix_tolerance` m of their mean.
  double fix_window = 1.5;
  int fix_samples = 5;
  double fix_tolerance = 0.004;
  double fix_timeout = 60.0;  ///< s: no stable fix by then is a failed session
  /// Loads and validates a session file; throws std::runtime_error naming
  /// the file and the field.
  static SessionConfig load(const std::string& path);
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// Recent estimates per acupoint, and whether they have settled.
class StableFix {
 public:
  StableFix(double window_s, int samples, double tolerance_m);
  /// One estimate at time t (s); an invalid one clears the acupoint's history.
  void add(const std::string& name, double t, const Eigen::Vector3d& position, bool valid);
  bool stable(const std::string& name, double now) const;
  /// The acupoints of `names` not stable at `now`.
  std::vector<std::string> unstable(const std::vector<std::string>& names, double now) const;
  /// Mean of the recent estimates (NaN when none).
  Eigen::Vector3d mean(const std::string& name, double now) const;

 private:
  struct Sample {
    double t;
    Eigen::Vector3d p;
  };
  std::vector<Sample> recent(const std::string& name, double now) const;
  double window_, tolerance_;
  int samples_;
  std::map<std::string, std::vector<Sample>> history_;
};

/// One acupoint's press, as the session saw it.
struct PressRecord {
  std::string acupoint;
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
  double error() const {
    return by_force ? (tool_at_depth - truth_at_depth).head<2>().norm() : (tool_at_depth - truth_at_depth).norm();
  }
  /// Mode force: how deep the tool held below the true skin point, m.
  double indentation() const { return truth_at_depth.z() - tool_at_depth.z(); }
  /// The arm's own share: the tool against where it was sent (CECT's acupoint).
  double placement() const { return (tool_at_depth - target_at_depth).norm(); }
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
  /// Presses done and within `tolerance` m of the truth.
  int within(double tolerance) const;
  /// Lines for the terminal: the fix, every press, the verdict.
  std::string summary(double tolerance) const;
  /// Writes `dir`/index.html: the summary's facts as tables, and the
  /// pictures named in `pictures` (file names in `dir`, with captions).
  /// Throws std::runtime_error naming the file when it cannot be written.
  void writeHtml(const std::string& dir, double tolerance,
                 const std::vector<std::pair<std::string, std::string>>& pictures) const;
};

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

}  // namespace massage_cell::arm
