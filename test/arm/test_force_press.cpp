// A press by force against a simulated back: the loop (force_press.h) streaming heights to an ideal position
// servo one cycle late, the force measured with the drive estimate's noise and filter, the back breathing.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "massage_cell/arm/force_press.h"
#include "massage_cell/arm/sim_body.h"

namespace {

using namespace massage_cell::arm;

struct PressRun {
  double rms = 0.0, peak = 0.0, end_z = 0.0;
  int hold_cycles = 0;
  ForcePress::Phase phase = ForcePress::Phase::kSeek;
  std::string failure;
};

/// Presses `goal` into `body` at (0.3, 0.2) at 100 Hz: the servo reaches each command by the next cycle, the force
/// is read with 1 N RMS of noise through a 20 ms low-pass; errors are taken while holding.
PressRun press(const SimBody& body, ForcePressGoal goal, ForceControlConfig config = {}, int abort_at = -1) {
  ForcePress p(config, goal);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  double z = goal.start_z, cmd = z, filtered = 0.0, t = 0.0, sq = 0.0;
  PressRun r;
  for (int k = 0; k < 6000 && !p.finished(); ++k, t += 0.01) {
    const double vz = (cmd - z) / 0.01;
    z = cmd;  // the servo, one cycle late
    const double truth = body.force(Eigen::Vector3d(0.3, 0.2, z), vz, t);
    filtered += 0.01 / 0.03 * (truth + noise(rng) - filtered);
    if (k == abort_at) p.abort("stop requested");
    cmd = p.update(filtered, z, 0.01);
    if (p.phase() == ForcePress::Phase::kHold) {
      sq += (truth - goal.force) * (truth - goal.force);
      ++r.hold_cycles;
    }
    r.peak = std::max(r.peak, truth);
  }
  r.rms = r.hold_cycles ? std::sqrt(sq / r.hold_cycles) : NAN;
  r.end_z = z;
  r.phase = p.phase();
  r.failure = p.failure();
  return r;
}

ForcePressGoal goal(double force) {
  ForcePressGoal g;
  g.start_z = 0.18;
  g.expected_skin_z = 0.15;
  g.force = force;
  g.max_force = 70.0;
  g.max_indentation = 0.015;
  g.hold = 5.0;
  return g;
}

SimBody back(double stiffness_scale = 1.0, double breathing_mm = 3.0) {
  Tissue t;
  t.stiffness *= stiffness_scale;
  Breathing b;
  b.amplitude = breathing_mm / 1000.0;
  return SimBody::flat(0.15, t, b);
}

TEST(ForcePress, HoldsItsForceWhileTheBackBreathesOnSoftAndStiffTissue) {
  for (double scale : {0.5, 1.0, 1.5}) {
    for (double force : {10.0, 30.0, 60.0}) {
      const PressRun r = press(back(scale), goal(force));
      EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
      EXPECT_GT(r.hold_cycles, 490);
      // Breathing 3 mm p-p pushes +-10-40 N on a tool held still: the loop follows it (without its integral, 0.7-1.4 N
      // RMS; with a fixed gain instead of the tissue's stiffness, 2-9 N on the soft back).
      EXPECT_LT(r.rms, 1.0) << "stiffness x" << scale << ", " << force << " N";
      EXPECT_LT(r.peak, 1.1 * force + 2.0) << "stiffness x" << scale << ", " << force << " N";  // overshoot
      EXPECT_NEAR(r.end_z, 0.18, 0.001);  // backed off to where it started
    }
  }
}

TEST(ForcePress, NoBodyWhereVisionSaidStopsWithinItsBand) {
  const SimBody none([](double, double) { return NAN; }, [](double, double) { return Tissue{}; });
  const PressRun r = press(none, goal(30.0));
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("no contact"), std::string::npos) << r.failure;
  EXPECT_NEAR(r.end_z, 0.18, 0.001);
}

TEST(ForcePress, EachLimitStopsThePressAndBacksOff) {
  ForcePressGoal capped = goal(30.0);
  capped.max_force = 20.0;  // asked beyond the cap (the plan refuses it; the loop still holds the line)
  PressRun r = press(back(), capped);
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("limit 20.0 N"), std::string::npos) << r.failure;
  EXPECT_LT(r.peak, 24.0);  // stopped within a cycle or two of the cap

  ForcePressGoal shallow = goal(30.0);
  shallow.max_indentation = 0.002;  // 30 N needs ~5 mm of this tissue
  r = press(back(1.0, 0.0), shallow);
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("sank"), std::string::npos) << r.failure;

  r = press(back(2000.0, 0.0), goal(30.0));  // bone, a table edge: three orders stiffer than tissue
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("N/s"), std::string::npos) << r.failure;

  r = press(back(), goal(30.0), {}, 400);  // a stop while holding
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_EQ(r.failure, "stop requested");
  EXPECT_NEAR(r.end_z, 0.18, 0.001);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
