// What the cect node's diagnostics say about the pairs it analysed. Not thread-safe: the nodelet guards it with its
// status mutex.
#pragma once

#include <cstdint>
#include <string>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <opencv2/core.hpp>

#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/tracker.h"
#include "stereo_pair_input.h"

namespace massage_cell::nodes {

class CectStatus {
 public:
  /// The last pair's analysis and tracking; `rejected`: the tracker's outliers so far.
  void record(const cect::CectFrame& frame, const cect::TrackerUpdate& update, int rejected);
  /// Size, rectification, focal length and baseline of the current calibration.
  void setInput(const std::string& summary) { input_ = summary; }
  /// What the last pair's skin markers gave (SkinMarkers::describe), with a kit.
  void setMarkers(const std::string& summary) { last_markers_ = summary; }
  /// The client's profile in effect ("none", "<file> ('<client>', C7 -> L4 ..., N corrections)") and why it could
  /// not be used ("" when it could: then the status is an error, every layout being refused with it).
  void setClientProfile(const std::string& summary, const std::string& problem) {
    client_profile_ = summary;
    client_profile_problem_ = problem;
  }

  /// The summary and values of the status, with the pairs' `stats` and `input` counts; `total`: the model's
  /// acupoints.
  void report(diagnostic_updater::DiagnosticStatusWrapper& status, const PairStats& stats,
              const StereoPairInput::Counts& input, int total, const std::string& model_path) const;

 private:
  std::string input_;
  std::uint64_t unusable_ = 0;
  std::string last_problem_;  ///< why the last analysed pair gave no acupoints (empty: it did)
  int last_valid_ = 0, last_measured_ = 0;
  int rejected_outliers_ = 0;
  double last_cect_ms_ = 0.0;
  double last_scale_ = 1.0;                   ///< the last valid pair's view scale (auto_scale)
  cv::Vec2d last_disparity_range_{0.0, 0.0};  ///< the disparities the last pair searched
  double last_body_angle_ = 0.0;         ///< the last pair's body turn against the image columns (landmarks), degrees
  std::string last_landmarks_;           ///< which landmarks the last pair measured and which it inferred
  std::string last_trunk_;               ///< what the last pair's segmentation cut away (arms, cloth)
  std::string last_background_;          ///< what the last pair's depth gate called far background
  std::string last_markers_;             ///< what the last pair's skin markers gave (empty: no kit)
  std::string client_profile_ = "none";  ///< the client's profile in effect
  std::string client_profile_problem_;   ///< why the named profile could not be used ("" it could, or none)
};

}  // namespace massage_cell::nodes
