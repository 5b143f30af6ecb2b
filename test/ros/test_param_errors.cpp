// rostest: a parameter of the wrong type stops every node of the package at
// start-up with a message naming it and a non-zero exit status (a plain
// ros::NodeHandle::param() would keep the default without a word). The node
// executables run as child processes of this test, against the rostest master.
#include <gtest/gtest.h>

#include <string>

#include <ros/package.h>
#include <ros/ros.h>

#include "test_util.h"

namespace {

using massage_cell::test::runCommand;

int run_counter = 0;

void expectStartupError(const std::string& executable, const std::string& params, const std::string& expected) {
  const std::string name = "param_error_" + std::to_string(run_counter++);
  const auto result = runCommand(std::string(executable) + " __name:=" + name + " " + params, 30);
  EXPECT_NE(result.exit_code, -1) << "the node did not exit by itself\n" << result.output;
  EXPECT_NE(result.exit_code, 0) << "the node exited with status 0\n" << result.output;
  EXPECT_NE(result.output.find(expected), std::string::npos)
      << "expected the message to contain '" << expected << "', got:\n"
      << result.output;
}

TEST(ParamErrors, StartupParametersOfTheWrongType) {
  expectStartupError(CECT_NODE, "_approximate_sync:=maybe", "parameter ~approximate_sync must be true or false");
  expectStartupError(CECT_NODE, "_max_width:=wide", "parameter ~max_width must be an integer");
  expectStartupError(HBDS_NODE, "_rectify:=1.5", "parameter ~rectify must be true or false, got a number");
  expectStartupError(HBDS_NODE, "_queue_size:=2.5", "parameter ~queue_size must be an integer");
  expectStartupError(PLANAR_NODE, "_views_frame:=3.5", "parameter ~views_frame must be a string, got a number");
  expectStartupError(ARM_NODE, "_publish_rate:=fast",
                     "parameter ~publish_rate must be a number, got a string ('fast')");
  expectStartupError(SESSION_PLAYER, "_loop:=sometimes", "parameter ~loop must be true or false");
  expectStartupError(MASSAGE_SESSION,
                     "_session:=" + ros::package::getPath("massage_cell") + "/config/session.yaml _tolerance:=small",
                     "parameter ~tolerance must be a number");
  expectStartupError(STEREO_MONITOR, "_max_pairs:=many", "parameter ~max_pairs must be an integer");
}

TEST(ParamErrors, ReconfigurableParametersOfTheWrongType) {
  expectStartupError(CECT_NODE, "_publish_debug:=maybe", "parameter ~publish_debug must be true or false");
  expectStartupError(HBDS_NODE, "_downsample:=half", "parameter ~downsample must be an integer");
}

/// A client's profile that cannot be read is an error in the log, not a stop: the node goes on without it.
TEST(ParamErrors, AnUnreadableClientProfileIsLoggedAndTheNodeGoesOn) {
  const auto result =
      runCommand(std::string(CECT_NODE) + " __name:=bad_profile _client_profile_file:=/nonexistent/client.yaml", 6);
  EXPECT_EQ(result.exit_code, -1) << "the node stopped\n" << result.output;
  EXPECT_NE(result.output.find("client profile '/nonexistent/client.yaml': cannot read the file; going on without "
                               "the client's profile"),
            std::string::npos)
      << result.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_param_errors");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
