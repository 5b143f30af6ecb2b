// Press plans: the routine's steps, depth limits per region, the envelope,
// normals, kneading, refusals with messages naming the target.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include <Eigen/Geometry>

#include "massage_cell/arm/plan.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::arm;

ArmConfig config() { return loadArmConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/arm.yaml"); }

PressTarget target(const std::string& name, const std::string& region, Eigen::Vector3d p,
                   Eigen::Vector3d n = Eigen::Vector3d::UnitZ()) {
  PressTarget t;
  t.name = name;
  t.region = region;
  t.point = p;
  t.normal = n;
  return t;
}

const Eigen::Vector3d kHome(0.0, 0.0, 0.30);  // where homing leaves the tool

/// Deepest signed position along the target's normal over every step of it.
double deepest(const std::vector<Step>& steps, const PressTarget& t, int index) {
  double d = 1e9;
  for (const Step& s : steps) {
    if (s.target == index) d = std::min(d, (s.tool - t.point).dot(t.normal.normalized()));
  }
  return d;
}

TEST(Plan, CheckToolNamesTheViolatedBound) {
  const ArmConfig c = config();
  EXPECT_EQ(checkTool(c, {0.4, 0.2, 0.2}), "");
  EXPECT_NE(checkTool(c, {0.9, 0.2, 0.2}).find("outside the workspace envelope: x above 0.760 m"), std::string::npos);
  EXPECT_NE(checkTool(c, {0.4, -0.01, 0.2}).find("y below 0.000 m"), std::string::npos);
  EXPECT_NE(checkTool(c, {0.4, 0.2, 0.05}).find("z below 0.080 m"), std::string::npos);
  EXPECT_NE(checkTool(c, {0.4, 0.2, NAN}).find("not finite"), std::string::npos);
}

TEST(Plan, VerticalPressSequence) {
  const ArmConfig c = config();
  PressRequest r;
  r.targets = {target("BL23_L", "lower_back", {0.5, 0.2, 0.18})};
  r.depth = 0.006;
  r.hold = 1.5;
  std::vector<Step> steps;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  // up (already at 0.30 > travel 0.28: no), travel, down, approach (its last 3 cm slowly), descend, hold, retract, up.
  std::vector<std::string> kinds;
  for (const Step& s : steps) kinds.push_back(s.label.substr(s.label.find(": ") + 2));
  EXPECT_EQ(kinds, (std::vector<std::string>{"travel", "down", "approach", "descend", "hold", "retract",
                                             "up to the travel height"}));
  EXPECT_TRUE(steps[0].tool.isApprox(Eigen::Vector3d(0.5, 0.2, 0.28)));
  EXPECT_TRUE(steps[1].tool.isApprox(Eigen::Vector3d(0.5, 0.2, 0.24)));  // fast to 3 cm above the approach point
  EXPECT_DOUBLE_EQ(steps[1].speed, 0.0);
  EXPECT_TRUE(steps[2].tool.isApprox(Eigen::Vector3d(0.5, 0.2, 0.21)));  // 3 cm above the skin
  EXPECT_DOUBLE_EQ(steps[2].speed, c.press.approach_speed);
  EXPECT_TRUE(steps[3].tool.isApprox(Eigen::Vector3d(0.5, 0.2, 0.174)));  // 6 mm in
  EXPECT_DOUBLE_EQ(steps[3].speed, c.press.speed);
  EXPECT_EQ(steps[4].kind, Step::Kind::kHold);
  EXPECT_DOUBLE_EQ(steps[4].duration, 1.5);
  EXPECT_TRUE(steps[4].contact);
  EXPECT_TRUE(steps[5].press_done);
  EXPECT_TRUE(steps[5].retract);
  EXPECT_FALSE(steps[2].contact);
  // Its contact steps carry the region's force cap (the controller's guard when the force is known); the others none.
  const double cap = c.regions.at("lower_back").forceCap(c.press.contact_area);
  for (int k : {3, 4, 5}) EXPECT_DOUBLE_EQ(steps[k].force_cap, cap) << k;
  for (int k : {0, 1, 2, 6}) EXPECT_DOUBLE_EQ(steps[k].force_cap, 0.0) << k;
  for (const Step& s : steps) EXPECT_EQ(checkTool(c, s.tool), "") << s.label;
  EXPECT_NEAR(deepest(steps, r.targets[0], 0), -0.006, 1e-12);
  // From below the travel height the plan goes up first.
  ASSERT_EQ(planMassage(c, {0.1, 0.1, 0.2}, r, &steps), "");
  EXPECT_TRUE(steps[0].tool.isApprox(Eigen::Vector3d(0.1, 0.1, 0.28)));
}

TEST(Plan, DepthLimitedPerRegion) {
  const ArmConfig c = config();
  PressRequest r;
  std::vector<Step> steps;
  // Default depths.
  r.targets = {target("GV4", "midline", {0.5, 0.25, 0.19}), target("BL13_L", "upper_back", {0.25, 0.2, 0.2}),
               target("p", "", {0.4, 0.3, 0.19})};
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  EXPECT_NEAR(deepest(steps, r.targets[0], 0), -0.001, 1e-12);
  EXPECT_NEAR(deepest(steps, r.targets[1], 1), -0.003, 1e-12);
  EXPECT_NEAR(deepest(steps, r.targets[2], 2), -0.001, 1e-12);  // no region: the default (midline)
  // A depth one region allows and another does not: refused naming the target and the limit.
  r.depth = 0.004;
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "GV4: depth 4.0 mm is deeper than the midline limit 2.0 mm");
  EXPECT_TRUE(steps.empty());
  r.targets = {target("BL13_L", "upper_back", {0.25, 0.2, 0.2})};
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "");
  r.depth = 0.0051;
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "BL13_L: depth 5.1 mm is deeper than the upper_back limit 5.0 mm");
  r.targets = {target("BL25_L", "lower_back", {0.6, 0.2, 0.18})};
  r.depth = 0.012;
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "");
  r.depth = 0.013;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("deeper than the lower_back limit 12.0 mm"), std::string::npos);
  r.targets[0].region = "neck";
  r.depth = 0.0;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("BL25_L: unknown region 'neck'"), std::string::npos);
}

