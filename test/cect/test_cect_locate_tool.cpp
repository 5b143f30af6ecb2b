// The cect_locate tool on pairs rendered here: every acupoint of the model
// listed once, the valid ones' 3D points on the simulator's surface, YAML and
// CSV agreeing, --layout-only's pixels next to the stereo mode's, a pair
// without a back not an error, bad input a one-line message and a non-zero exit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../ros/test_util.h"
#include "massage_cell/camera/calibration_io.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/sim/body_model.h"
#include "massage_cell/sim/renderer.h"
#include "massage_cell/sim/scene_builder.h"
#include "massage_cell/sim/stereo_frame.h"

namespace {

using namespace massage_cell;
using massage_cell::test::runCommand;
using massage_cell::test::TempDir;
namespace fs = std::filesystem;

const std::string kTool = CECT_LOCATE_TOOL;
const std::string kModel = std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/acupoints.yaml";

// ---------------------------------------------------------------------------
// A rendered pair on disk, with the simulator's surface for the ground truth.

struct PairOnDisk {
  std::unique_ptr<TempDir> dir;
  sim::StereoPairModel pair;
  sim::StereoFrame frame;
  std::string file(const std::string& name) const { return (dir->path() / name).string(); }
  /// The pair's options; the armless torso rendered here has no neck (its back ends at the neck's base), so its C7
  /// at the back's top is trusted (--trust-c7-at-top) unless `plain`.
  std::string args(bool plain = false) const {
    return "--left " + file("left.png") + " --right " + file("right.png") + " --left-info " + file("left.yaml") +
           " --right-info " + file("right.yaml") + (plain ? "" : kTorso);
  }
  static constexpr const char* kTorso = " --trust-c7-at-top";
  /// f B of the rectified pair, metres x pixels (-Tx of the right projection).
  double focalBaseline() const { return -pair.right_info.P[3]; }
  /// The surface point seen at a raw left pixel, left optical frame (bilinear
  /// between four pixels that all hit something).
  bool truth(double u, double v, Eigen::Vector3d* p) const {
    const cv::Mat& m = frame.left.points;
    const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
    if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return false;
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    for (int dy = 0; dy <= 1; ++dy)
      for (int dx = 0; dx <= 1; ++dx) {
        const cv::Vec3f q = m.at<cv::Vec3f>(y0 + dy, x0 + dx);
        const Eigen::Vector3d w(q[0], q[1], q[2]);
        if (!w.allFinite()) return false;
        acc += (dx ? u - x0 : 1 - (u - x0)) * (dy ? v - y0 : 1 - (v - y0)) * w;
      }
    *p = pair.left.world_from_camera.inverse() * acc;
    return true;
  }
};

std::unique_ptr<PairOnDisk> renderPair(int subject, bool rectified) {
  auto out = std::make_unique<PairOnDisk>();
  out->dir = std::make_unique<TempDir>("cect_locate");
  const sim::BackModel back(sim::BodyParameters::subject(subject));
  const sim::Renderer renderer(sim::makeBackScene(back, 1));
  sim::RigParameters rig;
  rig.rectified = rectified;
  out->pair = sim::makeStereoPair(rig);
  sim::RenderOptions ro;
  ro.supersample = 1;
  out->frame = sim::renderStereoFrame(renderer, out->pair, sim::Lighting::preset(sim::LightPreset::kTopCentre), ro);
  EXPECT_TRUE(cv::imwrite(out->file("left.png"), out->frame.left.image));
  EXPECT_TRUE(cv::imwrite(out->file("right.png"), out->frame.right.image));
  camera::writeCameraInfoYaml(out->file("left.yaml"), out->pair.left_info, "left");
  camera::writeCameraInfoYaml(out->file("right.yaml"), out->pair.right_info, "right");
  return out;
}

/// Rendered once for all tests: the mean subject (the model's constants are
/// calibrated on it) on a rectified pair and on a raw one.
const PairOnDisk& rectifiedPair() {
  static const std::unique_ptr<PairOnDisk> p = renderPair(0, true);
  return *p;
}
const PairOnDisk& rawPair() {
  static const std::unique_ptr<PairOnDisk> p = renderPair(0, false);
  return *p;
}

// ---------------------------------------------------------------------------
// Running the tool and reading its output.

/// Runs the tool with `args`, expects exit 0 and returns the text it wrote to `output`.
std::string runOk(const std::string& args, const std::string& output) {
  const auto r = runCommand(kTool + " " + args + " --output " + output, 300);
  EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  return test::readFile(output);
}

/// RFC 4180 records: fields split at commas outside quotes, "" inside quotes a quote.
std::vector<std::vector<std::string>> parseCsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> row;
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"')
        field += text[++i];
      else if (c == '"')
        quoted = false;
      else
        field += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      row.push_back(field);
      field.clear();
    } else if (c == '\n') {
      row.push_back(field);
      rows.push_back(row);
      row.clear();
      field.clear();
    } else {
      field += c;
    }
  }
  EXPECT_FALSE(quoted) << "unterminated quote";
  EXPECT_TRUE(row.empty() && field.empty()) << "the last line has no line break";
  return rows;
}

