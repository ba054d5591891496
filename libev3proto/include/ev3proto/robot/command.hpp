/// @file command.hpp
/// @brief Commands: one per ev3dev device command, named like it, checked against the device's own
///        limits, turned into the attribute writes it needs in the order the driver needs them.
///
/// Motor commands (tacho-motor `command`): run-forever, run-to-abs-pos, run-to-rel-pos, run-timed,
/// stop, reset; plus setting `position`. Sensor command: set the mode. Each is a plain struct;
/// Tacho::apply / Sensor::set_mode check it and append writes to a WriteQueue, or refuse with a
/// reason naming the port, the value and the limit.
///
/// The driver's traps, handled here once:
/// - A setpoint (speed_sp, position_sp, time_sp, stop_action) takes effect only when a command is
///   written after it: every command writes its setpoints first and `command` last, always (a new
///   speed is a new run-forever, never a lone speed_sp write).
/// - `stop` with `hold` after a run-to-abs-pos / run-to-rel-pos keeps driving to the position target
///   (the driver's hold loop keeps that target): that stop is written as run-forever at speed_sp 0
///   (the driver forgets the target and brakes the wheel to a standstill), then stop with hold (it
///   holds where it is).
/// - run-to-rel-pos after a run-to-rel-pos counts from the previous target, not from where the
///   wheel is (legoev3_motor.c: `position_sp += ...` when the last command was run-to-rel-pos): after
///   a move that stopped short or long, the next relative move goes somewhere else. RunToRelPos is
///   written as asked (it is ev3dev's command); the actions use run-to-abs-pos, whose target is
///   the one computed.
/// - Writing `position` fails with EBUSY while the motor runs or holds: refused beforehand when the
///   last command leaves it running or holding; if the driver still says EBUSY the runtime reports it.
/// - Setting a sensor mode is slow (~100 ms on the UART sensors): skipped when the mode is already
///   set; the ultrasonic's mode is never set twice within 250 ms (its single-shot modes lock up).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "../timers.hpp"
#include "device.hpp"
#include "../ring.hpp"
#include "text.hpp"

namespace ev3proto::robot {

using ev3proto::Millis;

/// One attribute write: `value` into ROOT/class/<class>/<device>/<attr> of the device on `dev`.
struct Write {
  Dev dev = Dev::outA;
  Attr attr = Attr::command;
  Text<24> value;
};

/// Writes in the order they must happen (a fixed ring). Full: the write is dropped and counted
/// (overflowed()); sized so that the runtime never fills it (tests check overflowed() == 0).
template <std::size_t N = 64>
class WriteQueue {
 public:
  void push(Dev d, Attr a, std::string_view v) noexcept {
    Write w;
    w.dev = d;
    w.attr = a;
    w.value = Text<24>(v);
    push(w);
  }
  void push_int(Dev d, Attr a, std::int64_t v) noexcept {
    Text<24> t;
    t.append_int(v);
    push(d, a, t.view());
  }
  void push(const Write& w) noexcept {
    if (!ring_.push(w)) ++overflowed_;
  }
  bool pop(Write& out) noexcept { return ring_.pop(out); }
  /// Drops the queued writes of @p d up to and including its next `command` (a command whose
  /// setpoint write failed must not run with the old setpoint).
  void drop_through_command(Dev d) noexcept {
    bool done = false;
    ring_.filter([&](const Write& w) {
      if (done || w.dev != d) return true;
      done = w.attr == Attr::command;
      return false;
    });
  }
  std::size_t size() const noexcept { return ring_.size(); }
  std::size_t overflowed() const noexcept { return overflowed_; }

 private:
  Ring<Write, N> ring_;
  std::size_t overflowed_ = 0;
};
using Writes = WriteQueue<64>;

// ------------------------------------------------------------------ motor commands

/// run-forever: turn at speed_sp until another command.
struct RunForever { std::int32_t speed_sp = 0; };
/// run-to-abs-pos: go to position_sp at |speed_sp|, then stop_action.
struct RunToAbsPos { std::int32_t position_sp = 0; std::int32_t speed_sp = 0; StopAction stop_action = StopAction::brake; };
/// run-to-rel-pos: go to position + position_sp at |speed_sp|, then stop_action.
struct RunToRelPos { std::int32_t position_sp = 0; std::int32_t speed_sp = 0; StopAction stop_action = StopAction::brake; };
/// run-timed: turn at speed_sp for time_sp ms, then stop_action.
struct RunTimed { std::int32_t time_sp = 0; std::int32_t speed_sp = 0; StopAction stop_action = StopAction::brake; };
/// stop: stop now with stop_action.
struct Stop { StopAction stop_action = StopAction::brake; };
/// reset: every attribute to its default, the motor stopped (coast), position 0.
struct Reset {};
/// Not a command: writes `position` (the count the motor calls its current position).
struct SetPosition { std::int32_t position = 0; };

/// The logic side of one tacho-motor: its limits (from MotorInfo) and what was last commanded
/// (the driver's traps depend on it). No I/O: commands become writes.
class Tacho {
 public:
  /// The port this motor logic stands for.
  void bind(Dev port) noexcept { port_ = port; }
  Dev port() const noexcept { return port_; }
  /// A motor appeared on the port with these limits (forgets what was commanded before).
  void attach(const MotorInfo& info) noexcept {
    info_ = info;
    present_ = true;
    last_ = MotorCommand::reset;
    last_stop_ = StopAction::coast;
    last_speed_ = 0;
  }
  /// The motor is gone.
  void detach() noexcept { present_ = false; }
  bool present() const noexcept { return present_; }
  /// True when the motor is there and lists run-timed in its commands.
  bool can_run_timed() const noexcept { return present_ && (info_.commands & bit(MotorCommand::run_timed)) != 0; }
  const MotorInfo& info() const noexcept { return info_; }
  /// The command written last (reset after attach).
  MotorCommand last_command() const noexcept { return last_; }
  /// True when the last command leaves the motor turning or holding (then `position` is busy).
  bool may_be_busy() const noexcept {
    if (last_ == MotorCommand::reset) return false;
    if (last_ == MotorCommand::stop) return last_stop_ == StopAction::hold;
    return true;  // a run command: turning, or holding / stopped at its end (unknown here)
  }

