// The CAN tools' command lines: bad options exit 2, a missing interface or a
// bad config exit 1, each with a message naming the problem (there is no
// vcan here: the SocketCAN paths past opening are covered elsewhere).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdio>
#include <string>

#ifndef MASSAGE_CELL_SOURCE_DIR
#define MASSAGE_CELL_SOURCE_DIR "."
#endif

namespace {

struct ToolRun {
  int status = -1;
  std::string output;  // stdout + stderr
};

ToolRun run(const std::string& command) {
  ToolRun r;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[512];
  while (std::fgets(buf, sizeof buf, p)) r.output += buf;
  const int s = pclose(p);
  r.status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  return r;
}

const std::string kProbe = CAN_PROBE_TOOL;
const std::string kSim = CAN_SIM_DRIVE_TOOL;
const std::string kConfig = std::string(MASSAGE_CELL_SOURCE_DIR) + "/config/can_axes.yaml";

TEST(CanProbeTool, UsageErrors) {
  ToolRun r = run(kProbe);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--interface is required"), std::string::npos) << r.output;
  r = run(kProbe + " --interface mcnocan7 --nodes 0-4");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--nodes: node list: 0 is outside 1..127"), std::string::npos) << r.output;
  r = run(kProbe + " --interface mcnocan7 --timeout-ms 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--timeout-ms: must be 1..60000"), std::string::npos) << r.output;
  r = run(kProbe + " --frobnicate");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("unknown option '--frobnicate'"), std::string::npos) << r.output;
  r = run(kProbe + " --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.output.find("Usage: can_probe"), std::string::npos);
}

TEST(CanProbeTool, MissingInterface) {
  const ToolRun r = run(kProbe + " --interface mcnocan7");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("SocketCAN interface 'mcnocan7' does not exist"), std::string::npos) << r.output;
}

TEST(CanSimDriveTool, UsageAndConfigErrors) {
  ToolRun r = run(kSim + " --interface mcnocan7");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--config is required"), std::string::npos) << r.output;
  r = run(kSim + " --config " + kConfig);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--interface is required"), std::string::npos) << r.output;
  r = run(kSim + " --interface mcnocan7 --config /nonexistent.yaml");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("/nonexistent.yaml: cannot read the file"), std::string::npos) << r.output;
  r = run(kSim + " --interface mcnocan7 --config " + kConfig + " --nodes 9");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("none of these nodes"), std::string::npos) << r.output;
}

TEST(CanSimDriveTool, MissingInterface) {
  const ToolRun r = run(kSim + " --interface mcnocan7 --config " + kConfig);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("SocketCAN interface 'mcnocan7' does not exist"), std::string::npos) << r.output;
}

TEST(CanBenchTool, MeasuresOnTheVirtualBus) {
  const std::string bench = CAN_BENCH_TOOL;
  ToolRun r = run(bench + " --samples 50 --faults 3 --csv");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.rfind("metric,value,unit\n", 0), 0u) << r.output;
  for (const char* key : {"sdo_round_trip_p50,", "sync_period_p99,", "sync_to_tpdo1_p50,", "fault_to_emcy_event_p50,",
                          "fault_to_axis_fault_p99,", "fault_to_emcy_event_samples,3,count"}) {
    EXPECT_NE(r.output.find(key), std::string::npos) << key << "\n" << r.output;
  }
  // The SYNC period is the configured 10 ms (median within 1 ms even on a loaded machine).
  const auto at = r.output.find("sync_period_p50,");
  ASSERT_NE(at, std::string::npos);
  EXPECT_NEAR(std::stod(r.output.substr(at + 16)), 10.0, 1.0);
  // The master's own heartbeat (100 ms by default) is measured meanwhile.
  const auto hb = r.output.find("heartbeat_period_p50,");
  ASSERT_NE(hb, std::string::npos) << r.output;
  EXPECT_NEAR(std::stod(r.output.substr(hb + 21)), 100.0, 10.0);
  r = run(bench + " --samples 5");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--samples: must be 10..100000"), std::string::npos) << r.output;
  for (const char* bad :
       {" --max-p99-ms 0", " --max-p99-ms fast", " --sdo-timeout-ms 0", " --heartbeat-timeout-ms x"}) {
    r = run(bench + bad);
    EXPECT_EQ(r.status, 2) << bad << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string(bad).substr(1, std::string(bad).find(' ', 1) - 1) + ":"), std::string::npos)
        << bad << "\n"
        << r.output;
  }
}

TEST(CanBenchTool, TableEndsWithTheSuccessLineOrAFailure) {
  const std::string bench = CAN_BENCH_TOOL;
  ToolRun r = run(bench + " --samples 30 --faults 2 --sdo-timeout-ms 500 --heartbeat-timeout-ms 1000 --max-p99-ms 200");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("SDO timeout 500 ms, heartbeat consumer 1000 ms"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("master heartbeat period"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\nCAN_BENCH OK\n"), std::string::npos) << r.output;
  // Limits nobody can meet: the table is printed, then the failure naming the metrics.
  r = run(bench + " --samples 30 --faults 2 --max-p99-ms 0.000001");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.find("CAN_BENCH OK"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("CAN_BENCH FAIL: over the limits (--max-p99-ms"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("SDO expedited upload round trip p99"), std::string::npos) << r.output;
  // A heartbeat consumer time shorter than the drive's heartbeat is refused.
  r = run(bench + " --samples 30 --heartbeat-timeout-ms 50");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(
      r.output.find("CAN_BENCH FAIL: --heartbeat-timeout-ms 50: must be longer than the drive's heartbeat_ms (100)"),
      std::string::npos)
      << r.output;
  // A missing interface is a failure naming it.
  r = run(bench + " --samples 30 --interface mcnocan7");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("CAN_BENCH FAIL: SocketCAN interface 'mcnocan7' does not exist"), std::string::npos)
      << r.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
