/// @file behaviours.hpp
/// @brief What model A offers: its actions (kModelAActions), the behaviours its agent core accepts
///        (kModelABehaviours: wait, drive, explore, exploit, custom, each with the devices it needs),
///        and hand-written plans of `wait` and `drive` (build_behaviour), used by tests only: the
///        reference the behaviour language's versions (behaviours/*.bhv) are checked against. The robot runs every behaviour through behaviour::Automaton.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "actions.hpp"
#include "model.hpp"
#include "text.hpp"

namespace ev3proto::robot {

/// A built-in behaviour and the model devices it needs (agent core: BehaviourSpec{name, devices}).
struct BuiltinBehaviour {
  std::string_view name;
  std::uint32_t devices = 0;
};

/// An action a model supports and the model devices it needs.
struct ActionSupport {
  action::Kind kind;
  std::uint32_t devices = 0;
};

/// The actions of model A (the set is fixed per model, thesis 3.1.2): the master learns from it
/// what the robot can do. Pause needs no motor (it only stops those there) but reads sensors.
inline constexpr ActionSupport kModelAActions[] = {
    {action::Kind::drive_distance, kMotors}, {action::Kind::turn, kMotors}, {action::Kind::run_forever, kMotors},
    {action::Kind::stop, kMotors},           {action::Kind::pause, 0},      {action::Kind::wait, 0},
};

/// Model A's behaviours and the devices each needs plugged (the agent core refuses BEHAVIOUR with
/// "missing device: the robot has no ... (NAME needs it)" otherwise): the built-ins of behaviours/*.bhv, each the devices its definition
/// needs (behaviour::devices_needed; a test keeps the two equal), and `custom`, whose definition the
/// runtime checks on receipt (Runtime::check_behaviour: NOT with its reason when it cannot run).
inline constexpr BuiltinBehaviour kModelABehaviours[] = {
    {"wait", 0},
    {"drive", kMotors | kTouch | kUltrasonic},
    {"explore", kMotors | kTouch | kUltrasonic | kColour},
    {"exploit", kMotors | kTouch | kUltrasonic | kColour},
    {"custom", 0},
};

/// Longest `wait` accepted (seconds).
inline constexpr std::int32_t kMaxWaitSeconds = 1000000;

namespace detail {
/// Splits "key=value"; false when there is no '='.
constexpr bool split_arg(std::string_view a, std::string_view& key, std::string_view& value) noexcept {
  const std::size_t eq = a.find('=');
  if (eq == std::string_view::npos) return false;
  key = a.substr(0, eq);
  value = a.substr(eq + 1);
  return true;
}
constexpr bool unknown_arg(std::string_view a, std::string_view takes, ReasonText& why) noexcept {
  why.clear();
  why.append("unknown argument ");
  append_quoted(why, a);
  why.append(" (").append(takes).append(")");
  return false;
}
constexpr bool bad_value(std::string_view key, std::string_view v, std::string_view expected, ReasonText& why) noexcept {
  why.clear();
  why.append("bad value for ").append(key).append(": ");
  append_quoted(why, v);
  why.append(" (").append(expected).append(")");
  return false;
}
}  // namespace detail

/// `wait seconds=N`: N a positive decimal with at most 3 digits after the point, at most 10^6.
constexpr bool build_wait(const std::string_view* args, std::size_t n, action::Plan& out, ReasonText& why) noexcept {
  std::int32_t ms = -1;
  for (std::size_t i = 0; i < n; ++i) {
    std::string_view k, v;
    if (!detail::split_arg(args[i], k, v) || k != "seconds") return detail::unknown_arg(args[i], "wait takes seconds=N", why);
    std::int32_t raw = 0;
    if (!parse_decimal(v, 3, raw) || raw <= 0 || raw > kMaxWaitSeconds * 1000)
      return detail::bad_value("seconds", v, "a positive number of seconds, at most 3 decimals", why);
    ms = raw;
  }
  if (ms < 0) {
    why.clear();
    why.append("missing seconds=N");
    return false;
  }
  out = action::single(action::wait(static_cast<Millis>(ms)));
  return true;
}

/// `drive speed=N [stop=coast|brake|hold]`: both wheels at N counts per second (deg/s on the EV3
/// motors; negative backwards; the motors' max_speed is checked when it starts) until an obstacle
/// (OBSTACLE_DETECTED, PROXIMITY_ALERT: driving forward) or STOP.
constexpr bool build_drive(const std::string_view* args, std::size_t n, action::Plan& out, ReasonText& why) noexcept {
  bool have_speed = false;
  std::int32_t speed = 0;
  StopAction stop = StopAction::brake;
  for (std::size_t i = 0; i < n; ++i) {
    std::string_view k, v;
    if (!detail::split_arg(args[i], k, v) || (k != "speed" && k != "stop"))
      return detail::unknown_arg(args[i], "drive takes speed=N and stop=coast|brake|hold", why);
    if (k == "speed") {
      if (!parse_int(v, speed) || speed == 0 || v.back() == '\n')
        return detail::bad_value("speed", v, "a non-zero whole number of counts per second", why);
      have_speed = true;
    } else if (!parse_stop_action(v, stop)) {
      return detail::bad_value("stop", v, "coast, brake or hold", why);
    }
  }
  if (!have_speed) {
    why.clear();
    why.append("missing speed=N");
    return false;
  }
  out = action::single(action::run_forever(speed, speed, stop));
  return true;
}

/// The Plan of built-in behaviour @p name with @p args; false with the reason ("behaviour 'x' has
/// no runner", a bad argument).
constexpr bool build_behaviour(std::string_view name, const std::string_view* args, std::size_t n,
                               action::Plan& out, ReasonText& why) noexcept {
  if (name == "wait") return build_wait(args, n, out, why);
  if (name == "drive") return build_drive(args, n, out, why);
  why.clear();
  why.append("behaviour ");
  append_quoted(why, name);
  why.append(" has no runner");
  return false;
}

}  // namespace ev3proto::robot
