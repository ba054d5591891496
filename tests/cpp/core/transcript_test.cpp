// Transcript tests (etcd datadriven style): every tests/cpp/testdata/agent_*.txt, master_*.txt and
// fleet_*.txt file is one test. EV3_REWRITE=1 rewrites the expectations instead of checking them.
#include <gtest/gtest.h>

#include <string>

#include "../datadriven/run.hpp"
#include "agent_driver.hpp"
#include "fleet_driver.hpp"
#include "master_driver.hpp"

namespace {

std::vector<std::string> files_with_prefix(const std::string& prefix) {
  return datadriven::files_with_prefix(EV3_TESTDATA, prefix);
}
using datadriven::run_file;
using datadriven::test_name;

class AgentTranscript : public ::testing::TestWithParam<std::string> {};
TEST_P(AgentTranscript, Matches) { run_file<ev3test::AgentDriver>(GetParam()); }
INSTANTIATE_TEST_SUITE_P(Testdata, AgentTranscript, ::testing::ValuesIn(files_with_prefix("agent_")),
                         test_name);

class MasterTranscript : public ::testing::TestWithParam<std::string> {};
TEST_P(MasterTranscript, Matches) { run_file<ev3test::MasterDriver>(GetParam()); }
INSTANTIATE_TEST_SUITE_P(Testdata, MasterTranscript, ::testing::ValuesIn(files_with_prefix("master_")),
                         test_name);

class FleetTranscript : public ::testing::TestWithParam<std::string> {};
TEST_P(FleetTranscript, Matches) { run_file<ev3test::FleetDriver>(GetParam()); }
INSTANTIATE_TEST_SUITE_P(Testdata, FleetTranscript, ::testing::ValuesIn(files_with_prefix("fleet_")),
                         test_name);

TEST(Transcripts, FilesExist) {
  EXPECT_GE(files_with_prefix("agent_").size(), 5u);
  EXPECT_GE(files_with_prefix("master_").size(), 2u);
  EXPECT_GE(files_with_prefix("fleet_").size(), 2u);
}

}  // namespace
