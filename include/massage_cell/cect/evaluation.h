// Scoring the acupoint chain's result on one pair against the anatomy (the
// simulator's, or any annotated back): the vertebral levels C7, T7 and L4
// along the body and across it, the spine line across, each placed acupoint
// against its anatomical place, and whether the pair was published valid -
// so that a layout published valid but far off ("wrongly trusted") is
// counted, not averaged away. ROS-free; cect_eval prints the summaries.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/locate.h"

namespace massage_cell::cect {

/// What is known of one pair's back (left optical frame, metres).
struct BackTruth {
  /// Vertebral levels on the skin of the midline: "C7", "T7", "L4" at least (more are ignored).
  std::map<std::string, Eigen::Vector3d> levels;
  /// The spine line on the skin, head to feet (at least two points).
  std::vector<Eigen::Vector3d> midline;
  /// Every anatomical acupoint in view (both cameras, on the back's skin); the others are not scored.
  std::map<std::string, Eigen::Vector3d> acupoints_in_view;
  /// The true surface point seen at a rectified left pixel; false off the body (the scorer then takes the pixel's
  /// ray at the depth of the truth it is compared with).
  std::function<bool(const cv::Point2f& rect_pixel, Eigen::Vector3d* point)> surface;
};

/// The levels the scorer measures, in order.
const std::vector<std::string>& scoredLevels();

/// One level's error: CECT's level pixel's surface point minus the true level, along the body (+: toward the feet;
/// the direction C7 -> L4) and across it (+: toward the subject's left), mm.
struct LevelError {
  std::string level;
  bool scored = false;  ///< the pair gave landmarks (valid or refused) and the truth has the level
  double along_mm = 0.0, across_mm = 0.0;
};

struct PairScore {
  bool landmarks = false;          ///< the chain found landmarks (whether or not it then trusted its layout)
  bool published = false;          ///< LocatedAcupoints::valid: the pair's acupoints were published as valid
  std::string reason;              ///< why not published
  std::vector<LevelError> levels;  ///< scoredLevels(), in order
  /// The largest |along| of the scored levels, mm (NaN without landmarks).
  double worst_level_mm = 0.0;
  /// Mean |across| of CECT's spine line between C7 and L4 against the true one, mm (NaN without landmarks).
  double midline_across_mm = 0.0;
  /// Per placed acupoint in view (published valid or not): its pixel's surface point to the anatomical acupoint, mm.
  std::map<std::string, double> layout_mm;
  int in_view = 0;            ///< acupoints in view
  int valid_in_view = 0;      ///< ... of them published valid (placed and localised)
  int valid_out_of_view = 0;  ///< acupoints published valid though not in view

  /// The landmarks more than `limit_mm` off: a level along the body (worst_level_mm) or the spine line across it
  /// (midline_across_mm); false without landmarks.
  bool farOff(double limit_mm = kWrongLevelMm) const;
  /// Published valid though farOff(limit_mm): the failure the checks must prevent.
  bool wronglyTrusted(double limit_mm = kWrongLevelMm) const;
  /// issue 44's limit, along and across: twice the experts' spread (16-24 mm)
  static constexpr double kWrongLevelMm = 40.0;
};

/// Scores `result` (landmarks and points as locateAcupoints gave them) on `geometry`'s rectified left view.
PairScore scorePair(const LocatedAcupoints& result, const AcupointModel& model, const camera::StereoModel& geometry,
                    const BackTruth& truth);

/// Mean, 95th percentile (nearest rank) and maximum of |values| (the finite ones), and their median (the upper
/// middle of an even count: a sample); NaN each when empty. The one place CECT's figures take these statistics.
struct Spread {
  int count = 0;
  double mean = 0.0, p95 = 0.0, max = 0.0;
  double median = 0.0;
};
Spread spreadOf(const std::vector<double>& values);

/// The pairs of one condition together.
struct ScoreSummary {
  int pairs = 0;
  int published = 0;        ///< pairs published valid
  int refused = 0;          ///< pairs not published (with a reason)
  int wrongly_trusted = 0;  ///< published though PairScore::farOff() (a level or the spine line > kWrongLevelMm)
  int refused_wrong = 0;    ///< refused pairs whose landmarks were indeed that far off (the checks were right)
  std::map<std::string, Spread> levels;  ///< |along| per level over the published pairs
  Spread worst_level;                    ///< per published pair, its worst level
  Spread midline_across;                 ///< over the published pairs
  Spread layout;                         ///< every scored acupoint of the published pairs
  /// Acupoints over the published pairs: in view, ... published valid, published valid though not in view.
  int in_view = 0, valid_in_view = 0, valid_out_of_view = 0;
  /// Share of the published pairs' in-view acupoints published valid (0 when none in view).
  double placedShare() const;
};
ScoreSummary summarise(const std::vector<PairScore>& pairs);

}  // namespace massage_cell::cect
