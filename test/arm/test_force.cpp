// The tool's force from the Z drive's torque, and the body the simulated drive pushes against: the tissue's
// stiffening, breathing, the baseline's identification from free motion, the estimate against the simulated
// mechanics (can/sim_mechanics.h) with a body under the tool.
#include <gtest/gtest.h>

#include <cmath>

#include "massage_cell/arm/force_estimate.h"
#include "massage_cell/arm/sim_body.h"
#include "massage_cell/can/sim_mechanics.h"

namespace {

using namespace massage_cell;
using namespace massage_cell::arm;

TEST(Tissue, StiffensWithIndentationAsPublishedAndNeverPulls) {
  const Tissue t;  // the default: paraspinal tissue
  // massage_forces.md: ~1-5 N/mm over the first millimetre, ~10-35 N/mm at 10-20 mm.
  EXPECT_GT(t.slope(0.001), 1000.0);
  EXPECT_LT(t.slope(0.001), 5000.0);
  EXPECT_GT(t.slope(0.015), 10000.0);
  EXPECT_LT(t.slope(0.015), 35000.0);
  EXPECT_NEAR(t.force(t.indentationAt(40.0), 0.0), 40.0, 1e-9);
  EXPECT_EQ(t.force(-0.001, 0.0), 0.0);
  EXPECT_GT(t.force(0.005, 0.01), t.force(0.005, 0.0));  // pressed in: damped, pushes back more
  EXPECT_EQ(t.force(0.005, -100.0), 0.0);                // let go faster than it springs back: no pull
}

TEST(SimBody, BreathingMovesTheSkinAndOffTheBodyNothingPushes) {
  Breathing b;
  b.amplitude = 0.004;
  b.period = 4.0;
  const SimBody body = SimBody::flat(0.15, Tissue{}, b);
  EXPECT_NEAR(body.skinHeight(0.3, 0.2, 1.0), 0.152, 1e-12);  // a quarter period: the top of the breath
  EXPECT_NEAR(body.skinHeight(0.3, 0.2, 3.0), 0.148, 1e-12);
  const Eigen::Vector3d tool(0.3, 0.2, 0.145);
  EXPECT_GT(body.force(tool, 0.0, 1.0), body.force(tool, 0.0, 3.0));
  EXPECT_EQ(body.force(Eigen::Vector3d(0.3, 0.2, 0.16), 0.0, 1.0), 0.0);
  const SimBody half([](double x, double) { return x < 0.5 ? 0.15 : NAN; }, [](double, double) { return Tissue{}; });
  EXPECT_GT(half.force(Eigen::Vector3d(0.4, 0.2, 0.14), 0.0, 0.0), 0.0);
  EXPECT_EQ(half.force(Eigen::Vector3d(0.6, 0.2, 0.14), 0.0, 0.0), 0.0);
}

TEST(SkinPoints, TheSkinIsWhereItsPointsAreAndNowhereElse) {
  auto skin = std::make_shared<SkinPoints>(0.05);
  EXPECT_TRUE(std::isnan(skin->height(0.3, 0.2)));  // no points yet: no body
  skin->set({Eigen::Vector3d(0.30, 0.20, 0.15), Eigen::Vector3d(0.34, 0.20, 0.17)});
  EXPECT_NEAR(skin->height(0.30, 0.20), 0.15, 1e-3);  // on a point: that point
  EXPECT_NEAR(skin->height(0.32, 0.20), 0.16, 1e-9);  // half-way: the mean
  EXPECT_TRUE(std::isnan(skin->height(0.50, 0.20)));  // beyond the radius of every point
  const SimBody body(SkinPoints::surface(skin), [](double, double) { return Tissue{}; });
  EXPECT_GT(body.force(Eigen::Vector3d(0.30, 0.20, 0.145), 0.0, 0.0), 0.0);
  skin->set({Eigen::Vector3d(0.30, 0.20, 0.12)});  // the body moved down
  EXPECT_EQ(body.force(Eigen::Vector3d(0.30, 0.20, 0.145), 0.0, 0.0), 0.0);
}

/// The simulated Z axis of config/can_axes.yaml (true values) and what the estimate is told (nominal).
can::SimDriveSettings::Mechanics trueAxis() {
  can::SimDriveSettings::Mechanics m;
  m.screw_lead = 0.0025;
  m.screw_efficiency = 0.88;
  m.moving_mass = 4.0;
  m.gravity = 9.81;
  m.coulomb_friction = 15.0;
  m.viscous_friction = 150.0;
  m.friction_stiffness = 2e6;
  return m;
}
constexpr double kRated = 0.32;
ScrewDrive nominalDrive() { return {0.0025, 0.9, kRated}; }

/// Drives the true axis and the estimate together through position samples at 100 Hz (1 ms physics steps).
struct Axis {
  can::SimMechanics truth{trueAxis(), kRated};
  double position = 0.3, velocity = 0.0, time = 0.0;
  double external = 0.0;  ///< N on the axis this cycle
  double torque = 0.0;    ///< per mille, the last cycle's
  std::vector<FreeMotionSample> samples;
  /// Moves at `v` for `seconds` (accelerating within one step), sampling like the controller.
  void run(double v, double seconds, AxialForceEstimate* estimate = nullptr, bool record = false) {
    const int cycles = static_cast<int>(std::lround(seconds / 0.01));
    for (int c = 0; c < cycles; ++c) {
      double last_v = velocity;
      for (int k = 0; k < 10; ++k) {
        const double a = (v - velocity) / 0.001;
        velocity = v;
        position += v * 0.001;
        torque = truth.torquePerMille(truth.step(v * 0.001, v, k == 0 ? a : 0.0, external));
      }
      time += 0.01;
      const double acc = (velocity - last_v) / 0.01;
      if (estimate) estimate->update(torque, position, velocity, acc, 0.01);
      if (record) samples.push_back({nominalDrive().force(torque), velocity, acc});
    }
  }
};

TEST(ForceEstimate, IdentifiesMassAndFrictionFromMovesBothWaysAtTwoSpeeds) {
  Axis axis;
  for (double v : {0.04, 0.015}) {
    axis.run(-v, 0.5, nullptr, true);
    axis.run(+v, 0.5, nullptr, true);
  }
  std::string why;
  const AxisBaseline b = identifyBaseline(axis.samples, AxisBaseline{}, &why);
  ASSERT_TRUE(why.empty()) << why;
  // The nominal efficiency (0.9 for the true 0.88) scales what the fit sees by 0.9 / 0.88.
  const double gain = 0.9 / 0.88;
  EXPECT_NEAR(b.mass, 4.0 * gain, 0.05);
  EXPECT_NEAR(b.coulomb, 15.0 * gain, 0.5);
  EXPECT_NEAR(b.viscous, 150.0 * gain, 15.0);

  // What cannot be told apart is refused, naming why, and the prior kept.
  AxisBaseline prior;
  prior.mass = 1.0;
  std::vector<FreeMotionSample> down;
  for (const FreeMotionSample& s : axis.samples)
    if (s.velocity < 0) down.push_back(s);
  EXPECT_EQ(identifyBaseline(down, prior, &why).mass, 1.0);
  EXPECT_NE(why.find("one way"), std::string::npos) << why;
  std::vector<FreeMotionSample> fast;
  for (const FreeMotionSample& s : axis.samples)
    if (std::abs(s.velocity) > 0.03) fast.push_back(s);
  identifyBaseline(fast, prior, &why);
  EXPECT_NE(why.find("one speed"), std::string::npos) << why;
  EXPECT_EQ(identifyBaseline({}, prior, &why).mass, 1.0);
  EXPECT_NE(why.find("too few"), std::string::npos) << why;
}

TEST(ForceEstimate, ReadsThePressingForceAfterAReZeroInTheAir) {
  Axis axis;
  for (double v : {0.04, 0.015}) {
    axis.run(-v, 0.5, nullptr, true);
    axis.run(+v, 0.5, nullptr, true);
  }
  std::string why;
  const AxisBaseline identified = identifyBaseline(axis.samples, AxisBaseline{}, &why);
  ASSERT_TRUE(why.empty());
  AxialForceEstimate estimate(nominalDrive(), identified, 0.02);
  // The same without the friction's turn-over: what the estimate would read if it did not track the friction.
  AxisBaseline sliding_only = identified;
  sliding_only.coulomb = 0.0;
  AxialForceEstimate untracked(nominalDrive(), sliding_only, 0.02);
  auto run = [&](double v, double seconds) {
    Axis copy = axis;
    axis.run(v, seconds, &estimate);
    copy.run(v, seconds, &untracked);
  };
  // Down to the approach point, still: zero there.
  run(-0.01, 1.0);
  run(0.0, 0.3);
  estimate.rezero();
  untracked.rezero();
  // Into the body: 30 N, then held still at 30 N and at 45 N (breathing pushes).
  axis.external = 30.0;
  run(-0.01, 0.2);
  run(0.0, 0.5);
  EXPECT_NEAR(estimate.force(), 30.0, 1.5);
  axis.external = 45.0;
  run(0.0, 0.3);
  EXPECT_NEAR(estimate.force(), 45.0, 1.5);
  // Backing off 1 mm (the body follows to 20 N): the friction turns over, 2 x 15 N the other way.
  axis.external = 20.0;
  run(0.01, 0.1);
  run(0.0, 0.3);
  EXPECT_NEAR(estimate.force(), 20.0, 1.5);
  EXPECT_GT(std::abs(untracked.force() - 20.0), 20.0);  // the sign of the friction is what tracking it gives
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
