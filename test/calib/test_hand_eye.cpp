// Hand-eye calibration: the umeyama fit on exact and noisy synthetic
// correspondences, refusal of degenerate poses, bad input, the YAML round
// trip, the marker detection on a rendered pair, and the simulator end to
// end (rendered marker at 8 poses over the gantry's workspace -> camera <-
// arm base within 1 mm / 0.1 degrees of the truth).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "massage_cell/calib/hand_eye.h"
#include "massage_cell/calib/recorded_set.h"
#include "massage_cell/calib/stereo_marker.h"
#include "massage_cell/sim/hand_eye_scene.h"

namespace mc = massage_cell::calib;
namespace ms = massage_cell::sim;

namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Isometry3d someTransform() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(2.9, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(-1.4, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
  t.translation() = Eigen::Vector3d(0.2, -0.42, 0.95);
  return t;
}

/// Base points on a 3 x 3 x 2 grid of the gantry's workspace (metres).
std::vector<Eigen::Vector3d> gridPoints() {
  std::vector<Eigen::Vector3d> out;
  for (double x : {0.1, 0.4, 0.7}) {
    for (double y : {0.05, 0.25, 0.45}) {
      for (double z : {0.1, 0.3}) out.emplace_back(x, y, z);
    }
  }
  return out;
}

std::vector<mc::Correspondence> correspondences(const Eigen::Isometry3d& camera_from_base,
                                                const std::vector<Eigen::Vector3d>& base, double noise_sigma,
                                                unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_sigma);
  std::vector<mc::Correspondence> out;
  for (const Eigen::Vector3d& p : base) {
    Eigen::Vector3d c = camera_from_base * p;
    if (noise_sigma > 0.0) c += Eigen::Vector3d(n(rng), n(rng), n(rng));
    out.push_back({p, c});
  }
  return out;
}

double translationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

double angleError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return mc::rotationAngle(a.linear().transpose() * b.linear());
}

/// Runs `f`, expecting std::invalid_argument whose message contains `needle`.
template <typename F>
void expectInvalid(F f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

std::string tempPath(const std::string& name) { return ::testing::TempDir() + "/" + name; }

}  // namespace