  bool apply(const RunForever& c, Writes& w, ReasonText& why) noexcept {
    if (!can(MotorCommand::run_forever, why) || !speed_ok(c.speed_sp, why)) return false;
    w.push_int(port_, Attr::speed_sp, c.speed_sp);
    command(MotorCommand::run_forever, w);
    last_speed_ = c.speed_sp;
    return true;
  }
  bool apply(const RunToAbsPos& c, Writes& w, ReasonText& why) noexcept {
    return run_to(MotorCommand::run_to_abs_pos, c.position_sp, c.speed_sp, c.stop_action, w, why);
  }
  bool apply(const RunToRelPos& c, Writes& w, ReasonText& why) noexcept {
    return run_to(MotorCommand::run_to_rel_pos, c.position_sp, c.speed_sp, c.stop_action, w, why);
  }
  bool apply(const RunTimed& c, Writes& w, ReasonText& why) noexcept {
    if (!can(MotorCommand::run_timed, why) || !speed_ok(c.speed_sp, why) || !stop_ok(c.stop_action, why))
      return false;
    if (c.time_sp < 0) {
      start(why).append("time_sp ").append_int(c.time_sp).append(" is negative");
      return false;
    }
    // run-timed again at the same speed and stop action (a watchdog's renewal): time_sp and command
    // only, the driver keeps the other setpoints
    const bool again = last_ == MotorCommand::run_timed;
    if (!again || last_speed_ != c.speed_sp) w.push_int(port_, Attr::speed_sp, c.speed_sp);
    w.push_int(port_, Attr::time_sp, c.time_sp);
    if (!again || last_stop_ != c.stop_action) w.push(port_, Attr::stop_action, to_string(c.stop_action));
    command(MotorCommand::run_timed, w);
    last_speed_ = c.speed_sp;
    last_stop_ = c.stop_action;
    return true;
  }
  /// stop; with hold after a run-to-*-pos: run-forever at 0 first (the trap, see the file doc).
  bool apply(const Stop& c, Writes& w, ReasonText& why) noexcept {
    if (!can(MotorCommand::stop, why) || !stop_ok(c.stop_action, why)) return false;
    if (c.stop_action == StopAction::hold &&
        (last_ == MotorCommand::run_to_abs_pos || last_ == MotorCommand::run_to_rel_pos) &&
        (info_.commands & bit(MotorCommand::run_forever)) != 0) {
      w.push_int(port_, Attr::speed_sp, 0);
      command(MotorCommand::run_forever, w);
      last_speed_ = 0;
    }
    w.push(port_, Attr::stop_action, to_string(c.stop_action));
    command(MotorCommand::stop, w);
    last_stop_ = c.stop_action;
    return true;
  }
  bool apply(const Reset&, Writes& w, ReasonText& why) noexcept {
    if (!can(MotorCommand::reset, why)) return false;
    command(MotorCommand::reset, w);
    last_stop_ = StopAction::coast;
    last_speed_ = 0;
    return true;
  }
  bool apply(const SetPosition& c, Writes& w, ReasonText& why) noexcept {
    if (!present_) return absent(why);
    if (may_be_busy()) {
      start(why).append("position is busy while the motor runs or holds (EBUSY): stop it with coast or brake first");
      return false;
    }
    w.push_int(port_, Attr::position, c.position);
    return true;
  }

  /// The stop action used by the last command that has one.
  StopAction last_stop_action() const noexcept { return last_stop_; }

