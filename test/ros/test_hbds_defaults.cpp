// The project's one default setting of the dense stereo: the library's StereoParams, mirrored by the hbds node's
// cfg/HBDS.cfg (dynamic_reconfigure needs its defaults there) and not restated by config/hbds.yaml, which holds only
// its rig's values. The tools take StereoParams as they are.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "../../src/nodes/hbds_config.h"

namespace ms = massage_cell::stereo;

namespace {

/// Every field of StereoParams the node's configuration sets, by its cfg name.
std::map<std::string, std::string> fields(const ms::StereoParams& p) {
  const auto str = [](double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  };
  return {{"cost", ms::toString(p.cost.data_term)},
          {"eta", str(p.cost.eta)},
          {"ncc_window", str(p.cost.ncc_window)},
          {"gradient_saturation", str(p.cost.gradient_saturation)},
          {"tau", str(p.smooth.tau)},
          {"u_min", str(p.smooth.u_min)},
          {"u_max", str(p.smooth.u_max)},
          {"overlap", str(p.hbds_overlap)},
          {"coarse", str(p.hbds_coarse)},
          {"polish_window", str(p.polish_window)},
          {"polish_coarse", str(p.polish_coarse)},
          {"refine", ms::toString(p.refine)},
          {"refine_window", str(p.refine_params.window)},
          {"subpixel", p.subpixel ? ms::toString(p.subpixel_params.fit) : "none"},
          {"lr_check", p.lr_check ? "true" : "false"},
          {"lr_tolerance", str(p.lr_tolerance)},
          {"threads", str(p.threads)}};
}

/// The parameter names cfg/HBDS.cfg adds.
std::set<std::string> cfgParameters() {
  std::ifstream in(std::string(MASSAGE_CELL_SOURCE_DIR) + "/cfg/HBDS.cfg");
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  std::set<std::string> names;
  const std::regex add(R"re(gen\.add\("([a-z_]+)")re");
  for (auto it = std::sregex_iterator(s.begin(), s.end(), add); it != std::sregex_iterator(); ++it)
    names.insert((*it)[1]);
  return names;
}

TEST(HbdsDefaults, TheNodesConfigurationDefaultsAreTheLibrarys) {
  const massage_cell::HBDSConfig& config = massage_cell::HBDSConfig::__getDefault__();
  const auto node = fields(massage_cell::nodes::stereoParams(config));
  const auto library = fields(ms::StereoParams{});
  for (const auto& [name, value] : library) {
    EXPECT_EQ(node.at(name), value) << "cfg/HBDS.cfg's default of " << name
                                    << " is not the library's (StereoParams in stereo/pipeline.h)";
  }
  EXPECT_EQ(config.method, "hbds");
  EXPECT_EQ(config.downsample, 1);
  EXPECT_TRUE(config.lr_fill);
}

TEST(HbdsDefaults, TheRigsYamlHoldsOnlyItsRigsValues) {
  const std::set<std::string> cfg = cfgParameters();
  ASSERT_GT(cfg.size(), 20u);  // the regex finds the parameters
  const std::set<std::string> rig{"min_disparity", "disparity_range"};
  const YAML::Node yaml = YAML::LoadFile(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/hbds.yaml");
  for (const auto& kv : yaml) {
    const std::string key = kv.first.as<std::string>();
    if (cfg.count(key)) {
      EXPECT_TRUE(rig.count(key)) << "config/hbds.yaml restates '" << key
                                  << "': its default is the library's (set it there only for a rig that needs another)";
    }
  }
  for (const std::string& key : rig) EXPECT_TRUE(yaml[key]) << key << " (the rig's range) missing";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
