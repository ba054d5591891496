/// @file script.hpp
/// @brief A console script (ev3-master --script FILE, ev3-agent --master-script FILE): console
///        command lines run in order from a start time, `wait SECONDS` lines pausing between them
///        (docs/programs.md). The runner only says which line is due; the program runs it.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <ev3proto/timers.hpp>

namespace ev3prog {

class Script {
 public:
  /// Reads @p path (stdio). "" or the error ("cannot open 'PATH': reason").
  std::string load(const std::string& path);
  /// The lines, for a test or a script given in memory (not started).
  void set_lines(std::vector<std::string> lines) {
    lines_ = std::move(lines);
    pos_ = lines_.size();
  }
  /// Runs from the first line on, from @p now (ev3-master at start, an agent when it is elected).
  void start(ev3proto::Millis now) {
    pos_ = 0;
    at_ = now;
  }
  /// True when the file had no lines.
  bool empty() const { return lines_.empty(); }
  /// The next line due at @p now into @p line; false when none is due. A `wait S` line is taken
  /// here: the line after it is due S seconds after the call that takes it (the program calls again
  /// at once after running a line, so that is S seconds after the line before the wait).
  bool next(ev3proto::Millis now, std::string& line);
  /// When the next line is due (kNever when all have run).
  ev3proto::Millis deadline() const;

 private:
  std::vector<std::string> lines_;
  std::size_t pos_ = 0;
  ev3proto::Millis at_ = 0;
};

}  // namespace ev3prog