 private:
  ReasonText& start(ReasonText& why) const noexcept {
    why.clear();
    why.append(to_string(port_)).append(": ");
    return why;
  }
  bool absent(ReasonText& why) const noexcept {
    start(why).append("no motor on the port");
    return false;
  }
  bool can(MotorCommand c, ReasonText& why) const noexcept {
    if (!present_) return absent(why);
    if ((info_.commands & bit(c)) == 0) {
      start(why).append("the motor does not list ").append(to_string(c)).append(" in commands");
      return false;
    }
    return true;
  }
  bool speed_ok(std::int32_t s, ReasonText& why) const noexcept {
    if (s > info_.max_speed || s < -info_.max_speed) {
      start(why).append("speed_sp ").append_int(s).append(" is beyond max_speed ").append_int(info_.max_speed);
      return false;
    }
    return true;
  }
  bool stop_ok(StopAction s, ReasonText& why) const noexcept {
    if ((info_.stop_actions & bit(s)) == 0) {
      start(why).append("the motor does not list ").append(to_string(s)).append(" in stop_actions");
      return false;
    }
    return true;
  }
  bool run_to(MotorCommand c, std::int32_t pos, std::int32_t speed, StopAction stop, Writes& w, ReasonText& why) noexcept {
    if (!can(c, why) || !speed_ok(speed, why) || !stop_ok(stop, why)) return false;
    if (speed == 0) {
      start(why).append("speed_sp 0 never reaches position_sp");
      return false;
    }
    w.push_int(port_, Attr::speed_sp, speed);
    w.push_int(port_, Attr::position_sp, pos);
    w.push(port_, Attr::stop_action, to_string(stop));
    command(c, w);
    last_speed_ = speed;
    last_stop_ = stop;
    return true;
  }
  void command(MotorCommand c, Writes& w) noexcept {
    w.push(port_, Attr::command, to_string(c));
    last_ = c;
  }

  Dev port_ = Dev::outA;
  MotorInfo info_;
  bool present_ = false;
  MotorCommand last_ = MotorCommand::reset;
  StopAction last_stop_ = StopAction::coast;
  std::int32_t last_speed_ = 0;
};

// ------------------------------------------------------------------ sensor mode

/// The least time between two mode writes to the ultrasonic (its single-shot and DC modes lock up
/// when the mode is set more often; ev3dev's sensor page: "250 msec ... seems sufficient").
inline constexpr Millis kUltrasonicModeGapMs = 250;

/// Outcome of a mode request.
enum class ModeOutcome : std::uint8_t {
  written,    ///< the write is queued; decimals / num_values / units must be read again
  unchanged,  ///< already in that mode: nothing written (mode writes are slow)
  too_soon,   ///< ultrasonic: wait until retry_at
  refused,    ///< not a mode of the sensor, or no sensor
};

/// The logic side of one lego-sensor: its description (SensorInfo) and its mode writes.
class Sensor {
 public:
  void bind(Dev port) noexcept { port_ = port; }
  Dev port() const noexcept { return port_; }
  void attach(const SensorInfo& info) noexcept {
    info_ = info;
    present_ = true;
    wrote_mode_ = false;
  }
  void detach() noexcept { present_ = false; }
  bool present() const noexcept { return present_; }
  const SensorInfo& info() const noexcept { return info_; }
  SensorInfo& info() noexcept { return info_; }

  /// A single-shot mode: each write of it takes one measurement, so it is written even when set.
  static constexpr bool single_shot(Driver d, std::string_view mode) noexcept {
    return d == Driver::ev3_ultrasonic && (mode == "US-SI-CM" || mode == "US-SI-IN");
  }

  /// Sets mode @p mode at @p now: skipped when already set (except single-shot modes), never
  /// twice within kUltrasonicModeGapMs on the ultrasonic (then too_soon with @p retry_at).
  ModeOutcome set_mode(std::string_view mode, Millis now, Writes& w, ReasonText& why, Millis& retry_at) noexcept {
    why.clear();
    if (!present_) {
      why.append(to_string(port_)).append(": no sensor on the port");
      return ModeOutcome::refused;
    }
    const int m = info_.find_mode(mode);
    if (m < 0) {
      why.append(to_string(port_)).append(": ").append(to_string(info_.driver)).append(" has no mode ");
      append_quoted(why, mode);
      return ModeOutcome::refused;
    }
    if (m == info_.mode && !single_shot(info_.driver, mode)) return ModeOutcome::unchanged;
    if (info_.driver == Driver::ev3_ultrasonic && wrote_mode_ && now < last_write_ + kUltrasonicModeGapMs) {
      retry_at = last_write_ + kUltrasonicModeGapMs;
      why.append(to_string(port_)).append(": mode set ").append_int(static_cast<std::int64_t>(now - last_write_))
          .append(" ms ago; the ultrasonic needs ").append_int(kUltrasonicModeGapMs).append(" ms between mode writes");
      return ModeOutcome::too_soon;
    }
    w.push(port_, Attr::mode, mode);
    info_.mode = static_cast<std::int8_t>(m);
    wrote_mode_ = true;
    last_write_ = now;
    return ModeOutcome::written;
  }

 private:
  Dev port_ = Dev::in1;
  SensorInfo info_;
  bool present_ = false;
  bool wrote_mode_ = false;
  Millis last_write_ = 0;
};

}  // namespace ev3proto::robot