/// CSV rows as name -> column -> text; checks the header and that every row has every column.
std::vector<std::map<std::string, std::string>> csvTable(const std::string& text, const std::string& header) {
  const auto rows = parseCsv(text);
  std::vector<std::map<std::string, std::string>> out;
  if (rows.empty()) {
    ADD_FAILURE() << "empty CSV";
    return out;
  }
  std::ostringstream h;
  for (std::size_t i = 0; i < rows[0].size(); ++i) h << (i ? "," : "") << rows[0][i];
  EXPECT_EQ(h.str(), header);
  for (std::size_t r = 1; r < rows.size(); ++r) {
    EXPECT_EQ(rows[r].size(), rows[0].size()) << "CSV line " << r + 1;
    std::map<std::string, std::string> m;
    for (std::size_t i = 0; i < rows[0].size() && i < rows[r].size(); ++i) m[rows[0][i]] = rows[r][i];
    out.push_back(m);
  }
  return out;
}

const std::string kStereoHeader = "name,region,valid,reason,u,v,x,y,z,sigma_x,sigma_y,sigma_z,disparity_sigma";
const std::string kLayoutHeader = "name,region,valid,reason,u,v";

double number(const std::string& s) { return s.empty() ? std::nan("") : std::stod(s); }

std::map<std::string, cv::Point2d> pixelsFromCsv(const std::vector<std::map<std::string, std::string>>& rows) {
  std::map<std::string, cv::Point2d> out;
  for (const auto& r : rows)
    if (!r.at("u").empty()) out[r.at("name")] = cv::Point2d(number(r.at("u")), number(r.at("v")));
  return out;
}

/// Every acupoint of the model once, in the model's order.
void expectModelOrder(const std::vector<std::string>& names) {
  EXPECT_EQ(names, cect::loadAcupointModel(kModel).names());
}

// ---------------------------------------------------------------------------
// Stereo mode.

/// The valid acupoints of a stereo YAML output, checked one by one.
struct ValidPoints {
  std::vector<std::string> names;   ///< every listed point
  int valid = 0, checked = 0;       ///< checked: with ground truth at the pixel
  double sum_error = 0.0;           ///< metres, over the checked ones
  std::vector<cv::Point2d> pixels;  ///< of the valid ones
};