TEST(Plan, PressAlongTheSurfaceNormal) {
  const ArmConfig c = config();
  PressRequest r;
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  r.targets = {target("BL23_R", "lower_back", {0.5, 0.3, 0.18}, n)};
  r.depth = 0.01;
  std::vector<Step> steps;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  const Step* descend = nullptr;
  for (const Step& s : steps) {
    if (s.label.find("descend") != std::string::npos) descend = &s;
  }
  ASSERT_NE(descend, nullptr);
  EXPECT_TRUE(descend->tool.isApprox(r.targets[0].point - 0.01 * n, 1e-12));
  EXPECT_TRUE(descend->retreat.isApprox(r.targets[0].point + c.press.approach_height * n, 1e-12));
  // Too steep a surface (60 deg) is refused.
  r.targets[0].normal = Eigen::Vector3d(std::sin(M_PI / 3), 0, std::cos(M_PI / 3));
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "BL23_R: the surface normal is 60.0 deg from vertical (limit 45.0 deg)");
  r.targets[0].normal = Eigen::Vector3d::Zero();
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("normal is zero"), std::string::npos);
}

TEST(Plan, EnvelopeRefusals) {
  const ArmConfig c = config();
  PressRequest r;
  std::vector<Step> steps;
  r.targets = {target("high", "lower_back", {0.5, 0.2, 0.29})};  // approach point 3 cm higher: above 0.30
  EXPECT_NE(
      planMassage(c, kHome, r, &steps)
          .find("high: the travel point (0.500, 0.200, 0.320) m is outside the workspace envelope: z above 0.300 m"),
      std::string::npos)
      << planMassage(c, kHome, r, &steps);
  r.targets = {target("low", "lower_back", {0.5, 0.2, 0.085})};  // 8 mm in: below z 0.08
  r.depth = 0.008;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("low: the press end point"), std::string::npos);
  r.targets = {target("far", "lower_back", {0.9, 0.2, 0.18})};
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("far: the travel point"), std::string::npos);
  r.targets = {};
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "no target given");
}

