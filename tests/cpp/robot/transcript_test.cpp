// Robot transcripts: every tests/cpp/testdata/action_*.txt and robot_*.txt file is one test, run by
// RobotDriver (robot_driver.hpp documents the commands). EV3_REWRITE=1 rewrites the expectations.
#include <gtest/gtest.h>

#include <string>

#include "../datadriven/run.hpp"
#include "robot_driver.hpp"

namespace {

std::vector<std::string> robot_files() {
  std::vector<std::string> v = datadriven::files_with_prefix(EV3_TESTDATA, "action_");
  for (const auto& f : datadriven::files_with_prefix(EV3_TESTDATA, "robot_")) v.push_back(f);
  return v;
}

class RobotTranscript : public ::testing::TestWithParam<std::string> {};
TEST_P(RobotTranscript, Matches) { datadriven::run_file<ev3test::RobotDriver>(GetParam()); }
INSTANTIATE_TEST_SUITE_P(Testdata, RobotTranscript, ::testing::ValuesIn(robot_files()), datadriven::test_name);

TEST(RobotTranscripts, FilesExist) {
  EXPECT_GE(datadriven::files_with_prefix(EV3_TESTDATA, "action_").size(), 6u);
  EXPECT_GE(datadriven::files_with_prefix(EV3_TESTDATA, "robot_").size(), 3u);
}

}  // namespace
