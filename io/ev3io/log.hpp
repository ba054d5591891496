/// @file log.hpp
/// @brief The programs' logger: levels 0 (none) .. 4 (verbose) as in the thesis, to stderr or a
///        file, buffered and flushed at an interval (and at exit).
#pragma once

#include <cstdio>
#include <string>

#include <ev3proto/timers.hpp>

namespace ev3io {

using ev3proto::Millis;

/// Log levels (`--log-level`): a message is written when its level <= the configured one. A program
/// takes them all with `using namespace ev3io::levels;`.
inline namespace levels {
enum Level : int { kNone = 0, kError = 1, kInfo = 2, kDebug = 3, kVerbose = 4 };
}  // namespace levels

/// A buffered line logger. Lines: `[   12.345] I agent: text` (seconds since start).
class Logger {
 public:
  /// Flush interval.
  static constexpr Millis kFlushMs = 100;

  Logger() = default;
  ~Logger();
  Logger(const Logger&) = delete;
  Logger& operator=(const Logger&) = delete;

  /// Name shown in every line ("agent", "master").
  void set_name(std::string name) { name_ = std::move(name); }
  /// Messages above @p level are not written.
  void set_level(int level) noexcept { level_ = level; }
  int level() const noexcept { return level_; }
  /// Writes to @p path (appending) instead of stderr. False (with errno) when it cannot be opened.
  bool open(const std::string& path);
  /// True when a message of @p level is written.
  bool enabled(int level) const noexcept { return level > kNone && level <= level_; }
  /// Writes a message (printf-style) at @p level.
  void log(int level, const char* fmt, ...) __attribute__((format(printf, 3, 4)));
  /// Writes the buffer out now.
  void flush();
  /// Flushes when the interval has passed; returns the next time it wants to be called.
  Millis tick(Millis now);

 private:
  std::string name_ = "ev3";
  int level_ = kInfo;
  std::FILE* file_ = nullptr;  // nullptr: stderr
  std::string buf_;
  Millis start_ = 0;
  Millis last_flush_ = 0;
};

}  // namespace ev3io
