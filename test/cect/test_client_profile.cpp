// A client's profile (client_profile.h): the file round trip and its errors, the corrections on the model's
// points, and its C7 -> L4 as a trust rule (layout_check.h). Hand-made landmarks: a straight back along the
// image's columns, C7 at row 100 and L4 at row 300, 2 mm a pixel. (Shares test_cect_layout's main().)
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "massage_cell/cect/client_profile.h"
#include "massage_cell/cect/layout_check.h"

using namespace massage_cell;

namespace {

cect::BackLandmarks straightBack() {
  cect::BackLandmarks l;
  l.valid = true;
  for (int y = 40; y <= 420; ++y) {
    l.midline.emplace_back(320.0f, static_cast<float>(y));
    l.lateral.emplace_back(-1.0f, 0.0f);
  }
  l.c7.body = {320.0f, 100.0f};
  l.l4.body = {320.0f, 300.0f};
  l.shoulder_row = 130;
  l.shoulder_width = 180;
  l.waist_row = 260;
  l.measured = {"C7 at the neck's base", "the waist"};
  l.c7.detail = cect::kFromNeckBase;
  l.l4.source = cect::LandmarkSource::kMeasured;
  return l;
}

cect::AcupointModel twoPoints() {
  cect::AcupointModel m;
  m.level_fraction = {{"C7", 0.0}, {"T7", 0.36}, {"L4", 1.0}};
  m.length_per_shoulder_width = 1.22;
  m.cun_per_shoulder_width = 0.18;
  m.points = {{"GV9", "T7", 0.0, "midline"}, {"BL17_L", "T7", 1.5, "upper_back"}};
  return m;
}

const cect::PixelScale kScale = [](const cv::Point2f&) { return 0.002; };

std::string tempFile(const std::string& name, const std::string& text = "") {
  const std::string path = ::testing::TempDir() + name;
  if (!text.empty()) std::ofstream(path) << text;
  return path;
}

/// The error loadClientProfile gives for a file of `text` (a failure when it reads it), checked to name the file.
std::string loadError(const std::string& name, const std::string& text) {
  const std::string path = tempFile(name, text);
  try {
    cect::loadClientProfile(path);
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("client profile '" + path + "': "), std::string::npos) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return "";
}

const std::string kHead = "format: massage_cell/client_profile 1\nclient: \"A. N. Other\"\n";

cv::Point2f pixelOf(const std::vector<cect::AcupointPixel>& pts, const std::string& name) {
  for (const auto& p : pts)
    if (p.name == name && p.valid) return p.pixel;
  ADD_FAILURE() << name << " not placed";
  return {};
}

}  // namespace

TEST(ClientProfile, SavedAndLoadedAgainUnchanged) {
  cect::ClientProfile p;
  p.client = "A. N. Other";
  p.c7_to_l4_m = 0.452;
  p.corrections["BL23_L"] = {0.012, -0.2};
  const std::string path = tempFile("profile_round_trip.yaml");
  cect::saveClientProfile(p, path);
  const cect::ClientProfile q = cect::loadClientProfile(path);
  EXPECT_EQ(q.client, p.client);
  EXPECT_DOUBLE_EQ(q.c7_to_l4_m, 0.452);
  EXPECT_DOUBLE_EQ(q.length_tolerance_m, 0.03);
  ASSERT_EQ(q.corrections.size(), 1u);
  EXPECT_DOUBLE_EQ(q.corrections.at("BL23_L").along, 0.012);
  EXPECT_DOUBLE_EQ(q.corrections.at("BL23_L").across_cun, -0.2);
  EXPECT_EQ(cect::describeClientProfile(q), "'A. N. Other', C7 -> L4 0.452 m, 1 correction");
  // Without a length or corrections: both stay unset.
  const std::string bare = tempFile("profile_bare.yaml", "format: massage_cell/client_profile 1\nclient: x\n");
  EXPECT_TRUE(std::isnan(cect::loadClientProfile(bare).c7_to_l4_m));
  EXPECT_TRUE(cect::loadClientProfile(bare).corrections.empty());
}