/// Each valid point: reason empty, sigmas consistent, within 2 cm of the surface at its pixel.
ValidPoints checkPoints(const PairOnDisk& p, const YAML::Node& points) {
  ValidPoints out;
  for (const YAML::Node& a : points) {
    const std::string name = a["name"].as<std::string>();
    out.names.push_back(name);
    const bool ok = a["valid"].as<bool>();
    EXPECT_EQ(a["reason"].as<std::string>().empty(), ok) << name;
    if (!ok) continue;
    ++out.valid;
    const cv::Point2d px(a["u"].as<double>(), a["v"].as<double>());
    out.pixels.push_back(px);
    const Eigen::Vector3d pos(a["x"].as<double>(), a["y"].as<double>(), a["z"].as<double>());
    const Eigen::Vector3d sigma(a["sigma_x"].as<double>(), a["sigma_y"].as<double>(), a["sigma_z"].as<double>());
    EXPECT_TRUE(sigma.allFinite() && (sigma.array() > 0.0).all()) << name;
    // z = f B / d: its standard deviation follows from the disparity's.
    const double sigma_d = a["disparity_sigma"].as<double>();
    EXPECT_NEAR(sigma.z(), pos.z() * pos.z() / p.focalBaseline() * sigma_d, 0.02 * sigma.z()) << name;
    Eigen::Vector3d gt;
    if (!p.truth(px.x, px.y, &gt)) continue;
    ++out.checked;
    out.sum_error += (pos - gt).norm();
    EXPECT_LT((pos - gt).norm(), 0.02) << name << " at " << px;
  }
  return out;
}

/// The overlay: the left image's size, a green dot on the valid points, drawn over.
void checkOverlay(const PairOnDisk& p, const std::string& overlay, const std::vector<cv::Point2d>& valid) {
  const cv::Mat left = cv::imread(p.file("left.png")), img = cv::imread(overlay);
  ASSERT_FALSE(img.empty()) << "no overlay";
  ASSERT_EQ(img.size(), left.size());
  // (A later point's name may cover a few dots.)
  int green = 0;
  for (const cv::Point2d& q : valid) {
    const cv::Vec3b c = img.at<cv::Vec3b>(cvRound(q.y), cvRound(q.x));
    green += c[1] > 180 && c[0] < 60 && c[2] < 60;
  }
  EXPECT_GE(green, 0.9 * static_cast<double>(valid.size())) << "green dots on the valid acupoints";
  cv::Mat diff;
  cv::absdiff(img, left, diff);
  EXPECT_GT(cv::countNonZero(diff.reshape(1) > 30), 1000) << "overlay hardly differs from the image";
}

/// YAML output of a rendered pair: every point listed, most valid, the valid
/// ones within 2 cm of the surface at their pixel; the overlay written.
void checkStereoYaml(const PairOnDisk& p) {
  const std::string overlay = p.file("overlay.png");
  const YAML::Node y = YAML::Load(runOk(p.args() + " --overlay " + overlay, p.file("out.yaml")));
  ASSERT_TRUE(y.IsMap());
  EXPECT_EQ(y["mode"].as<std::string>(), "stereo");
  EXPECT_TRUE(y["frame"]["valid"].as<bool>()) << y["frame"]["reason"].as<std::string>();
  EXPECT_TRUE(y["valid"].as<bool>()) << y["reason"].as<std::string>();
  EXPECT_GT(y["landmarks"]["shoulder_width_px"].as<double>(), 100.0);
  ASSERT_TRUE(y["acupoints"].IsSequence());
  const ValidPoints v = checkPoints(p, y["acupoints"]);
  expectModelOrder(v.names);
  EXPECT_EQ(y["acupoints_valid"].as<int>(), v.valid);
  EXPECT_GE(v.valid, static_cast<int>(0.9 * v.names.size()));
  EXPECT_GE(v.checked, v.valid - 2) << "valid points off the simulator's surface";
  // Pixels a few px off (raw and rectified confused) can keep each point
  // within 2 cm; their mean error shows it.
  EXPECT_LT(v.sum_error / std::max(1, v.checked), 0.006) << "mean error";
  checkOverlay(p, overlay, v.pixels);
}

TEST(CectLocateTool, RectifiedPairYaml) { checkStereoYaml(rectifiedPair()); }