TEST(HandEyeFit, ExactCorrespondencesRecoverTheTransform) {
  const Eigen::Isometry3d truth = someTransform();
  const mc::HandEyeResult r = mc::fitHandEye(correspondences(truth, gridPoints(), 0.0));
  EXPECT_LT((r.camera_from_base.matrix() - truth.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT(r.rms_mm, 1e-6);
  EXPECT_LT(r.max_mm, 1e-6);
  EXPECT_EQ(r.residuals_mm.size(), gridPoints().size());
  EXPECT_FALSE(r.warning());
  EXPECT_FALSE(r.date.empty());
}

TEST(HandEyeFit, NoisyCorrespondencesWithinTolerance) {
  const Eigen::Isometry3d truth = someTransform();
  const double sigma = 0.0005;  // 0.5 mm per axis
  const mc::HandEyeResult r = mc::fitHandEye(correspondences(truth, gridPoints(), sigma));
  EXPECT_LT(translationError(r.camera_from_base, truth), 0.001);
  EXPECT_LT(angleError(r.camera_from_base, truth), 0.2 * kDeg);
  // RMS of a 3D residual with 0.5 mm per axis is ~0.87 mm less the 6 fitted parameters' share.
  EXPECT_GT(r.rms_mm, 0.3);
  EXPECT_LT(r.rms_mm, 1.2);
  EXPECT_GE(r.max_mm, r.rms_mm);
}

TEST(HandEyeFit, LargeResidualsRaiseTheWarning) {
  const Eigen::Isometry3d truth = someTransform();
  mc::FitOptions o;
  o.warn_rms_mm = 1.0;
  const mc::HandEyeResult r = mc::fitHandEye(correspondences(truth, gridPoints(), 0.003), o);
  EXPECT_GT(r.rms_mm, 1.0);
  ASSERT_TRUE(r.warning());
  EXPECT_NE(r.warnings.front().find("RMS"), std::string::npos) << r.warnings.front();
}

TEST(HandEyeFit, DegeneratePosesAreRefused) {
  const Eigen::Isometry3d truth = someTransform();
  std::vector<Eigen::Vector3d> line, plane;
  for (int i = 0; i < 6; ++i) line.emplace_back(0.1 * i, 0.05 * i, 0.2);
  for (double x : {0.1, 0.4, 0.7}) {
    for (double y : {0.05, 0.45}) plane.emplace_back(x, y, 0.2);  // one Z height
  }
  expectInvalid([&] { mc::fitHandEye(correspondences(truth, line, 0.0)); }, "line");
  expectInvalid([&] { mc::fitHandEye(correspondences(truth, plane, 0.0)); }, "plane");
  std::vector<Eigen::Vector3d> same(5, Eigen::Vector3d(0.1, 0.2, 0.3));
  expectInvalid([&] { mc::fitHandEye(correspondences(truth, same, 0.0)); }, "same point");
}

TEST(HandEyeFit, BadInputIsRefused) {
  const Eigen::Isometry3d truth = someTransform();
  const std::vector<Eigen::Vector3d> grid = gridPoints();
  const std::vector<Eigen::Vector3d> three(grid.begin(), grid.begin() + 3);
  expectInvalid([&] { mc::fitHandEye(correspondences(truth, three, 0.0)); }, "at least 4");
  auto pairs = correspondences(truth, gridPoints(), 0.0);
  pairs[2].in_camera.x() = std::nan("");
  expectInvalid([&] { mc::fitHandEye(pairs); }, "pose 2");
  mc::FitOptions o;
  o.warn_rms_mm = 0.0;
  expectInvalid([&] { mc::fitHandEye(correspondences(truth, gridPoints(), 0.0), o); }, "warn_rms_mm");
}

TEST(HandEyeYaml, RoundTrip) {
  const Eigen::Isometry3d truth = someTransform();
  const mc::HandEyeResult r = mc::fitHandEye(correspondences(truth, gridPoints(), 0.0005));
  const std::string path = tempPath("hand_eye_round_trip.yaml");
  mc::writeHandEyeYaml(path, r);
  const mc::HandEyeResult back = mc::readHandEyeYaml(path);
  EXPECT_EQ(back.parent_frame, r.parent_frame);
  EXPECT_EQ(back.child_frame, r.child_frame);
  EXPECT_EQ(back.date, r.date);
  EXPECT_LT((back.camera_from_base.matrix() - r.camera_from_base.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  ASSERT_EQ(back.residuals_mm.size(), r.residuals_mm.size());
  for (std::size_t i = 0; i < r.residuals_mm.size(); ++i) EXPECT_DOUBLE_EQ(back.residuals_mm[i], r.residuals_mm[i]);
  EXPECT_DOUBLE_EQ(back.rms_mm, r.rms_mm);
  EXPECT_DOUBLE_EQ(back.max_mm, r.max_mm);
  std::remove(path.c_str());
}

TEST(HandEyeYaml, MalformedFilesNameTheProblem) {
  auto expectReadError = [](const std::string& text, const std::string& needle) {
    const std::string path = tempPath("hand_eye_bad.yaml");
    std::ofstream(path) << text;
    try {
      mc::readHandEyeYaml(path);
      ADD_FAILURE() << "no exception for: " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
    std::remove(path.c_str());
  };
  const std::string frames = "parent_frame: a\nchild_frame: b\n";
  expectReadError(frames + "rotation: {x: 0, y: 0, z: 0, w: 1}\n", "translation");
  expectReadError(frames + "translation: {x: 0, y: 0, z: 0}\nrotation: {x: 0, y: 0, z: 0, w: 2}\n", "norm");
  expectReadError(frames + "translation: {x: 0, y: oops, z: 0}\nrotation: {x: 0, y: 0, z: 0, w: 1}\n", "'y'");
  expectReadError("child_frame: b\n", "parent_frame");
  // A map where a warning's text belongs (found by fuzz_yaml_loaders: yaml-cpp's exception escaped).
  expectReadError(frames + "translation: {x: 0, y: 0, z: 0}\nrotation: {x: 0, y: 0, z: 0, w: 1}\nwarnings: [{a: 1}]\n",
                  "hand_eye_bad.yaml");
  try {
    mc::readHandEyeYaml(tempPath("does_not_exist.yaml"));
    ADD_FAILURE() << "no exception for a missing file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
}

TEST(Marker, SpecValidation) {
  mc::CharucoSpec s;
  EXPECT_NO_THROW(s.validate());
  s.marker_length = s.square_length;
  expectInvalid([&] { s.validate(); }, "marker_length");
  s = mc::CharucoSpec{};
  s.squares_x = 12;
  s.squares_y = 10;  // 60 markers, DICT_4X4_50 holds 50
  expectInvalid([&] { s.validate(); }, "dictionary holds 50");
}

TEST(RecordedSet, RoundTripAndErrors) {
  const std::string dir = ::testing::TempDir();
  const ms::StereoPairModel pair = ms::makeStereoPair(ms::RigParameters{});
  mc::RecordedSet set{pair.left_info, pair.right_info, Eigen::Vector3d(0.01, 0.0, 0.06), {}};
  set.poses.push_back({"a_left.png", "a_right.png", Eigen::Vector3d(0.1, 0.2, 0.3)});
  set.poses.push_back({"b_left.png", "b_right.png", Eigen::Vector3d(0.4, 0.0, 0.08)});
  mc::writeRecordedSet(dir, set);
  const mc::RecordedSet back = mc::readRecordedSet(dir);
  ASSERT_EQ(back.poses.size(), 2u);
  EXPECT_EQ(back.poses[1].left, "b_left.png");
  EXPECT_EQ(back.poses[1].right, "b_right.png");
  EXPECT_EQ(back.poses[1].tool_tip, set.poses[1].tool_tip);
  ASSERT_TRUE(back.marker_offset.has_value());
  EXPECT_EQ(*back.marker_offset, *set.marker_offset);
  EXPECT_EQ(back.right_info.P, set.right_info.P);
  std::ofstream(dir + "/poses.yaml") << "poses:\n  - {left: a.png, right: b.png, tool_tip: [0.1, 0.2]}\n";
  try {
    mc::readRecordedSet(dir);
    ADD_FAILURE() << "no exception for a 2-element tool_tip";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("poses[0].tool_tip"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------
// Simulator.

namespace {

ms::StereoPairModel cellPair() { return ms::makeStereoPair(ms::RigParameters{}); }

ms::MarkerMount testMount() {
  ms::MarkerMount m;
  m.offset = Eigen::Vector3d(0.01, -0.02, 0.06);
  return m;
}

ms::RenderOptions renderOptions() {
  ms::RenderOptions o;
  o.supersample = 3;
  o.noise_sigma = 1.0f;
  return o;
}

}  // namespace

TEST(SimCell, ArmBaseMatchesTheUrdf) {
  std::ifstream f(std::string(MASSAGE_CELL_SOURCE_DIR) + "/urdf/massage_arm.urdf");
  ASSERT_TRUE(f.good());
  const std::string urdf((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::size_t joint = urdf.find("<joint name=\"table_to_arm_base\"");
  ASSERT_NE(joint, std::string::npos);
  const std::string block = urdf.substr(joint, urdf.find("</joint>", joint) - joint);
  EXPECT_NE(block.find("xyz=\"0.15 0.25 0\" rpy=\"0 0 3.141592653589793\""), std::string::npos) << block;
  const Eigen::Isometry3d t = ms::tableFromArmBase();
  EXPECT_LT((t * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(-0.85, 0.25, 0)).norm(), 1e-12);
  // The simulated left camera sits where the URDF's stereo_left_optical_frame is.
  const ms::StereoPairModel pair = cellPair();
  EXPECT_LT((pair.left.centre() - Eigen::Vector3d(-0.27, 0.05, 0.95)).norm(), 1e-12);
}

TEST(SimCell, RenderedMarkerIsDetectedAtItsTruePoint) {
  const ms::StereoPairModel pair = cellPair();
  const ms::MarkerMount mount = testMount();
  const ms::MarkerPose pose = ms::renderMarkerPose(pair, Eigen::Vector3d(0.40, 0.25, 0.20), mount, renderOptions(), 1);
  const mc::RectifiedGeometry g = mc::rectifiedGeometry(pair.left_info, pair.right_info);
  const mc::MarkerDetection d = mc::detectMarker(pose.left, pose.right, g, mount.spec);
  ASSERT_TRUE(d.found) << d.problem;
  EXPECT_EQ(d.corners, mount.spec.cornerCount());
  EXPECT_LT((d.point - pose.marker_in_camera).norm(), 0.001)
      << d.point.transpose() << " vs " << pose.marker_in_camera.transpose();
  EXPECT_LT(d.fit_rms_mm, 1.0);
  // The board faces the camera: its normal (board z, into the board) along the optical axis.
  EXPECT_GT(d.camera_from_board.linear().col(2).cwiseAbs().z(), 0.99);
}

TEST(SimCell, BlankPairIsNotFound) {
  const ms::StereoPairModel pair = cellPair();
  const cv::Mat blank(pair.left.height, pair.left.width, CV_8UC3, cv::Scalar(128, 128, 128));
  const mc::MarkerDetection d =
      mc::detectMarker(blank, blank, mc::rectifiedGeometry(pair.left_info, pair.right_info), mc::CharucoSpec{});
  EXPECT_FALSE(d.found);
  EXPECT_NE(d.problem.find("0 left"), std::string::npos) << d.problem;
}

TEST(SimCell, EndToEndWithinOneMillimetreAndATenthOfADegree) {
  const ms::StereoPairModel pair = cellPair();
  const ms::MarkerMount mount = testMount();
  const std::vector<Eigen::Vector3d> tips =
      ms::spreadTipPositions(8, Eigen::Vector3d(0.0, 0.0, 0.08), Eigen::Vector3d(0.76, 0.46, 0.30), pair, mount);
  ASSERT_EQ(tips.size(), 8u);
  const mc::RectifiedGeometry g = mc::rectifiedGeometry(pair.left_info, pair.right_info);
  std::vector<mc::Correspondence> pairs;
  for (std::size_t i = 0; i < tips.size(); ++i) {
    const ms::MarkerPose pose = ms::renderMarkerPose(pair, tips[i], mount, renderOptions(), 10 + i);
    const mc::MarkerDetection d = mc::detectMarker(pose.left, pose.right, g, mount.spec);
    ASSERT_TRUE(d.found) << "pose " << i << ": " << d.problem;
    pairs.push_back({mc::markerInBase(tips[i], mount.offset), d.point});
  }
  const mc::HandEyeResult r = mc::fitHandEye(pairs);
  const Eigen::Isometry3d truth = ms::trueCameraFromBase(pair);
  const double dt = translationError(r.camera_from_base, truth), da = angleError(r.camera_from_base, truth);
  std::printf("end to end: %zu poses, translation error %.3f mm, rotation error %.4f deg, RMS %.3f mm, max %.3f mm\n",
              pairs.size(), dt * 1e3, da / kDeg, r.rms_mm, r.max_mm);
  EXPECT_LT(dt, 0.001);
  EXPECT_LT(da, 0.1 * kDeg);
  EXPECT_LT(r.rms_mm, 1.0);
  EXPECT_FALSE(r.warning());
  // A wrong mount offset shows in the transform: the check above can fail.
  std::vector<mc::Correspondence> shifted = pairs;
  for (auto& p : shifted) p.in_base += Eigen::Vector3d(0.0, 0.0, 0.005);
  EXPECT_GT(translationError(mc::fitHandEye(shifted).camera_from_base, truth), 0.004);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
