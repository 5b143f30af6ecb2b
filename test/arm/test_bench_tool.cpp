// arm_bench's command line: a short run prints the five metric rows with
// plausible values; bad options exit 2, a bad configuration 1.
#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>
#include <sys/wait.h>
#include <cstdio>
#include <map>
#include <sstream>

#include <thread>

#ifndef ARM_BENCH_TOOL
#define ARM_BENCH_TOOL "arm_bench"
#endif

namespace {

struct ToolRun {
  int status = -1;
  std::string out;
};

ToolRun run(const std::string& args) {
  ToolRun r;
  FILE* p = popen((std::string(ARM_BENCH_TOOL) + " " + args + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[512];
  while (fgets(buf, sizeof buf, p)) r.out += buf;
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

/// The metric,value,unit rows of a --csv run (other lines, e.g. warnings on stderr, skipped).
std::map<std::string, double> csvValues(const std::string& out) {
  std::map<std::string, double> values;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const auto a = line.find(','), b = line.rfind(',');
    if (a == std::string::npos || a == b || line == "metric,value,unit") continue;
    values[line.substr(0, a)] = std::stod(line.substr(a + 1, b - a - 1));
  }
  return values;
}

TEST(ArmBenchTool, ShortCsvRun) {
  const ToolRun r = run("--duration 2 --estops 3 --moves 3 --csv");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.out.rfind("metric,value,unit\n", 0), 0u) << r.out;
  std::map<std::string, double> values = csvValues(r.out);
  for (const char* m :
       {"cycle_jitter_p50_ms", "cycle_jitter_p99_ms", "cycle_jitter_max_ms", "estop_latency_ms", "move_error_mm"}) {
    ASSERT_TRUE(values.count(m)) << m << "\n" << r.out;
    EXPECT_GE(values[m], 0.0) << m;
  }
  EXPECT_LE(values["cycle_jitter_p50_ms"], values["cycle_jitter_p99_ms"]);
  EXPECT_LE(values["cycle_jitter_p99_ms"], values["cycle_jitter_max_ms"]);
  // About 100 cycles a second were measured (2 s).
  EXPECT_GT(values["cycles"], 150);
  EXPECT_LT(values["cycles"], 260);
  // The simulated drives end within a count or two of the goal (0.5 um counts).
  EXPECT_LT(values["move_error_mm"], 0.01);
  EXPECT_EQ(values["realtime_priority"], 0.0);  // normal scheduling unless asked
}

/// Whether this process may use SCHED_FIFO (then the tool, its child, may too).
bool mayUseFifo() {
  std::string error = "not tried";
  std::thread t([&] {
    sched_param p{};
    p.sched_priority = 50;
    error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) == 0 ? "" : "refused";
  });
  t.join();
  return error.empty();
}

TEST(ArmBenchTool, RtPriorityRunsTheControlThreadsUnderFifoOrSaysWhyNot) {
  const ToolRun r = run("--duration 1 --estops 1 --moves 1 --rt-priority 50 --csv");
  ASSERT_EQ(r.status, 0) << r.out;
  std::map<std::string, double> values = csvValues(r.out);
  ASSERT_TRUE(values.count("realtime_priority")) << r.out;
  if (mayUseFifo()) {
    EXPECT_EQ(values["realtime_priority"], 50.0) << r.out;
    EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  } else {
    EXPECT_EQ(values["realtime_priority"], 0.0) << r.out;
    EXPECT_NE(r.out.find("ulimit -r 50"), std::string::npos) << r.out;
  }
}

TEST(ArmBenchTool, BadInput) {
  ToolRun r = run("--duration 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--duration must be > 0"), std::string::npos) << r.out;
  r = run("--frobnicate");
  EXPECT_EQ(r.status, 2);
  r = run("--config /nonexistent/arm.yaml --duration 1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("/nonexistent/arm.yaml"), std::string::npos) << r.out;
  r = run("--help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("Usage: arm_bench"), std::string::npos);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