TEST(CectLocateTool, RawPairYaml) { checkStereoYaml(rawPair()); }

TEST(CectLocateTool, CsvAgreesWithYaml) {
  const PairOnDisk& p = rectifiedPair();
  const auto rows = csvTable(runOk(p.args() + " --format csv", p.file("out.csv")), kStereoHeader);
  const YAML::Node points = YAML::Load(runOk(p.args(), p.file("out.yaml")))["acupoints"];
  ASSERT_EQ(rows.size(), points.size());
  std::vector<std::string> names;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    const YAML::Node a = points[i];
    names.push_back(r.at("name"));
    EXPECT_EQ(r.at("name"), a["name"].as<std::string>());
    EXPECT_EQ(r.at("region"), a["region"].as<std::string>());
    EXPECT_EQ(r.at("valid"), a["valid"].as<bool>() ? "true" : "false");
    EXPECT_EQ(r.at("reason"), a["reason"].as<std::string>());
    for (const char* key : {"u", "v", "x", "y", "z", "sigma_x", "sigma_y", "sigma_z", "disparity_sigma"}) {
      const double c = number(r.at(key)), yv = a[key].as<double>();
      if (std::isnan(yv))
        EXPECT_TRUE(r.at(key).empty()) << r.at("name") << " " << key;
      else
        EXPECT_NEAR(c, yv, 1e-6 * std::max(1.0, std::abs(yv))) << r.at("name") << " " << key;
    }
  }
  expectModelOrder(names);
}

TEST(CectLocateTool, NamesWithCommasAndQuotesSurviveBothFormats) {
  const PairOnDisk& p = rectifiedPair();
  const std::string odd = "odd, \"quoted\": #1";
  std::ofstream(p.file("odd_model.yaml"))
      << test::readFile(kModel) << "\n  - {name: '" << odd << "', level: L2, lateral_cun: 1.0, region: lower_back}\n";
  const std::string args = p.args() + " --acupoints " + p.file("odd_model.yaml");
  const auto rows = csvTable(runOk(args + " --format csv", p.file("odd.csv")), kStereoHeader);
  const YAML::Node points = YAML::Load(runOk(args, p.file("odd.yaml")))["acupoints"];
  ASSERT_FALSE(rows.empty());
  ASSERT_EQ(rows.size(), points.size());
  EXPECT_EQ(rows.back().at("name"), odd);
  EXPECT_EQ(points[points.size() - 1]["name"].as<std::string>(), odd);
  EXPECT_EQ(rows.back().at("valid"), "true");
}

// ---------------------------------------------------------------------------
// Layout-only mode.

TEST(CectLocateTool, LayoutOnlyPixelsMatchTheStereoMode) {
  const PairOnDisk& p = rectifiedPair();
  const auto layout_rows = csvTable(
      runOk("--layout-only " + p.file("left.png") + PairOnDisk::kTorso + " --format csv", p.file("layout.csv")),
      kLayoutHeader);
  std::vector<std::string> names;
  for (const auto& r : layout_rows) names.push_back(r.at("name"));
  expectModelOrder(names);
  const auto layout = pixelsFromCsv(layout_rows);
  EXPECT_EQ(layout.size(), layout_rows.size()) << "every acupoint placed";
  // The stereo mode's 3D corrections off: the same silhouette and landmarks;
  // only the lateral offsets differ (converted with the depth along the back).
  const auto plain = pixelsFromCsv(csvTable(
      runOk(p.args() + " --format csv --no-parallax-correction --no-3d-levels", p.file("plain.csv")), kStereoHeader));
  // With them the midline moves off the silhouette's parallax and the levels
  // are spaced along the body in 3D: the points move by up to ~2 cm, so only
  // a bound against gross mistakes (another image, mirrored sides).
  const auto full = pixelsFromCsv(csvTable(runOk(p.args() + " --format csv", p.file("full.csv")), kStereoHeader));
  const cect::AcupointModel model = cect::loadAcupointModel(kModel);
  for (const auto& spec : model.points) {
    const auto l = layout.find(spec.name), s = plain.find(spec.name), f = full.find(spec.name);
    if (l == layout.end() || s == plain.end() || f == full.end()) {
      ADD_FAILURE() << spec.name << " not placed in every mode";
      continue;
    }
    EXPECT_LT(cv::norm(l->second - s->second), spec.lateral_cun == 0.0 ? 0.5 : 4.0) << spec.name;
    EXPECT_LT(cv::norm(l->second - f->second), 15.0) << spec.name;
  }
}

