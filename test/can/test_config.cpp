// Configuration tests: the example file loads, and every kind of mistake is
// a ConfigError naming the field.
#include <gtest/gtest.h>

#include "massage_cell/can/config.h"

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

using namespace massage_cell::can;

const char* const kMinimal = R"(
axes:
  - {name: X, node_id: 1, counts_per_metre: 1000}
  - {name: Y, node_id: 2, counts_per_metre: 1000}
)";

// The ConfigError message of parsing `yaml` (empty when it parsed).
std::string errorOf(const std::string& yaml) {
  try {
    parseCanConfig(yaml, "test.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return {};
}

TEST(CanConfig, ExampleFileLoads) {
  const CanConfig c = loadCanConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml");
  ASSERT_EQ(c.axes.size(), 3u);
  EXPECT_EQ(c.axes[0].name, "X");
  EXPECT_EQ(c.axes[0].node_id, 1);
  EXPECT_EQ(c.axes[1].node_id, 2);
  EXPECT_EQ(c.axes[2].node_id, 3);
  EXPECT_EQ(c.sync_period_us, 10000u);
  EXPECT_EQ(c.axes[0].heartbeatTimeoutMs(), 300u);
  EXPECT_EQ(c.axes[1].heartbeatTimeoutMs(), 300u);  // default 3 x 100
  EXPECT_EQ(c.axes[2].homing_method, 18);
  EXPECT_DOUBLE_EQ(c.axes[2].home_offset, 0.30);
  EXPECT_EQ(c.axes[2].sim.device_name, "massage_cell sim drive Z");
  EXPECT_EQ(c.findAxis("Y")->node_id, 2);
  EXPECT_EQ(c.findNode(3)->name, "Z");
  EXPECT_EQ(c.findNode(4), nullptr);
}

TEST(CanConfig, MinimalConfigGetsDefaults) {
  const CanConfig c = parseCanConfig(kMinimal);
  EXPECT_EQ(c.axes[0].heartbeat_ms, 100);
  EXPECT_EQ(c.axes[0].toCounts(0.0125), 13);  // rounded
  EXPECT_DOUBLE_EQ(c.axes[0].toMetres(-500), -0.5);
  EXPECT_EQ(c.sdo_timeout_ms, 100u);
}

TEST(CanConfig, DuplicateNodeIdNamesBothAxes) {
  const std::string e = errorOf(R"(
axes:
  - {name: X, node_id: 2, counts_per_metre: 1000}
  - {name: Y, node_id: 2, counts_per_metre: 1000}
)");
  EXPECT_NE(e.find("test.yaml: axes[1].node_id: duplicate node id 2 (axis 'X' already uses it)"), std::string::npos)
      << e;
}

TEST(CanConfig, MissingRequiredFieldsAreNamed) {
  EXPECT_NE(errorOf("axes:\n  - {name: X, counts_per_metre: 1}\n").find("axes[0].node_id: missing field"),
            std::string::npos);
  EXPECT_NE(errorOf("axes:\n  - {node_id: 1, counts_per_metre: 1}\n").find("axes[0].name: missing field"),
            std::string::npos);
  EXPECT_NE(errorOf("axes:\n  - {name: X, node_id: 1}\n").find("axes[0].counts_per_metre: missing field"),
            std::string::npos);
  EXPECT_NE(errorOf("bus: {sync_period_ms: 10}\n").find("axes: missing field"), std::string::npos);
  EXPECT_NE(errorOf("axes: []\n").find("no axes configured"), std::string::npos);
}

TEST(CanConfig, BadValuesAreNamed) {
  std::string e = errorOf("axes:\n  - {name: X, node_id: 128, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("axes[0].node_id: 128 is outside 1..127"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1.5, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("axes[0].node_id: expected an integer"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: abc}\n");
  EXPECT_NE(e.find("axes[0].counts_per_metre: expected a number, got 'abc'"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: -3}\n");
  EXPECT_NE(e.find("axes[0].counts_per_metre:"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, velocity_pdo: maybe}\n");
  EXPECT_NE(e.find("axes[0].velocity_pdo: expected true or false"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, min_position: 1, max_position: 0}\n");
  EXPECT_NE(e.find("axes[0].max_position: must be greater than min_position"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, heartbeat_ms: 100, heartbeat_timeout_ms: 50}\n");
  EXPECT_NE(e.find("axes[0].heartbeat_timeout_ms"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1e10}\n");
  EXPECT_NE(e.find("do not fit in 32-bit counts"), std::string::npos) << e;
  e = errorOf("bus: {sync_period_ms: 0}\naxes:\n  - {name: X, node_id: 1, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("bus.sync_period_ms"), std::string::npos) << e;
}

TEST(CanConfig, UnknownFieldsAndDuplicateNamesAreErrors) {
  std::string e = errorOf("axes:\n  - {name: X, node: 1, node_id: 1, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("axes[0].node: unknown field"), std::string::npos) << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, homing: {methd: 17}}\n");
  EXPECT_NE(e.find("axes[0].homing.methd: unknown field"), std::string::npos) << e;
  e = errorOf(
      "axes:\n  - {name: X, node_id: 1, counts_per_metre: 1}\n  - {name: X, node_id: 2, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("axes[1].name: duplicate axis name 'X'"), std::string::npos) << e;
  e = errorOf("busses: {}\naxes:\n  - {name: X, node_id: 1, counts_per_metre: 1}\n");
  EXPECT_NE(e.find("busses: unknown field"), std::string::npos) << e;
}

TEST(CanConfig, MasterHeartbeatKeysAndDefaults) {
  const CanConfig d = parseCanConfig(kMinimal);
  EXPECT_EQ(d.master_node_id, 127);  // defaults: heartbeat 0x77F every 100 ms
  EXPECT_EQ(d.master_heartbeat_ms, 100);
  EXPECT_EQ(d.axes[0].master_heartbeat_timeout_ms, 0u);  // drives do not monitor the master unless asked
  EXPECT_EQ(d.axes[0].abort_connection_option, 1);
  const CanConfig c = parseCanConfig(R"(
bus: {master_node_id: 100, master_heartbeat_ms: 50}
axes:
  - {name: X, node_id: 1, counts_per_metre: 1000, master_heartbeat_timeout_ms: 150, abort_connection_option: 3}
)");
  EXPECT_EQ(c.master_node_id, 100);
  EXPECT_EQ(c.master_heartbeat_ms, 50);
  EXPECT_EQ(c.axes[0].master_heartbeat_timeout_ms, 150u);
  EXPECT_EQ(c.axes[0].abort_connection_option, 3);
  EXPECT_EQ(parseCanConfig(std::string("bus: {master_heartbeat_ms: 0}\n") + kMinimal).master_heartbeat_ms, 0);  // off
  const CanConfig file = loadCanConfig(std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml");
  EXPECT_EQ(file.master_node_id, 127);
  EXPECT_EQ(file.master_heartbeat_ms, 100);
}

TEST(CanConfig, BadMasterHeartbeatValuesAreNamed) {
  const std::string axes = "axes:\n  - {name: X, node_id: 1, counts_per_metre: 1}\n";
  std::string e = errorOf("bus: {master_node_id: 0}\n" + axes);
  EXPECT_NE(e.find("test.yaml: bus.master_node_id: 0 is outside 1..127"), std::string::npos) << e;
  e = errorOf("bus: {master_node_id: 128}\n" + axes);
  EXPECT_NE(e.find("bus.master_node_id: 128 is outside 1..127"), std::string::npos) << e;
  e = errorOf("bus: {master_node_id: 1}\n" + axes);
  EXPECT_NE(e.find("axes[0].node_id: node id 1 is the master's own (bus.master_node_id)"), std::string::npos) << e;
  e = errorOf("bus: {master_heartbeat_ms: -5}\n" + axes);
  EXPECT_NE(e.find("bus.master_heartbeat_ms: -5 is outside 0..65535"), std::string::npos) << e;
  e = errorOf("bus: {master_heartbeat_ms: 70000}\n" + axes);
  EXPECT_NE(e.find("bus.master_heartbeat_ms: 70000 is outside 0..65535"), std::string::npos) << e;
  e = errorOf("bus: {master_heartbeat_ms: fast}\n" + axes);
  EXPECT_NE(e.find("bus.master_heartbeat_ms: expected a number, got 'fast'"), std::string::npos) << e;
  e = errorOf(
      "bus: {master_heartbeat_ms: 0}\naxes:\n  - {name: X, node_id: 1, counts_per_metre: 1, "
      "master_heartbeat_timeout_ms: 300}\n");
  EXPECT_NE(e.find("axes[0].master_heartbeat_timeout_ms: the drive would monitor the master's heartbeat, but "
                   "bus.master_heartbeat_ms is 0"),
            std::string::npos)
      << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, master_heartbeat_timeout_ms: 100}\n");
  EXPECT_NE(e.find("axes[0].master_heartbeat_timeout_ms: 100 ms must be longer than bus.master_heartbeat_ms (100 ms)"),
            std::string::npos)
      << e;
  e = errorOf("axes:\n  - {name: X, node_id: 1, counts_per_metre: 1, abort_connection_option: 4}\n");
  EXPECT_NE(e.find("axes[0].abort_connection_option: 4 is outside 0..3"), std::string::npos) << e;
  // validate() checks a config built in code the same way.
  CanConfig c = parseCanConfig(kMinimal);
  c.master_node_id = 2;
  try {
    validate(c, "code");
    FAIL() << "master id = axis Y's id accepted";
  } catch (const ConfigError& err) {
    EXPECT_NE(std::string(err.what()).find("code: axes[1].node_id: node id 2 is the master's own"), std::string::npos)
        << err.what();
  }
}

TEST(CanConfig, SyntaxErrorsAndMissingFiles) {
  EXPECT_NE(errorOf("axes: [\n").find("YAML syntax error"), std::string::npos);
  EXPECT_NE(errorOf("- 1\n- 2\n").find("expected a map"), std::string::npos);
  EXPECT_NE(errorOf("axes: 3\n").find("axes: expected a list"), std::string::npos);
  try {
    loadCanConfig("/nonexistent/can.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/can.yaml: cannot read"), std::string::npos);
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
