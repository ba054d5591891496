/// @file wait_runner.hpp
/// @brief The robot-side behaviour runner of ev3-agent, fed by the agent core's control events
///        (start, pause, resume, stop, restart). Its one built-in behaviour is `wait seconds=N`:
///        the robot stands still and reports ACTION_OK (core: action_ok) when the time is up.
///        No I/O and no thread: the running wait is a deadline the event loop sleeps towards.
#pragma once

#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/core.hpp>
#include <ev3proto/timers.hpp>

namespace ev3agent {

using ev3proto::ControlKind;
using ev3proto::Millis;

/// Longest wait accepted (seconds).
inline constexpr double kMaxWaitSeconds = 1e6;

/// Parses the arguments of `wait`: exactly one `seconds=N`, N a positive decimal (fractional
/// allowed). Returns "" and the duration in ms (at least 1), or what is wrong.
inline std::string parse_wait_args(const std::vector<std::string_view>& args, Millis& ms) {
  bool seen = false;
  double secs = 0;
  for (std::string_view a : args) {
    const std::size_t eq = a.find('=');
    const std::string_view key = a.substr(0, eq);
    if (eq == std::string_view::npos || key != "seconds")
      return "unknown argument '" + std::string(a) + "' (wait takes seconds=N)";
    const std::string v(a.substr(eq + 1));
    char* end = nullptr;
    const bool chars_ok = !v.empty() && v.find_first_not_of("0123456789.eE+-") == std::string::npos;
    const double d = chars_ok ? std::strtod(v.c_str(), &end) : 0.0;
    if (!chars_ok || end != v.c_str() + v.size() || !std::isfinite(d) || d <= 0 || d > kMaxWaitSeconds)
      return "bad value for seconds: '" + v + "' (expected a positive number)";
    seen = true;
    secs = d;
  }
  if (!seen) return "missing seconds=N";
  const auto v = static_cast<Millis>(std::llround(secs * 1000.0));
  ms = v == 0 ? 1 : v;
  return {};
}

/// The behaviour runner. Phases: idle (nothing loaded or stopped), running (deadline set),
/// paused (time left kept), done (ACTION_OK reported).
class WaitRunner {
 public:
  static constexpr Millis kNever = ~Millis{0};
  /// What poll() tells the program to report to the core.
  enum class Outcome { none, ok, failed };
  enum class Phase { idle, running, paused, done };

  /// A control event from the core for behaviour @p name with @p args, at @p now.
  void control(ControlKind k, std::string_view name, const std::vector<std::string_view>& args, Millis now) {
    switch (k) {
      case ControlKind::start:
      case ControlKind::restart: {
        error_.clear();
        Millis ms = 0;
        if (name != "wait")
          error_ = "behaviour '" + std::string(name) + "' has no runner";
        else
          error_ = parse_wait_args(args, ms);
        if (!error_.empty()) {
          phase_ = Phase::idle;
          fail_pending_ = true;
          return;
        }
        total_ = ms;
        left_ = ms;
        due_ = now + ms;
        phase_ = Phase::running;
        return;
      }
      case ControlKind::pause:
        if (phase_ == Phase::running) {
          left_ = due_ > now ? due_ - now : 0;
          phase_ = Phase::paused;
        }
        return;
      case ControlKind::resume:
        if (phase_ == Phase::paused) {
          due_ = now + left_;
          phase_ = Phase::running;
        }
        return;
      case ControlKind::stop:
        phase_ = Phase::idle;
        fail_pending_ = false;
        left_ = 0;
        return;
    }
  }

  /// When poll() has something to say next (kNever when nothing runs).
  Millis deadline() const noexcept {
    if (fail_pending_) return 0;
    return phase_ == Phase::running ? due_ : kNever;
  }

  /// At @p now: ok once when the wait is over, failed once after a start with bad arguments.
  Outcome poll(Millis now) noexcept {
    if (fail_pending_) {
      fail_pending_ = false;
      return Outcome::failed;
    }
    if (phase_ == Phase::running && now >= due_) {
      phase_ = Phase::done;
      left_ = 0;
      return Outcome::ok;
    }
    return Outcome::none;
  }

  Phase phase() const noexcept { return phase_; }
  /// Time left (running: until the deadline; paused: kept).
  Millis left(Millis now) const noexcept {
    if (phase_ == Phase::running) return due_ > now ? due_ - now : 0;
    return phase_ == Phase::paused ? left_ : 0;
  }
  Millis total() const noexcept { return total_; }
  /// Why the last start failed.
  const std::string& error() const noexcept { return error_; }

 private:
  Phase phase_ = Phase::idle;
  Millis total_ = 0, left_ = 0, due_ = 0;
  bool fail_pending_ = false;
  std::string error_;
};

}  // namespace ev3agent