TEST(CectLocateTool, LayoutOnlyCunComesFromTheShoulderWidth) {
  const PairOnDisk& p = rectifiedPair();
  const YAML::Node y =
      YAML::Load(runOk("--layout-only " + p.file("left.png") + PairOnDisk::kTorso, p.file("layout.yaml")));
  EXPECT_EQ(y["mode"].as<std::string>(), "layout_only");
  ASSERT_TRUE(y["valid"].as<bool>()) << y["reason"].as<std::string>();
  const cect::AcupointModel model = cect::loadAcupointModel(kModel);
  const double cun_px = model.cun_per_shoulder_width * y["landmarks"]["shoulder_width_px"].as<double>();
  std::map<std::string, cv::Point2d> px;
  for (const YAML::Node& a : y["acupoints"]) {
    EXPECT_FALSE(a["x"]) << "no 3D without a pair";
    px[a["name"].as<std::string>()] = cv::Point2d(a["u"].as<double>(), a["v"].as<double>());
  }
  // Same level, lateral_cun apart: BL23 (L2, +-1.5 cun) and BL52 (L2, +-3 cun) from GV4 (L2, midline).
  for (const auto& [name, cun] : std::vector<std::pair<std::string, double>>{
           {"BL23_L", 1.5}, {"BL23_R", 1.5}, {"BL52_L", 3.0}, {"BL52_R", 3.0}}) {
    ASSERT_TRUE(px.count(name)) << name;
    EXPECT_NEAR(cv::norm(px[name] - px["GV4"]), cun * cun_px, 0.01) << name;
  }
  // The subject's left is on the image's left (head up).
  EXPECT_LT(px["BL23_L"].x, px["GV4"].x);
  EXPECT_GT(px["BL23_R"].x, px["GV4"].x);
}

// ---------------------------------------------------------------------------
// No back: not an error.

/// Writes a uniform image of `colour` with a little noise, the pair's size.
void writePlain(const std::string& path, const cv::Scalar& colour, double noise) {
  cv::Mat img(480, 640, CV_8UC3, colour);
  if (noise > 0.0) {
    cv::Mat n(img.size(), CV_16SC3);
    cv::randn(n, cv::Scalar::all(0), cv::Scalar::all(noise));
    cv::Mat i16;
    img.convertTo(i16, CV_16SC3);
    i16 += n;
    i16.convertTo(img, CV_8UC3);
  }
  ASSERT_TRUE(cv::imwrite(path, img));
}

