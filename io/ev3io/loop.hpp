/// @file loop.hpp
/// @brief Event-loop helpers: the monotonic clock, SIGINT/SIGTERM as a flag, and one wait (ppoll)
///        that sleeps until a descriptor is readable, a deadline passes or a signal arrives.
#pragma once

#include <poll.h>

#include <cstddef>

#include <cstdint>

#include <ev3proto/timers.hpp>

namespace ev3io {

using ev3proto::Millis;

/// "No deadline".
inline constexpr Millis kNever = ~Millis{0};

/// Milliseconds of CLOCK_MONOTONIC.
Millis monotonic_ms() noexcept;

/// Milliseconds of CLOCK_REALTIME (since 1970; may jump when the clock is set).
std::uint64_t wall_ms() noexcept;

/// Blocks SIGINT and SIGTERM (they are delivered only inside wait()) and ignores SIGPIPE.
/// One per program.
class Signals {
 public:
  Signals() noexcept;
  /// The signal that asked the program to stop (0 when none).
  int stop_signal() const noexcept;
  /// Waits until one of @p fds is readable, @p deadline (monotonic ms) passes, or a signal
  /// arrives. Returns poll's count (0 on timeout or signal).
  int wait(pollfd* fds, std::size_t n, Millis deadline) const noexcept;
};

}  // namespace ev3io
