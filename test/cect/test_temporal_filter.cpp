// Unit tests of the temporal filter of localised points (cect/temporal_filter.h).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "massage_cell/cect/temporal_filter.h"

namespace {

using massage_cell::cect::FilteredPoint;
using massage_cell::cect::TemporalFilter;
using massage_cell::cect::TemporalFilterParams;

const Eigen::Matrix3d kCov = Eigen::Matrix3d::Identity() * 1e-6;  // (1 mm)^2

TemporalFilterParams params(double alpha = 0.5, double gate = 0.01, int reacquire_after = 3, double max_age = 2.0) {
  TemporalFilterParams p;
  p.alpha = alpha;
  p.gate = gate;
  p.reacquire_after = reacquire_after;
  p.max_age = max_age;
  return p;
}

TEST(TemporalFilter, FirstMeasurementIsTakenAsItIs) {
  TemporalFilter filter(params());
  EXPECT_EQ(filter.get("GV14", 0.0), nullptr);
  const Eigen::Vector3d p(0.05, -0.2, 0.75);
  EXPECT_TRUE(filter.update("GV14", p, kCov, 10.0));
  const FilteredPoint* f = filter.get("GV14", 10.0);
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->position.isApprox(p));
  EXPECT_TRUE(f->covariance.isApprox(kCov));
  EXPECT_DOUBLE_EQ(f->stamp, 10.0);
  EXPECT_EQ(f->updates, 1);
  EXPECT_EQ(f->outliers, 0);
  EXPECT_EQ(filter.get("BL23_L", 10.0), nullptr) << "another name is unknown";
}

TEST(TemporalFilter, SmoothingConverges) {
  // Noisy measurements (1 mm per axis) of a fixed point, starting 5 mm off.
  TemporalFilter filter(params(0.3));
  const Eigen::Vector3d truth(0.0, 0.1, 0.8);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.001);
  filter.update("p", truth + Eigen::Vector3d(0.005, 0.0, 0.0), kCov, 0.0);
  double sum_raw = 0.0, sum_filtered = 0.0;
  int n = 0;
  for (int i = 1; i <= 200; ++i) {
    const Eigen::Vector3d m = truth + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    ASSERT_TRUE(filter.update("p", m, kCov, 0.1 * i)) << "measurement " << i << " rejected";
    if (i > 50) {  // after the start-up transient
      sum_raw += (m - truth).norm();
      sum_filtered += (filter.get("p", 0.1 * i)->position - truth).norm();
      ++n;
    }
  }
  const FilteredPoint* f = filter.get("p", 20.0);
  ASSERT_NE(f, nullptr);
  EXPECT_LT((f->position - truth).norm(), 0.002) << "the estimate converges to the point";
  EXPECT_LT(sum_filtered / n, 0.7 * sum_raw / n) << "the filter reduces the noise";
  EXPECT_EQ(f->updates, 201);
  EXPECT_EQ(filter.rejected(), 0);
}

TEST(TemporalFilter, BlendsWithAlpha) {
  TemporalFilter filter(params(0.25));
  filter.update("p", Eigen::Vector3d(0, 0, 1), kCov, 0.0);
  filter.update("p", Eigen::Vector3d(0.008, 0, 1), 3.0 * kCov, 0.1);
  const FilteredPoint* f = filter.get("p", 0.1);
  ASSERT_NE(f, nullptr);
  EXPECT_NEAR(f->position.x(), 0.002, 1e-12);
  EXPECT_TRUE(f->covariance.isApprox(1.5 * kCov));  // 0.75 * 1 + 0.25 * 3
  EXPECT_DOUBLE_EQ(f->stamp, 0.1);

  TemporalFilter raw(params(1.0));  // alpha = 1: no smoothing
  raw.update("p", Eigen::Vector3d(0, 0, 1), kCov, 0.0);
  raw.update("p", Eigen::Vector3d(0.008, 0, 1), kCov, 0.1);
  EXPECT_NEAR(raw.get("p", 0.1)->position.x(), 0.008, 1e-12);
}

