// cect_eval --pictures: a pair's rectified left view with the back's
// contour, the model's midline and the acupoints coloured by CECT's error.
#pragma once

#include <functional>
#include <map>
#include <string>

#include <opencv2/core.hpp>

#include "cect_eval_options.h"
#include "cect_eval_pair.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/locate.h"

namespace massage_cell::tools::cect_eval {

/// --pictures: one pair's picture (see the usage).
void writePicture(const Options& o, const Condition& c, int subject, const cect::CectFrame& f,
                  const cect::LocatedAcupoints& result, const std::map<std::string, Eigen::Vector3d>& anatomical,
                  const camera::StereoModel& geometry,
                  const std::function<bool(const cv::Point2f&, Eigen::Vector3d*)>& truth);

}  // namespace massage_cell::tools::cect_eval
