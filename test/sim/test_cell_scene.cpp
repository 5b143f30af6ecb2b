// Tests of the dressed back scene (cell_scene.h): the default dressing is the
// plain back scene; arms touch the flank at 0 degrees and leave table between
// them at 20; the towel hides the acupoints below its edge; a framing that
// cuts the neck shows no head; every new label renders; skin tones, builds,
// varied subjects, toe-in and framing behave.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/cell_scene.h"
#include "massage_cell/sim/ground_truth.h"
#include "massage_cell/sim/photo_artefacts.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"

namespace {

namespace sim = massage_cell::sim;
using sim::ArmPose;
using sim::BackModel;
using sim::BodyParameters;
using sim::Dressing;

constexpr double kDegree = 3.14159265358979323846 / 180.0;

sim::RenderOptions fast() {
  sim::RenderOptions o;
  o.supersample = 1;
  o.noise_sigma = 0.0f;
  return o;
}

/// A rectified rig framed from x_top to x_bottom at the back's height.
sim::StereoPairModel framedPair(const BackModel& back, double x_top, double x_bottom, int width = 320,
                                int height = 240) {
  sim::RigParameters rig;
  rig.width = width;
  rig.height = height;
  rig.fx = 250.0 * width / 320.0;
  return sim::makeStereoPair(sim::frameRig(rig, x_top, x_bottom, back.body().back_height));
}

sim::StereoFrame render(const BackModel& back, const Dressing& d, const sim::StereoPairModel& pair) {
  const sim::Renderer renderer(sim::makeCellScene(back, 1, d));
  return sim::renderStereoFrame(renderer, pair, sim::Lighting{}, fast());
}

int countLabel(const cv::Mat& labels, std::uint8_t label) { return cv::countNonZero(labels == label); }

bool sameMesh(const sim::Mesh& a, const sim::Mesh& b) {
  return a.name == b.name && a.label == b.label && a.vertices == b.vertices && a.triangles == b.triangles &&
         a.normals == b.normals && a.uv == b.uv && a.triangle_labels == b.triangle_labels &&
         a.material.pattern == b.material.pattern && a.material.albedo == b.material.albedo &&
         a.material.seed == b.material.seed && a.material.contrast == b.material.contrast &&
         a.material.spots.size() == b.material.spots.size();
}

// ---------------------------------------------------------------------------
// The default dressing

TEST(CellScene, DefaultDressingIsTheBackScene) {
  for (int subject : {0, 5}) {
    const BackModel back(BodyParameters::subject(subject));
    const sim::Scene plain = sim::makeBackScene(back, 3);
    const sim::Scene dressed = sim::makeCellScene(back, 3, Dressing{});
    ASSERT_EQ(plain.meshes.size(), dressed.meshes.size());
    for (std::size_t i = 0; i < plain.meshes.size(); ++i)
      EXPECT_TRUE(sameMesh(plain.meshes[i], dressed.meshes[i])) << i;
    const sim::StereoPairModel pair = framedPair(back, 0.05, back.levelX("L4") - 0.1, 160, 120);
    const sim::Renderer r_plain(plain), r_dressed(dressed);
    const sim::ViewRender a = r_plain.render(pair.left, sim::Lighting{}, sim::RenderOptions{});
    const sim::ViewRender b = r_dressed.render(pair.left, sim::Lighting{}, sim::RenderOptions{});
    EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::countNonZero(a.labels != b.labels), 0);
  }
}

TEST(CellScene, DressingChangesTheScene) {
  const BackModel back(BodyParameters::mean());
  Dressing d;
  d.sheet = sim::Cloth{sim::clothColour("green"), sim::Weave::kWaffle};
  const sim::Scene s = sim::makeCellScene(back, 3, d);
  EXPECT_EQ(s.meshes[0].material.pattern, sim::Material::Pattern::kWaffle);
  EXPECT_EQ(s.meshes[0].material.albedo, sim::clothColour("green"));
}

// ---------------------------------------------------------------------------
// Arms

/// Per image row between the rows of world x_hi and x_lo: on each side of the
/// back, the number of table pixels between the back's outermost pixel and
/// the arm's innermost one (-1 when the row has no arm beside the back).
std::vector<int> tableBetweenArmAndBack(const cv::Mat& labels, int row) {
  const std::uint8_t* l = labels.ptr<std::uint8_t>(row);
  const int centre = labels.cols / 2;
  std::vector<int> out;
  for (int dir : {-1, 1}) {
    int c = centre;
    while (c >= 0 && c < labels.cols && l[c] != sim::kLabelBack) c += dir;  // onto the back
    while (c >= 0 && c < labels.cols && l[c] == sim::kLabelBack) c += dir;  // to its edge
    int table = 0;
    while (c >= 0 && c < labels.cols && l[c] != sim::kLabelArm) {
      if (l[c] == sim::kLabelTable) ++table;
      if (l[c] == sim::kLabelBack) break;
      c += dir;
    }
    out.push_back(c >= 0 && c < labels.cols && l[c] == sim::kLabelArm ? table : -1);
  }
  return out;
}