void checkNoBack(const PairOnDisk& p, const std::string& image) {
  const std::string info = " --left-info " + p.file("left.yaml") + " --right-info " + p.file("right.yaml");
  const std::string args = "--left " + image + " --right " + image + info;
  const YAML::Node y = YAML::Load(runOk(args + " --overlay " + p.file("none.png"), p.file("none.yaml")));
  EXPECT_FALSE(y["valid"].as<bool>());
  const std::string reason = y["reason"].as<std::string>();
  EXPECT_NE(reason.find("no back in view"), std::string::npos) << reason;
  EXPECT_FALSE(y["frame"]["valid"].as<bool>());
  EXPECT_EQ(y["acupoints_valid"].as<int>(), 0);
  std::vector<std::string> names;
  for (const YAML::Node& a : y["acupoints"]) {
    names.push_back(a["name"].as<std::string>());
    EXPECT_FALSE(a["valid"].as<bool>());
    EXPECT_EQ(a["reason"].as<std::string>(), reason);
    EXPECT_TRUE(std::isnan(a["u"].as<double>()));
  }
  expectModelOrder(names);
  EXPECT_FALSE(cv::imread(p.file("none.png")).empty()) << "the overlay is written too";
  const auto rows = csvTable(runOk(args + " --format csv", p.file("none.csv")), kStereoHeader);
  EXPECT_EQ(rows.size(), names.size());
  for (const auto& r : rows) {
    EXPECT_EQ(r.at("valid"), "false");
    EXPECT_EQ(r.at("reason"), reason);
    EXPECT_TRUE(r.at("u").empty() && r.at("x").empty());
  }
  const auto layout =
      csvTable(runOk("--layout-only " + image + " --format csv", p.file("none_layout.csv")), kLayoutHeader);
  EXPECT_EQ(layout.size(), names.size());
  for (const auto& r : layout) EXPECT_NE(r.at("reason").find("no back in view"), std::string::npos);
}

TEST(CectLocateTool, PairWithoutABackIsNotAnError) {
  const PairOnDisk& p = rectifiedPair();
  writePlain(p.file("grey.png"), cv::Scalar(180, 190, 200), 0.0);
  checkNoBack(p, p.file("grey.png"));
  // Skin-coloured noise: no region large enough.
  writePlain(p.file("skin.png"), cv::Scalar(140, 170, 225), 3.0);
  checkNoBack(p, p.file("skin.png"));
}

// ---------------------------------------------------------------------------
// Bad input.

void expectFailure(const std::string& args, int code, const std::string& message) {
  const auto r = runCommand(kTool + " " + args, 120);
  EXPECT_EQ(r.exit_code, code) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n" << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << "one line:\n" << r.output;
}

TEST(CectLocateTool, BadInputFailsWithAMessage) {
  const PairOnDisk& p = rectifiedPair();
  const std::string info = " --left-info " + p.file("left.yaml") + " --right-info " + p.file("right.yaml");
  const std::string right = " --right " + p.file("right.png");
  {
    cv::Mat small;
    cv::resize(cv::imread(p.file("left.png")), small, cv::Size(320, 240));
    ASSERT_TRUE(cv::imwrite(p.file("small.png"), small));
    std::ofstream(p.file("bad.yaml")) << "points: [1, 2\n  level: }\n";
    std::ofstream(p.file("text.png")) << "not an image\n";
  }
  expectFailure("--left " + p.file("missing.png") + right + info, 1, "no such image file '" + p.file("missing.png"));
  expectFailure("--left " + p.file("text.png") + right + info, 1,
                "cannot read '" + p.file("text.png") + "' as an image");
  expectFailure("--left " + p.file("small.png") + right + info, 1,
                "image size mismatch: '" + p.file("small.png") + "' is 320x240");
  expectFailure(p.args() + " --acupoints " + p.file("bad.yaml"), 1,
                "acupoint model '" + p.file("bad.yaml") + "': not valid YAML");
  expectFailure("--left " + p.file("left.png") + right + " --left-info " + p.file("bad.yaml") + " --right-info " +
                    p.file("right.yaml"),
                1, "calibration file '" + p.file("bad.yaml") + "' is not valid YAML");
  expectFailure(p.args() + " --bogus", 2, "unknown option '--bogus'");
  expectFailure("--left " + p.file("left.png") + right + " --left-info " + p.file("left.yaml"), 2,
                "missing --right-info");
  expectFailure(p.args() + " --format json", 2, "unknown format 'json'");
  expectFailure(p.args() + " --param ncc_radius=9,bogus=1", 2, "unknown CECT parameter 'bogus'");
  expectFailure(p.args() + " --min-depth 3", 2, "--min-depth must be less than --max-depth");
  expectFailure("--layout-only " + p.file("left.png") + right, 2, "--layout-only takes one image");
  expectFailure("--layout-only " + p.file("missing.png"), 1, "no such image file");
}

