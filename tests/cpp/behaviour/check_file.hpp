// Runs every case of a transcript file through a function and compares (or, with EV3_REWRITE=1,
// rewrites) the expected lines: shared by the behaviour and CLI transcript tests.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "../datadriven/datadriven.hpp"

namespace bhvtest {

/// The transcript files of the test data directory whose names start with @p prefix (and not with
/// @p except, when given), sorted.
inline std::vector<std::string> transcripts(const std::string& prefix, const std::string& except = "") {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(EV3_TESTDATA)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix, 0) == 0 && (except.empty() || n.rfind(except, 0) != 0) && e.path().extension() == ".txt")
      out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// A parameterised test's name: its transcript file's stem.
inline std::string name_of(const ::testing::TestParamInfo<std::string>& p) {
  return std::filesystem::path(p.param).stem().string();
}

template <typename F>
void check_file(const std::string& path, F&& run) {
  std::string error;
  const datadriven::File f = datadriven::parse(path, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_FALSE(f.cases.empty()) << path << " has no cases";
  std::vector<std::vector<std::string>> actual;
  for (const datadriven::Case& c : f.cases) {
    const std::string got = run(c);
    actual.push_back(datadriven::split_lines(got));
    if (!datadriven::rewriting()) {
      std::string want;
      for (const auto& l : c.expected) want += l + "\n";
      EXPECT_EQ(want, got) << c.file << ":" << c.line;
    }
  }
  if (datadriven::rewriting()) {
    ASSERT_TRUE(datadriven::rewrite(path, f, actual));
  }
}

}  // namespace bhvtest
