// The Middlebury stereo scenes the tools and tests evaluate on: loading a scene from the folder it is given (the
// tools find the folders: src/tools/package_paths.h), and the bad-pixel measure. ROS-free.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

/// A Middlebury scene as laid out in shared/data/middlebury2003 (tsukuba, venus, teddy, cones: official
/// masks) or shared/data/middlebury2005 (art, dolls: third size, no masks ship; `all` = every pixel with
/// known GT, `nonocc` = those whose match lies inside the right image (x >= d_gt), `disc` = nonocc pixels
/// within 4 px of a GT jump > 2 px).
struct MiddleburyScene {
  std::string name;
  cv::Mat left, right;
  cv::Mat ground_truth;       ///< CV_32F pixels, 0 = unknown
  cv::Mat nonocc, all, disc;  ///< CV_8U masks, non-zero (255) = evaluated
  int dmax = 0;               ///< search range 0..dmax (official for 2003; 79 for 2005's GT up to 75)
  int scale = 1;              ///< GT value / scale = disparity
};

/// The scene names in the order of the thesis's tables, and the two 2005 scenes.
const std::vector<std::string>& middleburyScenes();
const std::vector<std::string>& middlebury2005Scenes();
bool isMiddlebury2005Scene(const std::string& name);
/// Loads a scene from `root` (the folder of its year); throws std::runtime_error naming the missing file,
/// the folder or an unknown scene.
MiddleburyScene loadMiddleburyScene(const std::string& root, const std::string& name);

/// Percentage of evaluated pixels (mask == 255 and GT known) whose disparity
/// is off by more than `threshold` pixels (NaN counts as bad).
double badPixelPercent(const cv::Mat& disparity, const cv::Mat& ground_truth, const cv::Mat& mask, double threshold);

}  // namespace massage_cell::stereo
