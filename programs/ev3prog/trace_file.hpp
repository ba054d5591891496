/// @file trace_file.hpp
/// @brief A program's --trace FILE: the NDJSON trace of its cores (one line per spec action,
///        docs/core.md "Trace"), written with stdio and flushed every 200 ms by the event loop and
///        at every state-file write, so a killed program leaves a trace that ends at most 200 ms
///        before it and holds every durable change (an epoch, a vote, a membership) it announced.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

#include <ev3proto/timers.hpp>

namespace ev3prog {

class TraceFile {
 public:
  TraceFile() = default;
  TraceFile(const TraceFile&) = delete;
  TraceFile& operator=(const TraceFile&) = delete;
  ~TraceFile() { close(); }

  /// Opens (truncates) @p path. "" or the error ("cannot open 'PATH': reason").
  std::string open(const std::string& path);
  /// True between a successful open() and close().
  bool is_open() const { return f_ != nullptr; }
  /// Writes one line and a newline (nothing when closed).
  void write(const std::string& line);
  /// A callback writing lines here, for NdjsonTrace::set_output().
  std::function<void(const std::string&)> output() {
    return [this](const std::string& line) { write(line); };
  }
  /// Flushes when 200 ms have passed since the last flush; the next time to call it (kNever when
  /// closed).
  ev3proto::Millis tick(ev3proto::Millis now);
  /// Flushes now (nothing when closed).
  void flush();
  /// Flushes and closes.
  void close();

 private:
  std::FILE* f_ = nullptr;
  ev3proto::Millis next_flush_ = 0;
};

}  // namespace ev3prog
