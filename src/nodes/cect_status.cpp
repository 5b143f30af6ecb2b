#include "cect_status.h"

#include <cmath>

namespace massage_cell::nodes {

void CectStatus::record(const cect::CectFrame& frame, const cect::TrackerUpdate& update, int rejected) {
  if (!update.problem.empty()) ++unusable_;
  last_problem_ = update.problem;
  last_valid_ = update.valid;
  last_measured_ = update.measured;
  rejected_outliers_ = rejected;
  last_cect_ms_ = frame.timings().total_ms;
  if (frame.valid()) last_scale_ = frame.scale();
  last_disparity_range_ = frame.disparityRange();
  if (std::isfinite(update.body_angle_deg)) last_body_angle_ = update.body_angle_deg;
  if (!update.landmarks.empty()) last_landmarks_ = update.landmarks;
  if (frame.left().valid) last_trunk_ = frame.left().trunk.summary();
  last_background_ = frame.background().summary();
}

void CectStatus::report(diagnostic_updater::DiagnosticStatusWrapper& status, const PairStats& stats,
                        const StereoPairInput::Counts& input, int total, const std::string& model_path) const {
  using diagnostic_msgs::DiagnosticStatus;
  if (!client_profile_problem_.empty()) {  // a configuration error: no layout is trusted until a restart
    status.summary(DiagnosticStatus::ERROR, client_profile_problem_);
  } else if (stats.lastPairBad()) {
    status.summary(DiagnosticStatus::ERROR, "last pair skipped: " + stats.lastError());
  } else if (stats.processed() > 0 && !last_problem_.empty()) {
    status.summary(DiagnosticStatus::WARN, last_problem_);
  } else if (stats.recentError()) {
    status.summary(DiagnosticStatus::WARN, "some pairs were bad and skipped");
  } else if (input.received == 0) {
    status.summary(DiagnosticStatus::OK, "waiting for stereo pairs");
  } else if (last_valid_ < total) {
    status.summary(DiagnosticStatus::WARN,
                   std::to_string(last_valid_) + " of " + std::to_string(total) + " acupoints valid");
  } else {
    status.summary(DiagnosticStatus::OK, "all " + std::to_string(total) + " acupoints valid");
  }
  status.add("acupoint model", model_path);
  status.add("client profile", client_profile_);
  status.add("input", input_);
  stats.addCounts(status, input);
  status.add("pairs without acupoints", unusable_);
  status.add("valid acupoints", last_valid_);
  status.add("acupoints", total);
  status.add("acupoints measured in the last pair", last_measured_);
  status.add("outliers rejected", rejected_outliers_);
  stats.addTimes(status, "last CECT time (ms)", last_cect_ms_);
  status.add("view scale (auto_scale; 1 = the reference view)", last_scale_);
  status.add("disparities searched (px, from min_depth / max_depth and camera_info)",
             std::to_string(last_disparity_range_[0]) + ".." + std::to_string(last_disparity_range_[1]));
  status.add("body turned on the table (degrees, + head toward the image right)", last_body_angle_);
  status.add("landmarks (measured; inferred)", last_landmarks_);
  status.add("trunk (what the segmentation cut away)", last_trunk_);
  status.add("background (far behind the table, by depth)", last_background_);
  if (!last_markers_.empty()) status.add("skin markers", last_markers_);
  status.add("last reason", last_problem_);
  status.add("last error", stats.lastError());
}

}  // namespace massage_cell::nodes