TEST(ClientProfile, ABadFileIsRefusedNamingTheField) {
  const std::string head = "format: massage_cell/client_profile 1\nclient: x\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"client: x\n", "format"},
      {"format: massage_cell/client_profile 2\n", "format"},
      {head + "c7_to_l4_m: 1.5\n", "c7_to_l4_m"},
      {head + "c7_to_l4_m: long\n", "c7_to_l4_m is not a number"},
      {head + "corrections: {BL23_L: {along: 0.3}}\n", "corrections.BL23_L.along"},
      {head + "corrections: {BL23_L: {across_cun: 2}}\n", "corrections.BL23_L.across_cun"},
      {head + "corrections: [1, 2]\n", "corrections is not a map"},
      {head + "corrections: {BL23_L: 3}\n", "corrections.BL23_L is not a map"},
      {"[unclosed\n", "client profile"}};
  int i = 0;
  for (const auto& [text, field] : cases) {
    const std::string path = tempFile("profile_bad_" + std::to_string(i++) + ".yaml", text);
    try {
      cect::loadClientProfile(path);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(cect::loadClientProfile(tempFile("profile_missing.yaml")), std::runtime_error);
  cect::ClientProfile wild;
  wild.corrections["GV9"] = {0.5, 0.0};
  EXPECT_THROW(cect::saveClientProfile(wild, tempFile("profile_wild.yaml")), std::invalid_argument);
}

TEST(ClientProfile, AMisspeltKeyIsRefusedNamingIt) {
  // `c7_to_l4` for `c7_to_l4_m`: read leniently, the length check would be off without a word.
  const std::string error = loadError("profile_misspelt.yaml", kHead + "c7_to_l4: 0.452\n");
  EXPECT_NE(error.find("unknown key 'c7_to_l4' (known: format, client, c7_to_l4_m, length_tolerance_m, corrections)"),
            std::string::npos)
      << error;
}

TEST(ClientProfile, AnUnknownKeyInACorrectionIsRefusedNamingIt) {
  const std::string error =
      loadError("profile_correction_key.yaml", kHead + "corrections:\n  BL23_L: {along: 0.01, acros_cun: 0.2}\n");
  EXPECT_NE(error.find("unknown key 'corrections.BL23_L.acros_cun' (known: along, across_cun)"), std::string::npos)
      << error;
  // Either half alone is a correction (the other 0).
  const cect::ClientProfile p =
      cect::loadClientProfile(tempFile("profile_correction_half.yaml", kHead + "corrections: {GV14: {along: 0.0}}\n"));
  EXPECT_EQ(p.corrections.count("GV14"), 1u);
}

TEST(ClientProfile, AValueOfTheWrongTypeIsRefusedNamingItsKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {kHead + "c7_to_l4_m: \"0.45 m\"\n", "c7_to_l4_m is not a number (got '0.45 m')"},
      {kHead + "length_tolerance_m: [0.03]\n", "length_tolerance_m is not a number (got a list)"},
      {kHead + "c7_to_l4_m: .nan\n", "c7_to_l4_m is not a number"},
      {"format: massage_cell/client_profile 1\nclient: {name: x}\n", "client is not a name (got a map"},
      {"format: massage_cell/client_profile 1\nclient:\n", "client is not a name (got empty"},
      {kHead + "corrections: BL23_L\n", "corrections is not a map of acupoint names (got 'BL23_L')"},
      {kHead + "corrections: {BL23_L: [0.01, 0.2]}\n", "corrections.BL23_L is not a map {along, across_cun}"},
      {kHead + "corrections: {BL23_L: {along: up}}\n", "corrections.BL23_L.along is not a number (got 'up')"},
      {"format: [massage_cell/client_profile 1]\nclient: x\n", "format is a list"}};
  int i = 0;
  for (const auto& [text, expected] : cases) {
    const std::string error = loadError("profile_type_" + std::to_string(i++) + ".yaml", text);
    EXPECT_NE(error.find(expected), std::string::npos) << "expected '" << expected << "' in: " << error;
  }
}

TEST(ClientProfile, AMissingFormatOrClientIsRefusedNamingIt) {
  const std::string no_format = loadError("profile_no_format.yaml", "client: x\nc7_to_l4_m: 0.452\n");
  EXPECT_NE(no_format.find("missing key 'format'"), std::string::npos) << no_format;
  const std::string no_client =
      loadError("profile_no_client.yaml", "format: massage_cell/client_profile 1\nc7_to_l4_m: 0.452\n");
  EXPECT_NE(no_client.find("missing key 'client'"), std::string::npos) << no_client;
  const std::string empty = loadError("profile_empty.yaml", "# nothing yet\n");
  EXPECT_NE(empty.find("not a YAML map of the keys format, client"), std::string::npos) << empty;
}

TEST(ClientProfile, CorrectionsMoveTheirPointInTheLayoutsUnits) {
  const cect::BackLandmarks l = straightBack();
  const cect::AcupointModel m = twoPoints();
  cect::ClientProfile p;
  p.corrections["GV9"] = {0.05, 0.0};    // 5 % of C7 -> L4 toward L4: 10 rows here
  p.corrections["BL17_L"] = {0.0, 0.5};  // half a cun further left
  const auto before = cect::placeAcupoints(l, m, kScale);
  const auto after = cect::placeAcupoints(l, cect::withCorrections(m, p), kScale);
  const cv::Point2f gv0 = pixelOf(before, "GV9"), gv1 = pixelOf(after, "GV9");
  EXPECT_NEAR(gv1.y - gv0.y, 10.0, 0.05);
  EXPECT_NEAR(gv1.x, gv0.x, 1e-3);
  // 1 cun = 0.18 x 180 px = 32.4 px; the subject's left is -x here (lateral (-1, 0)).
  const cv::Point2f bl0 = pixelOf(before, "BL17_L"), bl1 = pixelOf(after, "BL17_L");
  EXPECT_NEAR(bl1.x - bl0.x, -0.5 * 32.4, 0.05);
  EXPECT_NEAR(bl1.y, bl0.y, 1e-3);
  // The other points as they were; a correction for a point the model lacks is refused by name.
  cect::ClientProfile unknown;
  unknown.corrections["BL99_L"] = {};
  try {
    cect::withCorrections(m, unknown);
    ADD_FAILURE() << "a correction for an unknown point accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("BL99_L"), std::string::npos) << e.what();
  }
}

TEST(ClientProfile, ALayoutWhoseLengthDisagreesWithTheProfileIsNotTrusted) {
  const cect::BackLandmarks l = straightBack();
  cect::TrustRules rules;
  EXPECT_TRUE(cect::checkLayout(l, twoPoints(), kScale, rules).trusted);  // 200 rows x 2 mm = 0.40 m
  rules.client_length_m = 0.42;
  EXPECT_TRUE(cect::checkLayout(l, twoPoints(), kScale, rules).trusted) << "within 3 cm";
  rules.client_length_m = 0.45;
  const cect::LayoutCheck c = cect::checkLayout(l, twoPoints(), kScale, rules);
  EXPECT_FALSE(c.trusted);
  EXPECT_NE(c.reason().find("the client's profile says 0.450 m"), std::string::npos) << c.reason();
  rules.length_tolerance_m = 0.06;
  EXPECT_TRUE(cect::checkLayout(l, twoPoints(), kScale, rules).trusted);
}