int rowOf(const sim::CameraModel& cam, const Eigen::Vector3d& p) {
  Eigen::Vector2d px;
  EXPECT_TRUE(cam.project(p, &px));
  return static_cast<int>(std::lround(px.y()));
}

TEST(CellScene, ArmsAlongTheTrunkTouchItsFlankAtZeroDegrees) {
  for (int subject : {0, 11}) {
    const BackModel back(BodyParameters::varied(subject));
    Dressing d;
    d.arms = ArmPose::kAlongTrunk;
    d.lower_body = true;
    const sim::StereoPairModel pair = framedPair(back, 0.05, back.levelX("L4") - 0.25, 320, 320);
    const sim::StereoFrame f = render(back, d, pair);
    const int r0 = rowOf(pair.left, {back.levelX("T4"), 0.0, 0.2}),
              r1 = rowOf(pair.left, {back.levelX("L4"), 0.0, 0.2});
    int rows = 0, touching = 0;
    for (int r = r0; r <= r1; ++r) {
      for (int table : tableBetweenArmAndBack(f.left.labels, r)) {
        if (table < 0) continue;
        ++rows;
        if (table == 0) ++touching;
      }
    }
    EXPECT_GT(rows, 2 * (r1 - r0) * 9 / 10) << "an arm beside the back on both sides of most rows";
    EXPECT_GE(touching, rows * 9 / 10) << "subject " << subject << ": " << touching << " of " << rows;
  }
}

TEST(CellScene, ArmsAbductedTwentyDegreesLeaveTableAtTheElbow) {
  const BackModel back(BodyParameters::mean());
  Dressing d;
  d.arms = ArmPose::kAlongTrunk;
  d.arm_abduction_left = d.arm_abduction_right = 20.0 * kDegree;
  const sim::StereoPairModel pair = framedPair(back, 0.05, back.levelX("L4") - 0.25, 320, 320);
  const sim::StereoFrame f = render(back, d, pair);
  // The elbow: the narrowest ring around a third of the way down the arm.
  const sim::TrunkSurface trunk(back, nullptr);
  const auto rings = sim::armRings(back, trunk, ArmPose::kAlongTrunk, 1, d.arm_abduction_left);
  std::size_t elbow = rings.size() / 4;
  for (std::size_t i = rings.size() / 4; i < rings.size() / 2; ++i) {
    if (rings[i].a < rings[elbow].a) elbow = i;
  }
  const int row = rowOf(pair.left, rings[elbow].centre);
  const std::vector<int> gaps = tableBetweenArmAndBack(f.left.labels, row);
  for (int table : gaps) EXPECT_GE(table, 8) << "table pixels between elbow and trunk at row " << row;
  // And at 0 degrees there is none at that row.
  d.arm_abduction_left = d.arm_abduction_right = 0.0;
  const sim::StereoFrame g = render(back, d, pair);
  for (int table : tableBetweenArmAndBack(g.left.labels, row)) EXPECT_EQ(table, 0);
}