TEST(Plan, RequestLimits) {
  const ArmConfig c = config();
  PressRequest r;
  r.targets = {target("a", "lower_back", {0.5, 0.2, 0.18})};
  std::vector<Step> steps;
  r.hold = 31;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("hold 31.000 s is beyond the limit 30.000 s"), std::string::npos);
  r.hold = 1;
  r.repeats = 0;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("repeats must be 1..10"), std::string::npos);
  r.repeats = 3;
  r.speed = 0.05;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("speed 0.050 m/s must be in (0, 0.030]"), std::string::npos);
  r.speed = 0.02;
  r.depth = -0.001;
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("depth must be >= 0"), std::string::npos);
  r.depth = 0;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  int presses = 0;
  for (const Step& s : steps) presses += s.press_done;
  EXPECT_EQ(presses, 3);
  EXPECT_NE(planMassage(c, {0.9, 0.2, 0.2}, r, &steps).find("the tool's current position"), std::string::npos);
  r.targets.assign(c.press.max_targets + 1, r.targets.front());
  EXPECT_NE(planMassage(c, kHome, r, &steps).find("51 targets: at most 50 in one request"), std::string::npos);
  r.targets.resize(c.press.max_targets);
  r.repeats = 1;
  EXPECT_EQ(planMassage(c, kHome, r, &steps), "") << "the limit itself is accepted";
}

TEST(Plan, BodySurfaceIsTheNearestPointWithinTheRadius) {
  BodySurface body;
  body.points = {{0.5, 0.2, 0.17}, {0.55, 0.2, 0.18}};
  EXPECT_DOUBLE_EQ(*body.heightAt(0.51, 0.2, 0.05), 0.17);
  EXPECT_DOUBLE_EQ(*body.heightAt(0.54, 0.21, 0.05), 0.18);
  EXPECT_FALSE(body.heightAt(0.7, 0.2, 0.05)) << "no point within 5 cm";
  EXPECT_FALSE(BodySurface{}.heightAt(0.5, 0.2, 0.05));
}

TEST(Plan, HeightGridHoldsTheHighestPointOfEachCellAndItsNeighbours) {
  const Eigen::Vector2d lo(0.0, 0.0), hi(1.0, 1.0);
  const HeightGrid grid(
      {{0.500, 0.200, 0.15}, {0.503, 0.202, 0.17}, {0.530, 0.200, 0.10}, {NAN, 0.2, 0.3}, {1000.0, -500.0, 0.2}}, 0.01,
      lo, hi);
  EXPECT_DOUBLE_EQ(*grid.heightAt(0.501, 0.201), 0.17f);  // the higher of the cell's two
  EXPECT_DOUBLE_EQ(*grid.heightAt(0.512, 0.201), 0.17f);  // the neighbouring cell's too
  EXPECT_DOUBLE_EQ(*grid.heightAt(0.531, 0.201), 0.10f);
  EXPECT_FALSE(grid.heightAt(0.60, 0.20)) << "no point within a cell";
  EXPECT_FALSE(grid.heightAt(1000.0, -500.0)) << "a point outside the bounds is skipped (not a 100000^2-cell grid)";
  EXPECT_FALSE(HeightGrid().heightAt(0.5, 0.2));
  EXPECT_TRUE(HeightGrid({{NAN, 0.0, 0.0}}, 0.01, lo, hi).empty());
}

