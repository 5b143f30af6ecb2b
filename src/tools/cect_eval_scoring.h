// cect_eval's scoring of query pixels: CECT's and StereoSGBM's 3D errors at
// rectified left pixels against the surface the simulator rendered there.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "cect_eval_options.h"
#include "cect_eval_pair.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/sim/stereo_frame.h"

namespace massage_cell::tools::cect_eval {

/// StereoSGBM (3-way) on the rectified pair: disparities, NaN where it gives none.
cv::Mat sgbmDisparity(const camera::StereoModel& geometry, const sim::StereoFrame& frame, int width);

/// A rectified left pixel to score, and CECT's point there when it is already known (the placed acupoints).
struct Query {
  cv::Point2f rect;
  const cect::LocalizedPoint* cect = nullptr;
  std::string name;  ///< acupoints
};

/// Up to `count` of the mask's pixels in a shuffled order (seeded), as rectified queries.
std::vector<Query> randomQueries(const cv::Mat& mask, std::uint32_t seed, int count,
                                 const camera::StereoModel& geometry);

/// CECT's and StereoSGBM's 3D errors at query pixels against the rendered surface.
class Scorer {
 public:
  Scorer(const cect::CectFrame& f, const camera::StereoModel& geometry, const sim::StereoFrame& frame,
         const Eigen::Isometry3d& left_from_world, const cv::Mat& sgbm, PairResult* res)
      : f_(f), geometry_(geometry), frame_(frame), left_from_world_(left_from_world), sgbm_(sgbm), res_(res) {}

  /// The surface point seen at a rectified left pixel.
  bool truth(const cv::Point2f& rect, Eigen::Vector3d* p) const;

  /// CECT's and SGBM's figures on a point set (`queried`: the set's nominal size; queries without ground truth
  /// are not counted). Named queries also fill the per-point figures.
  std::pair<Stats, Stats> score(const std::vector<Query>& qs, int queried) const;

 private:
  bool sgbmPoint(const cv::Point2f& q, Eigen::Vector3d* p) const;

  const cect::CectFrame& f_;
  const camera::StereoModel& geometry_;
  const sim::StereoFrame& frame_;
  const Eigen::Isometry3d left_from_world_;
  const cv::Mat& sgbm_;
  PairResult* res_;
};

/// --by-border: every 4th back pixel, by its distance to the back's border, scored per band.
void scoreByBorder(const Options& o, const sim::StereoFrame& frame, const camera::StereoModel& geometry,
                   const Scorer& scorer, PairResult* res);

}  // namespace massage_cell::tools::cect_eval