TEST(CellScene, ArmsRestOnTheTableAndStartInsideTheShoulder) {
  for (int subject : {0, 2, 7}) {
    const BackModel back(BodyParameters::varied(subject));
    const sim::TrunkSurface trunk(back, nullptr);
    for (ArmPose pose : {ArmPose::kAlongTrunk, ArmPose::kRaised}) {
      for (int side : {1, -1}) {
        const auto rings = sim::armRings(back, trunk, pose, side, 0.1);
        ASSERT_GT(rings.size(), 50u);
        // The first ring lies wholly under the shoulder's skin.
        const sim::TubeRing& first = rings.front();
        EXPECT_GT(trunk.height(first.centre.x(), first.centre.y()), first.centre.z() + first.b) << subject;
        double lowest = 1.0, resting = 0.0;
        for (const sim::TubeRing& r : rings) {
          lowest = std::min(lowest, r.centre.z() - r.b);
          EXPECT_EQ(r.centre.y() > 0.0, side > 0);
        }
        for (std::size_t i = rings.size() / 2; i < rings.size(); ++i)
          resting = std::max(resting, rings[i].centre.z() - rings[i].b);
        EXPECT_GE(lowest, -1e-9) << "never below the table top";
        EXPECT_LT(resting, 1e-9) << "forearm and hand lie on the table";
        // Radii scale with the build: the upper arm 4.5 .. 6 cm.
        const double upper = rings[rings.size() / 6].a;
        EXPECT_GT(upper, 0.04);
        EXPECT_LT(upper, 0.066);
      }
    }
  }
  EXPECT_THROW(
      sim::armRings(BackModel(BodyParameters::mean()), sim::TrunkSurface(BackModel(BodyParameters::mean()), nullptr),
                    ArmPose::kAlongTrunk, 0, 0.0),
      std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Towel, ground truth

TEST(CellScene, TowelHidesTheAcupointsBelowItsEdgeAndKeepsThoseAbove) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, 0.06, back.levelX("L4") - 0.2);
  Dressing bare;
  bare.arms = ArmPose::kAlongTrunk;
  bare.lower_body = true;
  Dressing towel = bare;
  towel.towel = sim::Cloth{sim::clothColour("white"), sim::Weave::kTerry};
  towel.towel_edge_x = back.levelX("L3") - 0.012;
  const auto acupoints = back.acupoints();
  const auto before = sim::acupointTruth(acupoints, pair, render(back, bare, pair));
  const auto after = sim::acupointTruth(acupoints, pair, render(back, towel, pair));
  int below = 0, above = 0;
  for (const auto& [name, p] : acupoints) {
    if (p.x() < towel.towel_edge_x - 0.01) {
      ++below;
      EXPECT_TRUE(before.at(name).in_view) << name << ": " << before.at(name).reason;
      EXPECT_FALSE(after.at(name).in_view) << name;
      EXPECT_EQ(after.at(name).reason, "under the towel") << name;
      EXPECT_EQ(after.at(name).left_label, sim::kLabelTowel) << name;
    } else if (p.x() > towel.towel_edge_x + 0.02 && before.at(name).in_view) {
      ++above;
      EXPECT_TRUE(after.at(name).in_view) << name << ": " << after.at(name).reason;
    }
  }
  EXPECT_GE(below, 8);  // L4, L5: GV3, BL25, BL26, EX_B2 ...
  EXPECT_GE(above, 60);
}

TEST(GroundTruth, PointsOutsideTheImageAndBehindTheCamera) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, back.levelX("T2"), back.levelX("L1"));
  const sim::StereoFrame f = render(back, Dressing{}, pair);
  const auto truth = sim::acupointTruth(back.acupoints(), pair, f);
  EXPECT_FALSE(truth.at("BL25_L").in_view);
  EXPECT_EQ(truth.at("BL25_L").reason, "below the image's bottom edge");
  EXPECT_EQ(truth.at("GV14").reason, "above the image's top edge");
  EXPECT_TRUE(truth.at("BL15_L").in_view) << truth.at("BL15_L").reason;
  EXPECT_LT(truth.at("BL15_L").surface_distance, 0.005);
  EXPECT_EQ(truth.at("BL15_L").left_label, sim::kLabelBack);
  // The optical-frame position projects to the stored pixels.
  const sim::PointTruth& t = truth.at("BL15_L");
  Eigen::Vector2d px;
  ASSERT_TRUE(pair.left.project(t.world, &px));
  EXPECT_LT((px - t.left_pixel).norm(), 1e-9);
  EXPECT_NEAR((pair.left.world_from_camera * t.left_optical - t.world).norm(), 0.0, 1e-12);
  const auto behind = sim::acupointTruth({{"above", Eigen::Vector3d(0.0, 0.0, 5.0)}}, pair, f);
  EXPECT_EQ(behind.at("above").reason, "behind the left camera");
  EXPECT_THROW(sim::acupointTruth(back.acupoints(), pair, f, 0.0), std::invalid_argument);
}

TEST(GroundTruth, PointsUnderAnArmOrTheHair) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, 0.12, back.levelX("T8"));
  Dressing d;
  d.head = true;
  d.hair = sim::HairLength::kLong;
  d.arms = ArmPose::kAlongTrunk;
  const sim::StereoFrame f = render(back, d, pair);
  const double x_nape = 0.6 * sim::headLayout(back).hairline_x;
  const double flank = back.halfWidth(back.levelX("T6")) - 0.01;
  const auto truth = sim::acupointTruth(
      {{"nape", {x_nape, 0.0, 0.16}}, {"flank", {back.levelX("T6"), flank, back.height(back.levelX("T6"), flank)}}},
      pair, f);
  EXPECT_EQ(truth.at("nape").reason, "under the hair");
  EXPECT_EQ(truth.at("flank").reason, "under an arm");
}

// ---------------------------------------------------------------------------
// Head, framing, labels