TEST(Plan, StereosSurfaceGuardsBetweenTheAcupoints) {
  const ArmConfig c = config();
  BodySurface body;
  // Two acupoints 10 cm apart at the skin's 0.15 m; between them the back rises 4 cm (the spine, a shoulder blade).
  body.points = {{0.40, 0.20, 0.15}, {0.50, 0.20, 0.15}};
  const Eigen::Vector3d above(0.45, 0.20, 0.28), target(0.45, 0.20, 0.16);
  EXPECT_EQ(checkBodyClearance(c, body, above, target, 0.002), "") << "the acupoints alone: 1 cm above the skin";
  std::vector<Eigen::Vector3d> seen;
  for (double x = 0.35; x <= 0.551; x += 0.005) {
    for (double y = 0.15; y <= 0.251; y += 0.005)
      seen.emplace_back(x, y, 0.15 + 0.04 * std::exp(-std::pow((x - 0.45) / 0.02, 2)));
  }
  body.dense = HeightGrid(seen, c.body.surface_cell, Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(1.0, 1.0));
  // 3 cm into the ridge stereo sees: refused, naming the surface and the limit.
  const std::string why = checkBodyClearance(c, body, above, target, 0.002);
  EXPECT_NE(why.find("the target (0.450, 0.200, 0.160) m is 30.0 mm below the surface stereo sees (limit 12.0 mm"),
            std::string::npos)
      << why;
  // Within stereo's depth error of it: allowed (a press point CECT put 5 mm under stereo's skin is not refused).
  EXPECT_EQ(checkBodyClearance(c, body, above, {0.45, 0.20, 0.185}, 0.002), "");
  // A path across the ridge at the acupoints' height: refused on its way.
  EXPECT_NE(checkBodyClearance(c, body, {0.40, 0.20, 0.16}, {0.50, 0.20, 0.16}, 0.002).find("the path at"),
            std::string::npos);
  // Where only stereo sees the body (no acupoint within the radius), it is known: below the safe height is allowed
  // above it, and refused into it.
  const Eigen::Vector3d over_edge(0.36, 0.24, 0.20);
  EXPECT_EQ(checkBodyClearance(c, body, {0.36, 0.24, 0.28}, over_edge, 0.002), "");
  EXPECT_NE(checkBodyClearance(c, body, {0.36, 0.24, 0.28}, {0.36, 0.24, 0.12}, 0.002), "");
}

TEST(Plan, BodyClearance) {
  const ArmConfig c = config();
  BodySurface body;
  body.points = {{0.563, 0.211, 0.167}};
  const Eigen::Vector3d above(0.563, 0.211, 0.28);
  // 5 cm under the skin (the move): refused, naming the depth.
  const std::string deep = checkBodyClearance(c, body, above, {0.563, 0.211, 0.118}, 0.002);
  EXPECT_NE(deep.find("the target (0.563, 0.211, 0.118) m is 49.0 mm below the body's surface (limit 2.0 mm)"),
            std::string::npos)
      << deep;
  EXPECT_EQ(checkBodyClearance(c, body, above, {0.563, 0.211, 0.166}, 0.002), "") << "1 mm in: within the limit";
  // Where no surface is known: not below the safe height...
  const std::string blind = checkBodyClearance(c, body, above, {0.2, 0.3, 0.2}, 0.002);
  EXPECT_NE(blind.find("below the safe height 0.250 m, and no body surface is known there"), std::string::npos)
      << blind;
  EXPECT_EQ(checkBodyClearance(c, BodySurface{}, above, {0.2, 0.3, 0.25}, 0.002), "");
  // ... unless the tool is already lower: at its height or up is allowed, further down is not.
  const Eigen::Vector3d low(0.2, 0.3, 0.2);
  EXPECT_EQ(checkBodyClearance(c, BodySurface{}, low, {0.3, 0.3, 0.2}, 0.002), "");
  EXPECT_EQ(checkBodyClearance(c, BodySurface{}, low, {0.2, 0.3, 0.27}, 0.002), "");
  EXPECT_NE(checkBodyClearance(c, BodySurface{}, low, {0.2, 0.3, 0.19}, 0.002), "");
  // A path that dips into the body between two safe ends: the line is sampled.
  body.points = {{0.4, 0.2, 0.2}, {0.5, 0.2, 0.14}};  // a ridge between two low ends
  const std::string dip = checkBodyClearance(c, body, {0.3, 0.2, 0.21}, {0.5, 0.2, 0.15}, 0.002);
  EXPECT_NE(dip.find("the path at"), std::string::npos) << dip;
}

