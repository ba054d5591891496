// ev3-behaviour's command line (tests/cpp/testdata/behaviour_cli.txt): each case is `cli ARGS`
// (run by /bin/sh in the source tree, so behaviours/explore.bhv names a built-in's file) and, in its
// other input lines, a definition written to a temporary file that $FILE names. The output is the
// program's stdout lines (`out: `), stderr lines (`err: `) and `exit N`, with the file's path as $FILE.
// EV3_REWRITE=1 rewrites the expectations instead of checking them.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "check_file.hpp"

namespace {

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
  return s;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string run_cli(const std::vector<std::string>& input, const std::string& dir) {
  const std::string file = dir + "/definition.bhv";
  {
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
    for (std::size_t i = 1; i < input.size(); ++i) f << input[i] << "\n";
  }
  std::string args = input[0].substr(input[0].find(' ') + 1);
  args = replace_all(args, "$FILE", file);
  const std::string cmd = "cd '" EV3_SOURCE_DIR "' && '" EV3_BEHAVIOUR_BIN "' " + args + " >'" + dir + "/out' 2>'" +
                          dir + "/err'";
  const int rc = std::system(cmd.c_str());
  std::string text;
  for (const auto& [prefix, name] : {std::pair<const char*, const char*>{"out: ", "/out"}, {"err: ", "/err"}})
    for (const std::string& l : datadriven::split_lines(slurp(dir + name))) text += prefix + l + "\n";
  text += "exit " + std::to_string(WIFEXITED(rc) ? WEXITSTATUS(rc) : -1) + "\n";
  return replace_all(text, file, "$FILE");
}

TEST(BehaviourCli, Transcript) {
  char tmpl[] = "/tmp/ev3bhvcli.XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl;
  bhvtest::check_file(std::string(EV3_TESTDATA) + "/behaviour_cli.txt", [&](const datadriven::Case& c) {
    EXPECT_EQ(c.input[0].rfind("cli ", 0), 0u) << c.file << ":" << c.line << ": a case starts with cli";
    return run_cli(c.input, dir);
  });
  std::system(("rm -rf '" + dir + "'").c_str());
}

}  // namespace
