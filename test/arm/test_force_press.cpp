// A press by force against a simulated back: the loop (force_press.h) streaming heights to an ideal position
// servo one cycle late, the force measured with the drive estimate's noise and filter, the back breathing.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "massage_cell/arm/force_press.h"
#include "massage_cell/arm/sim_body.h"

namespace {

using namespace massage_cell::arm;

struct PressRun {
  double rms = 0.0, peak = 0.0, end_z = 0.0;
  int hold_cycles = 0;
  // A stroke: the force error while gliding (RMS, worst), the tool's farthest distance from the path across the
  // skin, and where it ended (x, y).
  double glide_rms = 0.0, glide_worst = 0.0, path_error = 0.0;
  int glide_cycles = 0;
  Eigen::Vector2d end_xy{NAN, NAN};
  ForcePress::Phase phase = ForcePress::Phase::kSeek;
  std::string failure;
  double zero = NAN;  ///< the press's zero at the end (ForcePress::zero)
};

/// Presses `goal` into `body` at (0.3, 0.2) at 100 Hz: the servo reaches each command by the next cycle, the force
/// is read with 1 N RMS of noise through a 20 ms low-pass; errors are taken while holding.
/// Distance across the skin (x, y) from `p` to the polyline `path`.
double distanceToPath(const Eigen::Vector2d& p, const std::vector<Eigen::Vector3d>& path) {
  double best = INFINITY;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d a = path[i - 1].head<2>(), b = path[i].head<2>();
    const double f = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + f * (b - a))).norm());
  }
  return best;
}

