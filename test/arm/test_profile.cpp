// Synchronised trapezoid profiles: every axis within its limits, all arriving
// at the same time, the tool on the straight line.
#include <gtest/gtest.h>

#include <random>

#include "massage_cell/arm/profile.h"

namespace {

using namespace massage_cell::arm;

TEST(Profile, SingleAxisTrapezoidDuration) {
  // 0.15 m at 0.1 m/s, 0.5 m/s^2: 1.5 s cruise-equivalent + 0.2 s.
  EXPECT_NEAR(trapezoidDuration(0.15, 0.1, 0.5), 1.7, 1e-12);
  // Triangle: 0.01 m at 0.5 m/s^2 never reaches 0.1 m/s: 2 sqrt(d / a).
  EXPECT_NEAR(trapezoidDuration(0.01, 0.1, 0.5), 2.0 * std::sqrt(0.02), 1e-12);
  EXPECT_EQ(trapezoidDuration(0.0, 0.1, 0.5), 0.0);
}

TEST(Profile, AxesShareOneDurationWithinTheirLimits) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-0.5, 0.5), lim(0.02, 0.3);
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector3d a(pos(rng), pos(rng), pos(rng)), b(pos(rng), pos(rng), pos(rng));
    const Eigen::Vector3d vmax(lim(rng), lim(rng), lim(rng)), amax(5 * lim(rng), 5 * lim(rng), 5 * lim(rng));
    const SyncProfile p = planSyncProfile(a, b, vmax, amax);
    bool saturated = false;
    for (int i = 0; i < 3; ++i) {
      EXPECT_LE(p.velocity[i], vmax[i] * (1 + 1e-9));
      EXPECT_LE(p.acceleration[i], amax[i] * (1 + 1e-9));
      saturated |= p.velocity[i] > vmax[i] * (1 - 1e-9) || p.acceleration[i] > amax[i] * (1 - 1e-9);
      // Each axis's own trapezoid with these values lasts exactly the common duration.
      EXPECT_NEAR(trapezoidDuration(b[i] - a[i], p.velocity[i], p.acceleration[i]), p.duration, 1e-9);
    }
    EXPECT_TRUE(saturated) << "the profile is slower than it needs to be";
    // No axis alone could be faster than the slowest one's own time-optimal profile.
    double slowest = 0.0;
    for (int i = 0; i < 3; ++i) slowest = std::max(slowest, trapezoidDuration(b[i] - a[i], vmax[i], amax[i]));
    EXPECT_GE(p.duration, slowest - 1e-9);
  }
}

TEST(Profile, ToolFollowsTheStraightLineMonotonically) {
  const Eigen::Vector3d a(0.1, 0.2, 0.25), b(0.5, 0.25, 0.15);
  const SyncProfile p = planSyncProfile(a, b, {0.1, 0.1, 0.05}, {0.5, 0.5, 0.25});
  EXPECT_TRUE(p.positionAt(0).isApprox(a));
  EXPECT_TRUE(p.positionAt(p.duration).isApprox(b));
  double last = 0.0;
  for (double t = 0; t <= p.duration; t += 0.01) {
    const double s = p.progress(t);
    EXPECT_GE(s, last - 1e-12);
    last = s;
    const Eigen::Vector3d x = p.positionAt(t);
    const Eigen::Vector3d dir = (b - a).normalized();
    EXPECT_LT(((x - a) - dir.dot(x - a) * dir).norm(), 1e-12);
  }
  // The speed along the path never exceeds the peak.
  for (double t = 0; t + 0.001 <= p.duration; t += 0.001) {
    EXPECT_LE((p.positionAt(t + 0.001) - p.positionAt(t)).norm() / 0.001, (b - a).norm() * p.peak * (1 + 1e-6));
  }
}

TEST(Profile, PathLimitsAndNullMove) {
  const Eigen::Vector3d a(0, 0, 0.2), b(0, 0, 0.19);
  const SyncProfile p = planSyncProfile(a, b, {0.1, 0.1, 0.05}, {0.5, 0.5, 0.25}, 0.002, 0.1);
  EXPECT_NEAR(p.velocity.z(), 0.002, 1e-12);  // 2 mm/s down
  EXPECT_NEAR(p.duration, 0.01 / 0.002 + 0.002 / 0.1, 1e-9);
  const SyncProfile none = planSyncProfile(a, a, {0.1, 0.1, 0.05}, {0.5, 0.5, 0.25});
  EXPECT_EQ(none.duration, 0.0);
  EXPECT_TRUE(none.positionAt(1.0).isApprox(a));
  EXPECT_THROW(planSyncProfile(a, b, {0.1, 0.0, 0.05}, {0.5, 0.5, 0.25}), std::invalid_argument);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
