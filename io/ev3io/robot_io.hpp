/// @file robot_io.hpp
/// @brief The I/O half of the robot loop: moves bytes between the device layer (Ev3Devices) and
///        the robot runtime (libev3proto robot_runtime.hpp), so that the agent program's loop is
///        thin (docs/devices.md "The robot runtime"):
///
///     if (now >= io.next_scan()) io.scan(rt, now);        // plugged / unplugged, once a second
///     if (now >= rt.next_deadline()) io.tick(rt, now);    // the reads rt lists, then rt.tick()
///     ... rt.control() / rt.led() from the agent core's events ...
///     io.flush(rt, now);                                   // every write rt wants, in order
///     ... rt.poll_result() / poll_event() / poll_report() -> the agent core ...
///     sleep until min(core deadline, rt.next_deadline(), io.next_scan())
#pragma once

#include <cstddef>
#include <vector>

#include <ev3proto/robot_runtime.hpp>
#include <ev3proto/timers.hpp>

#include "ev3io/devices.hpp"

namespace ev3io {

class RobotIo {
 public:
  explicit RobotIo(Ev3Devices& devices) : devices_(devices) {}

  /// Scans for devices and tells @p rt what changed (the first call also announces the LEDs and
  /// the battery). Call at start and whenever now >= next_scan().
  void scan(ev3proto::robot::Runtime& rt, ev3proto::Millis now);
  ev3proto::Millis next_scan() const noexcept { return next_scan_; }

  /// One control tick: takes the reads @p rt lists (unplugged devices reported as they are found),
  /// feeds them, then rt.tick(now). Call when now >= rt.next_deadline().
  void tick(ev3proto::robot::Runtime& rt, ev3proto::Millis now);

  /// Makes every write @p rt wants, in order; a failed write goes back to rt before the next one
  /// (it drops what depended on it), an unplugged device is reported to it.
  void flush(ev3proto::robot::Runtime& rt, ev3proto::Millis now);

  /// Counters for the log and the benchmark.
  struct Stats {
    std::size_t reads = 0, writes = 0, failed_reads = 0, failed_writes = 0, unplugged = 0;
  };
  const Stats& stats() const noexcept { return stats_; }
  /// What the last scan found changed (for the log).
  const std::vector<DeviceChange>& changes() const noexcept { return changes_; }

 private:
  Ev3Devices& devices_;
  std::vector<DeviceChange> changes_;
  ev3proto::Millis next_scan_ = 0;
  bool announced_ = false;
  Stats stats_;
};

}  // namespace ev3io
