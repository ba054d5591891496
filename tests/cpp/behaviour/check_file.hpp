// Runs every case of a transcript file through a function and compares (or, with EV3_REWRITE=1,
// rewrites) the expected lines: shared by the behaviour and CLI transcript tests.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../datadriven/datadriven.hpp"

namespace bhvtest {

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