/// Without a neck in view the layout is not trusted, and says why; C7 and L4 given as a therapist palpates them make
/// it trusted, placed at them.
TEST(CectLocateTool, AC7WithoutANeckIsNotTrustedUntilGiven) {
  const PairOnDisk& p = rectifiedPair();
  const YAML::Node refused = YAML::Load(runOk(p.args(true), p.file("refused.yaml")));
  EXPECT_FALSE(refused["valid"].as<bool>());
  EXPECT_NE(refused["reason"].as<std::string>().find("layout not trusted: C7 not measured"), std::string::npos)
      << refused["reason"].as<std::string>();
  EXPECT_EQ(refused["acupoints_valid"].as<int>(), 0);
  // The therapist's C7 and L4: the simulator's, in the raw left image.
  const sim::BackModel back(sim::BodyParameters::subject(0));
  const auto truth = sim::toCameraFrame(back.landmarks(), p.pair.left);
  auto pixel = [&](const std::string& level) {
    const Eigen::Vector3d& q = truth.at(level);
    const double u = p.pair.left_info.K[0] * q.x() / q.z() + p.pair.left_info.K[2];
    const double v = p.pair.left_info.K[4] * q.y() / q.z() + p.pair.left_info.K[5];
    return std::make_pair(u, v);
  };
  const auto [c7u, c7v] = pixel("C7");
  const auto [l4u, l4v] = pixel("L4");
  const std::string given = " --landmark C7=" + std::to_string(c7u) + "," + std::to_string(c7v) +
                            " --landmark L4=" + std::to_string(l4u) + "," + std::to_string(l4v);
  const YAML::Node y = YAML::Load(runOk(p.args(true) + given, p.file("given.yaml")));
  ASSERT_TRUE(y["valid"].as<bool>()) << y["reason"].as<std::string>();
  EXPECT_GE(y["acupoints_valid"].as<int>(), 90);
  EXPECT_EQ(y["landmarks"]["given"].size(), 2u);
  // C7 given and the layout trusted: GV14 (at C7) must be localised, at the given pixel.
  int gv14_checked = 0;
  for (const YAML::Node& a : y["acupoints"]) {
    if (a["name"].as<std::string>() != "GV14") continue;
    ++gv14_checked;
    ASSERT_TRUE(a["valid"].as<bool>()) << "GV14 invalid with C7 given: " << a["reason"].as<std::string>("");
    EXPECT_NEAR(a["u"].as<double>(), c7u, 1.0);
    EXPECT_NEAR(a["v"].as<double>(), c7v, 1.0);
  }
  EXPECT_EQ(gv14_checked, 1) << "GV14 is not in the output";
  expectFailure(p.args(true) + " --landmark T3=10,10", 2, "unknown landmark 'T3'");
  expectFailure(p.args(true) + " --landmark C7=10", 2, "expected the pixel as U,V");

  // The client's profile: saved from this session (C7 and L4 given), applied in the next.
  const std::string profile = p.file("client.yaml");
  runOk(p.args(true) + given + " --save-profile " + profile + " --client subject0", p.file("saved.yaml"));
  const YAML::Node saved = YAML::LoadFile(profile);
  EXPECT_EQ(saved["client"].as<std::string>(), "subject0");
  const double length = saved["c7_to_l4_m"].as<double>();
  EXPECT_GT(length, 0.3);
  EXPECT_LT(length, 0.55);
  const YAML::Node again = YAML::Load(runOk(p.args(true) + given + " --profile " + profile, p.file("again.yaml")));
  EXPECT_TRUE(again["valid"].as<bool>()) << again["reason"].as<std::string>();
  // A profile 5 cm longer (another client, or a landmark a vertebra off): refused, saying so.
  {
    YAML::Node other = YAML::LoadFile(profile);
    other["c7_to_l4_m"] = length + 0.05;
    other["corrections"]["GV14"]["along"] = 0.0;
    std::ofstream(p.file("other.yaml")) << other << "\n";
  }
  const YAML::Node refused_other =
      YAML::Load(runOk(p.args(true) + given + " --profile " + p.file("other.yaml"), p.file("other_out.yaml")));
  EXPECT_FALSE(refused_other["valid"].as<bool>());
  EXPECT_NE(refused_other["reason"].as<std::string>().find("the client's profile says"), std::string::npos)
      << refused_other["reason"].as<std::string>();
  expectFailure(p.args(true) + " --save-profile " + p.file("x.yaml"), 1, "C7 and L4 must both be given");
  expectFailure(p.args(true) + " --client x", 2, "--client names the client");
  expectFailure(p.args(true) + " --profile " + p.file("missing.yaml"), 1, "client profile '" + p.file("missing.yaml"));
}

}  // namespace

