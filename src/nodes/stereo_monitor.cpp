// stereo_monitor: prints what a stereo camera publishes — each synchronised
// pair (stamp, interval, size, frame) and a summary (pairs, rate, stamp
// checks) — and exits when the stream goes quiet. The cell's demo uses it.
//
// Subscribes: left/image_raw, right/image_raw, left/camera_info,
//             right/camera_info (in its namespace; exact-time synchronised).
// Parameters: ~idle_timeout (s, 3.0): exit this long after the last pair;
//             ~start_timeout (s, 30.0): exit with an error if no pair comes;
//             ~max_pairs (0 = unlimited); ~print_every (1): print every n-th pair;
//             ~stereo_products (false): also count stereo_image_proc's
//             `disparity` and `points2` and report the median depth of points2;
//             ~products_from ("stereo_image_proc"): who publishes them (the
//             summary's label; "hbds" for this package's dense-stereo node).
// Exit code: 0 when pairs arrived and every check held, 1 otherwise, 2 a
// parameter of the wrong type.
#include <cstdio>
#include <memory>

#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <stereo_msgs/DisparityImage.h>

#include <algorithm>
#include <cmath>
#include "typed_param.h"

namespace {

using massage_cell::nodes::readParam;

using sensor_msgs::CameraInfo;
using sensor_msgs::CameraInfoConstPtr;
using sensor_msgs::Image;
using sensor_msgs::ImageConstPtr;

class Monitor {
 public:
  explicit Monitor(ros::NodeHandle& nh, ros::NodeHandle& pnh)
      : left_(nh, "left/image_raw", 5),
        right_(nh, "right/image_raw", 5),
        left_info_(nh, "left/camera_info", 5),
        right_info_(nh, "right/camera_info", 5),
        sync_(Policy(20), left_, right_, left_info_, right_info_) {
    readParam(pnh, "idle_timeout", &idle_timeout_);
    readParam(pnh, "start_timeout", &start_timeout_);
    readParam(pnh, "max_pairs", &max_pairs_);
    readParam(pnh, "print_every", &print_every_);
    if (print_every_ < 1) print_every_ = 1;
    bool products = false;
    readParam(pnh, "stereo_products", &products);
    readParam(pnh, "products_from", &products_from_);
    if (products) {
      disparity_sub_ = nh.subscribe<stereo_msgs::DisparityImage>(
          "disparity", 5, [this](const stereo_msgs::DisparityImageConstPtr&) { ++disparities_; });
      points_sub_ = nh.subscribe<sensor_msgs::PointCloud2>("points2", 5, &Monitor::onPoints, this);
    }
    sync_.registerCallback(&Monitor::onPair, this);
    left_.registerCallback([this](const ImageConstPtr&) { ++left_count_; });
    right_.registerCallback([this](const ImageConstPtr&) { ++right_count_; });
    started_ = ros::WallTime::now();
  }

  /// true while the monitor should keep listening.
  bool keepGoing() const {
    const ros::WallTime now = ros::WallTime::now();
    if (pairs_ == 0) return (now - started_).toSec() < start_timeout_;
    if (max_pairs_ > 0 && pairs_ >= static_cast<unsigned long>(max_pairs_)) return false;
    return (now - last_pair_wall_).toSec() < idle_timeout_;
  }

  int summarise() const {
    std::printf("---\n");
    if (pairs_ == 0) {
      std::printf("stereo_monitor: no synchronised pair on %s within %.0f s (left images %lu, right images %lu)\n",
                  ros::names::resolve("left/image_raw").c_str(), start_timeout_, left_count_, right_count_);
      return 1;
    }
    const double span = (last_stamp_ - first_stamp_).toSec();
    const double rate = pairs_ > 1 && span > 0 ? (pairs_ - 1) / span : 0.0;
    std::printf("pairs published:        %lu (left images %lu, right images %lu, unmatched %lu)\n", pairs_, left_count_,
                right_count_, left_count_ + right_count_ - 2 * pairs_);
    std::printf("stamps:                 %.6f .. %.6f (%.3f s)\n", first_stamp_.toSec(), last_stamp_.toSec(), span);
    std::printf("rate:                   %.2f Hz (intervals %.1f .. %.1f ms)\n", rate, min_dt_ * 1e3, max_dt_ * 1e3);
    std::printf("image size / encoding:  %ux%u %s\n", width_, height_, encoding_.c_str());
    std::printf("frame id:               %s\n", frame_id_.c_str());
    std::printf("baseline (from right P): %.4f m\n", baseline_);
    std::printf("left/right stamps equal: %s; camera_info stamps equal image stamps: %s; one frame id: %s\n",
                "yes (exact-time synchronised)", info_mismatch_ == 0 ? "yes" : "NO",
                frame_mismatch_ == 0 ? "yes" : "NO");
    if (disparity_sub_) {
      std::printf("%-24s%lu disparity images, %lu point clouds", (products_from_ + ":").c_str(), disparities_, clouds_);
      if (clouds_ > 0) std::printf("; last cloud: %.1f%% valid points, median depth %.4f m", valid_percent_, median_z_);
      std::printf("\n");
    }
    return info_mismatch_ == 0 && frame_mismatch_ == 0 ? 0 : 1;
  }

