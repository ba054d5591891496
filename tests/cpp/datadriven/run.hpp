// Running transcript files as GoogleTest tests: the files of a directory with a prefix, and one
// file checked (or, with EV3_REWRITE=1, rewritten) through a driver whose run(input lines) returns
// the output lines. Shared by the core and the robot transcripts.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <dirent.h>
#include <string>
#include <vector>

#include "datadriven.hpp"

namespace datadriven {

/// The .txt files of @p dir whose names start with @p prefix, sorted.
inline std::vector<std::string> files_with_prefix(const std::string& dir, const std::string& prefix) {
  std::vector<std::string> out;
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return out;
  while (dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n.rfind(prefix, 0) == 0 && n.size() > 4 && n.substr(n.size() - 4) == ".txt") out.push_back(dir + "/" + n);
  }
  closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

/// A test name from a file path ("agent_sync" for .../agent_sync.txt).
inline std::string test_name(const ::testing::TestParamInfo<std::string>& p) {
  std::string n = p.param.substr(p.param.rfind('/') + 1);
  n = n.substr(0, n.size() - 4);
  std::replace_if(n.begin(), n.end(), [](char ch) { return !std::isalnum(static_cast<unsigned char>(ch)); }, '_');
  return n;
}

/// Checks every case of @p path against a fresh Driver (one driver for the whole file).
template <typename Driver>
void run_file(const std::string& path) {
  std::string error;
  const File f = parse(path, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_FALSE(f.cases.empty()) << path << " has no cases";
  Driver driver;
  std::vector<std::vector<std::string>> actual;
  for (const Case& c : f.cases) {
    actual.push_back(driver.run(c.input));
    if (!rewriting()) {
      std::string want, got;
      for (const auto& l : c.expected) want += l + "\n";
      for (const auto& l : actual.back()) got += l + "\n";
      EXPECT_EQ(want, got) << c.file << ":" << c.line;
    }
  }
  if (rewriting()) {
    ASSERT_TRUE(rewrite(path, f, actual));
  }
}

}  // namespace datadriven
