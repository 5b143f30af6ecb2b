// rostest: the camera driver's stream. Pairs arrive with identical stamps,
// camera_info matches its image (stamp, frame, size), the right projection
// carries the baseline, the rate is the requested one (+-10%), the right
// optical frame is on tf, and diagnostics report the published frames.
//
// Parameters (private): stereo (bool), expected_rate (Hz), frame_id,
// right_frame_id, baseline (m), rectified (bool), min_pairs.
#include <gtest/gtest.h>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

using sensor_msgs::CameraInfo;
using sensor_msgs::CameraInfoConstPtr;
using sensor_msgs::Image;
using sensor_msgs::ImageConstPtr;

namespace {

struct Sample {
  ImageConstPtr image[2];
  CameraInfoConstPtr info[2];
};

class DriverStream : public ::testing::Test {
 protected:
  void SetUp() override {
    pnh_.param("stereo", stereo_, true);
    pnh_.param("expected_rate", expected_rate_, 20.0);
    pnh_.param("min_pairs", min_pairs_, 30);
    pnh_.param<std::string>("frame_id", frame_id_, "stereo_left_optical_frame");
    pnh_.param<std::string>("right_frame_id", right_frame_id_, "stereo_right_optical_frame");
    pnh_.param("baseline", baseline_, 0.06);
    pnh_.param("rectified", rectified_, true);
  }

  /// Collects synchronised samples until `count` arrived or `timeout` passed.
  std::vector<Sample> collect(int count, double timeout) {
    std::vector<Sample> samples;
    if (stereo_) {
      message_filters::Subscriber<Image> l(nh_, "left/image_raw", 50), r(nh_, "right/image_raw", 50);
      message_filters::Subscriber<CameraInfo> li(nh_, "left/camera_info", 50), ri(nh_, "right/camera_info", 50);
      using Policy = message_filters::sync_policies::ExactTime<Image, Image, CameraInfo, CameraInfo>;
      message_filters::Synchronizer<Policy> sync(Policy(50), l, r, li, ri);
      samples_ = &samples;
      sync.registerCallback(&DriverStream::onStereo, this);
      spinUntil([&] { return static_cast<int>(samples.size()) >= count; }, timeout);
    } else {
      message_filters::Subscriber<Image> l(nh_, "image_raw", 50);
      message_filters::Subscriber<CameraInfo> li(nh_, "camera_info", 50);
      using Policy = message_filters::sync_policies::ExactTime<Image, CameraInfo>;
      message_filters::Synchronizer<Policy> sync(Policy(50), l, li);
      samples_ = &samples;
      sync.registerCallback(&DriverStream::onMono, this);
      spinUntil([&] { return static_cast<int>(samples.size()) >= count; }, timeout);
    }
    return samples;
  }

  void onStereo(const ImageConstPtr& a, const ImageConstPtr& b, const CameraInfoConstPtr& c,
                const CameraInfoConstPtr& d) {
    samples_->push_back(Sample{{a, b}, {c, d}});
  }
  void onMono(const ImageConstPtr& a, const CameraInfoConstPtr& c) {
    samples_->push_back(Sample{{a, nullptr}, {c, nullptr}});
  }

  template <typename Done>
  static void spinUntil(Done done, double timeout) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
    while (ros::ok() && !done() && ros::WallTime::now() < end) {
      ros::spinOnce();
      ros::WallDuration(0.005).sleep();
    }
  }

  ros::NodeHandle nh_, pnh_{"~"};
  bool stereo_ = true, rectified_ = true;
  double expected_rate_ = 20.0, baseline_ = 0.06;
  int min_pairs_ = 30;
  std::vector<Sample>* samples_ = nullptr;
  std::string frame_id_, right_frame_id_;
};

