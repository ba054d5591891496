/// @file behaviour/model.hpp
/// @brief What the behaviour language and its checker need to know about a robot model: the devices
/// it declares, the actions it implements and the limits of its motors.
///
/// The checker reads a model from here only. Its devices are robot/'s roles (robot::Role) and their
/// bits; its actions name the robot layer's action kinds, plus `repeat`. Model A's
/// figures come from the ev3dev reference trees (tests/data/ev3dev: the large motor
/// `lego-ev3-l-motor` has max_speed 1050 and count_per_rot 360, so tacho counts per second are
/// degrees per second of the wheel) and from the thesis' test robot (docs/brief.md section 6).
#pragma once

#include <cstdint>
#include <string_view>

#include "../robot/device.hpp"
#include "../robot/events.hpp"
#include "../robot/model.hpp"

namespace ev3proto::behaviour {

/// The robot's words the language uses as they are: a device by its role (robot::Role, robot/model.hpp;
/// its bit in a device mask, robot::role_bit, is the agent core's Capabilities::devices bit, so a
/// robot's plugged mask can be passed as it is), an event by robot::EventKind (robot/events.hpp), a
/// stop mode by robot::StopAction (robot/device.hpp).
using robot::EventKind;
using robot::Role;
using robot::StopAction;

/// An action of the behaviour language: one of the robot layer's actions (robot/actions.hpp
/// action::Kind, other values), or `repeat`. The value is the bit position in Model::actions. `repeat` is Repeat(n, ...): a state that runs its
/// steps n times.
enum class ActionKind : std::uint8_t {
  run = 0,    ///< RunForever: both wheels at a speed until something else happens
  drive = 1,  ///< DriveDistance: straight ahead (or back) a distance
  turn = 2,   ///< Turn: in place about the axle midpoint, wheels opposite (positive: left)
  stop = 3,   ///< Stop: coast, brake or hold
  pause = 4,  ///< Pause: stop, let the robot settle, then take a clean reading of the reported sensors
  wait = 5,   ///< Wait: a time with the motors untouched
  repeat = 6, ///< Repeat(n, steps)
};
inline constexpr std::size_t kActionCount = 7;

/// Bit of an action in an action mask.
constexpr std::uint32_t bit(ActionKind a) noexcept { return std::uint32_t{1} << static_cast<unsigned>(a); }

/// The action's keyword in the language.
constexpr std::string_view to_string(ActionKind a) noexcept {
  switch (a) {
    case ActionKind::run: return "run";
    case ActionKind::drive: return "drive";
    case ActionKind::turn: return "turn";
    case ActionKind::stop: return "stop";
    case ActionKind::pause: return "pause";
    case ActionKind::wait: return "wait";
    case ActionKind::repeat: return "repeat";
  }
  return "?";
}

/// A robot model as the checker sees it.
struct Model {
  std::string_view name;       ///< as announced in AGENT ("A")
  std::uint32_t devices = 0;   ///< devices the model is built with (role_bit(Role))
  std::uint32_t actions = 0;   ///< actions it implements (bit(ActionKind))
  std::int32_t max_speed = 0;  ///< drive motors' max_speed, degrees of the wheel per second
};

/// Both drive motors.
inline constexpr std::uint32_t kDriveMotors = robot::kMotors;

/// Model A, the thesis' test robot: two large motors, touch, colour and ultrasonic sensors
/// (robot::kModelADevices); every action. max_speed is the large motor's (robot/ reads it from the motor).
inline constexpr Model kModelA{
    "A",
    robot::kModelADevices,
    bit(ActionKind::run) | bit(ActionKind::drive) | bit(ActionKind::turn) | bit(ActionKind::stop) | bit(ActionKind::pause) |
        bit(ActionKind::wait) | bit(ActionKind::repeat),
    1050,
};

}  // namespace ev3proto::behaviour