TEST(CellScene, FramingThatCutsTheNeckShowsNoHead) {
  for (int subject : {0, 4, 9}) {
    const BackModel back(BodyParameters::varied(subject));
    Dressing d;
    d.head = true;
    d.arms = ArmPose::kAlongTrunk;
    // The top edge 2 cm above C7 (at the back's height): the neck runs out of the image.
    const sim::StereoPairModel pair = framedPair(back, 0.02, back.levelX("L4") - 0.2);
    const sim::StereoFrame f = render(back, d, pair);
    EXPECT_EQ(countLabel(f.left.labels, sim::kLabelHead), 0) << subject;
    EXPECT_EQ(countLabel(f.left.labels, sim::kLabelHair), 0) << subject;
    EXPECT_GT(countLabel(f.left.labels.row(0), sim::kLabelNeck), 3) << "the neck runs out of the top edge";
    // Down the middle column the neck runs straight into the back: no gap.
    const cv::Mat column = f.left.labels.col(f.left.labels.cols / 2);
    int r = 0;
    while (r < column.rows && column.at<std::uint8_t>(r) == sim::kLabelNeck) ++r;
    EXPECT_GT(r, 2) << subject;
    ASSERT_LT(r, column.rows);
    EXPECT_EQ(column.at<std::uint8_t>(r), sim::kLabelBack) << subject;
    // The same rig further toward the head shows it.
    const sim::StereoPairModel wide = framedPair(back, 0.45, back.levelX("L4") - 0.2);
    EXPECT_GT(countLabel(render(back, d, wide).left.labels, sim::kLabelHair), 50) << subject;
  }
}

TEST(CellScene, EveryNewLabelRenders) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, 0.45, back.levelX("L4") - 0.45, 320, 320);
  Dressing d;
  d.arms = ArmPose::kAlongTrunk;
  d.head = true;
  d.hair = sim::HairLength::kShort;
  d.lower_body = true;
  d.towel = sim::Cloth{sim::clothColour("green"), sim::Weave::kFine};
  d.towel_edge_x = back.levelX("L4") - 0.03;
  const cv::Mat labels = render(back, d, pair).left.labels;
  for (std::uint8_t label : {sim::kLabelBack, sim::kLabelTable, sim::kLabelArm, sim::kLabelNeck, sim::kLabelHead,
                             sim::kLabelHair, sim::kLabelTowel, sim::kLabelCradle}) {
    EXPECT_GT(countLabel(labels, label), 20) << sim::labelName(label);
  }
  d.arms = ArmPose::kRaised;
  d.hair = sim::HairLength::kNone;
  const cv::Mat raised = render(back, d, pair).left.labels;
  EXPECT_GT(countLabel(raised, sim::kLabelArm), 500);
  EXPECT_EQ(countLabel(raised, sim::kLabelHair), 0);
  EXPECT_GT(countLabel(raised, sim::kLabelHead), 200) << "without hair the head's skin shows";
}

TEST(CellScene, LowerBodyFillsAViewEndingAtMidButtocks) {
  const BackModel back(BodyParameters::mean());
  const sim::LowerBody lower(back);
  const double x0 = lower.xStart();
  for (double s = -0.8; s <= 0.8; s += 0.1) {
    const double y = s * back.halfWidth(x0);
    EXPECT_NEAR(lower.height(x0, y), back.height(x0, y), 0.0015) << y;
  }
  EXPECT_LT(lower.foldX(), x0);
  EXPECT_LT(lower.xEnd(), lower.foldX());
  const sim::StereoPairModel pair = framedPair(back, back.levelX("T6"), x0 - 0.1);
  Dressing d;
  const cv::Mat without = render(back, d, pair).left.labels;
  d.lower_body = true;
  const cv::Mat with = render(back, d, pair).left.labels;
  const int bottom = with.rows - 1, mid = with.cols / 2;
  EXPECT_EQ(with.at<std::uint8_t>(bottom, mid), sim::kLabelBack);
  EXPECT_EQ(without.at<std::uint8_t>(bottom, mid), sim::kLabelTable);
}

TEST(CellScene, HairColoursAndClothNames) {
  std::set<std::string> seen;
  for (const auto& [name, colour] : sim::clothColours()) {
    EXPECT_EQ(sim::clothColour(name), colour);
    seen.insert(name);
  }
  for (const char* needed : {"white", "light_blue", "green", "grey", "beige", "peach", "pink"})
    EXPECT_TRUE(seen.count(needed));
  EXPECT_THROW(sim::clothColour("mauve"), std::invalid_argument);
  EXPECT_EQ(sim::weaveFromName("terry"), sim::Weave::kTerry);
  EXPECT_THROW(sim::weaveFromName("knit"), std::invalid_argument);
  EXPECT_EQ(sim::armPoseFromName("raised"), ArmPose::kRaised);
  EXPECT_EQ(sim::hairLengthFromName("nape"), sim::HairLength::kNape);
  EXPECT_LT(sim::hairAlbedo(sim::hairColourFromName("black")).sum(), sim::hairAlbedo(sim::HairColour::kBrown).sum());
  EXPECT_LT(sim::hairAlbedo(sim::HairColour::kBrown).sum(), sim::hairAlbedo(sim::HairColour::kBlond).sum());
  const Eigen::Vector3f red = sim::hairAlbedo(sim::HairColour::kRed);
  EXPECT_GT(red.x(), 2.5f * red.y());
}

