// Transcript tests (etcd datadriven style): every tests/cpp/testdata/agent_*.txt, master_*.txt and
// fleet_*.txt file is one test. EV3_REWRITE=1 rewrites the expectations instead of checking them.
#include <gtest/gtest.h>

#include <algorithm>
#include <dirent.h>
#include <string>
#include <vector>

#include "../datadriven/datadriven.hpp"
#include "agent_driver.hpp"
#include "fleet_driver.hpp"
#include "master_driver.hpp"

namespace {

std::vector<std::string> files_with_prefix(const std::string& prefix) {
  std::vector<std::string> out;
  DIR* d = opendir(EV3_TESTDATA);
  if (d == nullptr) return out;
  while (dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n.rfind(prefix, 0) == 0 && n.size() > 4 && n.substr(n.size() - 4) == ".txt") {
      out.push_back(std::string(EV3_TESTDATA) + "/" + n);
    }
  }
  closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

std::string test_name(const ::testing::TestParamInfo<std::string>& p) {
  std::string n = p.param.substr(p.param.rfind('/') + 1);
  n = n.substr(0, n.size() - 4);
  std::replace_if(n.begin(), n.end(), [](char ch) { return !isalnum(static_cast<unsigned char>(ch)); }, '_');
  return n;
}

template <typename Driver>
void run_file(const std::string& path) {
  std::string error;
  const datadriven::File f = datadriven::parse(path, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_FALSE(f.cases.empty()) << path << " has no cases";
  Driver driver;
  std::vector<std::vector<std::string>> actual;
  for (const datadriven::Case& c : f.cases) {
    actual.push_back(driver.run(c.input));
    if (!datadriven::rewriting()) {
      std::string want, got;
      for (const auto& l : c.expected) want += l + "\n";
      for (const auto& l : actual.back()) got += l + "\n";
      EXPECT_EQ(want, got) << c.file << ":" << c.line;
    }
  }
  if (datadriven::rewriting()) {
    ASSERT_TRUE(datadriven::rewrite(path, f, actual));
  }
}

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
