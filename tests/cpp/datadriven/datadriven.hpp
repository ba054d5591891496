// Transcript tests in the style of etcd's datadriven testdata.
//
// A test file is a sequence of cases. Each case is one or more input lines, a line `----`, and the
// expected output lines, ended by a blank line (or the end of the file). Lines starting with `#`
// between cases are comments and are kept when the file is rewritten.
//
//     # the agent syncs
//     recv 1:50001:0:2:50001
//     ----
//     send master 3:1:0:3:0
//     state ACTIVE
//
// The runner hands each case's input lines to a callback and compares what it returns with the
// expected lines. With the environment variable EV3_REWRITE=1 it writes the actual output back into
// the file instead of failing, so a change in behaviour is reviewed as a diff of the testdata.
#pragma once

#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace datadriven {

/// One case of a transcript file.
struct Case {
  std::string file;                  ///< path of the file it came from
  int line = 0;                      ///< 1-based line of its first input line
  std::vector<std::string> comments; ///< comment and blank lines that precede it
  std::vector<std::string> input;    ///< the input lines
  std::vector<std::string> expected; ///< the expected output lines
};

/// The cases of a file, in order, and the comment lines after the last case.
struct File {
  std::vector<Case> cases;
  std::vector<std::string> trailer;
};

/// Parses a transcript file. On a malformed file, sets `error` and returns what was read so far.
inline File parse(const std::string& path, std::string& error) {
  File f;
  std::ifstream in(path);
  if (!in) {
    error = "cannot open " + path;
    return f;
  }
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  std::vector<std::string> pending;
  std::size_t i = 0;
  while (i < lines.size()) {
    const std::string& l = lines[i];
    if (l.empty() || l[0] == '#') {
      pending.push_back(l);
      ++i;
      continue;
    }
    Case c;
    c.file = path;
    c.line = static_cast<int>(i) + 1;
    c.comments = std::move(pending);
    pending.clear();
    while (i < lines.size() && lines[i] != "----") {
      if (lines[i].empty()) {
        error = path + ":" + std::to_string(i + 1) + ": blank line inside the input of a case "
                "(each case's input ends with a line ----)";
        return f;
      }
      c.input.push_back(lines[i++]);
    }
    if (i == lines.size()) {
      error = path + ":" + std::to_string(c.line) + ": case has no ---- line";
      return f;
    }
    ++i;  // skip ----
    while (i < lines.size() && !lines[i].empty()) c.expected.push_back(lines[i++]);
    f.cases.push_back(std::move(c));
  }
  f.trailer = std::move(pending);
  return f;
}

/// Writes a parsed file back, with each case's expected lines replaced by `actual[k]`.
inline bool rewrite(const std::string& path, const File& f,
                    const std::vector<std::vector<std::string>>& actual) {
  std::ostringstream out;
  for (std::size_t k = 0; k < f.cases.size(); ++k) {
    const Case& c = f.cases[k];
    for (const auto& l : c.comments) out << l << '\n';
    for (const auto& l : c.input) out << l << '\n';
    out << "----\n";
    for (const auto& l : actual[k]) out << l << '\n';
    // A case ends at a blank line; the comments of the next case (or the trailer) begin with one
    // when the file had it, so only add a separator where none would follow.
    const std::vector<std::string>& next = k + 1 < f.cases.size() ? f.cases[k + 1].comments : f.trailer;
    if (next.empty() || !next.front().empty()) out << '\n';
  }
  for (const auto& l : f.trailer) out << l << '\n';
  std::ofstream o(path, std::ios::trunc);
  o << out.str();
  return static_cast<bool>(o);
}

/// Splits the text a callback produced into lines (a trailing newline adds no empty line).
inline std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> v;
  std::istringstream s(text);
  for (std::string l; std::getline(s, l);) v.push_back(l);
  return v;
}

/// True when EV3_REWRITE=1: expectations are rewritten instead of checked.
inline bool rewriting() {
  const char* r = std::getenv("EV3_REWRITE");
  return r != nullptr && std::string(r) == "1";
}

}  // namespace datadriven