TEST(CellScene, StickersSitOnTheirLandmarksInBothViews) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, 0.06, back.levelX("L4") - 0.2);
  Dressing d;
  d.stickers = {{"C7", sim::stickerColour("green"), 0.025}, {"L4", sim::stickerColour("blue"), 0.025}};
  const sim::StereoFrame bare = render(back, Dressing{}, pair);
  const sim::StereoFrame marked = render(back, d, pair);
  const auto landmarks = back.landmarks();
  for (const auto& [name, channel] : {std::pair<std::string, int>{"C7", 1}, {"L4", 0}}) {  // BGR: green 1, blue 0
    for (const auto* view : {&pair.left, &pair.right}) {
      Eigen::Vector2d q;
      ASSERT_TRUE(view->project(landmarks.at(name), &q)) << name;
      const cv::Point px(static_cast<int>(std::lround(q.x())), static_cast<int>(std::lround(q.y())));
      const cv::Mat& image = view == &pair.left ? marked.left.image : marked.right.image;
      const cv::Mat& plain = view == &pair.left ? bare.left.image : bare.right.image;
      const cv::Vec3b c = image.at<cv::Vec3b>(px), skin = plain.at<cv::Vec3b>(px);
      EXPECT_GT(c[channel], c[2] + 40) << name << ": the sticker's colour over red at its landmark";
      EXPECT_GT(skin[2], skin[channel]) << name << ": skin without it is red-dominant";
      EXPECT_EQ((view == &pair.left ? marked.left.labels : marked.right.labels).at<std::uint8_t>(px),
                sim::kLabelBack);  // a sticker is part of the skin for the labels
    }
  }
  // 4 cm off the landmark the skin is as it was.
  Eigen::Vector2d q;
  ASSERT_TRUE(pair.left.project(landmarks.at("C7") + Eigen::Vector3d(-0.04, 0.0, 0.0), &q));
  const cv::Point away(static_cast<int>(std::lround(q.x())), static_cast<int>(std::lround(q.y())));
  EXPECT_EQ(marked.left.image.at<cv::Vec3b>(away), bare.left.image.at<cv::Vec3b>(away));
  EXPECT_THROW(sim::stickerColour("teal"), std::invalid_argument);
}

TEST(CellScene, SkinPatchesAndPrintedSheetsRenderWhereTheyAre) {
  const BackModel back(BodyParameters::mean());
  const sim::StereoPairModel pair = framedPair(back, 0.06, back.levelX("L4") - 0.2);
  Dressing d;
  sim::Patch strap;  // a black strap 2 cm wide across the back at T7
  strap.centre = {static_cast<float>(back.levelX("T7")), 0.0f};
  strap.half_size = {0.01f, 0.5f};
  strap.albedo = {0.02f, 0.02f, 0.02f};
  d.skin_patches = {strap};
  d.sheet = sim::Cloth{sim::clothColour("white"), sim::Weave::kStripes, sim::clothColour("dark_blue"), 0.06};
  const sim::StereoFrame bare = render(back, Dressing{}, pair);
  const sim::StereoFrame marked = render(back, d, pair);
  auto pixel = [&](const Eigen::Vector3d& p) {
    Eigen::Vector2d q;
    EXPECT_TRUE(pair.left.project(p, &q));
    return cv::Point(static_cast<int>(std::lround(q.x())), static_cast<int>(std::lround(q.y())));
  };
  const cv::Point on = pixel(back.surfacePoint("T7", 2.0)), off = pixel(back.surfacePoint("T3", 2.0));
  EXPECT_LT(marked.left.image.at<cv::Vec3b>(on)[2], bare.left.image.at<cv::Vec3b>(on)[2] / 3) << "the strap is dark";
  EXPECT_EQ(marked.left.image.at<cv::Vec3b>(off), bare.left.image.at<cv::Vec3b>(off)) << "the skin beside it is not";
  EXPECT_EQ(marked.left.labels.at<std::uint8_t>(on), sim::kLabelBack);
  // The sheet beside the body: both colours, 3 cm bands along the table.
  const cv::Mat table = marked.left.labels == sim::kLabelTable;
  cv::Mat blue_over_red = cv::Mat::zeros(table.size(), CV_8U);
  for (int y = 0; y < table.rows; ++y) {
    for (int x = 0; x < table.cols; ++x) {
      const cv::Vec3b c = marked.left.image.at<cv::Vec3b>(y, x);
      if (table.at<std::uint8_t>(y, x) && c[0] > c[2] + 30) blue_over_red.at<std::uint8_t>(y, x) = 255;
    }
  }
  const double dark_blue = double(cv::countNonZero(blue_over_red)) / cv::countNonZero(table);
  EXPECT_GT(dark_blue, 0.3);
  EXPECT_LT(dark_blue, 0.7);
  EXPECT_EQ(sim::weaveFromName("checks"), sim::Weave::kChecks);
}

