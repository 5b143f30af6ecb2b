// rostest of the CECT node started with a client's profile it cannot read (test/ros/cect_client_profile_error.test):
// the node keeps running on the bundled recording, but every acupoint it publishes is invalid, the pairs with a
// layout saying "layout not trusted: client profile <file> not usable: ...", and its diagnostics are an error naming
// the profile.
//
// Parameters (private): profile (the unreadable file the node was given).
#include <gtest/gtest.h>

#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>

#include "massage_cell/AcupointArray.h"
#include "spin_util.h"

namespace {

const std::string kDiagnostics = "acupoints (cect)";  // the node's diagnostics task

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(CectClientProfileError, NoLayoutIsTrustedAndTheDiagnosticsSayWhy) {
  ros::NodeHandle nh, pnh("~");
  std::string profile;
  ASSERT_TRUE(pnh.getParam("profile", profile));
  const std::string problem = "client profile " + profile + " not usable: cannot read the file; no layout is trusted";

  int messages = 0, valid = 0, with_layout = 0, refused_for_profile = 0;
  std::string a_reason;
  diagnostic_msgs::DiagnosticStatus status;
  bool have_status = false;
  const ros::Subscriber acupoints =
      nh.subscribe<massage_cell::AcupointArray>("/stereo/acupoints", 10, [&](const auto& msg) {
        ++messages;
        if (!msg->landmarks.empty()) ++with_layout;
        bool profile_said = false;
        for (const auto& a : msg->acupoints) {
          if (a.valid) ++valid;
          if (contains(a.reason, "layout not trusted: " + problem)) profile_said = true;
          if (!a.reason.empty()) a_reason = a.reason;
        }
        if (profile_said) ++refused_for_profile;
      });
  const ros::Subscriber diagnostics =
      nh.subscribe<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10, [&](const auto& msg) {
        for (const auto& st : msg->status) {
          if (!contains(st.name, kDiagnostics)) continue;
          status = st;
          have_status = true;
        }
      });
  massage_cell::test::spinUntil([&] { return refused_for_profile >= 3 && have_status; }, 40.0);

  ASSERT_GT(messages, 0) << "no acupoints published: the node did not keep running?";
  EXPECT_EQ(valid, 0) << "an acupoint published valid while the node has no readable profile";
  EXPECT_GE(refused_for_profile, 3) << with_layout << " of " << messages
                                    << " messages with a layout; a reason: " << a_reason;
  ASSERT_TRUE(have_status) << "no diagnostics from the cect node";
  EXPECT_EQ(status.level, diagnostic_msgs::DiagnosticStatus::ERROR) << status.message;
  EXPECT_TRUE(contains(status.message, problem)) << status.message;
  std::string value;
  for (const auto& kv : status.values)
    if (kv.key == "client profile") value = kv.value;
  EXPECT_EQ(value, profile + " not usable");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cect_client_profile_error");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