TEST(Plan, MaxLineSpeedIsTheJointLimitsNorm) {
  ArmConfig c = config();
  c.joints[0].max_velocity = 0.3;
  c.joints[1].max_velocity = 0.4;
  c.joints[2].max_velocity = 0.0;
  EXPECT_NEAR(maxLineSpeed(c), 0.5, 1e-12);
}

TEST(Plan, KneadCirclesAtDepthInTheTangentPlane) {
  const ArmConfig c = config();
  PressRequest r;
  r.technique = Technique::kKnead;
  const Eigen::Vector3d n = Eigen::Vector3d(0.0, 0.3, 1.0).normalized();
  r.targets = {target("BL25_L", "lower_back", {0.6, 0.2, 0.18}, n)};
  r.depth = 0.008;
  r.hold = 2.0;  // 2 circles of 1 s
  std::vector<Step> steps;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  int knead = 0;
  for (const Step& s : steps) {
    if (s.label.find("knead") == std::string::npos) continue;
    ++knead;
    const Eigen::Vector3d rel = s.tool - r.targets[0].point;
    EXPECT_NEAR(rel.dot(n), -0.008, 1e-12);  // exactly at depth, never deeper
    const double radial = (rel - rel.dot(n) * n).norm();
    EXPECT_TRUE(std::abs(radial - c.press.knead_radius) < 1e-12 || radial < 1e-12) << radial;
    EXPECT_TRUE(s.contact);
  }
  EXPECT_EQ(knead, 1 + 2 * c.press.knead_segments + 1);
  EXPECT_NEAR(deepest(steps, r.targets[0], 0), -0.008, 1e-12);
}

TEST(Plan, RetractStepsGoBackToTheApproachPointThenUp) {
  const ArmConfig c = config();
  Step s;
  s.tool = {0.5, 0.2, 0.17};
  s.retreat = {0.5, 0.2, 0.21};
  s.contact = true;
  s.target = 0;
  const std::vector<Step> r = retractSteps(c, s);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_TRUE(r[0].tool.isApprox(s.retreat));
  EXPECT_TRUE(r[0].retract);
  EXPECT_DOUBLE_EQ(r[0].speed, c.press.retract_speed);
  EXPECT_TRUE(r[1].tool.isApprox(Eigen::Vector3d(0.5, 0.2, 0.28)));
}

PressRequest stroke(std::vector<PressTarget> path, double force = 0.0) {
  PressRequest r;
  r.technique = Technique::kStroke;
  r.mode = PressConfig::Mode::kForce;
  r.force = force;
  r.targets = std::move(path);
  return r;
}