TEST(TemporalFilter, OutlierRejectedAndCounted) {
  TemporalFilter filter(params(0.5, 0.01, 3));
  const Eigen::Vector3d p(0, 0, 0.8);
  filter.update("p", p, kCov, 0.0);
  filter.update("p", p, kCov, 0.1);
  // One wild measurement (5 cm off): rejected, counted, the estimate untouched.
  EXPECT_FALSE(filter.update("p", p + Eigen::Vector3d(0, 0.05, 0), kCov, 0.2));
  EXPECT_EQ(filter.rejected(), 1);
  const FilteredPoint* f = filter.get("p", 0.2);
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->position.isApprox(p));
  EXPECT_DOUBLE_EQ(f->stamp, 0.1) << "the stamp is the last accepted measurement's";
  EXPECT_EQ(f->outliers, 1);
  EXPECT_EQ(f->updates, 2);
  // A good measurement ends the streak.
  EXPECT_TRUE(filter.update("p", p, kCov, 0.3));
  EXPECT_EQ(filter.get("p", 0.3)->outliers, 0);
  // Outliers that disagree with each other never make the filter follow them.
  for (int i = 0; i < 6; ++i) {
    const double side = (i % 2 == 0) ? 1.0 : -1.0;
    EXPECT_FALSE(filter.update("p", p + Eigen::Vector3d(side * 0.05, 0, 0), kCov, 0.4 + 0.1 * i));
  }
  EXPECT_EQ(filter.rejected(), 7);
  EXPECT_TRUE(filter.get("p", 0.9)->position.isApprox(p));
  EXPECT_EQ(filter.get("p", 0.9)->outliers, 1) << "each disagreeing outlier starts a new streak";
  // A measurement exactly at the gate is still inside.
  TemporalFilter edge(params(1.0, 0.01, 3));
  edge.update("p", Eigen::Vector3d(0, 0, 1), kCov, 0.0);
  EXPECT_TRUE(edge.update("p", Eigen::Vector3d(0.01, 0, 1), kCov, 0.1));
}

TEST(TemporalFilter, SustainedJumpIsFollowed) {
  TemporalFilter filter(params(0.5, 0.01, 3));
  const Eigen::Vector3d before(0, 0, 0.8), after(0.03, 0.0, 0.78);  // the subject moved 3.6 cm
  filter.update("p", before, kCov, 0.0);
  EXPECT_FALSE(filter.update("p", after + Eigen::Vector3d(0.002, 0, 0), kCov, 0.1));
  EXPECT_FALSE(filter.update("p", after - Eigen::Vector3d(0.002, 0, 0), kCov, 0.2));
  EXPECT_TRUE(filter.get("p", 0.2)->position.isApprox(before)) << "not yet followed after 2 outliers";
  const FilteredPoint* f = filter.get("p", 0.2);
  EXPECT_EQ(f->outliers, 2);
  EXPECT_TRUE(f->pending.isApprox(after, 1e-9)) << "pending is the streak's mean";
  // The third agreeing outlier: the filter jumps to the streak's mean.
  EXPECT_TRUE(filter.update("p", after, kCov * 2.0, 0.3));
  f = filter.get("p", 0.3);
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->position.isApprox(after, 1e-9)) << f->position.transpose();
  EXPECT_TRUE(f->covariance.isApprox(kCov * 2.0));
  EXPECT_DOUBLE_EQ(f->stamp, 0.3);
  EXPECT_EQ(f->outliers, 0);
  EXPECT_EQ(filter.rejected(), 2) << "the followed measurement is not counted as rejected";
  // From there on it tracks the new position.
  EXPECT_TRUE(filter.update("p", after, kCov, 0.4));

  // reacquire_after = 1: every outlier is followed at once.
  TemporalFilter eager(params(0.5, 0.01, 1));
  eager.update("p", before, kCov, 0.0);
  EXPECT_TRUE(eager.update("p", after, kCov, 0.1));
  EXPECT_TRUE(eager.get("p", 0.1)->position.isApprox(after));
  EXPECT_EQ(eager.rejected(), 0);
}