PressRun press(const SimBody& body, ForcePressGoal goal, ForceControlConfig config = {}, int abort_at = -1,
               double offset = 0.0) {
  ForcePress p(config, goal);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  double z = goal.start_z, cmd = z, filtered = offset, t = 0.0, sq = 0.0, glide_sq = 0.0;  // the bias was there before
  // Across the skin the servo also follows one cycle late; a press stays at (0.3, 0.2).
  Eigen::Vector2d xy = goal.path.empty() ? Eigen::Vector2d(0.3, 0.2) : goal.path.front().head<2>(), xy_cmd = xy;
  PressRun r;
  for (int k = 0; k < 6000 && !p.finished(); ++k, t += 0.01) {
    const double vz = (cmd - z) / 0.01;
    z = cmd;  // the servo, one cycle late
    xy = xy_cmd;
    const double truth = body.force(Eigen::Vector3d(xy.x(), xy.y(), z), vz, t);
    filtered += 0.01 / 0.03 * (truth + offset + noise(rng) - filtered);
    if (k == abort_at) p.abort("stop requested");
    cmd = p.update(filtered, z, 0.01);
    if (!goal.path.empty()) xy_cmd = p.xy();
    if (p.phase() == ForcePress::Phase::kHold) {
      sq += (truth - goal.force) * (truth - goal.force);
      ++r.hold_cycles;
    }
    if (p.phase() == ForcePress::Phase::kGlide) {
      glide_sq += (truth - goal.force) * (truth - goal.force);
      r.glide_worst = std::max(r.glide_worst, std::abs(truth - goal.force));
      r.path_error = std::max(r.path_error, distanceToPath(xy, goal.path));
      ++r.glide_cycles;
    }
    r.peak = std::max(r.peak, truth);
  }
  r.rms = r.hold_cycles ? std::sqrt(sq / r.hold_cycles) : NAN;
  r.glide_rms = r.glide_cycles ? std::sqrt(glide_sq / r.glide_cycles) : NAN;
  r.end_z = z;
  r.end_xy = xy;
  r.phase = p.phase();
  r.failure = p.failure();
  r.zero = p.zero();
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

TEST(ForcePress, TheForceInTheAirIsItsZero) {
  // The estimate's zero off by 2.5 N (one late sample): taken out in the air, the press holds the true 30 N; without
  // the air's zero it would find "contact" at once and sink past its guard looking for 30 N (contact + 15 mm).
  const PressRun r = press(back(1.0, 0.0), goal(30.0), {}, -1, 2.5);
  EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
  EXPECT_LT(r.rms, 1.0);
  EXPECT_NEAR(r.zero, 2.5, 0.6) << "the zero the press reports (the arm's status) is not what it took out";
  // Off by 8 N (more than twice the contact force): the press does not start.
  const PressRun off = press(back(1.0, 0.0), goal(30.0), {}, -1, 8.0);
  EXPECT_EQ(off.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(off.failure.find("N leaving the approach point, in the air (more than 6.0 N)"), std::string::npos)
      << off.failure;
  EXPECT_EQ(off.peak, 0.0);
}

TEST(ForcePress, AClientPushingUpIsEscapedFasterThanAPressIsReleased) {
  // Holding 45 N (cap 60 N) when the back rises 10 mm at 40 mm/s (a startle): the cap stops the press and the tool
  // backs off at escape_speed; at release_speed (10 mm/s) the rising back would catch it (~130 N).
  auto lift = std::make_shared<double>(0.0);
  const SimBody body([lift](double, double) { return 0.15 + *lift; }, [](double, double) { return Tissue{}; },
                     Breathing{0.0, 4.0});
  ForcePressGoal g = goal(45.0);
  g.max_force = 60.0;
  for (double escape : {0.04, 0.01}) {
    ForceControlConfig c;
    c.escape_speed = escape;
    ForcePress p(c, g);
    *lift = 0.0;
    double z = g.start_z, cmd = z, filtered = 0.0, peak = 0.0, t_hold = -1.0;
    for (int k = 0; k < 3000 && !p.finished(); ++k) {
      const double t = 0.01 * k;
      if (p.phase() == ForcePress::Phase::kHold && t_hold < 0.0) t_hold = t;
      if (t_hold >= 0.0) *lift = std::clamp(0.04 * (t - t_hold - 0.5), 0.0, 0.010);
      const double vz = (cmd - z) / 0.01;
      z = cmd;
      const double truth = body.force(Eigen::Vector3d(0.3, 0.2, z), vz, t);
      filtered += 0.01 / 0.03 * (truth - filtered);
      cmd = p.update(filtered, z, 0.01);
      peak = std::max(peak, truth);
    }
    EXPECT_EQ(p.phase(), ForcePress::Phase::kFailed);
    EXPECT_NE(p.failure().find("limit 60.0 N"), std::string::npos) << p.failure();
    if (escape == 0.04) {
      EXPECT_LT(peak, 80.0);
    } else {
      EXPECT_GT(peak, 100.0);  // the case the escape speed is for
    }
    std::printf("a back rising 10 mm at 40 mm/s under 45 N, backing off at %.0f mm/s: peak %.1f N\n", 1e3 * escape,
                peak);
  }
}

TEST(ForcePress, AContactFarAboveWhereVisionPutTheSkinStops) {
  // The back is 2.5 cm higher than vision said (a pillow, the client rose): the press stops at the contact instead of
  // pressing there; 1 cm higher (within the 1.5 cm band) is pressed.
  PressRun r = press(SimBody::flat(0.175, Tissue{}, Breathing{0.0, 4.0}), goal(30.0));
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("above where vision put the skin"), std::string::npos) << r.failure;
  EXPECT_LT(r.peak, 10.0);
  EXPECT_NEAR(r.end_z, 0.18, 0.001);
  r = press(SimBody::flat(0.16, Tissue{}, Breathing{0.0, 4.0}), goal(30.0));
  EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
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

/// A back that rises 8 cm over 20 cm along x and curves across it (the spine's line), not where vision saw it:
/// the stroke's points carry +-3 mm of error in z.
SimBody curvedBack(double breathing_mm = 3.0) {
  Breathing b;
  b.amplitude = breathing_mm / 1000.0;
  return SimBody([](double x, double y) { return 0.15 + 0.4 * (x - 0.25) - 1.5 * (x - 0.35) * (x - 0.35) + 0.0 * y; },
                 [](double, double) { return Tissue{}; }, b);
}

ForcePressGoal stroke(const SimBody& body, double force, bool downhill = false) {
  ForcePressGoal g = goal(force);
  const double vision_error[] = {0.003, -0.003, 0.002, -0.002, 0.003, -0.001};
  for (int i = 0; i < 6; ++i) {
    const double x = downhill ? 0.45 - 0.04 * i : 0.25 + 0.04 * i, y = 0.2 + 0.01 * (i % 2);
    g.path.emplace_back(x, y, body.skinHeight(x, y, 0.0) + vision_error[i]);
  }
  g.expected_skin_z = g.path.front().z();
  g.start_z = g.expected_skin_z + 0.03;
  g.glide_speed = 0.015;
  return g;
}

TEST(ForcePress, AStrokeGlidesAlongItsPathAtItsForceOverACurvedBreathingBack) {
  const SimBody body = curvedBack();
  for (double force : {10.0, 20.0, 40.0}) {
    const ForcePressGoal g = stroke(body, force);
    const PressRun r = press(body, g);
    EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
    // 0.2 m at 15 mm/s: ~14 s of glide.
    EXPECT_GT(r.glide_cycles, 1300);
    // 1 N of noise on the force, breathing, and the skin's slope fed forward from vision's points: 0.8-1.0 N RMS,
    // worst 1.9-3.2 N (without the slope: 1.2-2.3 N RMS, worst 4.7-7.2 N).
    EXPECT_LT(r.glide_rms, 1.1) << force << " N";
    EXPECT_LT(r.glide_worst, 4.0) << force << " N";
    EXPECT_LT(r.path_error, 0.001) << force << " N";
    EXPECT_NEAR((r.end_xy - g.path.back().head<2>()).norm(), 0.0, 1e-6);  // it went the whole way
    // ... and backed off, up to the approach height over the end's skin (as vision's points give it, smoothed)
    EXPECT_NEAR(r.end_z, g.path.back().z() + 0.03, 0.004);
    std::printf("stroke %.0f N over 0.2 m: force error RMS %.2f N, worst %.2f N\n", force, r.glide_rms, r.glide_worst);
  }
}

TEST(ForcePress, AStrokeFollowsTheSkinNotTheHeightItStartedAt) {
  // Down the back's 8 cm slope: guarded from the contact height, the fall would read as the tool sinking 8 cm; it
  // is guarded from the skin along the path.
  const SimBody body = curvedBack(0.0);
  ForcePressGoal g = stroke(body, 20.0, true);
  g.max_indentation = 0.010;  // 20 N needs ~4 mm of this tissue
  const PressRun r = press(body, g);
  EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
}

TEST(ForcePress, AStrokeIsGuardedByEachRegionsIndentationLimitWhereTheToolIs) {
  // Firm tissue (20 N: ~4 mm) with a 6 mm guard, then soft lumbar tissue (20 N: ~10 mm) with a 15 mm guard.
  Tissue soft;
  soft.stiffness = 2.0e4;
  const SimBody body([](double, double) { return 0.15; },
                     [soft](double x, double) { return x < 0.38 ? Tissue{} : soft; }, Breathing{0.0, 4.0});
  ForcePressGoal g = stroke(SimBody::flat(0.15, Tissue{}), 20.0);
  g.max_indentation = 0.006;
  g.path_max_indentation = {0.006, 0.006, 0.006, 0.015, 0.015, 0.015};
  const PressRun r = press(body, g);
  EXPECT_EQ(r.phase, ForcePress::Phase::kDone) << r.failure;
  // The soft part under the firm part's guard: stopped where the tissue softens.
  g.path_max_indentation = {0.006, 0.006, 0.006, 0.006, 0.006, 0.015};
  const PressRun tight = press(body, g);
  EXPECT_EQ(tight.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(tight.failure.find("past the skin along the stroke (limit 6.0 mm)"), std::string::npos) << tight.failure;
  EXPECT_GT(tight.end_xy.x(), 0.37);
  EXPECT_LT(tight.end_xy.x(), 0.42);
}

TEST(ForcePress, AStrokeOfOnePointIsRefused) {
  ForcePressGoal g = goal(20.0);
  g.path = {Eigen::Vector3d(0.3, 0.2, 0.15)};
  const PressRun r = press(SimBody::flat(0.15, Tissue{}), g);
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_EQ(r.failure, "a stroke's path needs at least two points");
}

TEST(ForcePress, AStrokeOverAGapInTheBodyStops) {
  // The path runs off the body half way (a gap where vision put skin): the tool sinks looking for its force.
  const SimBody body([](double x, double) { return x < 0.33 ? 0.15 : NAN; }, [](double, double) { return Tissue{}; },
                     Breathing{0.0, 4.0});
  ForcePressGoal g = stroke(SimBody::flat(0.15, Tissue{}), 20.0);
  const PressRun r = press(body, g);
  EXPECT_EQ(r.phase, ForcePress::Phase::kFailed);
  EXPECT_NE(r.failure.find("past the skin along the stroke"), std::string::npos) << r.failure;
  EXPECT_LT(r.end_xy.x(), 0.36);  // stopped there, not at the path's end
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