TEST(Plan, AStrokeIsOnePressByForceGlidingThroughItsPoints) {
  const ArmConfig c = config();
  const PressRequest r =
      stroke({target("BL11_L", "upper_back", {0.30, 0.20, 0.15}), target("BL17_L", "upper_back", {0.36, 0.20, 0.16}),
              target("BL25_L", "lower_back", {0.45, 0.21, 0.15})});
  std::vector<Step> steps;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  // travel over the first point / down / approach / the glide / up over the last point
  ASSERT_EQ(steps.size(), 5u);
  EXPECT_EQ(steps[0].label, "stroke BL11_L -> BL25_L: travel");
  EXPECT_TRUE(steps[2].tool.isApprox(Eigen::Vector3d(0.30, 0.20, 0.15 + c.press.approach_height)));
  const Step& glide = steps[3];
  EXPECT_EQ(glide.kind, Step::Kind::kForcePress);
  EXPECT_EQ(glide.label, "stroke BL11_L -> BL25_L: glide at 20 N");  // the lower default of both regions
  ASSERT_EQ(glide.force.path.size(), 3u);
  EXPECT_TRUE(glide.force.path[1].isApprox(r.targets[1].point));
  EXPECT_DOUBLE_EQ(glide.force.glide_speed, c.force_control.stroke_speed);
  // The most conservative force cap of the regions it crosses (upper back's); each point's own indentation guard.
  EXPECT_DOUBLE_EQ(glide.force.max_force, c.regions.at("upper_back").forceCap(c.press.contact_area));
  EXPECT_DOUBLE_EQ(glide.force.max_indentation, c.regions.at("upper_back").max_indentation);
  EXPECT_EQ(glide.force.path_max_indentation,
            (std::vector<double>{c.regions.at("upper_back").max_indentation, c.regions.at("upper_back").max_indentation,
                                 c.regions.at("lower_back").max_indentation}));
  EXPECT_TRUE(glide.press_done);
  EXPECT_TRUE(steps[4].tool.isApprox(Eigen::Vector3d(0.45, 0.21, c.press.travel_height)));
}

TEST(Plan, KneadingByForceGlidesRoundACircleAtItsForce) {
  const ArmConfig c = config();
  PressRequest r;
  r.technique = Technique::kKnead;
  r.mode = PressConfig::Mode::kForce;
  r.hold = 2.0;
  r.targets = {target("BL23_L", "lower_back", {0.40, 0.20, 0.15})};
  std::vector<Step> steps;
  ASSERT_EQ(planMassage(c, kHome, r, &steps), "");
  const auto knead =
      std::find_if(steps.begin(), steps.end(), [](const Step& s) { return s.kind == Step::Kind::kForcePress; });
  ASSERT_NE(knead, steps.end());
  EXPECT_EQ(knead->label, "press 1/1 BL23_L: knead 30 N");
  const std::vector<Eigen::Vector3d>& path = knead->force.path;
  // Out from the point, two circles (1 s each) of 36 segments, closed, back to the point.
  ASSERT_EQ(path.size(), 1u + 2 * 36 + 2);
  EXPECT_TRUE(path.front().isApprox(r.targets[0].point));
  EXPECT_TRUE(path.back().isApprox(r.targets[0].point));
  for (std::size_t k = 1; k + 1 < path.size(); ++k)
    EXPECT_NEAR((path[k] - r.targets[0].point).norm(), c.press.knead_radius, 1e-12) << k;
  EXPECT_NEAR(knead->force.glide_speed, 2.0 * M_PI * c.press.knead_radius / c.press.knead_period, 1e-12);
}

TEST(Plan, DistanceFromAPathIsAcrossTheSkin) {
  const std::vector<Eigen::Vector3d> path = {{0.0, 0.0, 0.1}, {0.1, 0.0, 0.2}, {0.1, 0.1, 0.2}};
  EXPECT_NEAR(distanceFromPath({0.05, 0.003}, path), 0.003, 1e-12);     // beside the first leg (z does not count)
  EXPECT_NEAR(distanceFromPath({0.104, 0.05}, path), 0.004, 1e-12);     // beside the second
  EXPECT_NEAR(distanceFromPath({-0.003, -0.004}, path), 0.005, 1e-12);  // before its start: from the end point
  EXPECT_NEAR(distanceFromPath({0.2, 0.2}, {{0.1, 0.2, 0.0}}), 0.1, 1e-12);
  EXPECT_TRUE(std::isinf(distanceFromPath({0.0, 0.0}, {})));
}