TEST(CellScene, DressingValidation) {
  const BackModel back(BodyParameters::mean());
  auto expectThrowNaming = [&](const Dressing& d, const std::string& name) {
    try {
      d.validate(back);
      ADD_FAILURE() << name << ": no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
    EXPECT_THROW(sim::makeCellScene(back, 1, d), std::invalid_argument);
  };
  Dressing d;
  d.arm_abduction_left = 0.5;
  expectThrowNaming(d, "arm_abduction_left");
  d = Dressing{};
  d.arm_abduction_right = -0.1;
  expectThrowNaming(d, "arm_abduction_right");
  d = Dressing{};
  d.towel = sim::Cloth{};
  expectThrowNaming(d, "towel_edge_x");  // NaN
  d.towel_edge_x = 0.2;                  // above the shoulders
  expectThrowNaming(d, "towel_edge_x");
  d.towel_edge_x = back.levelX("L4");
  d.towel_edge_tilt = 0.5;
  expectThrowNaming(d, "towel_edge_tilt");
  d = Dressing{};
  d.sheet = sim::Cloth{Eigen::Vector3f(1.2f, 0.5f, 0.5f), sim::Weave::kFine};
  expectThrowNaming(d, "sheet");
  d = Dressing{};
  d.stickers = {{"T3x", sim::stickerColour("green"), 0.025}};
  expectThrowNaming(d, "T3x");
  d.stickers = {{"C7", sim::stickerColour("green"), 0.2}};
  expectThrowNaming(d, "diameter");
  d = Dressing{};
  d.skin_patches = {sim::Patch{}};
  d.skin_patches[0].half_size.x() = 0.0f;
  expectThrowNaming(d, "skin patch");
  d = Dressing{};
  d.skin_spots = {sim::Spot{}};
  d.skin_spots[0].radius = 0.2f;
  expectThrowNaming(d, "skin spot");
  d = Dressing{};
  d.sheet = sim::Cloth{};
  d.sheet->period = 0.001;
  expectThrowNaming(d, "period");
}

TEST(PhotoArtefacts, EachChangesTheImageAsACameraWould) {
  cv::Mat img(120, 160, CV_8UC3, cv::Scalar(100, 140, 180));
  cv::rectangle(img, cv::Rect(70, 0, 20, 120), cv::Scalar(20, 20, 20), cv::FILLED);
  sim::PhotoArtefacts none;
  EXPECT_FALSE(none.any());
  EXPECT_EQ(cv::norm(sim::applyPhotoArtefacts(img, none), img, cv::NORM_INF), 0.0);
  sim::PhotoArtefacts cast;
  cast.colour_gains = {0.8, 1.0, 1.2};
  const cv::Vec3b c = sim::applyPhotoArtefacts(img, cast).at<cv::Vec3b>(60, 10);
  EXPECT_EQ(c, cv::Vec3b(80, 140, 216));
  sim::PhotoArtefacts vignette;
  vignette.vignetting = 0.4;
  const cv::Mat v = sim::applyPhotoArtefacts(img, vignette);
  EXPECT_NEAR(v.at<cv::Vec3b>(60, 40)[2], 180, 25);
  EXPECT_NEAR(v.at<cv::Vec3b>(0, 0)[2], 0.6 * 180, 6);
  sim::PhotoArtefacts blur;
  blur.motion_blur_px = 10.0;  // along x: the dark bar's edges spread, rows do not
  const cv::Mat b = sim::applyPhotoArtefacts(img, blur);
  EXPECT_GT(b.at<cv::Vec3b>(60, 67)[2], 40);
  EXPECT_LT(b.at<cv::Vec3b>(60, 67)[2], 170);
  EXPECT_EQ(b.at<cv::Vec3b>(60, 20), img.at<cv::Vec3b>(60, 20));
  sim::PhotoArtefacts jpeg;
  jpeg.jpeg_quality = 30;
  const cv::Mat j = sim::applyPhotoArtefacts(img, jpeg);
  EXPECT_GT(cv::norm(j, img, cv::NORM_INF), 0.0);
  EXPECT_LT(cv::norm(j, img, cv::NORM_L1) / img.total(), 10.0);
  EXPECT_EQ(jpeg.describe(), "JPEG 30");
  using Change = void (*)(sim::PhotoArtefacts&);
  for (Change bad : std::initializer_list<Change>{[](sim::PhotoArtefacts& a) { a.colour_gains[1] = 2.0; },
                                                  [](sim::PhotoArtefacts& a) { a.vignetting = 0.9; },
                                                  [](sim::PhotoArtefacts& a) { a.motion_blur_px = -1.0; },
                                                  [](sim::PhotoArtefacts& a) { a.jpeg_quality = 101; }}) {
    sim::PhotoArtefacts a;
    bad(a);
    EXPECT_THROW(sim::applyPhotoArtefacts(img, a), std::invalid_argument);
  }
  EXPECT_THROW(sim::applyPhotoArtefacts(cv::Mat(), none), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Subjects

double luminance(const Eigen::Vector3f& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

TEST(Subjects, SixSkinTonesOrderedByLuminanceAndDistinct) {
  EXPECT_THROW(sim::fitzpatrickAlbedo(0), std::invalid_argument);
  EXPECT_THROW(sim::fitzpatrickAlbedo(7), std::invalid_argument);
  // Rendered: the mean brightness of the back's pixels falls from type I to VI.
  BodyParameters body = BodyParameters::mean();
  const sim::StereoPairModel pair = framedPair(BackModel(body), 0.05, BackModel(body).levelX("L4") - 0.1, 160, 120);
  double previous = 256.0;
  for (int type = 1; type <= 6; ++type) {
    const Eigen::Vector3f albedo = sim::fitzpatrickAlbedo(type);
    EXPECT_GT(albedo.x(), albedo.y());
    EXPECT_GT(albedo.y(), albedo.z());
    if (type > 1) {
      EXPECT_LT(luminance(albedo), 0.92 * luminance(sim::fitzpatrickAlbedo(type - 1))) << type;
    }
    body.skin_albedo = albedo;
    const BackModel back(body);
    const sim::Renderer renderer(sim::makeCellScene(back, 1, Dressing{}));
    const sim::ViewRender v = renderer.render(pair.left, sim::Lighting{}, fast());
    cv::Mat grey;
    cv::cvtColor(v.image, grey, cv::COLOR_BGR2GRAY);
    const double mean = cv::mean(grey, v.labels == sim::kLabelBack)[0];
    EXPECT_LT(mean, previous - 6.0) << "type " << type;
    previous = mean;
  }
}

TEST(Subjects, BuildsFollowBmiSexAndStature) {
  sim::Build lean, obese;
  lean.bmi = 18.5;
  obese.bmi = 37.0;
  const BodyParameters l = sim::bodyFromBuild(lean), o = sim::bodyFromBuild(obese);
  EXPECT_GT(o.waist_width, l.waist_width + 0.1);
  EXPECT_GT(o.back_height, l.back_height + 0.04);
  EXPECT_GT(o.lateral_rounding, l.lateral_rounding + 0.5);
  EXPECT_GT(o.waist_width / o.hip_width, l.waist_width / l.hip_width + 0.15) << "the obese waist hardly narrows";
  EXPECT_GT(l.scapula_prominence, 2.0 * o.scapula_prominence);
  EXPECT_GT(l.spine_depth, 1.5 * o.spine_depth);
  EXPECT_GT(l.spinous_prominence, 0.002);
  EXPECT_EQ(o.spinous_prominence, 0.0);
  sim::Build woman = lean, tall = lean;
  woman.female = true;
  tall.stature = 1.95;
  EXPECT_GT(sim::bodyFromBuild(woman).hip_width / sim::bodyFromBuild(woman).shoulder_width,
            l.hip_width / l.shoulder_width);
  EXPECT_GT(sim::bodyFromBuild(tall).torso_length, l.torso_length + 0.04);
  sim::Build bad;
  bad.bmi = 60.0;
  EXPECT_THROW(sim::bodyFromBuild(bad), std::invalid_argument);
  bad = sim::Build{};
  bad.skin_type = 7;
  EXPECT_THROW(sim::bodyFromBuild(bad), std::invalid_argument);
  // Lean backs show their spinous processes: bumps along the midline.
  const BackModel bony(l);
  const double t6 = bony.levelX("T6"), between = 0.5 * (t6 + bony.levelX("T7"));
  EXPECT_GT(bony.height(t6 + 0.006, 0.0) - bony.height(between, 0.0), 0.001);
}

TEST(Subjects, VariedPopulationCoversSexesBmiAndSkinTypes) {
  std::set<int> types_male, types_female;
  double bmi_lo_waist = 1.0, bmi_hi_waist = 0.0;
  for (int i = 1; i <= 24; ++i) {
    const BodyParameters p = BodyParameters::varied(i, 7);
    EXPECT_NO_THROW(p.validate()) << i;
    EXPECT_NO_THROW(BackModel{p}.mesh(0.01)) << i;
    const double ratio = p.waist_width / p.hip_width;
    bmi_lo_waist = std::min(bmi_lo_waist, ratio);
    bmi_hi_waist = std::max(bmi_hi_waist, ratio);
    int type = 0;
    double best = 1e9;
    for (int t = 1; t <= 6; ++t) {
      const double dl = std::abs(luminance(p.skin_albedo) - luminance(sim::fitzpatrickAlbedo(t)));
      if (dl < best) best = dl, type = t;
    }
    (i % 2 == 0 ? types_female : types_male).insert(type);
    EXPECT_TRUE(BodyParameters::varied(i, 7).skin_albedo == p.skin_albedo) << "deterministic";
  }
  EXPECT_EQ(types_male.size(), 6u);
  EXPECT_EQ(types_female.size(), 6u);
  EXPECT_LT(bmi_lo_waist, 0.75);
  EXPECT_GT(bmi_hi_waist, 0.95);
  EXPECT_THROW(BodyParameters::varied(-1), std::invalid_argument);
  EXPECT_TRUE(BodyParameters::varied(0).skin_albedo == BodyParameters::mean().skin_albedo);
}

// ---------------------------------------------------------------------------
// Rigs

TEST(Rig, ToeInCamerasConverge) {
  for (double baseline : {0.06, 0.12}) {
    sim::RigParameters rig;
    rig.rectified = false;
    rig.baseline = baseline;
    rig.left_rotation.setZero();
    rig.right_rotation.setZero();
    rig.toe_in = 3.0 * kDegree;
    const sim::StereoPairModel pair = sim::makeStereoPair(rig);
    const Eigen::Vector3d zl = pair.left.world_from_camera.linear().col(2),
                          zr = pair.right.world_from_camera.linear().col(2);
    EXPECT_NEAR(std::acos(zl.dot(zr)), 2.0 * rig.toe_in, 1e-9);
    // Where the axes meet: in front of both, baseline / (2 tan(toe-in)) from the
    // baseline (baseline / (2 sin(toe-in)) along each axis).
    const Eigen::Vector3d cl = pair.left.centre(), cr = pair.right.centre();
    const Eigen::Vector3d w = cl - cr;
    const double a = zl.dot(zl), b = zl.dot(zr), c = zr.dot(zr), d = zl.dot(w), e = zr.dot(w);
    const double sl = (b * e - c * d) / (a * c - b * b), sr = (a * e - b * d) / (a * c - b * b);
    EXPECT_NEAR((cl + sl * zl - (cr + sr * zr)).norm(), 0.0, 1e-9) << "the axes intersect";
    EXPECT_NEAR(sl, baseline / (2.0 * std::sin(rig.toe_in)), 1e-6);
    EXPECT_NEAR(sr, sl, 1e-9);
    const Eigen::Vector3d meet = cl + sl * zl;
    EXPECT_NEAR(pair.left.centre().z() - meet.z(), baseline / (2.0 * std::tan(rig.toe_in)), 1e-6);
    // The calibration of the raw pair still rectifies it.
    EXPECT_LT(pair.right_info.P[3], 0.0);
    rig.toe_in = 0.0;
    const sim::StereoPairModel parallel = sim::makeStereoPair(rig);
    EXPECT_NEAR(parallel.left.world_from_camera.linear().col(2).dot(parallel.right.world_from_camera.linear().col(2)),
                1.0, 1e-12);
  }
  sim::RigParameters bad;
  bad.toe_in = 0.05;  // rectified
  EXPECT_THROW(sim::makeStereoPair(bad), std::invalid_argument);
  bad.rectified = false;
  bad.toe_in = 0.5;
  EXPECT_THROW(sim::makeStereoPair(bad), std::invalid_argument);
}

TEST(Rig, FramingPutsTheImageEdgesAtTheGivenX) {
  for (bool raw : {false, true}) {
    sim::RigParameters rig;
    rig.rectified = !raw;
    rig.toe_in = raw ? 2.0 * kDegree : 0.0;
    rig.baseline = raw ? 0.08 : 0.1;
    const double top = 0.04, bottom = -0.72, z = 0.2;
    const sim::RigParameters framed = sim::frameRig(rig, top, bottom, z);
    const sim::CameraModel cam = sim::makeStereoPair(framed).left;
    auto hit = [&](double row) {
      const Eigen::Vector3d d = cam.rayDirection((cam.width - 1) / 2.0, row);
      return cam.centre().x() + (cam.centre().z() - z) / -d.z() * d.x();
    };
    EXPECT_NEAR(hit(-0.5), top, 1e-6);
    EXPECT_NEAR(hit(cam.height - 0.5), bottom, 1e-6);
    EXPECT_GT(cam.centre().z(), z + 0.5);
    EXPECT_EQ(framed.centre.y(), rig.centre.y());
  }
  EXPECT_THROW(sim::frameRig(sim::RigParameters{}, -0.5, 0.0, 0.2), std::invalid_argument);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
