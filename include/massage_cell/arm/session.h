// A massage session (the cell's main job): the routine from
// config/session.yaml and the wait for a stable acupoint fix before the arm
// moves. ROS-free (Eigen + yaml-cpp); the massage_session node
// (src/nodes/massage_session.cpp) drives it, and its report (each press
// against the recording's ground truth) is session/report.h's.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace massage_cell::arm {

struct SessionConfig {
  std::vector<std::string> acupoints;  ///< pressed in this order (names of config/acupoints.yaml)
  std::string technique = "press";     ///< press or knead
  std::string mode = "depth";          ///< force (each press held at `force`) or depth (pressed `depth` past the skin)
  double force = 0.0;                  ///< N (mode force); 0: each region's default force
  double depth = 0.003;                ///< m past the surface (mode depth; the arm clamps it to the region's limit)
  double hold = 2.0;                   ///< s at depth
  int repeats = 1;                     ///< presses per acupoint
  /// Strokes after the presses (mode force): each a path of acupoint names, glided along in order.
  std::vector<std::vector<std::string>> strokes;
  double stroke_force = 0.0;  ///< N; 0: the lowest default force of the regions a stroke crosses
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
  /// Every acupoint the routine needs a fix for: the pressed ones, then the strokes' not pressed, each once.
  std::vector<std::string> allAcupoints() const;
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

}  // namespace massage_cell::arm