TEST(Plan, StrokeRefusals) {
  const ArmConfig c = config();
  std::vector<Step> steps;
  const auto plan = [&](const PressRequest& r) { return planMassage(c, kHome, r, &steps); };
  const PressTarget a = target("BL11_L", "upper_back", {0.30, 0.20, 0.15});
  const PressTarget b = target("BL25_L", "lower_back", {0.45, 0.20, 0.15});
  EXPECT_EQ(plan(stroke({a})), "a stroke needs a path of at least two points (frames or points)");
  PressRequest by_depth = stroke({a, b});
  by_depth.mode = PressConfig::Mode::kDepth;
  EXPECT_EQ(plan(by_depth), "a stroke glides at a force: mode force, not depth");
  PressRequest held = stroke({a, b});
  held.hold = 2.0;
  EXPECT_EQ(plan(held), "a stroke holds its force while it glides: give no hold");
  // Over the spine the whole stroke takes the midline's cap (15 N), whatever the other points allow.
  const PressTarget spine = target("GV4", "midline", {0.40, 0.23, 0.15});
  EXPECT_NE(plan(stroke({a, spine, b}, 30.0)).find("above the midline limit 15.0 N"), std::string::npos)
      << plan(stroke({a, spine, b}, 30.0));
  EXPECT_EQ(plan(stroke({a, spine, b}, 12.0)), "");
  const PressTarget twice = target("BL11_L again", "upper_back", {0.301, 0.20, 0.15});
  EXPECT_EQ(plan(stroke({a, twice, b})),
            "stroke: BL11_L and BL11_L again are 1.0 mm apart across the skin (at least 5.0 mm)");
  const PressTarget cliff = target("edge", "upper_back", {0.32, 0.20, 0.20});  // 5 cm up over 2 cm
  EXPECT_NE(plan(stroke({a, cliff})).find("the skin from BL11_L to edge rises 68.2 deg (limit 45.0 deg)"),
            std::string::npos)
      << plan(stroke({a, cliff}));
  const PressTarget outside = target("far", "upper_back", {0.90, 0.20, 0.15});
  EXPECT_NE(plan(stroke({a, outside})).find("stroke point far: the approach point"), std::string::npos)
      << plan(stroke({a, outside}));
}

TEST(Plan, PressSettingsOfAServiceCall) {
  const ArmConfig c = config();
  MassageFields f;
  f.targets = 2;
  PressRequest r;
  EXPECT_EQ(pressSettings(c, f, &r), "");
  EXPECT_EQ(r.technique, Technique::kPress);
  EXPECT_EQ(r.hold, -1.0);  // 0: the default
  EXPECT_EQ(r.repeats, 1);  // 0: once
  f.technique = "knead";
  f.hold = -2.0;
  f.repeats = 3;
  f.depth = 0.004;
  EXPECT_EQ(pressSettings(c, f, &r), "");
  EXPECT_EQ(r.technique, Technique::kKnead);
  EXPECT_EQ(r.hold, 0.0);  // < 0: none
  EXPECT_EQ(r.repeats, 3);
  EXPECT_EQ(r.depth, 0.004);
}

TEST(Plan, PressSettingsRefusals) {
  const ArmConfig c = config();
  auto refusal = [&](const std::function<void(MassageFields&)>& edit) {
    MassageFields f;
    f.targets = 2;
    edit(f);
    PressRequest r;
    return pressSettings(c, f, &r);
  };
  EXPECT_EQ(refusal([](MassageFields& f) { f.targets = 0; }), "no target (frames or points) given");
  EXPECT_NE(refusal([&](MassageFields& f) { f.targets = c.press.max_targets + 1; }).find("press.max_targets"),
            std::string::npos);
  EXPECT_NE(refusal([](MassageFields& f) { f.hold = std::nan(""); }).find("hold must be a finite"), std::string::npos);
  EXPECT_EQ(refusal([](MassageFields& f) { f.regions = 1; }), "regions has 1 entries for 2 targets");
  EXPECT_EQ(refusal([](MassageFields& f) { f.normals = 3; }), "normals has 3 entries for 2 targets");
  EXPECT_EQ(refusal([](MassageFields& f) { f.technique = "tap"; }), "unknown technique 'tap' (press, knead or stroke)");
  EXPECT_EQ(refusal([](MassageFields& f) { f.regions = 2; }), "");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