TEST_F(DriverStream, PairsShareStampsFramesAndMatchingCameraInfo) {
  const auto samples = collect(min_pairs_, 30.0);
  ASSERT_GE(static_cast<int>(samples.size()), min_pairs_) << "too few synchronised samples";
  const int views = stereo_ ? 2 : 1;
  for (const auto& s : samples) {
    for (int v = 0; v < views; ++v) {
      EXPECT_EQ(s.image[v]->header.stamp, s.image[0]->header.stamp);
      EXPECT_EQ(s.info[v]->header.stamp, s.image[v]->header.stamp) << "camera_info stamp differs from its image";
      EXPECT_EQ(s.image[v]->header.frame_id, frame_id_);
      EXPECT_EQ(s.info[v]->header.frame_id, frame_id_);
      EXPECT_EQ(s.info[v]->width, s.image[v]->width);
      EXPECT_EQ(s.info[v]->height, s.image[v]->height);
      EXPECT_GT(s.info[v]->K[0], 0.0) << "camera_info is not calibrated";
      if (rectified_) {
        for (double d : s.info[v]->D) EXPECT_EQ(d, 0.0);
        EXPECT_EQ(s.info[v]->R[0], 1.0);
        EXPECT_EQ(s.info[v]->R[4], 1.0);
        EXPECT_EQ(s.info[v]->K[0], s.info[v]->P[0]);
      }
    }
    EXPECT_EQ(s.info[0]->P[3], 0.0);
    if (stereo_) {
      EXPECT_NEAR(-s.info[1]->P[3] / s.info[1]->P[0], baseline_, 1e-6) << "right P[3] must be -fx*B";
      EXPECT_EQ(s.image[0]->width, s.image[1]->width);
    }
  }
  // Distinct frames, strictly increasing stamps.
  for (std::size_t i = 1; i < samples.size(); ++i) {
    EXPECT_LT(samples[i - 1].image[0]->header.stamp, samples[i].image[0]->header.stamp);
  }
}

TEST_F(DriverStream, RateIsTheRequestedOne) {
  collect(5, 30.0);  // let the stream settle
  const auto samples = collect(min_pairs_, 30.0);
  ASSERT_GE(static_cast<int>(samples.size()), min_pairs_);
  const double span = (samples.back().image[0]->header.stamp - samples.front().image[0]->header.stamp).toSec();
  const double rate = (samples.size() - 1) / span;
  EXPECT_NEAR(rate, expected_rate_, 0.1 * expected_rate_)
      << "measured " << rate << " Hz over " << samples.size() << " samples";
}

TEST_F(DriverStream, RightOpticalFrameIsOnTf) {
  if (!stereo_) GTEST_SKIP() << "mono driver: no right camera";
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  geometry_msgs::TransformStamped t;
  bool found = false;
  spinUntil(
      [&] {
        try {
          t = buffer.lookupTransform(frame_id_, right_frame_id_, ros::Time(0));
          found = true;
        } catch (const tf2::TransformException&) {
        }
        return found;
      },
      10.0);
  ASSERT_TRUE(found) << "no transform " << frame_id_ << " -> " << right_frame_id_;
  EXPECT_NEAR(t.transform.translation.x, baseline_, 1e-6);
  EXPECT_NEAR(t.transform.translation.y, 0.0, 1e-9);
  EXPECT_NEAR(t.transform.rotation.w, 1.0, 1e-9);
}

TEST_F(DriverStream, DiagnosticsReportPublishedFrames) {
  diagnostic_msgs::DiagnosticArrayConstPtr last;
  long published = -1;
  long bad = -1;
  bool rate_ok = false;
  ros::Subscriber sub = nh_.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 20, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        for (const auto& status : msg->status) {
          if (status.name.find("source") != std::string::npos) {
            for (const auto& kv : status.values) {
              if (kv.key == "frames published") published = std::stol(kv.value);
              if (kv.key == "bad frames") bad = std::stol(kv.value);
            }
          }
          if (status.name.find("images") != std::string::npos || status.name.find("image pairs") != std::string::npos) {
            rate_ok = rate_ok || status.level == diagnostic_msgs::DiagnosticStatus::OK;
          }
        }
      });
  spinUntil([&] { return published > 10 && rate_ok; }, 20.0);
  EXPECT_GT(published, 10);
  EXPECT_EQ(bad, 0);
  EXPECT_TRUE(rate_ok) << "the rate diagnostic never reported OK";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_driver_stream");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
