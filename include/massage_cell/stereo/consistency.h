// Left-right consistency and occlusion filling. A pixel of the left view
// whose match is not confirmed by the right view's own disparity map is
// occluded (seen by one camera only), in the border band where its match
// would lie off the right image, or mismatched; such pixels are marked and
// filled from the background side along their row, as an occlusion is
// background that the foreground hides from the other camera.
// ROS-free (OpenCV only). Conventions as in cost_volume.h.
#pragma once

#include <opencv2/core.hpp>

namespace massage_cell::stereo {

/// The right view's disparity map from a matcher for left-reference maps:
/// `match_left(a, b)` returns the disparity of a against b (a's pixel x
/// matches x - d in b); the right view's map is that of the mirrored pair
/// (flip(right) against flip(left)), mirrored back. Right pixel x matches
/// x + d in the left image.
template <typename LeftMatcher>
cv::Mat rightViewDisparity(const cv::Mat& left, const cv::Mat& right, LeftMatcher match_left) {
  cv::Mat left_flipped, right_flipped, disparity;
  cv::flip(left, left_flipped, 1);
  cv::flip(right, right_flipped, 1);
  cv::flip(match_left(right_flipped, left_flipped), disparity, 1);
  return disparity;
}

/// The left-right check: left pixel (x, y) with disparity d is consistent
/// when x - d lands in the right image (linear interpolation between the two
/// nearest right pixels, both finite) and the right map there is within
/// `tolerance` of d. CV_8U, 255 = consistent, 0 = not (NaN, off the right
/// image, or another disparity seen from the right). Throws
/// std::invalid_argument for maps of different sizes or types other than
/// CV_32F, or a tolerance that is not finite and >= 0.
cv::Mat leftRightCheck(const cv::Mat& left_disparity, const cv::Mat& right_disparity, float tolerance = 1.0f);

/// Each pixel where `keep` (CV_8U) is 0 takes the smaller of the nearest
/// kept finite disparities to its left and right on its row (one side only
/// at the image's edge: the border band takes the surface beside it); rows
/// with none stay NaN. Kept pixels are copied. CV_32F. Throws
/// std::invalid_argument for sizes or types that do not fit.
cv::Mat fillFromBackground(const cv::Mat& disparity, const cv::Mat& keep);

}  // namespace massage_cell::stereo