/// The shipped back pair (data/back_pair, a dressed subject: arms along the trunk, head in the cradle, a towel):
/// C7 and L4 clicked on the spine are used (>= 100 of 108 points); the same clicks 10 cm to the subject's right (a
/// mis-click, or the previous client's places) are refused, naming them; a click outside the image is an error.
TEST(CectLocateTool, OnTheShippedBackPairClicksBesideTheSpineAreRefused) {
  const std::string dir = std::string(MASSAGE_CELL_SOURCE_DIR) + "/data/back_pair/";
  const std::string args = "--left " + dir + "left.png --right " + dir + "right.png --left-info " + dir +
                           "left_camera_info.yaml --right-info " + dir + "right_camera_info.yaml";
  const YAML::Node truth = YAML::LoadFile(dir + "acupoints_truth.yaml")["landmarks"];
  const YAML::Node info = YAML::LoadFile(dir + "left_camera_info.yaml");
  const double fx = info["camera_matrix"]["data"][0].as<double>();
  // The therapist's clicks: the true C7 and iliac-crest line, then 10 cm toward the subject's right (the camera's
  // +x: the subject lies prone, head up in the image, the subject's left on the image's left).
  auto clicks = [&](double right_m) {
    std::string s;
    for (const std::string level : {"C7", "L4"}) {
      const double z = truth[level]["left_optical"][2].as<double>();
      const double u = truth[level]["left_pixel"][0].as<double>() + right_m * fx / z;
      s += " --landmark " + level + "=" + std::to_string(u) + "," +
           std::to_string(truth[level]["left_pixel"][1].as<double>());
    }
    return s;
  };
  const TempDir tmp("back_pair");
  const std::string out = tmp.str() + "/out.yaml";
  const YAML::Node on = YAML::Load(runOk(args + clicks(0.0), out));
  ASSERT_TRUE(on["valid"].as<bool>()) << on["reason"].as<std::string>();
  EXPECT_GE(on["acupoints_valid"].as<int>(), 100);
  EXPECT_TRUE(on["landmarks"]["trusted"].as<bool>());
  EXPECT_EQ(on["landmarks"]["used"][0].as<std::string>(), "C7 given (--landmark)");
  const YAML::Node beside = YAML::Load(runOk(args + clicks(0.10), out));
  EXPECT_FALSE(beside["valid"].as<bool>());
  EXPECT_EQ(beside["acupoints_valid"].as<int>(), 0);
  EXPECT_FALSE(beside["landmarks"]["trusted"].as<bool>());
  for (const std::string level : {"C7", "L4"})
    EXPECT_NE(beside["reason"].as<std::string>().find("the given " + level + " (--landmark) lies "), std::string::npos)
        << beside["reason"].as<std::string>();
  EXPECT_NE(beside["reason"].as<std::string>().find("to the subject's right of the back's midline"), std::string::npos);
  expectFailure(args + " --landmark C7=900,62", 1,
                "--landmark: landmark C7 at (900.0, 62.0) lies outside the 640x480 image");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