 private:
  using Policy = message_filters::sync_policies::ExactTime<Image, Image, CameraInfo, CameraInfo>;

  void onPair(const ImageConstPtr& l, const ImageConstPtr& r, const CameraInfoConstPtr& li,
              const CameraInfoConstPtr& ri) {
    const ros::Time stamp = l->header.stamp;
    if (li->header.stamp != stamp || ri->header.stamp != stamp) ++info_mismatch_;
    if (r->header.frame_id != l->header.frame_id || li->header.frame_id != l->header.frame_id ||
        ri->header.frame_id != l->header.frame_id) {
      ++frame_mismatch_;
    }
    double dt = 0.0;
    if (pairs_ == 0) {
      first_stamp_ = stamp;
    } else {
      dt = (stamp - last_stamp_).toSec();
      min_dt_ = pairs_ == 1 ? dt : std::min(min_dt_, dt);
      max_dt_ = pairs_ == 1 ? dt : std::max(max_dt_, dt);
    }
    last_stamp_ = stamp;
    last_pair_wall_ = ros::WallTime::now();
    width_ = l->width;
    height_ = l->height;
    encoding_ = l->encoding;
    frame_id_ = l->header.frame_id;
    baseline_ = ri->P[0] > 0 ? -ri->P[3] / ri->P[0] : 0.0;
    if (pairs_ % print_every_ == 0) {
      std::printf("pair %4lu  stamp %.6f  dt %7.1f ms  %ux%u %s  frame %s\n", pairs_, stamp.toSec(), dt * 1e3, l->width,
                  l->height, l->encoding.c_str(), l->header.frame_id.c_str());
      std::fflush(stdout);
    }
    ++pairs_;
  }

  void onPoints(const sensor_msgs::PointCloud2ConstPtr& cloud) {
    ++clouds_;
    std::vector<float> z;
    for (sensor_msgs::PointCloud2ConstIterator<float> it(*cloud, "z"); it != it.end(); ++it) {
      if (std::isfinite(*it)) z.push_back(*it);
    }
    const std::size_t n = static_cast<std::size_t>(cloud->width) * cloud->height;
    valid_percent_ = n > 0 ? 100.0 * z.size() / n : 0.0;
    if (!z.empty()) {
      std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
      median_z_ = z[z.size() / 2];
    }
  }

  message_filters::Subscriber<Image> left_, right_;
  message_filters::Subscriber<CameraInfo> left_info_, right_info_;
  message_filters::Synchronizer<Policy> sync_;
  double idle_timeout_ = 3.0;
  double start_timeout_ = 30.0;
  int max_pairs_ = 0;
  int print_every_ = 1;
  ros::WallTime started_, last_pair_wall_;
  unsigned long pairs_ = 0, left_count_ = 0, right_count_ = 0, info_mismatch_ = 0, frame_mismatch_ = 0;
  ros::Time first_stamp_, last_stamp_;
  double min_dt_ = 0.0, max_dt_ = 0.0, baseline_ = 0.0;
  unsigned width_ = 0, height_ = 0;
  ros::Subscriber disparity_sub_, points_sub_;
  std::string products_from_ = "stereo_image_proc";
  unsigned long disparities_ = 0, clouds_ = 0;
  double valid_percent_ = 0.0, median_z_ = 0.0;
  std::string encoding_, frame_id_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "stereo_monitor");
  ros::NodeHandle nh, pnh("~");
  std::unique_ptr<Monitor> owned;
  try {
    owned = std::make_unique<Monitor>(nh, pnh);
  } catch (const massage_cell::nodes::ParamError& e) {
    ROS_FATAL("stereo_monitor: %s", e.what());
    return 2;
  }
  Monitor& monitor = *owned;
  std::printf("stereo_monitor: listening on %s and %s\n", ros::names::resolve("left/image_raw").c_str(),
              ros::names::resolve("right/image_raw").c_str());
  std::fflush(stdout);
  ros::WallRate tick(50);  // wall time: works under /use_sim_time too
  while (ros::ok() && monitor.keepGoing()) {
    ros::spinOnce();
    tick.sleep();
  }
  return monitor.summarise();
}