TEST(TemporalFilter, MaxAgeDrop) {
  TemporalFilter filter(params(0.5, 0.01, 3, 1.0));
  const Eigen::Vector3d p(0, 0, 0.8), far(0.1, 0, 0.8);
  filter.update("p", p, kCov, 5.0);
  EXPECT_NE(filter.get("p", 5.9), nullptr);
  EXPECT_NE(filter.get("p", 6.0), nullptr) << "exactly max_age old is still kept";
  EXPECT_EQ(filter.get("p", 6.01), nullptr) << "older than max_age: dropped";
  // Outliers do not refresh the estimate: it ages while they are rejected.
  filter.update("p", p, kCov, 10.0);
  filter.update("q", p, kCov, 10.0);
  EXPECT_FALSE(filter.update("p", far, kCov, 10.5));
  EXPECT_EQ(filter.get("p", 11.2), nullptr);
  // A measurement after max_age starts the point afresh, however far it is.
  EXPECT_TRUE(filter.update("p", far + Eigen::Vector3d(0.2, 0, 0), kCov, 11.5));
  const FilteredPoint* f = filter.get("p", 11.5);
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->position.isApprox(far + Eigen::Vector3d(0.2, 0, 0)));
  EXPECT_EQ(f->updates, 1);
  EXPECT_EQ(filter.get("q", 11.5), nullptr) << "q was not updated for 1.5 s";
  // The clock going back (a replay restarting) restarts the point too.
  EXPECT_TRUE(filter.update("p", p, kCov, 3.0));
  EXPECT_TRUE(filter.get("p", 3.0)->position.isApprox(p));
  EXPECT_EQ(filter.get("p", 3.0)->updates, 1);
  filter.clear();
  EXPECT_EQ(filter.get("p", 3.0), nullptr);
  EXPECT_EQ(filter.rejected(), 1) << "clear() keeps the count";
}

TEST(TemporalFilter, NonFiniteMeasurementIgnored) {
  TemporalFilter filter(params());
  const Eigen::Vector3d p(0, 0, 0.8);
  filter.update("p", p, kCov, 0.0);
  EXPECT_FALSE(filter.update("p", Eigen::Vector3d(std::nan(""), 0, 0.8), kCov, 0.1));
  Eigen::Matrix3d bad = kCov;
  bad(1, 1) = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(filter.update("p", p, bad, 0.1));
  EXPECT_FALSE(filter.update("new", Eigen::Vector3d(std::nan(""), 0, 0.8), kCov, 0.1));
  EXPECT_EQ(filter.get("new", 0.1), nullptr);
  EXPECT_EQ(filter.rejected(), 0);
  EXPECT_TRUE(filter.get("p", 0.1)->position.isApprox(p));
}

TEST(TemporalFilter, BadParamsThrow) {
  EXPECT_THROW(TemporalFilter(params(0.0)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(1.5)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(std::nan(""))), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(0.5, 0.0)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(0.5, -0.01)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(0.5, 0.01, 0)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(0.5, 0.01, 3, 0.0)), std::invalid_argument);
  EXPECT_THROW(TemporalFilter(params(0.5, 0.01, 3, -1.0)), std::invalid_argument);
  EXPECT_NO_THROW(TemporalFilter(params(1.0, 0.01, 1, 0.1)));
  try {
    TemporalFilter filter(params(0.5, 0.01, 0));
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("reacquire_after"), std::string::npos) << e.what();
  }
  // setParams throws too and keeps the previous parameters.
  TemporalFilter filter(params(1.0));
  EXPECT_THROW(filter.setParams(params(-1.0)), std::invalid_argument);
  filter.update("p", Eigen::Vector3d(0, 0, 1), kCov, 0.0);
  filter.update("p", Eigen::Vector3d(0.004, 0, 1), kCov, 0.1);
  EXPECT_NEAR(filter.get("p", 0.1)->position.x(), 0.004, 1e-12) << "alpha is still 1";
  filter.setParams(params(0.5));
  filter.update("p", Eigen::Vector3d(0.008, 0, 1), kCov, 0.2);
  EXPECT_NEAR(filter.get("p", 0.2)->position.x(), 0.006, 1e-12) << "the new alpha applies";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
